#include "cli/farm/incremental.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"
#include "plantview/store.h"

namespace plantview::cli::farm {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr char kObjectsMagic[8] = {'P', 'V', 'O', 'B', 'J', 'S', '0', '1'};
constexpr char kDrawnMagic[8] = {'P', 'V', 'D', 'R', 'A', 'W', 'N', '1'};

uint64_t fnv1a(const uint8_t* data, size_t size, uint64_t h = 14695981039346656037ull) {
  for (size_t i = 0; i < size; ++i) {
    h ^= data[i];
    h *= 1099511628211ull;
  }
  return h;
}

template <typename T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}

// Reads fixed-size values from a file's bytes; `ok` false once it runs out.
struct Reader {
  const std::string& bytes;
  size_t at = 0;
  bool ok = true;
  template <typename T>
  T get() {
    T value{};
    if (at + sizeof value > bytes.size()) {
      ok = false;
      return value;
    }
    std::memcpy(&value, bytes.data() + at, sizeof value);
    at += sizeof value;
    return value;
  }
};

void put_box(std::string& out, const DAabb& b) {
  for (const double v : {b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z}) put(out, v);
}
DAabb get_box(Reader& r) {
  DAabb b;
  b.min.x = r.get<double>(), b.min.y = r.get<double>(), b.min.z = r.get<double>();
  b.max.x = r.get<double>(), b.max.y = r.get<double>(), b.max.z = r.get<double>();
  return b;
}

bool overlap(const DAabb& a, const DAabb& b) {
  return !a.empty() && !b.empty() && a.min.x <= b.max.x && b.min.x <= a.max.x &&
         a.min.y <= b.max.y && b.min.y <= a.max.y && a.min.z <= b.max.z && b.min.z <= a.max.z;
}

glm::dvec3 vec3_of(const json& j) {
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}

// The side planes of a view's frustum (inside where dot(n, p) + d >= 0, model space), its
// field of view widened by a margin (a few pixels, and whatever a supersampled or filtered edge
// reaches). No near or far plane: conservative.
struct Frustum {
  glm::dvec3 eye{0.0};
  std::array<glm::dvec3, 4> normals{};
};
Frustum frustum_of(const Camera& camera, uint32_t width, uint32_t height) {
  const glm::dvec3 forward = glm::normalize(camera.target_m - camera.eye_m);
  glm::dvec3 up = camera.up;
  if (glm::length(glm::cross(forward, up)) < 1e-9 * glm::length(up)) up = glm::dvec3(0, 1, 0);
  if (glm::length(glm::cross(forward, up)) < 1e-9) up = glm::dvec3(1, 0, 0);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, up));
  const glm::dvec3 true_up = glm::cross(right, forward);
  const double margin = 1.0 + 8.0 / double(std::min(width, height));
  const double tan_y = std::tan(glm::radians(camera.fov_deg) / 2) * margin;
  const double tan_x = tan_y * double(width) / double(height);
  Frustum f;
  f.eye = camera.eye_m;
  // Inside: the point's sideways offset is within tan x its depth along `forward`.
  f.normals = {forward * tan_x + right, forward * tan_x - right, forward * tan_y + true_up,
               forward * tan_y - true_up};
  return f;
}
bool box_enters(const Frustum& f, const DAabb& b) {
  if (b.empty()) return false;
  for (const glm::dvec3& n : f.normals) {
    // The box's corner farthest along the normal.
    const glm::dvec3 p(n.x > 0 ? b.max.x : b.min.x, n.y > 0 ? b.max.y : b.min.y,
                       n.z > 0 ? b.max.z : b.min.z);
    if (glm::dot(n, p - f.eye) < 0) return false;
  }
  return true;
}

}  // namespace

