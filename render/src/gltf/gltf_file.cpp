// One glTF file being written (rules in gltf_file.h).
#include "gltf_file.h"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

#include <tiny_gltf.h>

#include "gltf_text.h"

namespace plantview::detail::gltf {

namespace {

constexpr int kVertexView = 0, kIndexView = 1, kInstanceView = 2;

double srgb_to_linear(uint8_t v) {
  const double c = v / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

std::string system_reason() { return std::strerror(errno); }

// Appends `size` bytes to `file`; false on a write error.
bool put(std::FILE* file, const void* data, size_t size) {
  return size == 0 || std::fwrite(data, 1, size, file) == size;
}

bool copy_file_into(std::FILE* out, const std::string& from, std::string& error) {
  std::FILE* in = std::fopen(from.c_str(), "rb");
  if (!in) {
    error = "cannot read back " + from + ": " + system_reason();
    return false;
  }
  std::vector<char> block(1 << 20);
  size_t n;
  bool ok = true;
  while ((n = std::fread(block.data(), 1, block.size(), in)) > 0) {
    if (!put(out, block.data(), n)) {
      ok = false;
      break;
    }
  }
  ok = ok && !std::ferror(in);
  std::fclose(in);
  return ok;
}

}  // namespace

struct GltfFile::State {
  // A node to be: an object, a merged run, or a group (site, zone, pipeline placeholder).
  struct Record {
    std::string name;
    tinygltf::Value extras;
    int parent = -1;
    int mesh = kNoMesh;
    bool placed = false;      // has a transform (objects and runs)
    bool is_object = false;   // an object of the store (counted, may be instanced)
    bool has_children = false;
    glm::dvec3 position_m{0.0};
    glm::dquat rotation{1, 0, 0, 0};
  };
  struct MeshInfo {
    float min[3], max[3];
    uint64_t triangles = 0, lines = 0;
    bool has_box = false;
  };

  std::string path, temp_out, temp_vertices, temp_indices, bin_name, temp_bin;
  bool binary = true, finished = false;
  std::FILE* vertices = nullptr;
  std::FILE* indices = nullptr;
  uint64_t vertex_bytes = 0, index_bytes = 0;
  tinygltf::Model model;
  std::unordered_map<MeshKey, int, MeshKeyHash> meshes;
  std::vector<MeshInfo> mesh_info;
  std::map<uint32_t, int> materials;
  std::vector<Record> records;
  std::map<std::string, int, std::less<>> sites;
  std::map<std::pair<int, std::string>, int> zones;
  std::unordered_map<uint64_t, int> pipelines;
  std::vector<uint64_t> pipeline_ids_unnamed;

  ~State() { close_parts(); }
  void close_parts() {
    if (vertices) std::fclose(vertices);
    if (indices) std::fclose(indices);
    vertices = indices = nullptr;
  }
  void remove_all() {
    close_parts();
    std::error_code ignored;
    for (const std::string& p : {temp_out, temp_vertices, temp_indices, temp_bin})
      if (!p.empty()) std::filesystem::remove(p, ignored);
  }

