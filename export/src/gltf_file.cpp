// One glTF file being written: opening it, its meshes and materials, and its nodes (objects,
// runs and the groups they hang under) as they come (rules in gltf_file.h). Vertex and index
// data: gltf_buffers.cpp; finish(): gltf_finish.cpp.
#include "gltf_file.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "gltf_file_state.h"
#include "gltf_text.h"

namespace plantview::detail::gltf {

namespace {

double srgb_to_linear(uint8_t v) {
  const double c = v / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

}  // namespace

void GltfFileState::close_parts() {
  for (Part* p : parts) p->close();
}

void GltfFileState::remove_all() {
  for (Part* p : parts) p->remove();
  std::error_code ignored;
  for (const std::string& p : {temp_out, temp_bin})
    if (!p.empty()) std::filesystem::remove(p, ignored);
}

void GltfFileState::note_failure(const Part& part) {
  if (!failed) write_error = "cannot write " + part.path + ": " + system_reason();
  failed = true;
}

int GltfFileState::material(Colour colour) {
  const uint32_t key = uint32_t(colour.r) | uint32_t(colour.g) << 8 | uint32_t(colour.b) << 16 |
                       uint32_t(colour.a) << 24;
  if (const auto it = materials.find(key); it != materials.end()) return it->second;
  tinygltf::Material m;
  m.pbrMetallicRoughness.baseColorFactor = {srgb_to_linear(colour.r), srgb_to_linear(colour.g),
                                            srgb_to_linear(colour.b), colour.a / 255.0};
  m.pbrMetallicRoughness.metallicFactor = 0.0;
  m.pbrMetallicRoughness.roughnessFactor = 0.7;
  m.doubleSided = true;  // facet groups and cut-away parts are open
  if (colour.a < 255) m.alphaMode = "BLEND";
  char name[16];
  std::snprintf(name, sizeof name, "#%02x%02x%02x%02x", colour.r, colour.g, colour.b, colour.a);
  m.name = name;
  model.materials.push_back(std::move(m));
  return materials[key] = int(model.materials.size() - 1);
}

// A node's placement relative to the origin with `mesh`'s dequantization folded in:
// node * (centre + grid_scale * v) = (t + R (S * centre)) R (S * grid_scale) v.
void GltfFileState::placement(int mesh, const glm::dvec3& position, const glm::quat& q, glm::vec3& scale,
                              glm::dvec3& translation) const {
  translation = position - origin_m;
  if (mesh < 0 || !mesh_info[size_t(mesh)].quantized) return;
  const MeshInfo& info = mesh_info[size_t(mesh)];
  translation += glm::dquat(q) * (glm::dvec3(scale) * info.centre);
  scale *= float(info.grid_scale);
}

std::string GltfFileState::transform_json(const glm::dvec3& position, const glm::quat& q, glm::vec3 scale,
                                          int mesh) const {
  glm::dvec3 t;
  placement(mesh, position, q, scale, t);
  std::string j = ",\"translation\":[" + json_number(t.x, 4) + "," + json_number(t.y, 4) + "," + json_number(t.z, 4) + "]";
  if (q != glm::quat(1, 0, 0, 0))
    j += ",\"rotation\":[" + json_number(q.x, 6) + "," + json_number(q.y, 6) + "," + json_number(q.z, 6) + "," +
         json_number(q.w, 6) + "]";
  if (scale != glm::vec3(1.0f))
    j += ",\"scale\":[" + json_number(scale.x) + "," + json_number(scale.y) + "," + json_number(scale.z) + "]";
  return j;
}

void GltfFileState::count(int mesh, const glm::dvec3& position, const glm::quat& rotation, const glm::vec3& scale,
                          GltfFileSummary& summary) const {
  if (mesh < 0) return;
  const MeshInfo& info = mesh_info[size_t(mesh)];
  summary.triangles += info.triangles;
  summary.lines += info.lines;
  if (!info.has_box) return;
  const glm::dquat q(rotation);
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 corner = glm::dvec3(scale) * glm::dvec3((c & 1) ? info.max[0] : info.min[0],
                                                             (c & 2) ? info.max[1] : info.min[1],
                                                             (c & 4) ? info.max[2] : info.min[2]);
    summary.bounds.extend(position + q * corner);
  }
}

void GltfFileState::append_node(const std::string& json) {
  if (!nodes.append(nodes.bytes ? "," + json : json)) note_failure(nodes);
}

void GltfFileState::stream_node(int parent, const std::string& name_and_extras, int mesh, const glm::dvec3& position,
                                const glm::quat& rotation, const glm::vec3& scale, bool is_object) {
  std::string node = "{" + name_and_extras;
  if (mesh >= 0) node += ",\"mesh\":" + std::to_string(mesh);
  node += transform_json(position, rotation, scale, mesh) + "}";
  append_node(node);
  streamed_children[parent].push_back(streamed++);
  records[size_t(parent)].has_children = true;
  if (is_object) streamed_summary.objects += 1;
  count(mesh, position, rotation, scale, streamed_summary);
}

int GltfFileState::add_record(int parent, const std::string& name_and_extras) {
  Record& r = records.emplace_back();
  r.parent = parent;
  if (parent >= 0) records[size_t(parent)].has_children = true;
  set_text(r, name_and_extras);
  return int(records.size() - 1);
}

void GltfFileState::set_text(Record& r, const std::string& name_and_extras) {
  r.text_offset = text.bytes;
  r.text_bytes = uint32_t(name_and_extras.size());
  if (!text.append(name_and_extras)) note_failure(text);
}

int GltfFileState::group(std::string_view source, std::string_view zone) {
  auto site = sites.find(source);
  if (site == sites.end()) {
    const int r = add_record(-1, "\"name\":" + json_string(utf8_text(source)));
    site = sites.emplace(std::string(source), r).first;
  }
  if (zone.empty()) return site->second;
  const auto key = std::make_pair(site->second, std::string(zone));
  if (const auto it = zones.find(key); it != zones.end()) return it->second;
  return zones[key] = add_record(site->second, "\"name\":" + json_string(utf8_text(zone)));
}

int GltfFileState::pipeline(uint64_t id, int parent) {
  if (const auto it = pipelines.find(id); it != pipelines.end()) return it->second;
  pipeline_ids_unnamed.push_back(id);
  char name[40];
  std::snprintf(name, sizeof name, "\"name\":\"pipeline %016llx\"", static_cast<unsigned long long>(id));
  return pipelines[id] = add_record(parent, name);
}

GltfFile::GltfFile() : state_(std::make_unique<GltfFileState>()) {}
GltfFile::~GltfFile() {
  if (!state_->finished) state_->remove_all();
}

bool GltfFile::open(const std::string& path, const glm::dvec3& origin_m, bool gpu_instancing,
                    double quantization_error_m, bool share_geometry, std::string& error) {
  GltfFileState& s = *state_;
  s.share_geometry = share_geometry;
  s.path = path;
  s.quantization_error_m = quantization_error_m;
  s.origin_m = origin_m;
  s.gpu_instancing = gpu_instancing;
  const std::filesystem::path p(path);
  s.binary = p.extension() == ".glb" || p.extension() == ".GLB";
  const std::string stem = (p.parent_path() / ("." + p.filename().string())).string() + ".tmp-" +
                           std::to_string(::getpid());
  s.temp_out = stem;
  if (!s.binary) {
    s.bin_name = p.stem().string() + ".bin";
    s.temp_bin = stem + ".bin";
  }
  const char* suffixes[7] = {".vertices", ".quantized", ".indices", ".accessors", ".meshes", ".text", ".nodes"};
  for (int i = 0; i < 7; ++i) {
    if (!s.parts[i]->open(stem + suffixes[i])) {
      error = "cannot write " + path + ": " + system_reason();
      s.remove_all();
      return false;
    }
  }
  return true;
}

void GltfFile::reserve(size_t nodes) { state_->records.reserve(nodes); }

int GltfFile::find_mesh(const MeshKey& key) const {
  const auto it = state_->meshes.find(key);
  return it == state_->meshes.end() ? kUnknownMesh : it->second;
}

int GltfFile::add_mesh(const MeshKey& key, const MeshData& data, Colour colour, bool stretched,
                       std::string& error) {
  GltfFileState& s = *state_;
  if (data.empty()) return s.meshes[key] = kNoMesh;
  const int material = s.material(colour);
  MeshKey geometry_id{};
  if (s.share_geometry) {
    geometry_id = geometry_key(data);
    geometry_id.b ^= uint64_t(stretched);
  }
  auto found = s.share_geometry ? s.geometries.find(geometry_id) : s.geometries.end();
  GltfFileState::Geometry unshared;  // without sharing: not kept
  const GltfFileState::Geometry* geometry = found != s.geometries.end() ? &found->second : nullptr;
  if (!geometry) {
    unshared = s.write_geometry(data, stretched);
    geometry = s.share_geometry ? &s.geometries.emplace(geometry_id, std::move(unshared)).first->second : &unshared;
  }
  const GltfFileState::Geometry& g = *geometry;
  const GltfFileState::MeshInfo info = g.info;
  const std::string tail = ",\"material\":" + std::to_string(material);
  std::string mesh = "{\"primitives\":[";
  if (!g.triangles.empty()) mesh += g.triangles + tail + "}";  // mode: triangles, the default
  if (!g.lines.empty())
    mesh += (g.triangles.empty() ? "" : ",") + g.lines + tail + ",\"mode\":" + std::to_string(kLines) + "}";
  mesh += "]}";
  if (!s.meshes_text.append(s.mesh_info.empty() ? mesh : "," + mesh)) s.note_failure(s.meshes_text);
  if (s.failed) {
    error = s.write_error;
    return kUnknownMesh;
  }
  s.mesh_info.push_back(info);
  return s.meshes[key] = int(s.mesh_info.size() - 1);
}

void GltfFile::add_object(const Object& object, std::string_view zone, const glm::dvec3& position_m,
                          const glm::dquat& rotation, const glm::vec3& scale, int mesh) {
  GltfFileState& s = *state_;
  int parent = s.group(object.source, zone);
  if (object.pipeline_id != 0 &&
      (object.object_class == ObjectClass::pipe || object.object_class == ObjectClass::component))
    parent = s.pipeline(object.pipeline_id, parent);
  const std::string text = "\"name\":" + json_string(utf8_text(object.name)) + ",\"extras\":" + object_extras(object);
  if (!s.gpu_instancing && object.object_class != ObjectClass::pipeline) {
    s.stream_node(parent, text, mesh, position_m, glm::quat(rotation), scale, true);
    return;
  }
  int index;
  if (object.object_class == ObjectClass::pipeline && s.pipelines.count(object.id)) {
    // The placeholder made for an earlier member becomes this pipeline's node.
    index = s.pipelines[object.id];
    s.set_text(s.records[size_t(index)], text);
    std::erase(s.pipeline_ids_unnamed, object.id);
  } else {
    index = s.add_record(parent, text);
    if (object.object_class == ObjectClass::pipeline) s.pipelines[object.id] = index;
  }
  GltfFileState::Record& r = s.records[size_t(index)];
  r.mesh = mesh;
  r.placed = true;
  r.is_object = true;
  r.position_m = position_m;
  r.rotation = glm::quat(rotation);
  r.scale = scale;
}

void GltfFile::add_run(std::string name, uint64_t pipeline_id, std::string_view source, std::string_view zone,
                       const glm::dvec3& position_m, const glm::dquat& rotation, const glm::vec3& scale,
                       int mesh) {
  GltfFileState& s = *state_;
  const int parent = s.pipeline(pipeline_id, s.group(source, zone));
  if (!s.gpu_instancing) {
    s.stream_node(parent, "\"name\":" + json_string(utf8_text(name)), mesh, position_m, glm::quat(rotation), scale, false);
    return;
  }
  GltfFileState::Record& r = s.records[size_t(s.add_record(parent, "\"name\":" + json_string(utf8_text(name))))];
  r.mesh = mesh;
  r.placed = true;
  r.position_m = position_m;
  r.rotation = glm::quat(rotation);
  r.scale = scale;
}

std::vector<uint64_t> GltfFile::unnamed_pipelines() const { return state_->pipeline_ids_unnamed; }

void GltfFile::name_pipeline(const Object& pipeline) {
  GltfFileState& s = *state_;
  const auto it = s.pipelines.find(pipeline.id);
  if (it == s.pipelines.end()) return;
  s.set_text(s.records[size_t(it->second)],
             "\"name\":" + json_string(utf8_text(pipeline.name)) + ",\"extras\":" + object_extras(pipeline));
  std::erase(s.pipeline_ids_unnamed, pipeline.id);
}

void GltfFile::abandon() {
  GltfFileState& s = *state_;
  s.remove_all();
  if (s.finished) {
    std::error_code ignored;
    std::filesystem::remove(s.path, ignored);
    if (!s.binary) std::filesystem::remove(std::filesystem::path(s.path).parent_path() / s.bin_name, ignored);
  }
}

}  // namespace plantview::detail::gltf
