// Review views to BCF topics and back (plantview/bcf.h states the mapping).
#include "plantview/bcf.h"

#include <fnmatch.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "../views_internal.h"
#include "bcf_internal.h"
#include "plantview/image.h"
#include "plantview/store.h"

namespace plantview {

namespace {

namespace fs = std::filesystem;
using bcf::Component;

constexpr const char* kSystem = "plantview";
constexpr const char* kDocumentName = "plantview-view.json";
constexpr double kDefaultTargetDistance_m = 10.0;
constexpr double kOrthogonalFov_deg = 50.0;

uint64_t fnv1a(std::string_view text, uint64_t h) {
  for (const unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

uint64_t mix(uint64_t x) {  // splitmix64's finaliser
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

std::string now_iso8601_utc() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

const std::string* find_attribute(const Object& o, std::string_view key) {
  for (const Attribute& a : o.attributes)
    if (a.key == key) return &a.value;
  return nullptr;
}

// The Tag attribute, else the decimal id: a component's AuthoringToolId.
std::string tool_id_of(const Object& o) {
  const std::string* tag = find_attribute(o, "Tag");
  return tag && !tag->empty() ? *tag : std::to_string(o.id);
}

Component component_for(const std::string& tool_id) { return {"", kSystem, tool_id}; }

// view_filters.h: a word is a class name or a glob against the name and the Tag.
bool matches_word(std::string_view word, ObjectClass object_class, const std::string& name,
                  const std::string& tag) {
  const std::string w(word);
  if (class_name(object_class) == word) return true;
  return fnmatch(w.c_str(), name.c_str(), 0) == 0 ||
         (!tag.empty() && fnmatch(w.c_str(), tag.c_str(), 0) == 0);
}
bool matches_any(const std::vector<std::string>& words, ObjectClass c, const std::string& name,
                 const std::string& tag) {
  for (const std::string& w : words)
    if (matches_word(w, c, name, tag)) return true;
  return false;
}

// What Visibility and Coloring need of every object (one pass over the store).
struct ObjectFacts {
  uint64_t id = 0;
  ObjectClass object_class = ObjectClass::other;
  std::string name, tag;
  std::map<std::string, std::string> values;  // the colour_by keys the views name
};

// A fixed palette, distinct on white and on the model's greys.
const char* kPalette[] = {"E6194B", "3CB44B", "FFE119", "4363D8", "F58231", "911EB4",
                          "46F0F0", "F032E6", "BCF60C", "FABEBE", "008080", "9A6324"};

std::string rgb_hex(const Colour& c) {
  char text[8];
  std::snprintf(text, sizeof text, "%02X%02X%02X", c.r, c.g, c.b);
  return text;
}

// "AARRGGBB" (BCF 2.1 and 3.0 read a Color of 8 digits as ARGB).
std::string argb_hex(const Colour& c, double alpha) {
  char text[12];
  std::snprintf(text, sizeof text, "%02X%02X%02X%02X", unsigned(std::lround(alpha * 255)), c.r, c.g, c.b);
  return text;
}

std::string colour_of(const std::string& value) {
  return kPalette[mix(fnv1a(value, 14695981039346656037ull)) % (sizeof kPalette / sizeof kPalette[0])];
}

// The snapshot to store for a view: the PNG itself, or a JPEG re-encoded as a temporary PNG.
bool png_snapshot(const fs::path& image, const fs::path& scratch, fs::path& png, bool& converted,
                  std::string& error) {
  converted = false;
  std::string ext = image.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  std::error_code ec;
  if (!fs::is_regular_file(image, ec)) {
    error = image.string() + ": no such image";
    return false;
  }
  if (ext == ".png") {
    png = image;
    return true;
  }
  if (ext != ".jpg" && ext != ".jpeg") {
    error = image.string() + ": a snapshot must be PNG or JPEG (BCF snapshots are PNG)";
    return false;
  }
  Image decoded;
  std::vector<uint8_t> bytes;
  if (!read_image(image.string(), decoded, error) ||
      !encode_image(decoded, ImageFormat::png, 0, bytes, error)) {
    error = image.string() + ": cannot convert to PNG: " + error;
    return false;
  }
  png = scratch;
  FILE* f = std::fopen(png.c_str(), "wb");
  const bool ok = f && std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  if (f && std::fclose(f) != 0) ec = std::make_error_code(std::errc::io_error);
  if (!ok || ec) {
    error = "cannot write " + png.string();
    return false;
  }
  converted = true;
  return true;
}

// The section as clipping planes: the box's six faces first, then the planes.
std::vector<ClipPlane> clipping_planes(const Section& s) {
  std::vector<ClipPlane> out;
  if (s.has_box) {
    const glm::dvec3 c = (s.box.min + s.box.max) * 0.5;
    for (int axis = 0; axis < 3; ++axis) {
      ClipPlane low, high;
      low.point_m = c;
      low.point_m[axis] = s.box.min[axis];
      low.normal = glm::dvec3(0.0);
      low.normal[axis] = -1.0;
      high.point_m = c;
      high.point_m[axis] = s.box.max[axis];
      high.normal = glm::dvec3(0.0);
      high.normal[axis] = 1.0;
      out.push_back(low);
      out.push_back(high);
    }
  }
  out.insert(out.end(), s.planes.begin(), s.planes.end());
  return out;
}

// Six planes in clipping_planes' box order, as a box; false if they are not.
bool planes_as_box(const std::vector<ClipPlane>& planes, DAabb& box) {
  if (planes.size() < 6) return false;
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      glm::dvec3 n(0.0);
      n[axis] = side == 0 ? -1.0 : 1.0;
      if (planes[size_t(axis * 2 + side)].normal != n) return false;
    }
    box.min[axis] = planes[size_t(axis * 2)].point_m[axis];
    box.max[axis] = planes[size_t(axis * 2 + 1)].point_m[axis];
    if (!(box.min[axis] <= box.max[axis])) return false;
  }
  return true;
}

}  // namespace

std::string bcf_guid(std::string_view text) {
  const uint64_t a = mix(fnv1a(text, 14695981039346656037ull));
  const uint64_t b = mix(fnv1a(text, 0x84222325cbf29ce4ull) ^ a);
  uint8_t bytes[16];
  for (int i = 0; i < 8; ++i) {
    bytes[i] = uint8_t(a >> (56 - 8 * i));
    bytes[8 + i] = uint8_t(b >> (56 - 8 * i));
  }
  bytes[6] = uint8_t((bytes[6] & 0x0f) | 0x50);  // version 5 (name-based)
  bytes[8] = uint8_t((bytes[8] & 0x3f) | 0x80);  // RFC 4122 variant
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (int i = 0; i < 16; ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out += '-';
    out += hex[bytes[i] >> 4];
    out += hex[bytes[i] & 15];
  }
  return out;
}

bool write_bcf(const fs::path& path, const std::vector<ReviewView>& views,
               const std::vector<fs::path>& snapshots, const ReadView* store, const BcfWriteOptions& options,
               BcfWriteReport& report, std::string& error) {
  assert(snapshots.size() == views.size());
  report = {};
  const std::string date = options.date.empty() ? now_iso8601_utc() : options.date;

  // Each subject's AuthoringToolId (its Tag, else its id).
  std::unordered_map<uint64_t, std::string> tool_ids;
  bool need_pass = false;
  std::set<std::string> colour_keys;
  for (const ReviewView& v : views) {
    if (!v.style.hide.empty() || !v.style.only.empty() || !v.style.colour_by.empty()) need_pass = true;
    if (!v.style.colour_by.empty()) colour_keys.insert(v.style.colour_by);
  }
  std::vector<ObjectFacts> facts;
  if (store && need_pass) {
    const bool ok = store->for_each_object(
        [&](uint32_t, Object&& o) {
          ObjectFacts f;
          f.id = o.id;
          f.object_class = o.object_class;
          f.tag = [&] {
            const std::string* t = find_attribute(o, "Tag");
            return t ? *t : std::string();
          }();
          f.name = std::move(o.name);
          for (const std::string& key : colour_keys)
            if (const std::string* value = find_attribute(o, key); value && !value->empty())
              f.values[key] = *value;
          tool_ids[f.id] = f.tag.empty() ? std::to_string(f.id) : f.tag;
          facts.push_back(std::move(f));
          return true;
        },
        true, error);
    if (!ok) return false;
  } else if (store) {
    for (const ReviewView& v : views) {
      for (const uint64_t id : v.subject) {
        if (tool_ids.count(id)) continue;
        std::optional<uint32_t> slot;
        if (!store->slot_of(id, slot, error)) return false;
        Object o;
        if (slot && !store->object(*slot, o, true, error)) return false;
        tool_ids[id] = slot ? tool_id_of(o) : std::to_string(id);
      }
    }
  } else if (need_pass) {
    report.notes.push_back(
        "no store: hide, only and colour_by are not listed as BCF Visibility and Coloring "
        "(they travel in plantview-view.json only)");
  }
  const auto tool_id = [&](uint64_t id) {
    const auto found = tool_ids.find(id);
    return found != tool_ids.end() ? found->second : std::to_string(id);
  };

  // The temporary file, then the archive.
  std::string pattern = path.string() + ".tmp-XXXXXX";
  const int fd = mkstemp(pattern.data());
  if (fd < 0) {
    error = "cannot create a temporary file beside " + path.string() + ": " + std::strerror(errno);
    return false;
  }
  ::close(fd);
  const fs::path tmp = pattern;
  std::vector<fs::path> scratch_files;
  const auto clean_up = [&] {
    std::error_code ec;
    fs::remove(tmp, ec);
    for (const fs::path& p : scratch_files) fs::remove(p, ec);
  };
  bool ok = [&] {
    bcf::ZipWriter zip;
    if (!zip.open(tmp, error)) return false;
    if (!zip.add_bytes("bcf.version",
                       "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                       "<Version VersionId=\"2.1\">\n  <DetailedVersion>2.1</DetailedVersion>\n</Version>\n",
                       error))
      return false;
    size_t wide_fov = 0, visibility_unlisted = 0, colours_unlisted = 0;
    for (size_t i = 0; i < views.size(); ++i) {
      const ReviewView& view = views[i];
      const std::string topic_guid = bcf_guid(options.seed + "\ntopic\n" + view.name);
      const std::string folder = topic_guid + "/";
      bcf::Viewpoint vp;
      vp.guid = bcf_guid(options.seed + "\nviewpoint\n" + view.name);
      vp.camera = bcf::Viewpoint::CameraKind::perspective;
      vp.eye = view.camera.eye_m;
      vp.direction = glm::normalize(view.camera.target_m - view.camera.eye_m);
      vp.up = view.camera.up;
      vp.fov_deg = view.camera.fov_deg;
      if (vp.fov_deg < 45.0 || vp.fov_deg > 60.0) ++wide_fov;
      vp.planes = clipping_planes(view.section);
      for (const uint64_t id : view.subject) vp.selection.push_back(component_for(tool_id(id)));
      // Which objects the style shows (Coloring lists only those).
      const auto shown_by_style = [&](const ObjectFacts& f) {
        return (view.style.only.empty() || matches_any(view.style.only, f.object_class, f.name, f.tag)) &&
               !matches_any(view.style.hide, f.object_class, f.name, f.tag);
      };
      if (!facts.empty() && (!view.style.hide.empty() || !view.style.only.empty())) {
        std::vector<Component> shown, hidden;
        for (const ObjectFacts& f : facts)
          (shown_by_style(f) ? shown : hidden).push_back(component_for(tool_id(f.id)));
        if (!view.style.only.empty() && shown.size() <= options.max_listed) {
          vp.default_visibility = false;
          vp.exceptions = std::move(shown);
        } else if (hidden.size() <= options.max_listed) {
          vp.exceptions = std::move(hidden);
        } else {
          ++visibility_unlisted;
        }
      }
      if (!facts.empty() && !view.style.colour_by.empty()) {
        std::map<std::string, std::vector<Component>> groups;
        size_t listed = 0;
        for (const ObjectFacts& f : facts) {
          const auto value = f.values.find(view.style.colour_by);
          if (value == f.values.end() || !shown_by_style(f)) continue;
          groups[value->second].push_back(component_for(tool_id(f.id)));
          ++listed;
        }
        if (listed == 0) {
          report.notes.push_back("view '" + view.name + "': no object shown has the attribute '" +
                                 view.style.colour_by + "' (colour_by): no Coloring");
        } else if (listed > options.max_listed) {
          ++colours_unlisted;
        } else {
          // Values of one colour share a group (the schema allows one Color per colour).
          std::map<std::string, bcf::ColourGroup> by_colour;
          for (auto& [value, components] : groups) {
            std::optional<Colour> drawn;
            if (i < options.legends.size() && options.legends[i].key == view.style.colour_by)
              drawn = options.legends[i].colour_of(value);
            const std::string hex = drawn ? rgb_hex(*drawn) : colour_of(value);
            bcf::ColourGroup& g = by_colour[hex];
            g.rgb_hex = hex;
            g.components.insert(g.components.end(), components.begin(), components.end());
          }
          for (auto& [colour, group] : by_colour) vp.colours.push_back(std::move(group));
        }
      }
      // Subject colours (a clash's two objects): one Coloring each, as the image shows them
      // (a see-through one with its alpha, ARGB).
      for (const SubjectColour& c : view.colours)
        vp.colours.push_back({c.see_through ? argb_hex(c.colour, kSeeThroughSubjectAlpha) : rgb_hex(c.colour),
                              {component_for(tool_id(c.id))}});

      bcf::Markup markup;
      markup.guid = topic_guid;
      markup.title = view.title.empty() ? view.name : view.title;
      for (const std::string& line : caption_lines(view))
        markup.description += (markup.description.empty() ? "" : "\n") + line;
      markup.date = date;
      markup.author = options.author;
      markup.topic_type = view.kind == "clash" ? "Clash" : "Review";
      markup.documents.push_back({kDocumentName, "plantview review view (views-file format)"});
      markup.viewpoints.push_back({vp.guid, "viewpoint.bcfv", snapshots[i].empty() ? "" : "snapshot.png"});

      if (!zip.add_bytes(folder + "markup.bcf", bcf::write_markup(markup), error) ||
          !zip.add_bytes(folder + "viewpoint.bcfv", bcf::write_viewpoint(vp), error) ||
          !zip.add_bytes(folder + kDocumentName, review_views_json({view}, view.kind), error))
        return false;
      if (!snapshots[i].empty()) {
        fs::path png;
        bool converted = false;
        const fs::path scratch = tmp.string() + "-" + std::to_string(i) + ".png";
        if (!png_snapshot(snapshots[i], scratch, png, converted, error)) {
          error = "view '" + view.name + "': " + error;
          return false;
        }
        if (converted) {
          scratch_files.push_back(scratch);
          ++report.snapshots_converted;
        }
        if (!zip.add_file(folder + "snapshot.png", png, error)) return false;
      }
      ++report.topics;
    }
    if (wide_fov)
      report.notes.push_back(
          std::to_string(wide_fov) +
          " view(s) have a field of view outside BCF 2.1's 45..60 degrees; written as they are");
    if (visibility_unlisted)
      report.notes.push_back(
          std::to_string(visibility_unlisted) + " view(s) hide or show more than " +
          std::to_string(options.max_listed) +
          " objects: Visibility left at its default (plantview-view.json keeps hide/only)");
    if (colours_unlisted)
      report.notes.push_back(std::to_string(colours_unlisted) + " view(s) colour more than " +
                             std::to_string(options.max_listed) +
                             " objects: no Coloring written (plantview-view.json keeps colour_by)");
    return zip.close(error);
  }();
  if (ok) {
    // mkstemp made the file private; a BCF file is for sharing: rw-r--r--.
    std::error_code ec;
    fs::permissions(
        tmp, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read,
        ec);
    fs::rename(tmp, path, ec);
    if (ec) {
      error = "cannot rename " + tmp.string() + " to " + path.string() + ": " + ec.message();
      ok = false;
    }
  }
  if (!ok) report.topics = 0;
  clean_up();
  return ok;
}

// ---------------------------------------------------------------------------------------------
// Import.

namespace {

// Store objects by id, tag and name, for matching components (one pass).
struct ObjectIndex {
  std::unordered_set<uint64_t> ids;
  std::unordered_map<std::string, std::vector<uint64_t>> by_tag, by_name;
  std::unordered_map<uint64_t, std::pair<std::string, DAabb>> word_and_bounds;  // tag or name
};

bool parse_decimal(const std::string& text, uint64_t& out) {
  if (text.empty() || text.size() > 20) return false;
  out = 0;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
    const uint64_t next = out * 10 + uint64_t(c - '0');
    if (next / 10 != out) return false;
    out = next;
  }
  return true;
}

class Matcher {
 public:
  Matcher(const ObjectIndex* index, BcfReadReport& report) : index_(index), report_(report) {}