  int material(Colour colour) {
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

  // Writes vertices and indices; adds the accessors; returns the primitive.
  bool primitive(const std::vector<GltfVertex>& vs, const std::vector<uint32_t>& is, int mode,
                 int material_index, MeshInfo& info, tinygltf::Primitive& out, std::string& error) {
    tinygltf::Accessor position;
    position.bufferView = kVertexView;
    position.byteOffset = size_t(vertex_bytes);
    position.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    position.type = TINYGLTF_TYPE_VEC3;
    position.count = vs.size();
    glm::vec3 mn(INFINITY), mx(-INFINITY);
    for (const GltfVertex& v : vs) {
      mn = glm::min(mn, glm::vec3(v.position[0], v.position[1], v.position[2]));
      mx = glm::max(mx, glm::vec3(v.position[0], v.position[1], v.position[2]));
    }
    position.minValues = {mn.x, mn.y, mn.z};
    position.maxValues = {mx.x, mx.y, mx.z};
    for (int a = 0; a < 3; ++a) {
      info.min[a] = info.has_box ? std::min(info.min[a], mn[a]) : mn[a];
      info.max[a] = info.has_box ? std::max(info.max[a], mx[a]) : mx[a];
    }
    info.has_box = true;
    tinygltf::Accessor normal = position;
    normal.byteOffset += 12;
    normal.minValues.clear();
    normal.maxValues.clear();
    if (!put(vertices, vs.data(), vs.size() * sizeof(GltfVertex))) {
      error = "cannot write " + temp_vertices + ": " + system_reason();
      return false;
    }
    vertex_bytes += vs.size() * sizeof(GltfVertex);

    tinygltf::Accessor index;
    index.bufferView = kIndexView;
    index.byteOffset = size_t(index_bytes);
    index.type = TINYGLTF_TYPE_SCALAR;
    index.count = is.size();
    size_t bytes;
    bool ok;
    // 16 bits while no index reaches 65535 (the primitive-restart value readers reject).
    if (vs.size() < 65535) {
      index.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
      std::vector<uint16_t> narrow(is.begin(), is.end());
      if (narrow.size() % 2) narrow.push_back(0);  // pad to 4 bytes
      bytes = narrow.size() * 2;
      ok = put(indices, narrow.data(), bytes);
    } else {
      index.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
      bytes = is.size() * 4;
      ok = put(indices, is.data(), bytes);
    }
    if (!ok) {
      error = "cannot write " + temp_indices + ": " + system_reason();
      return false;
    }
    index_bytes += bytes;

    const int first = int(model.accessors.size());
    model.accessors.push_back(std::move(position));
    model.accessors.push_back(std::move(index));
    out.attributes["POSITION"] = first;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      model.accessors.push_back(std::move(normal));
      out.attributes["NORMAL"] = first + 2;
    }
    out.indices = first + 1;
    out.mode = mode;
    out.material = material_index;
    return true;
  }

  int group(std::string_view source, std::string_view zone) {
    auto site = sites.find(source);
    if (site == sites.end()) {
      Record& r = records.emplace_back();
      r.name = std::string(source);
      site = sites.emplace(std::string(source), int(records.size() - 1)).first;
    }
    if (zone.empty()) return site->second;
    const auto key = std::make_pair(site->second, std::string(zone));
    if (const auto it = zones.find(key); it != zones.end()) return it->second;
    Record& r = records.emplace_back();
    r.name = std::string(zone);
    r.parent = site->second;
    records[size_t(site->second)].has_children = true;
    return zones[key] = int(records.size() - 1);
  }