bool store_objects(const ReadView& read, std::vector<ObjectState>& out, std::string& error) {
  out.clear();
  bool hashed = true;
  std::vector<std::pair<uint64_t, uint64_t>> in_branches;  // (member id, pipeline id)
  const bool ok = read.for_each_object(
      [&](uint32_t slot, Object&& object) {
        uint64_t hash = 0;
        hashed = read.content_hash(slot, hash, error);
        out.push_back({object.id, hash, object.pipeline_id, object_bounds(object)});
        for (const Branch& branch : object.branches)
          for (const uint64_t member : branch.members) in_branches.emplace_back(member, object.id);
        return hashed;
      },
      false, error);
  if (!ok || !hashed) return false;
  std::sort(out.begin(), out.end(), [](const ObjectState& a, const ObjectState& b) { return a.id < b.id; });
  // A pipe joins its pipeline's runs only where a branch lists it (render/src/hlod.h): the
  // others keep no pipeline here, so that changing them reaches no run.
  std::sort(in_branches.begin(), in_branches.end());
  for (ObjectState& o : out) {
    if (o.pipeline_id == 0) continue;
    const auto it = std::lower_bound(in_branches.begin(), in_branches.end(), std::make_pair(o.id, o.pipeline_id));
    if (it == in_branches.end() || *it != std::make_pair(o.id, o.pipeline_id)) o.pipeline_id = 0;
  }
  return true;
}

fs::path objects_file(const fs::path& dir, const std::string& identity) {
  return dir / "objects" / (identity + ".bin");
}

bool write_objects_file(const fs::path& path, const std::vector<ObjectState>& objects, std::string& error) {
  std::string bytes(kObjectsMagic, sizeof kObjectsMagic);
  put(bytes, uint64_t(objects.size()));
  for (const ObjectState& o : objects) {
    put(bytes, o.id);
    put(bytes, o.hash);
    put(bytes, o.pipeline_id);
    put_box(bytes, o.bounds);
  }
  return prepare_output_dir(path.parent_path(), error) && write_file_atomically(path, bytes, error);
}

bool read_objects_file(const fs::path& path, std::vector<ObjectState>& objects, std::string& error) {
  std::string bytes;
  if (!read_file(path, bytes, error)) return false;
  Reader r{bytes};
  const bool magic = bytes.compare(0, sizeof kObjectsMagic, kObjectsMagic, sizeof kObjectsMagic) == 0;
  r.at = sizeof kObjectsMagic;
  const uint64_t count = r.get<uint64_t>();
  if (!magic || !r.ok || count > bytes.size() / 72) {
    error = path.string() + ": not an objects file of the farm";
    return false;
  }
  objects.resize(count);
  for (ObjectState& o : objects) {
    o.id = r.get<uint64_t>();
    o.hash = r.get<uint64_t>();
    o.pipeline_id = r.get<uint64_t>();
    o.bounds = get_box(r);
  }
  if (!r.ok) {
    error = path.string() + ": truncated objects file";
    return false;
  }
  return true;
}

bool ensure_objects_file(const fs::path& dir, const std::string& identity, const ReadView& read,
                         std::string& error) {
  const fs::path path = objects_file(dir, identity);
  std::error_code ec;
  if (fs::is_regular_file(path, ec)) return true;
  std::vector<ObjectState> objects;
  return store_objects(read, objects, error) && write_objects_file(path, objects, error);
}

bool drawn_set(const ReadView& read, const FrameStats& stats, const std::vector<ObjectState>& objects,
               DrawnSet& out, std::string& error) {
  std::vector<uint32_t> slots = stats.drawn_slots;
  std::sort(slots.begin(), slots.end());
  slots.erase(std::unique(slots.begin(), slots.end()), slots.end());
  out.objects.clear();
  for (const uint32_t slot : slots) {
    uint64_t id = 0, pipeline_id = 0;
    if (!read.object_key(slot, id, pipeline_id, error)) return false;
    const auto it = std::lower_bound(objects.begin(), objects.end(), id,
                                     [](const ObjectState& o, uint64_t key) { return o.id < key; });
    if (it == objects.end() || it->id != id) {
      error = "object " + std::to_string(id) + " (slot " + std::to_string(slot) +
              ") was drawn but is not in the store's objects file";
      return false;
    }
    out.objects.emplace_back(id, it->hash);
    if (pipeline_id != 0) out.pipelines.push_back(pipeline_id);
  }
  std::sort(out.objects.begin(), out.objects.end());
  std::sort(out.pipelines.begin(), out.pipelines.end());
  out.pipelines.erase(std::unique(out.pipelines.begin(), out.pipelines.end()), out.pipelines.end());
  out.regions = stats.drawn_regions;
  return true;
}

