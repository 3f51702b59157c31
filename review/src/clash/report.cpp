// clashes.json, status against a previous run, and merging shards (plantview/clash.h).
#include <algorithm>
#include <cassert>
#include <charconv>
#include <cstdio>
#include <functional>
#include <istream>
#include <limits>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "clash/clash_internal.h"
#include "plantview/store.h"

namespace plantview {

namespace {

using nlohmann::json;

json xyz(const glm::dvec3& p) { return json::array({p.x, p.y, p.z}); }

std::string hex(uint64_t v) {
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}


// Reading: each getter throws a message naming the field; parse_clash_report catches it.
struct Bad {
  std::string message;
};

const json& field(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw Bad{where + ": '" + key + "' is missing"};
  return j.at(key);
}
double number(const json& j, const char* key, const std::string& where) {
  const json& v = field(j, key, where);
  if (!v.is_number()) throw Bad{where + ": '" + key + "' must be a number"};
  return v.get<double>();
}
std::string text(const json& j, const char* key, const std::string& where) {
  const json& v = field(j, key, where);
  if (!v.is_string()) throw Bad{where + ": '" + key + "' must be a string"};
  return v.get<std::string>();
}
// A count: a whole number from 0 to `max` (a JSON integer, not a fraction or a sign).
uint64_t count(const json& j, const char* key, const std::string& where,
               uint64_t max = std::numeric_limits<uint64_t>::max()) {
  const json& v = field(j, key, where);
  if (!v.is_number_unsigned() || v.get<uint64_t>() > max)
    throw Bad{where + ": '" + key + "' must be a whole number from 0 to " + std::to_string(max)};
  return v.get<uint64_t>();
}
uint64_t decimal(const json& j, const char* key, const std::string& where, int base = 10) {
  const std::string s = text(j, key, where);
  uint64_t v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v, base);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size())
    throw Bad{where + ": '" + key + "' must be a " + (base == 16 ? "hex" : "decimal") + " id"};
  return v;
}
glm::dvec3 point(const json& v, const std::string& where) {
  if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
    throw Bad{where + ": a point must be a list of 3 numbers"};
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}
// The texts of a file being read: each tag and group made once (clash.h: ClashText).
// The map's keys view the texts' own characters (a ClashText's never move). Without `share`
// each text is its own (a reading that keeps few of its clashes holds no table of them all).
struct Texts {
  bool share = true;
  std::unordered_map<std::string_view, ClashText> made;
  ClashText operator()(const std::string& text) {
    if (!share) return ClashText(text);
    auto it = made.find(text);
    if (it == made.end()) {
      ClashText shared(text);
      const std::string_view key = shared.view();
      it = made.emplace(key, std::move(shared)).first;
    }
    return it->second;
  }
};

ClashObject read_side(const json& j, const char* key, const std::string& where, Texts& texts) {
  const json& s = field(j, key, where);
  const std::string w = where + "." + key;
  ClashObject o;
  o.id = decimal(s, "id", w);
  o.tag = texts(text(s, "tag", w));
  if (!class_from_name(text(s, "class", w), o.object_class)) throw Bad{w + ": unknown 'class'"};
  o.pipeline_id = decimal(s, "pipeline_id", w);
  return o;
}

}  // namespace

namespace {

// One clash as the document's dump (json::dump(2), keys in order) writes it two levels in,
// appended to `out` without building its JSON value: at millions of clashes the values were
// most of the writing time. Numbers and texts go through nlohmann's own serializer, so the
// bytes are its bytes (tested against the document's dump).
class ClashWriter {
 public:
  void append(std::string& out, const Clash& c) {
    out += "{\n";
    side(out, "a", c.a);
    out += ",\n";
    side(out, "b", c.b);
    out += ",\n";
    if (c.changed_id) {
      field(out, 6, "changed_id") += '"' + std::to_string(c.changed_id) + "\",\n";
      text(field(out, 6, "changed_tag"), c.changed_tag().view()) += ",\n";  // (for readers)
    }
    if (c.kind == ClashKind::hard)
      number(field(out, 6, "depth_m"), c.depth_m) += ",\n";
    else
      number(field(out, 6, "distance_m"), c.distance_m) += ",\n";
    number(field(out, 6, "error_m"), c.error_m) += ",\n";
    text(field(out, 6, "group"), c.group.view()) += ",\n";
    field(out, 6, "id") += '"' + hex(c.id) + "\",\n";
    field(out, 6, "kind") += c.kind == ClashKind::hard ? "\"hard\",\n" : "\"clearance\",\n";
    field(out, 6, "points_m") += c.points_m.empty() ? "[]" : "[\n";
    for (size_t i = 0; i < c.points_m.size(); ++i) {
      out.append(8, ' ') += "[\n";
      for (int k = 0; k < 3; ++k) number(out.append(10, ' '), c.points_m[i][k]) += k < 2 ? ",\n" : "\n";
      out.append(8, ' ') += i + 1 < c.points_m.size() ? "],\n" : "]\n";
    }
    if (!c.points_m.empty()) out.append(6, ' ') += "]";
    out += ",\n";
    field(out, 6, "status") += '"' + std::string(clash_status_name(c.status)) + "\"\n";
    out.append(4, ' ') += "}";
  }

