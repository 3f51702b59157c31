// Subjects of review views from a store's model: equipment items, pipelines (the whole line)
// and areas (RVM zones, generated plants' units), or the whole plant.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <unordered_map>

#include "views_internal.h"

namespace plantview::views {

namespace {

const std::string* find_attribute(const Object& o, std::string_view key) {
  for (const Attribute& a : o.attributes)
    if (a.key == key) return &a.value;
  return nullptr;
}

std::string attribute_or(const Object& o, std::string_view key, std::string fallback) {
  const std::string* value = find_attribute(o, key);
  return value && !value->empty() ? *value : std::move(fallback);
}

// PDMS element types ("EQUI", "PIPE") are codes, not words for a title.
bool is_type_code(const std::string& type) {
  return type.size() <= 4 &&
         std::all_of(type.begin(), type.end(), [](char c) { return c >= 'A' && c <= 'Z'; });
}

// A generated plant's unit from an object's name: the second '-' field of the first path part
// ("/P-01-0203-B1/ELBO-3" -> "01"; generate.h: "The area is the plant unit's index + 1").
std::string generated_unit(std::string_view name) {
  if (name.empty() || name.front() != '/') return {};
  name.remove_prefix(1);
  name = name.substr(0, name.find('/'));
  const size_t dash = name.find('-');
  if (dash == std::string_view::npos) return {};
  std::string_view unit = name.substr(dash + 1);
  unit = unit.substr(0, unit.find('-'));
  if (unit.empty() || !std::all_of(unit.begin(), unit.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return {};
  return std::string(unit);
}

// The area an object belongs to, as (what kind of area, its name): its RVM zone, its generated
// unit, its RVM site, else the file it came from.
std::pair<std::string, std::string> area_of(const Object& o) {
  if (const std::string* zone = find_attribute(o, "Zone"); zone && !zone->empty())
    return {"Zone", *zone};
  if (o.source.rfind("gen:", 0) == 0) {
    const std::string unit = generated_unit(o.name);
    if (!unit.empty()) return {"Unit", unit};
  }
  if (const std::string* site = find_attribute(o, "Site"); site && !site->empty())
    return {"Site", *site};
  return {"File", std::filesystem::path(o.source).filename().string()};
}

void add_object(Subject& s, uint32_t slot, uint64_t id, const DAabb& bounds) {
  s.ids.push_back(id);
  s.slots.push_back(slot);
  s.bounds.extend(bounds);
  if (!bounds.empty()) s.boxes.push_back(bounds);
}

// Cameras are fitted to at most about this many boxes per subject.
constexpr size_t kMaxFitBoxes = 1024;

// An object's name as the plant names it, without the path's leading '/' ("/-ART1105BA-" ->
// "-ART1105BA-"): what a subject without a tag is called in its view's name, title and caption.
std::string plant_name(std::string_view name) {
  if (!name.empty() && name.front() == '/') name.remove_prefix(1);
  return std::string(name);
}

Subject equipment_subject(const Object& o) {
  Subject s;
  s.kind = "equipment";
  s.key = attribute_or(o, "Tag", plant_name(o.name));
  const std::string type = attribute_or(o, "Type", "");
  s.title = (type.empty() || is_type_code(type) ? std::string("Equipment") : type) + " " + s.key;
  s.attributes.emplace_back("tag", s.key);
  if (!type.empty()) s.attributes.emplace_back("type", type);
  if (const std::string* d = find_attribute(o, "Description"); d && !d->empty())
    s.attributes.emplace_back("description", *d);
  return s;
}

void describe_pipeline(Subject& s, const Object& o) {
  s.key = attribute_or(o, "Line number", plant_name(o.name));
  s.title = "Pipeline " + s.key;
  s.attributes.emplace_back("tag", s.key);
  s.attributes.emplace_back("type", "Pipeline");
  std::string description = attribute_or(o, "Description", "");
  for (const char* key : {"Fluid", "Bore"}) {
    if (const std::string* v = find_attribute(o, key); v && !v->empty())
      description += (description.empty() ? "" : ", ") + *v;
  }
  if (!description.empty()) s.attributes.emplace_back("description", description);
}

}  // namespace

std::string safe_name(std::string_view key, size_t max_chars) {
  // Each run of characters a file name cannot hold becomes one '-', marked as made here: such a
  // '-' is dropped at either end, and so are leading '.' (no hidden files, no ".."); a '-' of
  // the key itself stays ("-ART1105BA-" keeps its name).
  std::string out;
  std::vector<bool> made;
  bool pending = false;
  for (const char c : key) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) {
      pending = true;
      continue;
    }
    if (pending && !out.empty()) {
      out += '-';
      made.push_back(true);
    }
    pending = false;
    out += c;
    made.push_back(false);
  }
  size_t start = 0;
  while (start < out.size() && (out[start] == '.' || made[start])) ++start;
  size_t end = std::min(out.size(), start + max_chars);
  while (end > start && made[end - 1]) --end;
  out = out.substr(start, end - start);
  return out.empty() ? "view" : out;
}

bool read_subjects(const ReadView& view, std::string_view per, std::vector<Subject>& out,
                   std::string& error, const std::function<void(double)>& progress) {
  const StoreInfo info = view.info();
  std::vector<Subject> subjects;
  if (per == "overview") {
    if (!info.statistics.bounds.empty()) {
      Subject s;
      s.kind = "overview";
      s.key = "overview";
      s.title = "Overview";
      s.bounds = info.statistics.bounds;
      s.boxes = overview_boxes(view);
      s.attributes.emplace_back("objects", std::to_string(info.objects));
      subjects.push_back(std::move(s));
    }
    out = std::move(subjects);
    return true;
  }

  // One pass over the objects, in slot order (so each subject's slots come out ascending).
  std::unordered_map<uint64_t, size_t> pipeline_of;   // pipeline id -> subjects index
  std::vector<bool> pipeline_seen;                    // its pipeline object was read
  std::map<std::pair<std::string, std::string>, size_t> area_of_key;
  uint64_t read = 0;
  const bool ok = view.for_each_object(
      [&](uint32_t slot, Object&& o) {
        const DAabb bounds = object_bounds(o);
        if (per == "equipment") {
          if (o.object_class == ObjectClass::equipment && !bounds.empty()) {
            subjects.push_back(equipment_subject(o));
            add_object(subjects.back(), slot, o.id, bounds);
          }
        } else if (per == "pipeline") {
          const uint64_t line = o.object_class == ObjectClass::pipeline ? o.id : o.pipeline_id;
          if (line != 0) {
            auto [it, added] = pipeline_of.try_emplace(line, subjects.size());
            if (added) {
              subjects.emplace_back().kind = "pipeline";
              pipeline_seen.push_back(false);
            }
            Subject& s = subjects[it->second];
            if (o.object_class == ObjectClass::pipeline) {
              describe_pipeline(s, o);
              pipeline_seen[it->second] = true;
            }
            add_object(s, slot, o.id, bounds);
          }
        } else if (per == "area") {
          auto area = area_of(o);
          auto [it, added] = area_of_key.try_emplace(area, subjects.size());
          if (added) {
            Subject& s = subjects.emplace_back();
            s.kind = "area";
            s.key = area.first == "Unit" ? "Unit " + area.second : area.second;
            s.title = area.first + " " + area.second;
            s.attributes.emplace_back("tag", area.second);
            s.attributes.emplace_back("type", area.first);
          }
          add_object(subjects[it->second], slot, o.id, bounds);
        }
        if (progress && (++read & 1023) == 0) progress(double(read) / double(std::max<uint64_t>(info.objects, 1)));
        return true;
      },
      true, error);
  if (!ok) return false;

  // Pipelines whose pipeline object is not in the store have no name: left out.
  if (per == "pipeline") {
    std::vector<Subject> named;
    for (size_t i = 0; i < subjects.size(); ++i)
      if (pipeline_seen[i]) named.push_back(std::move(subjects[i]));
    subjects = std::move(named);
  }
  if (per == "area") {
    for (Subject& s : subjects) s.attributes.emplace_back("description", std::to_string(s.ids.size()) + " objects");
  }
  std::erase_if(subjects, [](const Subject& s) { return s.bounds.empty(); });
  for (Subject& s : subjects) s.boxes = merge_boxes_on_grid(std::move(s.boxes), kMaxFitBoxes);
  std::sort(subjects.begin(), subjects.end(), [](const Subject& a, const Subject& b) {
    return a.key != b.key ? a.key < b.key : a.ids.front() < b.ids.front();
  });
  if (progress) progress(1.0);
  out = std::move(subjects);
  return true;
}

}  // namespace plantview::views