std::string drawn_digest(const DrawnSet& drawn) {
  std::string bytes;
  for (const auto& [id, hash] : drawn.objects) {
    put(bytes, id);
    put(bytes, hash);
  }
  for (const DAabb& b : drawn.regions) put_box(bytes, b);
  for (const uint64_t p : drawn.pipelines) put(bytes, p);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx",
                static_cast<unsigned long long>(fnv1a(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size())));
  return hex;
}

fs::path drawn_file(const fs::path& dir, const std::string& view_name) {
  return dir / "drawn" / (view_name + ".drawn");
}

bool write_drawn_file(const fs::path& path, const DrawnSet& drawn, std::string& error) {
  std::string bytes(kDrawnMagic, sizeof kDrawnMagic);
  put(bytes, uint64_t(drawn.objects.size()));
  for (const auto& [id, hash] : drawn.objects) {
    put(bytes, id);
    put(bytes, hash);
  }
  put(bytes, uint64_t(drawn.regions.size()));
  for (const DAabb& b : drawn.regions) put_box(bytes, b);
  put(bytes, uint64_t(drawn.pipelines.size()));
  for (const uint64_t p : drawn.pipelines) put(bytes, p);
  return prepare_output_dir(path.parent_path(), error) && write_file_atomically(path, bytes, error);
}

bool read_drawn_file(const fs::path& path, DrawnSet& drawn, std::string& error) {
  std::string bytes;
  if (!read_file(path, bytes, error)) return false;
  Reader r{bytes};
  const bool magic = bytes.compare(0, sizeof kDrawnMagic, kDrawnMagic, sizeof kDrawnMagic) == 0;
  r.at = sizeof kDrawnMagic;
  const uint64_t count = r.get<uint64_t>();
  if (!magic || !r.ok || count > bytes.size() / 16) {
    error = path.string() + ": not a drawn-set file of the farm";
    return false;
  }
  drawn.objects.resize(count);
  for (auto& [id, hash] : drawn.objects) {
    id = r.get<uint64_t>();
    hash = r.get<uint64_t>();
  }
  const uint64_t regions = r.get<uint64_t>();
  if (!r.ok || regions > bytes.size() / 48) {
    error = path.string() + ": truncated drawn-set file";
    return false;
  }
  drawn.regions.resize(regions);
  for (DAabb& b : drawn.regions) b = get_box(r);
  const uint64_t pipelines = r.get<uint64_t>();
  if (!r.ok || pipelines > bytes.size() / 8) {
    error = path.string() + ": truncated drawn-set file";
    return false;
  }
  drawn.pipelines.resize(pipelines);
  for (uint64_t& p : drawn.pipelines) p = r.get<uint64_t>();
  if (!r.ok) {
    error = path.string() + ": truncated drawn-set file";
    return false;
  }
  return true;
}

bool uses_model_bounds(const RenderOptions& view_options) {
  return view_options.ground || view_options.section.has_box;
}

std::string global_inputs_hash(const DAabb& model_bounds, bool uses_bounds) {
  std::string text = "v1";
  if (uses_bounds) {
    char buffer[256];
    std::snprintf(buffer, sizeof buffer, " bounds %.17g %.17g %.17g %.17g %.17g %.17g", model_bounds.min.x,
                  model_bounds.min.y, model_bounds.min.z, model_bounds.max.x, model_bounds.max.y,
                  model_bounds.max.z);
    text += buffer;
  }
  return hash_hex(text);
}

