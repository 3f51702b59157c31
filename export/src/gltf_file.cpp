// One glTF file being written (rules in gltf_file.h).
#include "gltf_file.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

#include <tiny_gltf.h>

#include "gltf_text.h"

namespace plantview::detail::gltf {

namespace {

constexpr int kTriangles = 4, kLines = 1;                           // glTF primitive modes
constexpr int kFloat = 5126, kUnsignedShort = 5123, kUnsignedInt = 5125;  // component types
constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122;
constexpr double kQuantized = 32767.0;  // normalized int16: q / 32767
// Dequantization scales: the smallest that holds a mesh's half extent, from numbers short to
// write (a node's scale carries it); 1 (no scale at all) for meshes up to 2 m across.
constexpr double kGridScales[] = {1, 1.5, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256,
                                  384, 512, 768, 1024, 1536, 2048, 3072, 4096};

// A quantized vertex: position normalized int16 (x, y, z, padding), normal normalized int8.
struct QuantizedVertex {
  int16_t position[4];
  int8_t normal[4];
};
static_assert(sizeof(QuantizedVertex) == 12);

// The int8 normal nearest `n`: rounded, or where that lands more than 0.004 off unit length
// (the validator allows 0.00674; rounding can land just outside), the neighbour closest in
// direction and length.
void quantize_normal(const float n[3], int8_t out[4]) {
  int base[3];
  for (int a = 0; a < 3; ++a) base[a] = std::clamp(int(std::lround(double(n[a]) * 127.0)), -127, 127);
  auto length_of = [](const int c[3]) { return std::sqrt(double(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])) / 127.0; };
  int chosen[3] = {base[0], base[1], base[2]};
  if (std::abs(length_of(base) - 1) > 0.004) {
    double best = INFINITY;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const int c[3] = {base[0] + dx, base[1] + dy, base[2] + dz};
          if (std::abs(c[0]) > 127 || std::abs(c[1]) > 127 || std::abs(c[2]) > 127) continue;
          const double length = length_of(c);
          if (!(length > 0)) continue;
          double misfit = 0;  // distance from n after normalising, plus length off 1
          for (int a = 0; a < 3; ++a) {
            const double d = c[a] / 127.0 / length - double(n[a]);
            misfit += d * d;
          }
          misfit = std::sqrt(misfit) + 4 * std::abs(length - 1);
          if (misfit < best) {
            best = misfit;
            chosen[0] = c[0], chosen[1] = c[1], chosen[2] = c[2];
          }
        }
  }
  for (int a = 0; a < 3; ++a) out[a] = int8_t(chosen[a]);
  out[3] = 0;
}

double srgb_to_linear(uint8_t v) {
  const double c = v / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

std::string system_reason() { return std::strerror(errno); }

bool put(std::FILE* file, const void* data, size_t size) {
  return size == 0 || std::fwrite(data, 1, size, file) == size;
}
bool put(std::FILE* file, const std::string& text) { return put(file, text.data(), text.size()); }

// Appends the file at `from` to `out`; false on an error (`error` set when reading failed).
bool copy_file_into(std::FILE* out, const std::string& from, std::string& error) {
  std::FILE* in = std::fopen(from.c_str(), "rb");
  if (!in) {
    error = "cannot read back " + from + ": " + system_reason();
    return false;
  }
  std::vector<char> block(1 << 20);
  size_t n;
  bool ok = true;
  while (ok && (n = std::fread(block.data(), 1, block.size(), in)) > 0) ok = put(out, block.data(), n);
  ok = ok && !std::ferror(in);
  std::fclose(in);
  return ok;
}

// A temporary file written in order, its size kept.
struct Part {
  std::string path;
  std::FILE* file = nullptr;
  uint64_t bytes = 0;
  bool open(const std::string& p) {
    path = p;
    file = std::fopen(p.c_str(), "w+b");
    return file != nullptr;
  }
  bool append(const void* data, size_t size) {
    bytes += size;
    return put(file, data, size);
  }
  bool append(const std::string& text) { return append(text.data(), text.size()); }
  void close() {
    if (file) std::fclose(file);
    file = nullptr;
  }
  void remove() {
    close();
    std::error_code ignored;
    if (!path.empty()) std::filesystem::remove(path, ignored);
  }
};

std::string vec3_json(const float v[3]) {
  return "[" + json_number(v[0]) + "," + json_number(v[1]) + "," + json_number(v[2]) + "]";
}

}  // namespace