 private:
  static std::string& field(std::string& out, size_t indent, std::string_view key) {
    out.append(indent, ' ') += '"';
    return out.append(key) += "\": ";
  }
  std::string& number(std::string& out, double v) {
    value_ = v;
    return out += value_.dump();
  }
  std::string& text(std::string& out, std::string_view v) {
    value_ = std::string(v);
    return out += value_.dump(-1, ' ', false, json::error_handler_t::replace);
  }
  void side(std::string& out, std::string_view key, const ClashObject& o) {
    field(out, 6, key) += "{\n";
    field(out, 8, "class") += '"' + std::string(class_name(o.object_class)) + "\",\n";
    field(out, 8, "id") += '"' + std::to_string(o.id) + "\",\n";
    field(out, 8, "pipeline_id") += '"' + std::to_string(o.pipeline_id) + "\",\n";
    text(field(out, 8, "tag"), o.tag.view()) += "\n";
    out.append(6, ' ') += "}";
  }
  json value_;  // (reused: one allocation less a number)
};

}  // namespace

bool write_clash_report(const ClashReport& r, const std::function<bool(std::string_view)>& sink) {
  json rules = json::array();
  for (int i = 0; i < kClashRuleCount; ++i) rules.push_back(std::string(clash_rule_name(ClashRule(i))));
  json skipped = json::object();
  for (int i = 0; i < kClashRuleCount; ++i)
    skipped[std::string(clash_rule_name(ClashRule(i)))] = r.counts.skipped_by_rule[i];
  const json out = {
      {"version", 1},
      {"store",
       {{"directory", r.store_directory},
        {"spatial_origin_m", xyz(r.spatial_origin_m)},
        {"commit_id", std::to_string(r.commit_id)},
        {"revision", r.revision},
        {"objects", r.objects}}},
      {"settings",
       {{"tolerance_m", r.tolerance_m},
        {"clearance_m", r.clearance_m},
        {"between", r.between},
        {"and", r.with},
        {"include_connected", r.include_connected},
        {"rules", r.include_connected ? json::array() : rules},
        {"shard", std::to_string(r.shard.index) + "/" + std::to_string(r.shard.count)}}},
      {"counts",
       {{"block_pairs", r.counts.block_pairs},
        {"candidate_pairs", r.counts.candidate_pairs},
        {"narrow_pairs", r.counts.narrow_pairs},
        {"skipped_by_rule", skipped}}},
      {"clashes", json::array()}};
  // Keys are written in order: "clashes" first, then counts, settings, store, version.
  const std::string whole = out.dump(2, ' ', false, json::error_handler_t::replace);
  const std::string empty = "\"clashes\": []";
  const size_t at = whole.find(empty);
  assert(at != std::string::npos);
  if (!sink(std::string_view(whole).substr(0, at + empty.size() - 1))) return false;
  bool first = true;
  ClashWriter writer;
  std::string text;
  for (const Clash& c : r.clashes) {
    // Each clash as the whole document's dump would indent it (two levels in).
    text = first ? "\n    " : ",\n    ";
    first = false;
    writer.append(text, c);
    if (!sink(text)) return false;
  }
  return sink(r.clashes.empty() ? std::string_view("]") : std::string_view("\n  ]")) &&
         sink(std::string_view(whole).substr(at + empty.size())) && sink("\n");
}

std::string clash_report_json(const ClashReport& r) {
  std::string out;
  write_clash_report(r, [&out](std::string_view text) {
    out += text;
    return true;
  });
  return out;
}