  // The store ids a component names (usually one); counts it matched or unknown.
  std::vector<uint64_t> match(const Component& c, const std::string& topic) {
    std::vector<uint64_t> ids;
    const std::string& key = c.authoring_tool_id;
    uint64_t id = 0;
    if (!key.empty()) {
      if (!index_) {
        if (parse_decimal(key, id)) ids.push_back(id);
      } else if (parse_decimal(key, id) && index_->ids.count(id)) {
        ids.push_back(id);
      } else if (const auto t = index_->by_tag.find(key); t != index_->by_tag.end()) {
        ids = t->second;
      } else if (const auto n = index_->by_name.find(key); n != index_->by_name.end()) {
        ids = n->second;
      } else if (const auto n2 = index_->by_name.find("/" + key); n2 != index_->by_name.end()) {
        ids = n2->second;
      }
    }
    if (!ids.empty()) {
      ++report_.components_matched;
      return ids;
    }
    ++report_.components_unknown;
    if (key.empty() && !c.ifc_guid.empty()) ++report_.components_ifc_only;
    if (report_.unknown_examples.size() < 5) {
      std::string what = !key.empty()          ? "AuthoringToolId '" + key + "'"
                         : !c.ifc_guid.empty() ? "IfcGuid " + c.ifc_guid
                                               : std::string("a component with no id");
      if (!c.originating_system.empty()) what += " (" + c.originating_system + ")";
      report_.unknown_examples.push_back("topic '" + topic + "': " + what);
    }
    return {};
  }