struct GltfFile::State {
  // A node to be: an object, a merged run, or a group (site, zone, pipeline placeholder). Its
  // name and extras are JSON text in `text` at [text_offset, + text_bytes).
  struct Record {
    int32_t parent = -1;
    int32_t mesh = kNoMesh;
    uint64_t text_offset = 0;
    uint32_t text_bytes = 0;
    bool placed = false;      // has a transform (objects and runs)
    bool is_object = false;   // an object of the store (may be instanced)
    bool has_children = false;
    glm::dvec3 position_m{0.0};
    glm::quat rotation{1, 0, 0, 0};
    glm::vec3 scale{1.0f};
  };
  struct MeshInfo {
    float min[3], max[3];
    uint32_t triangles = 0, lines = 0;
    bool has_box = false;
    // Quantized: model = node * (centre + grid_scale * q / 32767) for each int16 position q.
    bool quantized = false;
    glm::dvec3 centre{0.0};
    double grid_scale = 1;
  };

  std::string path, temp_out, bin_name, temp_bin;
  bool binary = true, finished = false, failed = false;
  glm::dvec3 origin_m{0.0};
  bool gpu_instancing = false;
  // Nodes written as they came (objects and runs, without GPU instancing): numbered from 0,
  // listed as children of their group record; their counts and bounds.
  uint32_t streamed = 0;
  std::unordered_map<int, std::vector<uint32_t>> streamed_children;
  GltfFileSummary streamed_summary;
  Part vertices, quantized, indices, accessors, meshes_text, text, nodes;
  double quantization_error_m = 0;
  bool share_geometry = true;
  // Buffer views by first use: float vertices, quantized vertices, indices, instances.
  int float_view = -1, quantized_view = -1, index_view = -1, instance_view = -1, views = 0;
  int view(int& v) { return v >= 0 ? v : (v = views++); }
  uint64_t accessor_count = 0;
  std::string write_error;  // the first write error, reported by the next fallible call
  tinygltf::Model model;    // the document's small parts
  std::unordered_map<MeshKey, int, MeshKeyHash> meshes;
  // Each distinct geometry's primitives up to their material (meshes of another colour reuse
  // its accessors), with its box and quantization.
  struct Geometry {
    std::string triangles, lines;
    MeshInfo info;
  };
  std::unordered_map<MeshKey, Geometry, MeshKeyHash> geometries;
  std::vector<MeshInfo> mesh_info;
  std::map<uint32_t, int> materials;
  std::vector<Record> records;
  std::map<std::string, int, std::less<>> sites;
  std::map<std::pair<int, std::string>, int> zones;
  std::unordered_map<uint64_t, int> pipelines;
  std::vector<uint64_t> pipeline_ids_unnamed;