  int pipeline(uint64_t id, int parent) {
    if (const auto it = pipelines.find(id); it != pipelines.end()) return it->second;
    Record& r = records.emplace_back();
    r.parent = parent;
    records[size_t(parent)].has_children = true;
    pipeline_ids_unnamed.push_back(id);
    return pipelines[id] = int(records.size() - 1);
  }
};

GltfFile::GltfFile() : state_(std::make_unique<State>()) {}
GltfFile::~GltfFile() {
  if (!state_->finished) state_->remove_all();
}

bool GltfFile::open(const std::string& path, std::string& error) {
  State& s = *state_;
  s.path = path;
  const std::filesystem::path p(path);
  s.binary = p.extension() == ".glb" || p.extension() == ".GLB";
  const std::string stem = (p.parent_path() / ("." + p.filename().string())).string() + ".tmp-" +
                           std::to_string(::getpid());
  s.temp_out = stem;
  s.temp_vertices = stem + ".vertices";
  s.temp_indices = stem + ".indices";
  if (!s.binary) {
    s.bin_name = p.stem().string() + ".bin";
    s.temp_bin = stem + ".bin";
  }
  s.vertices = std::fopen(s.temp_vertices.c_str(), "wb");
  if (s.vertices) s.indices = std::fopen(s.temp_indices.c_str(), "wb");
  if (!s.vertices || !s.indices) {
    error = "cannot write " + path + ": " + system_reason();
    s.remove_all();
    return false;
  }
  return true;
}

int GltfFile::find_mesh(const MeshKey& key) const {
  const auto it = state_->meshes.find(key);
  return it == state_->meshes.end() ? kUnknownMesh : it->second;
}

int GltfFile::add_mesh(const MeshKey& key, const MeshData& data, Colour colour, std::string& error) {
  State& s = *state_;
  if (data.empty()) return s.meshes[key] = kNoMesh;
  const int material = s.material(colour);
  tinygltf::Mesh mesh;
  State::MeshInfo info;
  if (!data.triangles.empty()) {
    tinygltf::Primitive p;
    if (!s.primitive(data.triangle_vertices, data.triangles, TINYGLTF_MODE_TRIANGLES, material, info, p, error))
      return kUnknownMesh;
    mesh.primitives.push_back(std::move(p));
    info.triangles = data.triangles.size() / 3;
  }
  if (!data.lines.empty()) {
    tinygltf::Primitive p;
    if (!s.primitive(data.line_vertices, data.lines, TINYGLTF_MODE_LINE, material, info, p, error))
      return kUnknownMesh;
    mesh.primitives.push_back(std::move(p));
    info.lines = data.lines.size() / 2;
  }
  s.model.meshes.push_back(std::move(mesh));
  s.mesh_info.push_back(info);
  return s.meshes[key] = int(s.model.meshes.size() - 1);
}

void GltfFile::add_object(const Object& object, std::string_view zone, const glm::dvec3& position_m,
                          const glm::dquat& rotation, int mesh) {
  State& s = *state_;
  int parent = s.group(object.source, zone);
  if (object.pipeline_id != 0 &&
      (object.object_class == ObjectClass::pipe || object.object_class == ObjectClass::component))
    parent = s.pipeline(object.pipeline_id, parent);
  int index;
  if (object.object_class == ObjectClass::pipeline) {
    // A placeholder made for an earlier member becomes this pipeline's node.
    if (const auto it = s.pipelines.find(object.id); it != s.pipelines.end()) {
      index = it->second;
      std::erase(s.pipeline_ids_unnamed, object.id);
    } else {
      s.records.emplace_back().parent = parent;
      s.records[size_t(parent)].has_children = true;
      index = s.pipelines[object.id] = int(s.records.size() - 1);
    }
  } else {
    s.records.emplace_back().parent = parent;
    s.records[size_t(parent)].has_children = true;
    index = int(s.records.size() - 1);
  }
  State::Record& r = s.records[size_t(index)];
  r.name = utf8_text(object.name);
  r.extras = object_extras(object);
  r.mesh = mesh;
  r.placed = true;
  r.is_object = true;
  r.position_m = position_m;
  r.rotation = rotation;
}

void GltfFile::add_run(std::string name, uint64_t pipeline_id, std::string_view source, std::string_view zone,
                       const glm::dvec3& position_m, const glm::dquat& rotation, int mesh) {
  State& s = *state_;
  const int parent = s.pipeline(pipeline_id, s.group(source, zone));
  State::Record& r = s.records.emplace_back();
  r.parent = parent;
  r.name = utf8_text(name);
  r.mesh = mesh;
  r.placed = true;
  r.position_m = position_m;
  r.rotation = rotation;
  s.records[size_t(parent)].has_children = true;
}

std::vector<uint64_t> GltfFile::unnamed_pipelines() const { return state_->pipeline_ids_unnamed; }

void GltfFile::name_pipeline(const Object& pipeline) {
  State& s = *state_;
  const auto it = s.pipelines.find(pipeline.id);
  if (it == s.pipelines.end()) return;
  State::Record& r = s.records[size_t(it->second)];
  r.name = utf8_text(pipeline.name);
  r.extras = object_extras(pipeline);
  std::erase(s.pipeline_ids_unnamed, pipeline.id);
}

bool GltfFile::finish(const glm::dvec3& origin_m, bool gpu_instancing, GltfFileSummary& summary,
                      std::string& error) {
  State& s = *state_;
  tinygltf::Model& m = s.model;
  summary.path = s.path;
  summary.meshes = m.meshes.size();

  // 1. Which objects are drawn through EXT_mesh_gpu_instancing: per parent and mesh, when
  //    enough of them share it (and they have no children of their own).
  std::vector<int> instancing_group(s.records.size(), -1);
  std::vector<std::vector<int>> groups;
  if (gpu_instancing) {
    std::map<std::pair<int, int>, std::vector<int>> by_mesh;
    for (size_t i = 0; i < s.records.size(); ++i) {
      const State::Record& r = s.records[i];
      if (r.is_object && r.mesh >= 0 && !r.has_children) by_mesh[{r.parent, r.mesh}].push_back(int(i));
    }
    for (auto& [key, members] : by_mesh) {
      if (members.size() < kGpuInstancingMin) continue;
      for (int i : members) instancing_group[size_t(i)] = int(groups.size());
      groups.push_back(std::move(members));
    }
  }

  // 2. Nodes: records in order (parents come before their children), instanced ones replaced
  //    by one node per group, placed where its group's first member was.
  std::vector<int> node_of(s.records.size(), -1);
  std::vector<float> instance_data;
  std::vector<int> roots;
  auto attach = [&](int parent_record, int node) {
    if (parent_record < 0) roots.push_back(node);
    else m.nodes[size_t(node_of[size_t(parent_record)])].children.push_back(node);
  };
  auto extend_bounds = [&](const State::MeshInfo& info, const glm::dvec3& position, const glm::dquat& rotation) {
    if (!info.has_box) return;
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? info.max[0] : info.min[0], (c & 2) ? info.max[1] : info.min[1],
                              (c & 4) ? info.max[2] : info.min[2]);
      summary.bounds.extend(position + rotation * corner);
    }
  };
  for (size_t i = 0; i < s.records.size(); ++i) {
    State::Record& r = s.records[i];
    if (r.is_object) summary.objects += 1;
    if (r.mesh >= 0) {
      const State::MeshInfo& info = s.mesh_info[size_t(r.mesh)];
      summary.triangles += info.triangles;
      summary.lines += info.lines;
      extend_bounds(info, r.position_m, r.rotation);
    }
    const int g = instancing_group[i];
    if (g >= 0) {
      const std::vector<int>& members = groups[size_t(g)];
      if (members.front() != int(i)) continue;  // the group's node is made at its first member
      tinygltf::Node node;
      node.mesh = r.mesh;
      node.name = r.name + " and " + std::to_string(members.size() - 1) + " more";
      tinygltf::Value::Array objects;
      const size_t first_float = instance_data.size();
      for (int member : members) {
        State::Record& mr = s.records[size_t(member)];
        tinygltf::Value::Object o = mr.extras.IsObject() ? mr.extras.Get<tinygltf::Value::Object>()
                                                         : tinygltf::Value::Object{};
        o["name"] = tinygltf::Value(mr.name);
        objects.emplace_back(std::move(o));
        const glm::dvec3 t = mr.position_m - origin_m;
        instance_data.insert(instance_data.end(), {float(t.x), float(t.y), float(t.z)});
        mr.extras = tinygltf::Value();
      }
      const size_t rotations_float = instance_data.size();
      for (int member : members) {
        const glm::dquat& q = s.records[size_t(member)].rotation;
        instance_data.insert(instance_data.end(), {float(q.x), float(q.y), float(q.z), float(q.w)});
      }
      tinygltf::Accessor translation;
      translation.bufferView = kInstanceView;
      translation.byteOffset = first_float * 4;
      translation.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
      translation.type = TINYGLTF_TYPE_VEC3;
      translation.count = members.size();
      tinygltf::Accessor rotation = translation;
      rotation.byteOffset = rotations_float * 4;
      rotation.type = TINYGLTF_TYPE_VEC4;
      m.accessors.push_back(std::move(translation));
      m.accessors.push_back(std::move(rotation));
      tinygltf::Value::Object attributes{{"TRANSLATION", tinygltf::Value(int(m.accessors.size() - 2))},
                                         {"ROTATION", tinygltf::Value(int(m.accessors.size() - 1))}};
      node.extensions["EXT_mesh_gpu_instancing"] =
          tinygltf::Value(tinygltf::Value::Object{{"attributes", tinygltf::Value(attributes)}});
      node.extras = tinygltf::Value(tinygltf::Value::Object{{"objects", tinygltf::Value(objects)}});
      summary.instanced_objects += members.size();
      m.nodes.push_back(std::move(node));
      node_of[i] = int(m.nodes.size() - 1);
      attach(r.parent, node_of[i]);
      continue;
    }
    tinygltf::Node node;
    node.name = r.name.empty() ? "(unnamed)" : r.name;
    node.extras = std::move(r.extras);
    if (r.mesh >= 0) node.mesh = r.mesh;
    if (r.placed) {
      const glm::dvec3 t = r.position_m - origin_m;
      node.translation = {t.x, t.y, t.z};
      if (r.rotation != glm::dquat(1, 0, 0, 0)) node.rotation = {r.rotation.x, r.rotation.y, r.rotation.z, r.rotation.w};
    }
    m.nodes.push_back(std::move(node));
    node_of[i] = int(m.nodes.size() - 1);
    attach(r.parent, node_of[i]);
  }
  s.records.clear();
  s.records.shrink_to_fit();