namespace {

// One clash of the file (clash.h's format), naming the field and the clash index when wrong.
Clash read_clash(const json& c, size_t i, Texts& texts) {
  const std::string where = "clash " + std::to_string(i);
  Clash k;
  k.id = decimal(c, "id", where, 16);
  const std::string status = text(c, "status", where);
  if (status == "new") k.status = ClashStatus::new_clash;
  else if (status == "active") k.status = ClashStatus::active;
  else if (status == "resolved") k.status = ClashStatus::resolved;
  else throw Bad{where + ": unknown 'status'"};
  const std::string kind = text(c, "kind", where);
  if (kind == "hard") k.kind = ClashKind::hard;
  else if (kind == "clearance") k.kind = ClashKind::clearance;
  else throw Bad{where + ": unknown 'kind'"};
  k.a = read_side(c, "a", where, texts);
  k.b = read_side(c, "b", where, texts);
  if (k.kind == ClashKind::hard) k.depth_m = number(c, "depth_m", where);
  else k.distance_m = number(c, "distance_m", where);
  k.error_m = number(c, "error_m", where);
  const json& points = field(c, "points_m", where);
  if (!points.is_array() || points.empty()) throw Bad{where + ": 'points_m' must be a list of points"};
  for (const json& p : points) k.points_m.push_back(point(p, where + ".points_m"));
  k.group = texts(text(c, "group", where));
  if (c.contains("changed_id")) k.changed_id = decimal(c, "changed_id", where);
  return k;
}

// Reads a clashes file from parser events: the document as a tree, except that each element of
// the top-level "clashes" list becomes a Clash as soon as it is complete and its tree is dropped,
// so a file of millions of clashes is never held as JSON. Bad values throw Bad.
class ReportReader final : public nlohmann::json_sax<json> {
 public:
  json root;
  std::deque<Clash> clashes;
  std::string parse_error_message;
  // When set, each clash goes there (in the file's order) instead of `clashes`, and its texts
  // are not shared with the others' (the sink keeps few or none of them).
  std::function<void(Clash&&)> sink;

  void share_texts(bool share) { texts_.share = share; }
  bool null() override { return add(nullptr); }
  bool boolean(bool v) override { return add(v); }
  bool number_integer(number_integer_t v) override { return add(v); }
  bool number_unsigned(number_unsigned_t v) override { return add(v); }
  bool number_float(number_float_t v, const string_t&) override { return add(v); }
  bool string(string_t& v) override { return add(std::move(v)); }
  bool binary(binary_t&) override { return false; }
  bool start_object(std::size_t) override {
    if (in_clash_list()) {  // a clash: built aside
      clash_ = json::object();
      stack_.push_back(&clash_);
      return true;
    }
    stack_.push_back(add_container(json::object()));
    return true;
  }
  bool key(string_t& k) override {
    key_ = &(*stack_.back())[k];
    if (stack_.size() == 1) top_key_ = k;
    return true;
  }
  bool end_object() override {
    const json* done = stack_.back();
    stack_.pop_back();
    if (done == &clash_) {
      Clash c = read_clash(clash_, read_++, texts_);
      if (sink)
        sink(std::move(c));
      else
        clashes.push_back(std::move(c));
      clash_ = json();
    }
    return true;
  }
  bool start_array(std::size_t) override {
    json* list = add_container(json::array());
    if (stack_.size() == 1 && top_key_ == "clashes") clash_list_ = list;
    stack_.push_back(list);
    return true;
  }
  bool end_array() override {
    stack_.pop_back();
    return true;
  }
  bool parse_error(std::size_t position, const std::string&, const nlohmann::detail::exception&) override {
    parse_error_message = "not JSON (truncated or damaged) at byte " + std::to_string(position);
    return false;
  }

 private:
  std::vector<json*> stack_;
  json* key_ = nullptr;
  json* clash_list_ = nullptr;
  std::string top_key_;
  json clash_;
  Texts texts_;
  size_t read_ = 0;