  // A word for style.hide / style.only naming the object (its tag, else its name).
  std::string word_of(uint64_t id) const {
    if (index_)
      if (const auto found = index_->word_and_bounds.find(id); found != index_->word_and_bounds.end())
        return found->second.first;
    return {};
  }
  DAabb bounds_of(const std::vector<uint64_t>& ids) const {
    DAabb box;
    if (index_)
      for (const uint64_t id : ids)
        if (const auto found = index_->word_and_bounds.find(id); found != index_->word_and_bounds.end())
          box.extend(found->second.second);
    return box;
  }

 private:
  const ObjectIndex* index_;
  BcfReadReport& report_;
};

void add_unique(std::vector<uint64_t>& to, const std::vector<uint64_t>& ids) {
  for (const uint64_t id : ids)
    if (std::find(to.begin(), to.end(), id) == to.end()) to.push_back(id);
}

std::string unique_name(const std::string& base, std::set<std::string>& used) {
  std::string name = base;
  for (int n = 2; used.count(name); ++n) name = base + "-" + std::to_string(n);
  used.insert(name);
  return name;
}

}  // namespace

bool read_bcf(const fs::path& path, const ReadView* store, const BcfReadOptions& options,
              std::vector<ReviewView>& out, BcfReadReport& report, std::string& error) {
  report = {};
  bcf::ZipReader zip;
  if (!zip.open(path, options.max_entry_bytes, options.max_total_bytes, error)) return false;
  const std::string file = path.string();

  std::vector<std::string> folders;  // topic folders, "GUID/", in archive order
  for (const std::string& name : zip.names()) {
    const size_t slash = name.find('/');
    if (slash != std::string::npos && name.substr(slash) == "/markup.bcf")
      folders.push_back(name.substr(0, slash + 1));
  }
  if (folders.empty()) {
    error = file + ": no topic (no FOLDER/markup.bcf entry): not a BCF file";
    return false;
  }

  ObjectIndex index;
  if (store) {
    const bool ok = store->for_each_object(
        [&](uint32_t, Object&& o) {
          const std::string* tag = find_attribute(o, "Tag");
          index.ids.insert(o.id);
          if (tag && !tag->empty()) index.by_tag[*tag].push_back(o.id);
          index.by_name[o.name].push_back(o.id);
          index.word_and_bounds[o.id] = {tag && !tag->empty() ? *tag : o.name, object_bounds(o)};
          return true;
        },
        true, error);
    if (!ok) return false;
  }
  Matcher matcher(store ? &index : nullptr, report);

  std::vector<ReviewView> views;
  std::set<std::string> used_names;
  size_t colour_groups_dropped = 0, planes_dropped = 0, fov_clamped = 0, up_replaced = 0;
  for (const std::string& folder : folders) {
    std::string text;
    bcf::Markup markup;
    if (!zip.read(folder + "markup.bcf", text, error) || !bcf::parse_markup(text, markup, error)) {
      error = file + ": " + folder + "markup.bcf: " + error;
      return false;
    }
    ++report.topics;
    const std::string topic = markup.title.empty() ? folder.substr(0, folder.size() - 1) : markup.title;
    // plantview's own document, when the topic has one.
    std::optional<ReviewView> own;
    for (const bcf::DocumentRef& d : markup.documents) {
      if (d.file != kDocumentName || !zip.has(folder + d.file)) continue;
      std::vector<ReviewView> parsed;
      std::string doc_error;
      if (zip.read(folder + d.file, text, doc_error) && parse_review_views(text, parsed, doc_error) &&
          parsed.size() == 1)
        own = std::move(parsed.front());
      else
        report.notes.push_back("topic '" + topic + "': " + folder + d.file + " ignored: " + doc_error);
    }
    std::vector<bcf::ViewpointRef> refs;
    for (const bcf::ViewpointRef& r : markup.viewpoints)
      if (!r.viewpoint.empty()) refs.push_back(r);
    if (refs.empty() && zip.has(folder + "viewpoint.bcfv")) refs.push_back({"", "viewpoint.bcfv", ""});
    if (refs.empty()) {
      ++report.topics_without_viewpoint;
      continue;
    }
    for (const bcf::ViewpointRef& r : refs) {
      const std::string entry = folder + r.viewpoint;
      const std::string where = file + ": " + entry + " (topic '" + topic + "')";
      if (r.viewpoint.find("..") != std::string::npos || r.viewpoint.front() == '/' ||
          r.viewpoint.front() == '\\') {
        error = where + ": the viewpoint's name escapes its topic folder";
        return false;
      }
      bcf::Viewpoint vp;
      if (!zip.read(entry, text, error) || !bcf::parse_viewpoint(text, vp, error)) {
        error = where + ": " + error;
        return false;
      }
      ++report.viewpoints;
      if (vp.camera == bcf::Viewpoint::CameraKind::none) {
        error = where + ": the viewpoint has no camera (no PerspectiveCamera or OrthogonalCamera)";
        return false;
      }
      if (!(glm::length(vp.direction) > 1e-12)) {
        error = where + ": CameraDirection is zero";
        return false;
      }
      ReviewView view;
      if (own) view = *own;
      view.title = markup.title.empty() ? (own ? own->title : topic) : markup.title;
      if (!own) view.aspect = options.aspect;

      // Selection and visibility.
      view.subject.clear();
      for (const Component& c : vp.selection) add_unique(view.subject, matcher.match(c, topic));
      std::vector<std::string> words;
      for (const Component& c : vp.exceptions)
        for (const uint64_t id : matcher.match(c, topic))
          if (std::string w = matcher.word_of(id);
              !w.empty() && std::find(words.begin(), words.end(), w) == words.end())
            words.push_back(std::move(w));
      if (!own) {
        (vp.default_visibility ? view.style.hide : view.style.only) = std::move(words);
        if (!vp.default_visibility && view.style.only.empty())
          report.notes.push_back("topic '" + topic +
                                 "': DefaultVisibility false with no object matched: every object shown");
        colour_groups_dropped += vp.colours.size();
      }

      // Camera.
      const glm::dvec3 direction = glm::normalize(vp.direction);
      double distance = kDefaultTargetDistance_m;
      if (own) {
        distance = glm::length(own->camera.target_m - own->camera.eye_m);
      } else if (const DAabb box = matcher.bounds_of(view.subject); !box.empty()) {
        distance = std::max(1.0, glm::dot((box.min + box.max) * 0.5 - vp.eye, direction));
      }
      Camera camera;
      if (vp.camera == bcf::Viewpoint::CameraKind::orthogonal) {
        ++report.orthogonal_converted;
        camera.fov_deg = kOrthogonalFov_deg;
        const double back =
            0.5 * std::max(vp.view_scale_m, 0.01) / std::tan(glm::radians(kOrthogonalFov_deg) * 0.5);
        camera.target_m = vp.eye;
        camera.eye_m = vp.eye - direction * back;
      } else {
        camera.fov_deg = vp.fov_deg;
        if (!(camera.fov_deg > 0.0 && camera.fov_deg < 179.0)) {
          camera.fov_deg = std::clamp(camera.fov_deg, 1.0, 170.0);
          ++fov_clamped;
        }
        camera.eye_m = vp.eye;
        camera.target_m = vp.eye + direction * distance;
      }
      camera.up = vp.up;
      std::string camera_error;
      if (!validate_camera(camera, camera_error)) {
        camera.up = default_up(direction);
        ++up_replaced;
        if (!validate_camera(camera, camera_error)) {
          error = where + ": the camera cannot be used: " + camera_error;
          return false;
        }
      }
      view.camera = camera;

      // Section.
      std::vector<ClipPlane> planes;
      for (ClipPlane p : vp.planes) {
        if (!(glm::length(p.normal) > 1e-12)) {
          ++planes_dropped;
          continue;
        }
        p.normal = glm::normalize(p.normal);
        planes.push_back(p);
      }
      Section section;
      section.capped = own ? own->section.capped : true;
      if (planes_as_box(planes, section.box)) {
        section.has_box = true;
        planes.erase(planes.begin(), planes.begin() + 6);
      }
      if (planes.size() > kMaxClipPlanes) {
        planes_dropped += planes.size() - kMaxClipPlanes;
        planes.resize(kMaxClipPlanes);
      }
      section.planes = std::move(planes);
      view.section = std::move(section);

      // Name and kind.
      const std::string base = own && refs.size() == 1 ? own->name : views::safe_name(view.title, 180);
      view.name = unique_name(base, used_names);
      if (!own)
        view.kind = view.subject.empty() ? "overview" : view.subject.size() == 1 ? "equipment" : "area";
      views.push_back(std::move(view));
      ++report.imported;
    }
  }
  if (colour_groups_dropped)
    report.notes.push_back(
        std::to_string(colour_groups_dropped) +
        " Coloring group(s) not imported: plantview colours by an attribute, not per object");
  if (planes_dropped)
    report.notes.push_back(std::to_string(planes_dropped) +
                           " clipping plane(s) dropped (zero direction, or over " +
                           std::to_string(kMaxClipPlanes) + " planes besides a box)");
  if (fov_clamped)
    report.notes.push_back(std::to_string(fov_clamped) + " field(s) of view clamped to 1..170 degrees");
  if (up_replaced)
    report.notes.push_back(std::to_string(up_replaced) +
                           " camera up vector(s) along the view replaced by the default up");
  if (views.empty()) {
    error = file + ": no topic has a viewpoint (" + std::to_string(report.topics) + " topic(s) read)";
    return false;
  }
  // The views file's own rules, checked once more by its parser.
  std::vector<ReviewView> checked;
  if (!parse_review_views(review_views_json(views, "area"), checked, error)) {
    error = file + ": the imported views are not valid: " + error;
    return false;
  }
  out = std::move(checked);
  return true;
}

std::string BcfReadReport::to_json() const {
  return nlohmann::json{{"topics", topics},
                        {"topics_without_viewpoint", topics_without_viewpoint},
                        {"viewpoints", viewpoints},
                        {"imported", imported},
                        {"orthogonal_converted", orthogonal_converted},
                        {"components_matched", components_matched},
                        {"components_unknown", components_unknown},
                        {"components_ifc_only", components_ifc_only},
                        {"unknown_examples", unknown_examples},
                        {"notes", notes}}
      .dump();
}

std::string BcfReadReport::to_text() const {
  std::string text = std::to_string(topics) + " topic(s) read, " + std::to_string(viewpoints) +
                     " viewpoint(s), " + std::to_string(imported) + " view(s) imported";
  if (topics_without_viewpoint)
    text += ", " + std::to_string(topics_without_viewpoint) + " topic(s) without a viewpoint skipped";
  if (orthogonal_converted)
    text += ", " + std::to_string(orthogonal_converted) + " orthogonal camera(s) converted to perspective";
  text += "\ncomponents: " + std::to_string(components_matched) + " matched, " +
          std::to_string(components_unknown) + " unknown";
  if (components_ifc_only)
    text += " (" + std::to_string(components_ifc_only) +
            " with only an IfcGuid, which plantview objects do not have)";
  for (const std::string& e : unknown_examples) text += "\n  unknown: " + e;
  if (components_unknown > unknown_examples.size()) text += "\n  ...";
  for (const std::string& n : notes) text += "\nnote: " + n;
  return text;
}

}  // namespace plantview