  // 3. The document: buffer views over [vertices][indices][instances], the scene, the asset.
  if (s.vertex_bytes > 0) {
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = 0;
    v.byteLength = size_t(s.vertex_bytes);
    v.byteStride = sizeof(GltfVertex);
    v.target = TINYGLTF_TARGET_ARRAY_BUFFER;
    m.bufferViews.push_back(v);
    tinygltf::BufferView i;
    i.buffer = 0;
    i.byteOffset = size_t(s.vertex_bytes);
    i.byteLength = size_t(s.index_bytes);
    i.target = TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER;
    m.bufferViews.push_back(i);
    if (!instance_data.empty()) {
      tinygltf::BufferView n;
      n.buffer = 0;
      n.byteOffset = size_t(s.vertex_bytes + s.index_bytes);
      n.byteLength = instance_data.size() * 4;
      m.bufferViews.push_back(n);
      m.extensionsUsed.push_back("EXT_mesh_gpu_instancing");
      // The extension defines no fallback: a reader without it would draw one copy.
      m.extensionsRequired.push_back("EXT_mesh_gpu_instancing");
    }
  }
  const uint64_t bin_bytes = s.vertex_bytes + s.index_bytes + instance_data.size() * 4;
  tinygltf::Scene scene;
  scene.nodes = std::move(roots);
  m.scenes.push_back(std::move(scene));
  m.defaultScene = 0;
  m.asset.version = "2.0";
  m.asset.generator = "plantview";
  m.asset.extras = tinygltf::Value(tinygltf::Value::Object{
      {"origin_m", tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(origin_m.x), tinygltf::Value(origin_m.y),
                                                           tinygltf::Value(origin_m.z)})}});
  std::string json;
  {
    std::ostringstream text;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&m, text, false, false)) {
      error = "cannot serialise the glTF document of " + s.path;
      return false;
    }
    json = std::move(text).str();
  }
  m = tinygltf::Model();
  // tinygltf wants the buffer's bytes in memory; ours are on disk: the one buffer is added here.
  while (!json.empty() && json.back() != '}') json.pop_back();
  if (json.empty()) {
    error = "cannot serialise the glTF document of " + s.path;
    return false;
  }
  if (bin_bytes > 0) {
    json.pop_back();
    json += ",\"buffers\":[{\"byteLength\":" + std::to_string(bin_bytes);
    if (!s.binary) json += ",\"uri\":" + json_string(s.bin_name);
    json += "}]}";
  }

  // 4. The file(s): the binary chunk assembled from the parts on disk.
  s.close_parts();
  auto fail_write = [&](const std::string& what) {
    error = "cannot write " + what + ": " + system_reason();
    return false;
  };
  std::FILE* out = std::fopen(s.temp_out.c_str(), "wb");
  if (!out) return fail_write(s.path);
  std::FILE* bin = out;
  bool ok = true;
  if (s.binary) {
    const uint32_t json_padded = uint32_t((json.size() + 3) & ~size_t(3));
    const uint32_t bin_padded = uint32_t((bin_bytes + 3) & ~uint64_t(3));
    const uint64_t total = 12 + 8 + uint64_t(json_padded) + (bin_bytes ? 8 + uint64_t(bin_padded) : 0);
    if (total > UINT32_MAX) {
      std::fclose(out);
      error = "cannot write " + s.path + ": " + std::to_string(total) +
              " bytes, more than a .glb can hold (4 GiB); select less, raise the tolerance or write .gltf";
      return false;
    }
    const uint32_t header[5] = {0x46546C67u, 2u, uint32_t(total), json_padded, 0x4E4F534Au};
    json.resize(json_padded, ' ');
    ok = put(out, header, sizeof header) && put(out, json.data(), json.size());
    if (bin_bytes) {
      const uint32_t chunk[2] = {bin_padded, 0x004E4942u};
      ok = ok && put(out, chunk, sizeof chunk);
    }
  } else {
    ok = put(out, json.data(), json.size()) && put(out, "\n", 1);
    if (bin_bytes) {
      bin = std::fopen(s.temp_bin.c_str(), "wb");
      if (!bin) {
        std::fclose(out);
        return fail_write(s.path.substr(0, s.path.size() - std::filesystem::path(s.path).extension().string().size()) + ".bin");
      }
    }
  }
  if (ok && bin_bytes) {
    ok = copy_file_into(bin, s.temp_vertices, error) && copy_file_into(bin, s.temp_indices, error) &&
         put(bin, instance_data.data(), instance_data.size() * 4);
    const char zeros[4] = {};
    if (s.binary) ok = ok && put(bin, zeros, size_t(((bin_bytes + 3) & ~uint64_t(3)) - bin_bytes));
  }
  ok = ok && std::fflush(out) == 0 && !std::ferror(out);
  if (bin != out) ok = std::fclose(bin) == 0 && ok;
  ok = std::fclose(out) == 0 && ok;
  if (!ok) {
    if (error.empty()) return fail_write(s.path);
    return false;
  }
  // 5. Into place: the .bin before the .gltf that refers to it.
  std::error_code ec;
  const std::filesystem::path final_path(s.path);
  if (!s.binary && bin_bytes) {
    std::filesystem::rename(s.temp_bin, final_path.parent_path() / s.bin_name, ec);
    if (ec) {
      error = "cannot write " + (final_path.parent_path() / s.bin_name).string() + ": " + ec.message();
      return false;
    }
  }
  std::filesystem::rename(s.temp_out, final_path, ec);
  if (ec) {
    error = "cannot write " + s.path + ": " + ec.message();
    return false;
  }
  std::filesystem::remove(s.temp_vertices, ec);
  std::filesystem::remove(s.temp_indices, ec);
  s.finished = true;
  summary.bytes = std::filesystem::file_size(final_path, ec);
  if (!s.binary && bin_bytes) summary.bytes += bin_bytes;
  return true;
}

void GltfFile::abandon() {
  State& s = *state_;
  s.remove_all();
  if (s.finished) {
    std::error_code ignored;
    std::filesystem::remove(s.path, ignored);
    if (!s.binary) std::filesystem::remove(std::filesystem::path(s.path).parent_path() / s.bin_name, ignored);
  }
}

}  // namespace plantview::detail::gltf