  bool in_clash_list() const { return clash_list_ && !stack_.empty() && stack_.back() == clash_list_; }
  template <typename V>
  bool add(V&& v) {
    if (in_clash_list()) throw Bad{"clash " + std::to_string(read_) + ": must be an object"};
    add_container(json(std::forward<V>(v)));
    return true;
  }
  // Places the value where the events say (the root, a list's end, an object's key): its address.
  json* add_container(json&& v) {
    if (stack_.empty()) {
      root = std::move(v);
      return &root;
    }
    json& parent = *stack_.back();
    if (parent.is_array()) {
      parent.push_back(std::move(v));
      return &parent.back();
    }
    *key_ = std::move(v);
    return key_;
  }
};

template <typename Parse>
bool read_report(Parse&& parse, ClashReport& out, std::string& error,
                 std::function<void(Clash&&)> sink = nullptr) {
  try {
    ReportReader reader;
    reader.share_texts(!sink);
    reader.sink = std::move(sink);
    if (!parse(reader)) {
      error = reader.parse_error_message.empty() ? "not JSON (truncated or damaged)" : reader.parse_error_message;
      return false;
    }
    const json& j = reader.root;
    ClashReport r;
    const json& version = field(j, "version", "clashes file");
    if (!version.is_number_integer() || version.get<int>() != 1) throw Bad{"clashes file: version must be 1"};
    const json& store = field(j, "store", "clashes file");
    r.store_directory = text(store, "directory", "store");
    r.spatial_origin_m = point(field(store, "spatial_origin_m", "store"), "store.spatial_origin_m");
    r.commit_id = decimal(store, "commit_id", "store");
    r.revision = uint32_t(count(store, "revision", "store", std::numeric_limits<uint32_t>::max()));
    r.objects = count(store, "objects", "store");
    const json& settings = field(j, "settings", "clashes file");
    r.tolerance_m = number(settings, "tolerance_m", "settings");
    r.clearance_m = number(settings, "clearance_m", "settings");
    r.between = text(settings, "between", "settings");
    r.with = text(settings, "and", "settings");
    const json& connected = field(settings, "include_connected", "settings");
    if (!connected.is_boolean()) throw Bad{"settings: 'include_connected' must be true or false"};
    r.include_connected = connected.get<bool>();
    const std::string shard = text(settings, "shard", "settings");
    if (std::sscanf(shard.c_str(), "%u/%u", &r.shard.index, &r.shard.count) != 2 || r.shard.count == 0 ||
        r.shard.index >= r.shard.count)
      throw Bad{"settings: 'shard' must be I/N"};
    if (const json& counts = field(j, "counts", "clashes file"); counts.is_object()) {
      r.counts.block_pairs = count(counts, "block_pairs", "counts");
      r.counts.candidate_pairs = count(counts, "candidate_pairs", "counts");
      r.counts.narrow_pairs = count(counts, "narrow_pairs", "counts");
      const json& skipped = field(counts, "skipped_by_rule", "counts");
      for (int i = 0; i < kClashRuleCount; ++i)
        r.counts.skipped_by_rule[i] = count(skipped, std::string(clash_rule_name(ClashRule(i))).c_str(), "counts");
    }
    const json& clashes = field(j, "clashes", "clashes file");
    if (!clashes.is_array()) throw Bad{"clashes file: 'clashes' must be a list"};
    r.clashes = std::move(reader.clashes);
    out = std::move(r);
    return true;
  } catch (const Bad& bad) {
    error = bad.message;
    return false;
  }
}

}  // namespace

bool parse_clash_report(std::string_view input, ClashReport& out, std::string& error) {
  return read_report([&](ReportReader& reader) { return json::sax_parse(input.begin(), input.end(), &reader); },
                     out, error);
}

bool read_clash_report(std::istream& input, ClashReport& out, std::string& error) {
  return read_report([&](ReportReader& reader) { return json::sax_parse(input, &reader); }, out, error);
}

bool read_clash_report(std::istream& input, ClashReport& out, std::string& error,
                       const std::function<bool(const Clash&)>& keep) {
  std::deque<Clash> kept;
  ClashReport read;
  if (!read_report([&](ReportReader& reader) { return json::sax_parse(input, &reader); }, read, error,
                   [&](Clash&& c) {
                     if (keep(c)) kept.push_back(std::move(c));
                   }))
    return false;
  read.clashes = std::move(kept);
  out = std::move(read);
  return true;
}

bool read_previous_clashes(std::istream& input, PreviousClashes& out, std::string& error) {
  std::vector<ClashKey> keys;
  ClashReport header;
  const bool read = read_report([&](ReportReader& reader) { return json::sax_parse(input, &reader); }, header, error,
                                [&keys](Clash&& c) {
                                  keys.push_back({c.id, c.a.id, c.b.id, c.points_m.front(),
                                                  c.status == ClashStatus::resolved});
                                });
  if (!read) return false;
  out.header = std::move(header);
  out.keys = std::move(keys);
  return true;
}