  ~State() { close_parts(); }
  Part* parts[7] = {&vertices, &quantized, &indices, &accessors, &meshes_text, &text, &nodes};
  void close_parts() {
    for (Part* p : parts) p->close();
  }
  void remove_all() {
    for (Part* p : parts) p->remove();
    std::error_code ignored;
    for (const std::string& p : {temp_out, temp_bin})
      if (!p.empty()) std::filesystem::remove(p, ignored);
  }
  void note_failure(const Part& part) {
    if (!failed) write_error = "cannot write " + part.path + ": " + system_reason();
    failed = true;
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

  uint64_t accessor(const std::string& json) {
    if (!accessors.append(accessor_count ? "," + json : json)) note_failure(accessors);
    return accessor_count++;
  }

  // Writes vertices and indices, their accessors; returns the primitive's JSON up to its
  // material ({"attributes":..,"indices":N). `info` has the mesh's box and quantization.
  std::string primitive(const std::vector<GltfVertex>& vs, const std::vector<uint32_t>& is, int mode,
                        const MeshInfo& info) {
    const std::string count = std::to_string(vs.size());
    std::string attributes;
    if (info.quantized) {
      std::vector<QuantizedVertex> qs(vs.size());
      int mn[3] = {32767, 32767, 32767}, mx[3] = {-32767, -32767, -32767};
      for (size_t i = 0; i < vs.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
          const double q = std::round((double(vs[i].position[a]) - info.centre[a]) / info.grid_scale * kQuantized);
          qs[i].position[a] = int16_t(std::clamp(q, -kQuantized, kQuantized));
          mn[a] = std::min(mn[a], int(qs[i].position[a]));
          mx[a] = std::max(mx[a], int(qs[i].position[a]));
        }
        qs[i].position[3] = 0;
        quantize_normal(vs[i].normal, qs[i].normal);
      }
      const std::string view_json = "{\"bufferView\":" + std::to_string(view(quantized_view)) + ",\"byteOffset\":";
      const uint64_t position = accessor(view_json + std::to_string(quantized.bytes) + ",\"componentType\":" +
                                         std::to_string(kShort) + ",\"normalized\":true,\"count\":" + count +
                                         ",\"type\":\"VEC3\",\"min\":[" + std::to_string(mn[0]) + "," +
                                         std::to_string(mn[1]) + "," + std::to_string(mn[2]) + "],\"max\":[" +
                                         std::to_string(mx[0]) + "," + std::to_string(mx[1]) + "," +
                                         std::to_string(mx[2]) + "]}");
      attributes = "{\"POSITION\":" + std::to_string(position);
      if (mode == kTriangles) {
        const uint64_t normal = accessor(view_json + std::to_string(quantized.bytes + 8) + ",\"componentType\":" +
                                         std::to_string(kByte) + ",\"normalized\":true,\"count\":" + count +
                                         ",\"type\":\"VEC3\"}");
        attributes += ",\"NORMAL\":" + std::to_string(normal);
      }
      if (!quantized.append(qs.data(), qs.size() * sizeof(QuantizedVertex))) note_failure(quantized);
    } else {
      float mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
      for (const GltfVertex& v : vs) {
        for (int a = 0; a < 3; ++a) {
          mn[a] = std::min(mn[a], v.position[a]);
          mx[a] = std::max(mx[a], v.position[a]);
        }
      }
      const std::string view_json = "{\"bufferView\":" + std::to_string(view(float_view)) + ",\"byteOffset\":";
      const uint64_t position = accessor(view_json + std::to_string(vertices.bytes) + ",\"componentType\":" +
                                         std::to_string(kFloat) + ",\"count\":" + count + ",\"type\":\"VEC3\",\"min\":" +
                                         vec3_json(mn) + ",\"max\":" + vec3_json(mx) + "}");
      attributes = "{\"POSITION\":" + std::to_string(position);
      if (mode == kTriangles) {
        const uint64_t normal = accessor(view_json + std::to_string(vertices.bytes + 12) + ",\"componentType\":" +
                                         std::to_string(kFloat) + ",\"count\":" + count + ",\"type\":\"VEC3\"}");
        attributes += ",\"NORMAL\":" + std::to_string(normal);
      }
      if (!vertices.append(vs.data(), vs.size() * sizeof(GltfVertex))) note_failure(vertices);
    }
    attributes += "}";

    // 8 bits under 255 vertices, 16 under 65535 (255 and 65535 are the primitive-restart values
    // readers reject), each mesh's indices padded to 4 bytes.
    const uint64_t index_offset = indices.bytes;
    int component;
    bool ok;
    if (vs.size() < 255) {
      component = kUnsignedByte;
      std::vector<uint8_t> narrow(is.begin(), is.end());
      narrow.resize((narrow.size() + 3) & ~size_t(3), 0);
      ok = indices.append(narrow.data(), narrow.size());
    } else if (vs.size() < 65535) {
      component = kUnsignedShort;
      std::vector<uint16_t> narrow(is.begin(), is.end());
      if (narrow.size() % 2) narrow.push_back(0);
      ok = indices.append(narrow.data(), narrow.size() * 2);
    } else {
      component = kUnsignedInt;
      ok = indices.append(is.data(), is.size() * 4);
    }
    if (!ok) note_failure(indices);
    const uint64_t index = accessor("{\"bufferView\":" + std::to_string(view(index_view)) + ",\"byteOffset\":" +
                                    std::to_string(index_offset) + ",\"componentType\":" + std::to_string(component) +
                                    ",\"count\":" + std::to_string(is.size()) + ",\"type\":\"SCALAR\"}");
    return "{\"attributes\":" + attributes + ",\"indices\":" + std::to_string(index);
  }