json section_json(const Section& section) {
  json planes = json::array();
  for (const ClipPlane& p : section.planes)
    planes.push_back({p.point_m.x, p.point_m.y, p.point_m.z, p.normal.x, p.normal.y, p.normal.z});
  json out = {{"planes", planes}, {"capped", section.capped}};
  if (section.has_box)
    out["box"] = {section.box.min.x, section.box.min.y, section.box.min.z,
                  section.box.max.x, section.box.max.y, section.box.max.z};
  return out;
}

bool parse_section_json(const json& j, Section& out) {
  out = Section{};
  if (!j.is_object()) return false;
  try {
    for (const json& p : j.value("planes", json::array())) {
      ClipPlane plane;
      plane.point_m = {p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
      plane.normal = {p.at(3).get<double>(), p.at(4).get<double>(), p.at(5).get<double>()};
      out.planes.push_back(plane);
    }
    out.capped = j.value("capped", true);
    if (j.contains("box")) {
      const json& b = j["box"];
      out.has_box = true;
      out.box.min = {b.at(0).get<double>(), b.at(1).get<double>(), b.at(2).get<double>()};
      out.box.max = {b.at(3).get<double>(), b.at(4).get<double>(), b.at(5).get<double>()};
    }
  } catch (const json::exception&) {
    return false;
  }
  return true;
}

StoreChange diff_states(const std::vector<ObjectState>& before, const std::vector<ObjectState>& after) {
  StoreChange change;
  size_t i = 0, k = 0;
  while (i < before.size() || k < after.size()) {
    if (k == after.size() || (i < before.size() && before[i].id < after[k].id)) {
      change.gone.push_back(before[i].id);
      if (!before[i].bounds.empty()) change.gone_bounds.push_back(before[i].bounds);
      ++change.removed;
      ++i;
    } else if (i == before.size() || after[k].id < before[i].id) {
      change.arrived.push_back(after[k]);
      ++change.added;
      ++k;
    } else {
      if (before[i].hash != after[k].hash) {
        change.gone.push_back(before[i].id);
        if (!before[i].bounds.empty()) change.gone_bounds.push_back(before[i].bounds);
        change.arrived.push_back(after[k]);
        ++change.modified;
      }
      ++i;
      ++k;
    }
  }
  // Pipelines touched: the changed objects' own (before and after) and changed pipelines.
  std::vector<uint64_t>& p = change.pipelines;
  for (const ObjectState& o : change.arrived) {
    if (o.pipeline_id != 0) p.push_back(o.pipeline_id);
    p.push_back(o.id);
  }
  for (const ObjectState& o : before)
    if (std::binary_search(change.gone.begin(), change.gone.end(), o.id)) {
      if (o.pipeline_id != 0) p.push_back(o.pipeline_id);
      p.push_back(o.id);
    }
  std::sort(p.begin(), p.end());
  p.erase(std::unique(p.begin(), p.end()), p.end());
  return change;
}

const char* staleness_name(Staleness::Reason reason) {
  switch (reason) {
    case Staleness::Reason::fresh: return "fresh";
    case Staleness::Reason::settings: return "settings";
    case Staleness::Reason::global_input: return "global input";
    case Staleness::Reason::changed_object: return "changed object";
    case Staleness::Reason::added_in_view: return "added object in view";
    case Staleness::Reason::no_record: return "no record";
  }
  return "?";
}

bool StalenessJudge::judge(const json& record, const std::string& settings_hash,
                           const std::string& global_hash, Staleness& out, std::string& error) {
  out = Staleness{};
  const auto stale = [&](Staleness::Reason reason, std::string detail) {
    out.reason = reason;
    out.detail = std::move(detail);
    return true;
  };
  if (!settings_hash.empty() && record.value("settings_hash", "") != settings_hash)
    return stale(Staleness::Reason::settings, "the view or the render options changed");
  const std::string drawn_at = record.value("store", "");
  if (drawn_at == current_) return true;
  if (drawn_at.empty() || !record.contains("drawn") || !record.contains("size") || !record.contains("camera"))
    return stale(Staleness::Reason::no_record, "rendered without a record of what it drew");
  if (record.value("global", "") != global_hash)
    return stale(Staleness::Reason::global_input, "the model bounds changed (ground, section box)");

  if (!loaded_) {
    std::error_code ec;
    if (!fs::is_regular_file(objects_file(dir_, current_), ec)) {
      error = objects_file(dir_, current_).string() + ": missing (the store's objects, written before views are judged)";
      return false;
    }
    if (!read_objects_file(objects_file(dir_, current_), current_objects_, error)) return false;
    loaded_ = true;
  }
  auto& change = changes_[drawn_at];
  if (!change) {
    std::vector<ObjectState> before;
    std::string ignored;
    if (!read_objects_file(objects_file(dir_, drawn_at), before, ignored))
      return stale(Staleness::Reason::no_record, "no record of the store it was drawn from");
    change = std::make_unique<StoreChange>(diff_states(before, current_objects_));
  }
  DrawnSet drawn;
  std::string why;
  const fs::path drawn_path = dir_ / record["drawn"].value("file", "");
  if (!read_drawn_file(drawn_path, drawn, why) || drawn_digest(drawn) != record["drawn"].value("digest", ""))
    return stale(Staleness::Reason::no_record, "its drawn set is missing or damaged (" + drawn_path.string() + ")");
  // Drawn objects modified or removed (both lists by id).
  size_t i = 0, k = 0;
  while (i < drawn.objects.size() && k < change->gone.size()) {
    if (drawn.objects[i].first < change->gone[k]) {
      ++i;
    } else if (change->gone[k] < drawn.objects[i].first) {
      ++k;
    } else {
      char hex[17];
      std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(change->gone[k]));
      return stale(Staleness::Reason::changed_object, std::string("drew object ") + hex + ", modified or removed");
    }
  }
  for (const uint64_t pipeline : drawn.pipelines)
    if (std::binary_search(change->pipelines.begin(), change->pipelines.end(), pipeline)) {
      char hex[17];
      std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(pipeline));
      return stale(Staleness::Reason::changed_object,
                   std::string("drew a member of pipeline ") + hex + ", which changed");
    }
  for (const DAabb& region : drawn.regions)
    for (const DAabb& b : change->gone_bounds)
      if (overlap(region, b))
        return stale(Staleness::Reason::changed_object, "a node it drew whole held a modified or removed object");
  // Added or modified objects entering the frustum, not removed by the section.
  Camera camera;
  Section section;
  try {
    const json& c = record["camera"];
    camera.eye_m = vec3_of(c.at("eye"));
    camera.target_m = vec3_of(c.at("target"));
    camera.up = vec3_of(c.at("up"));
    camera.fov_deg = c.at("fov_deg").get<double>();
  } catch (const json::exception&) {
    return stale(Staleness::Reason::no_record, "its record's camera is unreadable");
  }
  const uint32_t width = record["size"].value("width", 0u), height = record["size"].value("height", 0u);
  if (width == 0 || height == 0 || !parse_section_json(record.value("section", json::object()), section))
    return stale(Staleness::Reason::no_record, "its record's size or section is unreadable");
  const Frustum frustum = frustum_of(camera, width, height);
  for (const ObjectState& o : change->arrived) {
    if (!box_enters(frustum, o.bounds)) continue;
    if (!section.empty() && section_removes_all(section, o.bounds)) continue;
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(o.id));
    return stale(Staleness::Reason::added_in_view, std::string("object ") + hex + " added or moved into its frustum");
  }
  return true;
}

}  // namespace plantview::cli::farm