namespace {

bool same_store(const ClashRun& x, const ClashRun& y, std::string& error) {
  if (x.store_directory != y.store_directory || x.spatial_origin_m != y.spatial_origin_m) {
    error = "it comes from another store (" + y.store_directory + ", not " + x.store_directory + ")";
    return false;
  }
  return true;
}

bool same_settings(const ClashRun& x, const ClashRun& y, std::string& error) {
  if (x.tolerance_m != y.tolerance_m || x.clearance_m != y.clearance_m || x.between != y.between ||
      x.with != y.with || x.include_connected != y.include_connected) {
    error = "it was run with other settings (tolerance, clearance, --between/--and, --include-connected)";
    return false;
  }
  return true;
}

}  // namespace

const ClashText& Clash::changed_tag() const {
  static const ClashText none;
  return changed_id == 0 ? none : changed_id == a.id ? a.tag : changed_id == b.id ? b.tag : none;
}

bool match_previous(ClashReport& report, const PreviousClashes& previous, std::vector<bool>& matched,
                    std::string& error) {
  if (!same_store(report, previous.header, error) || !same_settings(report, previous.header, error)) return false;
  const std::vector<ClashKey>& keys = previous.keys;
  matched.assign(keys.size(), false);
  // The previous clashes by pair (then by their order in the file).
  std::vector<uint32_t> by_pair;
  by_pair.reserve(keys.size());
  for (size_t i = 0; i < keys.size(); ++i)
    if (!keys[i].resolved) by_pair.push_back(uint32_t(i));
  const auto pair_of = [&](uint32_t i) { return std::pair(keys[i].a, keys[i].b); };
  std::sort(by_pair.begin(), by_pair.end(), [&](uint32_t x, uint32_t y) {
    return pair_of(x) != pair_of(y) ? pair_of(x) < pair_of(y) : x < y;
  });
  for (Clash& c : report.clashes) {
    c.status = ClashStatus::new_clash;
    // The same id, else the same pair with its first point within kClashMatchM.
    const auto key = std::pair(c.a.id, c.b.id);
    auto it = std::lower_bound(by_pair.begin(), by_pair.end(), key,
                               [&](uint32_t i, const std::pair<uint64_t, uint64_t>& k) { return pair_of(i) < k; });
    size_t best = keys.size();
    double best_m = kClashMatchM;
    for (; it != by_pair.end() && pair_of(*it) == key; ++it) {
      const ClashKey& p = keys[*it];
      if (matched[*it]) continue;
      const double d = p.id == c.id ? -1.0 : glm::length(p.first_point_m - c.points_m.front());
      if (d <= best_m) {
        best = *it;
        best_m = d;
      }
    }
    if (best < keys.size()) {
      matched[best] = true;
      c.status = ClashStatus::active;
      c.id = keys[best].id;
    }
  }
  return true;
}

namespace {

// The previous clash `index` (status `previous`) as this run lists it: resolved, unless found
// again or resolved already (then nothing).
bool still_resolved(size_t index, ClashStatus previous, const std::vector<bool>& matched) {
  return index < matched.size() && !matched[index] && previous != ClashStatus::resolved;
}

}  // namespace

bool append_resolved(ClashReport& report, std::istream& previous_file, const std::vector<bool>& matched,
                     std::string& error) {
  size_t index = 0;
  ClashReport header;
  const bool read = read_report([&](ReportReader& reader) { return json::sax_parse(previous_file, &reader); },
                                header, error, [&](Clash&& c) {
                                  if (still_resolved(index++, c.status, matched)) {
                                    c.status = ClashStatus::resolved;
                                    report.clashes.push_back(std::move(c));
                                  }
                                });
  if (read && index != matched.size()) {
    error = "it changed since it was first read (" + std::to_string(index) + " clashes, not " +
            std::to_string(matched.size()) + ")";
    return false;
  }
  if (read) sort_clashes(report.clashes);
  return read;
}