  // A node's placement relative to the origin with `mesh`'s dequantization folded in:
  // node * (centre + grid_scale * v) = (t + R (S * centre)) R (S * grid_scale) v.
  void placement(int mesh, const glm::dvec3& position, const glm::quat& q, glm::vec3& scale,
                 glm::dvec3& translation) const {
    translation = position - origin_m;
    if (mesh < 0 || !mesh_info[size_t(mesh)].quantized) return;
    const MeshInfo& info = mesh_info[size_t(mesh)];
    translation += glm::dquat(q) * (glm::dvec3(scale) * info.centre);
    scale *= float(info.grid_scale);
  }
  std::string transform_json(const glm::dvec3& position, const glm::quat& q, glm::vec3 scale, int mesh) const {
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
  // Counts a placed mesh into `summary`: triangles, lines, and the bounds of its box.
  void count(int mesh, const glm::dvec3& position, const glm::quat& rotation, const glm::vec3& scale,
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
  void append_node(const std::string& json) {
    if (!nodes.append(nodes.bytes ? "," + json : json)) note_failure(nodes);
  }
  // Writes a leaf node now (no GPU instancing): an object's or a run's.
  void stream_node(int parent, const std::string& name_and_extras, int mesh, const glm::dvec3& position,
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

  int add_record(int parent, const std::string& name_and_extras) {
    Record& r = records.emplace_back();
    r.parent = parent;
    if (parent >= 0) records[size_t(parent)].has_children = true;
    set_text(r, name_and_extras);
    return int(records.size() - 1);
  }
  void set_text(Record& r, const std::string& name_and_extras) {
    r.text_offset = text.bytes;
    r.text_bytes = uint32_t(name_and_extras.size());
    if (!text.append(name_and_extras)) note_failure(text);
  }

  int group(std::string_view source, std::string_view zone) {
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

  int pipeline(uint64_t id, int parent) {
    if (const auto it = pipelines.find(id); it != pipelines.end()) return it->second;
    pipeline_ids_unnamed.push_back(id);
    char name[40];
    std::snprintf(name, sizeof name, "\"name\":\"pipeline %016llx\"", static_cast<unsigned long long>(id));
    return pipelines[id] = add_record(parent, name);
  }
};

GltfFile::GltfFile() : state_(std::make_unique<State>()) {}
GltfFile::~GltfFile() {
  if (!state_->finished) state_->remove_all();
}

bool GltfFile::open(const std::string& path, const glm::dvec3& origin_m, bool gpu_instancing,
                    double quantization_error_m, bool share_geometry, std::string& error) {
  State& s = *state_;
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
  State& s = *state_;
  if (data.empty()) return s.meshes[key] = kNoMesh;
  const int material = s.material(colour);
  MeshKey geometry_id{};
  if (s.share_geometry) {
    geometry_id = geometry_key(data);
    geometry_id.b ^= uint64_t(stretched);
  }
  auto found = s.share_geometry ? s.geometries.find(geometry_id) : s.geometries.end();
  State::Geometry unshared;  // without sharing: not kept
  const State::Geometry* geometry = found != s.geometries.end() ? &found->second : nullptr;
  if (!geometry) {
    State::Geometry& g = unshared;
    State::MeshInfo& info = g.info;
    for (const std::vector<GltfVertex>* vs : {&data.triangle_vertices, &data.line_vertices}) {
      for (const GltfVertex& v : *vs) {
        for (int a = 0; a < 3; ++a) {
          info.min[a] = info.has_box ? std::min(info.min[a], v.position[a]) : v.position[a];
          info.max[a] = info.has_box ? std::max(info.max[a], v.position[a]) : v.position[a];
        }
        info.has_box = true;
      }
    }
    // The grid: centred on the box, the smallest short scale holding it; its worst error (half
    // a step on each axis) must be within the bound.
    if (s.quantization_error_m > 0 && !stretched && info.has_box) {
      double half = 0;
      for (int a = 0; a < 3; ++a) {
        info.centre[a] = (double(info.min[a]) + double(info.max[a])) / 2;
        half = std::max(half, (double(info.max[a]) - double(info.min[a])) / 2);
      }
      for (const double grid : kGridScales) {
        if (grid < half * (1 + 1e-6)) continue;
        info.grid_scale = grid;
        info.quantized = std::sqrt(3.0) * 0.5 * grid / kQuantized <= s.quantization_error_m;
        break;
      }
      if (!info.quantized) info.centre = glm::dvec3(0.0), info.grid_scale = 1;
    }
    if (!data.triangles.empty()) g.triangles = s.primitive(data.triangle_vertices, data.triangles, kTriangles, info);
    if (!data.lines.empty()) g.lines = s.primitive(data.line_vertices, data.lines, kLines, info);
    info.triangles = uint32_t(data.triangles.size() / 3);
    info.lines = uint32_t(data.lines.size() / 2);
    geometry = s.share_geometry ? &s.geometries.emplace(geometry_id, std::move(g)).first->second : &unshared;
  }
  const State::Geometry& g = *geometry;
  const State::MeshInfo info = g.info;
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
  State& s = *state_;
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
  State::Record& r = s.records[size_t(index)];
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
  State& s = *state_;
  const int parent = s.pipeline(pipeline_id, s.group(source, zone));
  if (!s.gpu_instancing) {
    s.stream_node(parent, "\"name\":" + json_string(utf8_text(name)), mesh, position_m, glm::quat(rotation), scale, false);
    return;
  }
  State::Record& r = s.records[size_t(s.add_record(parent, "\"name\":" + json_string(utf8_text(name))))];
  r.mesh = mesh;
  r.placed = true;
  r.position_m = position_m;
  r.rotation = glm::quat(rotation);
  r.scale = scale;
}

std::vector<uint64_t> GltfFile::unnamed_pipelines() const { return state_->pipeline_ids_unnamed; }

void GltfFile::name_pipeline(const Object& pipeline) {
  State& s = *state_;
  const auto it = s.pipelines.find(pipeline.id);
  if (it == s.pipelines.end()) return;
  s.set_text(s.records[size_t(it->second)],
             "\"name\":" + json_string(utf8_text(pipeline.name)) + ",\"extras\":" + object_extras(pipeline));
  std::erase(s.pipeline_ids_unnamed, pipeline.id);
}

bool GltfFile::finish(GltfFileSummary& summary, std::string& error) {
  State& s = *state_;
  const glm::dvec3& origin_m = s.origin_m;
  const bool gpu_instancing = s.gpu_instancing;
  summary.path = s.path;
  summary.meshes = s.mesh_info.size();
  if (s.failed) {
    error = s.write_error;
    return false;
  }
  if (std::fflush(s.text.file) != 0) {
    error = "cannot write " + s.text.path + ": " + system_reason();
    return false;
  }
  const size_t n = s.records.size();

  // 1. Which objects are drawn through EXT_mesh_gpu_instancing: per parent and mesh, when
  //    enough of them share it (and they have no children of their own). The group's node
  //    stands where its first member was.
  std::vector<int32_t> first_of_group(n, -1);  // instanced: the record standing for the group
  std::map<std::pair<int, int>, std::vector<uint32_t>> groups;
  if (gpu_instancing) {
    for (size_t i = 0; i < n; ++i) {
      const State::Record& r = s.records[i];
      if (r.is_object && r.mesh >= 0 && !r.has_children) groups[{r.parent, r.mesh}].push_back(uint32_t(i));
    }
    for (auto it = groups.begin(); it != groups.end();) {
      if (it->second.size() < kGpuInstancingMin) {
        it = groups.erase(it);
        continue;
      }
      for (uint32_t i : it->second) first_of_group[i] = int32_t(it->second.front());
      ++it;
    }
  }

  // 2. Node numbers (records in order, instanced ones as their group), children lists (CSR).
  //    A node with children carries no transform (its children's are in model space): an
  //    object that has both children and geometry (an RVM pipeline with primitives of its own)
  //    gets its geometry in a child node of its own, numbered right after it.
  std::vector<int32_t> node_of(n, -1);
  std::vector<uint8_t> split_geometry(n, 0);
  int32_t nodes = int32_t(s.streamed);  // the streamed nodes come first
  for (size_t i = 0; i < n; ++i) {
    if (first_of_group[i] >= 0 && first_of_group[i] != int32_t(i)) continue;
    node_of[i] = nodes++;
    const State::Record& r = s.records[i];
    if (r.has_children && r.mesh >= 0) {
      split_geometry[i] = 1;
      nodes++;
    }
  }
  std::vector<uint32_t> child_start(n + 1, 0), children;
  std::vector<int> roots;
  for (size_t i = 0; i < n; ++i) {
    if (node_of[i] < 0) continue;
    if (s.records[i].parent < 0) roots.push_back(node_of[i]);
    else child_start[size_t(s.records[i].parent) + 1] += 1;
    child_start[i + 1] += split_geometry[i];
  }
  for (size_t i = 0; i < n; ++i) child_start[i + 1] += child_start[i];
  children.resize(child_start[n]);
  {
    std::vector<uint32_t> fill(child_start.begin(), child_start.end() - 1);
    for (size_t i = 0; i < n; ++i) {
      if (split_geometry[i]) children[fill[i]++] = uint32_t(node_of[i] + 1);
      if (node_of[i] >= 0 && s.records[i].parent >= 0) children[fill[size_t(s.records[i].parent)]++] = uint32_t(node_of[i]);
    }
  }

  // 3. The nodes, in order, to their part; the instances' transforms to memory.
  std::vector<float> instance_data;
  std::string text, node;
  auto read_text = [&](const State::Record& r) {
    text.resize(r.text_bytes);
    return ::pread(fileno(s.text.file), text.data(), r.text_bytes, off_t(r.text_offset)) == ssize_t(r.text_bytes);
  };
  for (size_t i = 0; i < n; ++i) {
    const State::Record& r = s.records[i];
    if (r.is_object) summary.objects += 1;
    s.count(r.mesh, r.position_m, r.rotation, r.scale, summary);
    if (node_of[i] < 0) continue;  // drawn by its group's node
    node = "{";
    if (first_of_group[i] >= 0) {
      const std::vector<uint32_t>& members = groups.at({r.parent, r.mesh});
      const size_t translations = instance_data.size();
      std::string objects;
      for (uint32_t m : members) {
        const State::Record& mr = s.records[m];
        if (!read_text(mr)) {
          error = "cannot read back " + s.text.path + ": " + system_reason();
          return false;
        }
        objects += (objects.empty() ? "{" : ",{") + text + "}";
        glm::vec3 scale = mr.scale;
        glm::dvec3 t;
        s.placement(r.mesh, mr.position_m, mr.rotation, scale, t);
        instance_data.insert(instance_data.end(), {float(t.x), float(t.y), float(t.z)});
      }
      const size_t rotations = instance_data.size();
      const float grid_scale = float(s.mesh_info[size_t(r.mesh)].grid_scale);
      bool scaled = false;
      for (uint32_t m : members) {
        const glm::quat& q = s.records[m].rotation;
        instance_data.insert(instance_data.end(), {q.x, q.y, q.z, q.w});
        scaled = scaled || s.records[m].scale * grid_scale != glm::vec3(1.0f);
      }
      const size_t scales = instance_data.size();
      if (scaled) {
        for (uint32_t m : members) {
          const glm::vec3 v = s.records[m].scale * grid_scale;
          instance_data.insert(instance_data.end(), {v.x, v.y, v.z});
        }
      }
      const uint64_t t = s.accessor("{\"bufferView\":" + std::to_string(s.view(s.instance_view)) + ",\"byteOffset\":" +
                                    std::to_string(translations * 4) + ",\"componentType\":" + std::to_string(kFloat) +
                                    ",\"count\":" + std::to_string(members.size()) + ",\"type\":\"VEC3\"}");
      const uint64_t q = s.accessor("{\"bufferView\":" + std::to_string(s.view(s.instance_view)) + ",\"byteOffset\":" +
                                    std::to_string(rotations * 4) + ",\"componentType\":" + std::to_string(kFloat) +
                                    ",\"count\":" + std::to_string(members.size()) + ",\"type\":\"VEC4\"}");
      std::string scale_attribute;
      if (scaled) {
        const uint64_t v = s.accessor("{\"bufferView\":" + std::to_string(s.view(s.instance_view)) + ",\"byteOffset\":" +
                                      std::to_string(scales * 4) + ",\"componentType\":" + std::to_string(kFloat) +
                                      ",\"count\":" + std::to_string(members.size()) + ",\"type\":\"VEC3\"}");
        scale_attribute = ",\"SCALE\":" + std::to_string(v);
      }
      node += "\"name\":\"" + std::to_string(members.size()) + " instances\",\"mesh\":" + std::to_string(r.mesh) +
              ",\"extensions\":{\"EXT_mesh_gpu_instancing\":{\"attributes\":{\"TRANSLATION\":" + std::to_string(t) +
              ",\"ROTATION\":" + std::to_string(q) + scale_attribute + "}}},\"extras\":{\"objects\":[" + objects + "]}";
      summary.instanced_objects += members.size();
    } else {
      if (!read_text(r)) {
        error = "cannot read back " + s.text.path + ": " + system_reason();
        return false;
      }
      node += text;
      if (!r.has_children) {
        if (r.mesh >= 0) node += ",\"mesh\":" + std::to_string(r.mesh);
        if (r.placed) node += s.transform_json(r.position_m, r.rotation, r.scale, r.mesh);
      }
    }
    const auto streamed = s.streamed_children.find(int(i));
    if (child_start[i + 1] > child_start[i] || streamed != s.streamed_children.end()) {
      std::string list;
      for (uint32_t c = child_start[i]; c < child_start[i + 1]; ++c) list += "," + std::to_string(children[c]);
      if (streamed != s.streamed_children.end())
        for (uint32_t c : streamed->second) list += "," + std::to_string(c);
      node += ",\"children\":[" + list.substr(1) + "]";
    }
    node += "}";
    if (split_geometry[i]) {
      node += ",{\"name\":\"geometry\",\"mesh\":" + std::to_string(r.mesh) +
              s.transform_json(r.position_m, r.rotation, r.scale, r.mesh) + "}";
    }
    s.append_node(node);
  }
  summary.objects += s.streamed_summary.objects;
  summary.triangles += s.streamed_summary.triangles;
  summary.lines += s.streamed_summary.lines;
  summary.bounds.extend(s.streamed_summary.bounds);
  s.records.clear();
  s.records.shrink_to_fit();
  if (s.failed) {
    error = s.write_error;
    return false;
  }

  // 4. The document's small parts by tinygltf: buffer views over [vertices][indices][instances],
  //    materials, the scene, the asset; the arrays spliced in after them.
  tinygltf::Model& m = s.model;
  const uint64_t bin_bytes = s.vertices.bytes + s.quantized.bytes + s.indices.bytes + instance_data.size() * 4;
  {
    // [float vertices][quantized vertices][indices][instances], listed by view number.
    std::vector<std::pair<int, tinygltf::BufferView>> views;
    auto view = [&](int number, uint64_t offset, uint64_t length, size_t stride, int target) {
      if (number < 0 || length == 0) return;
      tinygltf::BufferView v;
      v.buffer = 0;
      v.byteOffset = size_t(offset);
      v.byteLength = size_t(length);
      v.byteStride = stride;
      v.target = target;
      views.emplace_back(number, v);
    };
    view(s.float_view, 0, s.vertices.bytes, sizeof(GltfVertex), TINYGLTF_TARGET_ARRAY_BUFFER);
    view(s.quantized_view, s.vertices.bytes, s.quantized.bytes, sizeof(QuantizedVertex), TINYGLTF_TARGET_ARRAY_BUFFER);
    view(s.index_view, s.vertices.bytes + s.quantized.bytes, s.indices.bytes, 0, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    view(s.instance_view, s.vertices.bytes + s.quantized.bytes + s.indices.bytes, instance_data.size() * 4, 0, 0);
    std::sort(views.begin(), views.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [number, v] : views) m.bufferViews.push_back(std::move(v));
    if (s.quantized.bytes > 0) {
      // Readers without it cannot read the int16 and int8 attributes.
      m.extensionsUsed.push_back("KHR_mesh_quantization");
      m.extensionsRequired.push_back("KHR_mesh_quantization");
    }
    if (!instance_data.empty()) {
      m.extensionsUsed.push_back("EXT_mesh_gpu_instancing");
      // The extension defines no fallback: a reader without it would draw one copy.
      m.extensionsRequired.push_back("EXT_mesh_gpu_instancing");
    }
  }
  tinygltf::Scene scene;
  scene.nodes = std::move(roots);
  m.scenes.push_back(std::move(scene));
  m.defaultScene = 0;
  m.asset.version = "2.0";
  m.asset.generator = "plantview";
  m.asset.extras = tinygltf::Value(tinygltf::Value::Object{
      {"origin_m", tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(origin_m.x), tinygltf::Value(origin_m.y),
                                                           tinygltf::Value(origin_m.z)})}});
  std::string head;
  {
    std::ostringstream out;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&m, out, false, false)) {
      error = "cannot serialise the glTF document of " + s.path;
      return false;
    }
    head = std::move(out).str();
  }
  while (!head.empty() && head.back() != '}') head.pop_back();
  if (head.size() < 2) {
    error = "cannot serialise the glTF document of " + s.path;
    return false;
  }
  head.pop_back();  // the arrays follow
  struct Piece {
    std::string text;
    const Part* part = nullptr;
  };
  std::vector<Piece> pieces{{head}};
  auto array = [&](const char* name, const Part& part) {
    if (part.bytes == 0) return;
    pieces.push_back({",\"" + std::string(name) + "\":["});
    pieces.push_back({"", &part});
    pieces.push_back({"]"});
  };
  array("accessors", s.accessors);
  array("meshes", s.meshes_text);
  array("nodes", s.nodes);
  std::string tail;
  if (bin_bytes > 0) {
    tail = ",\"buffers\":[{\"byteLength\":" + std::to_string(bin_bytes);
    if (!s.binary) tail += ",\"uri\":" + json_string(utf8_text(s.bin_name));
    tail += "}]";
  }
  pieces.push_back({tail + "}"});
  uint64_t json_bytes = 0;
  for (const Piece& p : pieces) json_bytes += p.part ? p.part->bytes : p.text.size();

  // 5. The file(s), the binary chunk assembled from the parts on disk.
  for (Part* p : s.parts) {
    if (p->file && std::fflush(p->file) != 0) {
      error = "cannot write " + p->path + ": " + system_reason();
      return false;
    }
  }
  auto fail_write = [&](const std::string& what) {
    if (error.empty()) error = "cannot write " + what + ": " + system_reason();
    return false;
  };
  std::FILE* out = std::fopen(s.temp_out.c_str(), "wb");
  if (!out) return fail_write(s.path);
  std::FILE* bin = out;
  bool ok = true;
  const uint64_t json_padded = (json_bytes + 3) & ~uint64_t(3);
  const uint64_t bin_padded = (bin_bytes + 3) & ~uint64_t(3);
  if (s.binary) {
    const uint64_t total = 12 + 8 + json_padded + (bin_bytes ? 8 + bin_padded : 0);
    if (total > UINT32_MAX) {
      std::fclose(out);
      error = "cannot write " + s.path + ": " + std::to_string(total) +
              " bytes, more than a .glb can hold (4 GiB); select less, raise the tolerance or write .gltf";
      return false;
    }
    const uint32_t header[5] = {0x46546C67u, 2u, uint32_t(total), uint32_t(json_padded), 0x4E4F534Au};
    ok = put(out, header, sizeof header);
  }
  for (const Piece& p : pieces) {
    if (!ok) break;
    ok = p.part ? copy_file_into(out, p.part->path, error) : put(out, p.text);
  }
  if (s.binary) {
    ok = ok && put(out, "   ", size_t(json_padded - json_bytes));  // JSON chunk padding: spaces
    if (bin_bytes) {
      const uint32_t chunk[2] = {uint32_t(bin_padded), 0x004E4942u};
      ok = ok && put(out, chunk, sizeof chunk);
    }
  } else {
    ok = ok && put(out, "\n", 1);
    if (ok && bin_bytes) {
      bin = std::fopen(s.temp_bin.c_str(), "wb");
      if (!bin) {
        std::fclose(out);
        return fail_write((std::filesystem::path(s.path).parent_path() / s.bin_name).string());
      }
    }
  }
  if (ok && bin_bytes) {
    ok = copy_file_into(bin, s.vertices.path, error) && copy_file_into(bin, s.quantized.path, error) &&
         copy_file_into(bin, s.indices.path, error) &&
         put(bin, instance_data.data(), instance_data.size() * 4);
    const char zeros[4] = {};
    if (s.binary) ok = ok && put(bin, zeros, size_t(bin_padded - bin_bytes));
  }
  if (bin != out) ok = std::fclose(bin) == 0 && ok;
  ok = std::fclose(out) == 0 && ok;
  if (!ok) return fail_write(s.path);

  // 6. Into place: the .bin before the .gltf that refers to it.
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
  for (Part* p : s.parts) p->remove();
  s.finished = true;
  // A split keeps its finished files (to remove them if a later one fails): only their names.
  s.model = tinygltf::Model();
  s.meshes = {};
  s.mesh_info = {};
  s.geometries = {};
  s.streamed_children = {};
  s.sites = {};
  s.zones = {};
  s.pipelines = {};
  summary.bytes = std::filesystem::file_size(final_path, ec);
  if (!s.binary) summary.bytes += bin_bytes;
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