bool apply_previous(ClashReport& report, const ClashReport& previous, std::string& error) {
  PreviousClashes keys;
  keys.header = previous;  // (its header)
  keys.keys.reserve(previous.clashes.size());
  for (const Clash& c : previous.clashes)
    keys.keys.push_back({c.id, c.a.id, c.b.id, c.points_m.front(), c.status == ClashStatus::resolved});
  std::vector<bool> matched;
  if (!match_previous(report, keys, matched, error)) return false;
  for (size_t i = 0; i < previous.clashes.size(); ++i) {
    if (!still_resolved(i, previous.clashes[i].status, matched)) continue;
    Clash c = previous.clashes[i];
    c.status = ClashStatus::resolved;
    report.clashes.push_back(std::move(c));
  }
  sort_clashes(report.clashes);
  return true;
}

bool name_changed_objects(ClashReport& report, const ReadView& view, uint32_t since_revision,
                          std::string& note) {
  note.clear();
  const uint32_t now = view.info().revision;
  if (since_revision == now) return true;  // nothing changed: nothing new was caused
  if (since_revision > now) {
    note = "the previous run's revision " + std::to_string(since_revision) +
           " is later than the store's " + std::to_string(now) + ": changed objects not named";
    return false;
  }
  std::vector<ObjectChange> changes;
  std::string why;
  if (!view.changes(since_revision, now, changes, why)) {
    note = "changed objects not named: " + why;
    return false;
  }
  // (changes come in id order)
  const auto changed = [&](uint64_t id) {
    const auto it = std::lower_bound(changes.begin(), changes.end(), id,
                                     [](const ObjectChange& c, uint64_t v) { return c.id < v; });
    return it != changes.end() && it->id == id && it->kind != ChangeKind::removed;
  };
  for (Clash& c : report.clashes) {
    if (c.status != ClashStatus::new_clash) continue;
    c.changed_id = changed(c.a.id) ? c.a.id : changed(c.b.id) ? c.b.id : 0;
  }
  return true;
}

bool merge_reports(std::vector<ClashReport> shards, ClashReport& out, std::string& error) {
  if (shards.empty()) {
    error = "no shard results to merge";
    return false;
  }
  ClashReport merged;
  static_cast<ClashRun&>(merged) = shards.front();  // the first shard's header (the clashes below)
  merged.counts = ClashCounts();
  std::vector<bool> seen(shards.front().shard.count, false);
  for (size_t i = 0; i < shards.size(); ++i) {
    const ClashReport& s = shards[i];
    std::string why;
    if (!same_store(merged, s, why) || !same_settings(merged, s, why) || s.commit_id != merged.commit_id) {
      error = "shard result " + std::to_string(i + 1) + ": " + (why.empty() ? "another snapshot of the store" : why);
      return false;
    }
    if (s.shard.count != merged.shard.count || s.shard.index >= seen.size() || seen[s.shard.index]) {
      error = "shard result " + std::to_string(i + 1) + ": shard " + std::to_string(s.shard.index) + "/" +
              std::to_string(s.shard.count) + " is repeated or does not belong with the others";
      return false;
    }
    seen[s.shard.index] = true;
    for (std::deque<Clash>& from = shards[i].clashes; !from.empty(); from.pop_front())
      merged.clashes.push_back(std::move(from.front()));  // (the shard's list shrinks as the merge grows)
    merged.counts.block_pairs += s.counts.block_pairs;
    merged.counts.candidate_pairs += s.counts.candidate_pairs;
    merged.counts.narrow_pairs += s.counts.narrow_pairs;
    for (int r = 0; r < kClashRuleCount; ++r) merged.counts.skipped_by_rule[r] += s.counts.skipped_by_rule[r];
  }
  for (size_t i = 0; i < seen.size(); ++i)
    if (!seen[i]) {
      error = "shard " + std::to_string(i) + "/" + std::to_string(seen.size()) + " is missing";
      return false;
    }
  merged.shard = ClashShard();
  sort_clashes(merged.clashes);
  out = std::move(merged);
  return true;
}

bool clash_set_matches(const ReadView& view, const ClashSet& set, bool& matches, std::string& error) {
  matches = set.empty();
  if (matches) return true;
  ObjectClass c;
  if (class_from_name(set.word, c)) {
    matches = view.info().statistics.objects_by_class[int(c)] > 0;
    return true;
  }
  return view.for_each_object(
      [&](uint32_t, Object&& o) {
        matches = set.contains(o);
        return !matches;
      },
      true, error);
}

}  // namespace plantview
