// What a GltfFile holds while it is written (rules in gltf_file.h), shared by its parts:
// gltf_file.cpp (open, meshes, objects, runs, nodes), gltf_buffers.cpp (vertex and index data,
// quantization, accessors) and gltf_finish.cpp (finish(): the document and the file).
//
// Rules
//   - Errors: a write to a Part that fails is noted (note_failure) and the calls go on; the
//     first failure's message is kept in write_error and `failed` stays set, so that the next
//     fallible call (add_mesh, finish) reports it. Nothing here asserts on input.
//   - Offsets and sizes are in bytes; positions in metres, model space (the origin is taken off
//     only where a node's translation is written).
//   - Owns its temporary files (the Parts, closed on destruction; removed by remove_all()).
// Threads: one thread.
#pragma once

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include <tiny_gltf.h>

#include "gltf_file.h"
#include "object_mesh.h"

#include "plantview/gltf.h"
#include "plantview/model.h"

namespace plantview::detail::gltf {

inline constexpr int kTriangles = 4, kLines = 1;                                       // glTF primitive modes
inline constexpr int kFloat = 5126, kUnsignedShort = 5123, kUnsignedInt = 5125;         // component types
inline constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122;

// A quantized vertex: position normalized int16 (x, y, z, padding), normal normalized int8.
struct QuantizedVertex {
  int16_t position[4];
  int8_t normal[4];
};
static_assert(sizeof(QuantizedVertex) == 12);

// The message of the last failed system call (errno): call it before anything else may set errno.
inline std::string system_reason() { return std::strerror(errno); }

// Writes `size` bytes of `data` to `file`; false when fewer were written (errno says why).
inline bool put(std::FILE* file, const void* data, size_t size) {
  return size == 0 || std::fwrite(data, 1, size, file) == size;
}
inline bool put(std::FILE* file, const std::string& text) { return put(file, text.data(), text.size()); }

// A temporary file written in order, its size in bytes kept (counted also when a write fails).
struct Part {
  std::string path;
  std::FILE* file = nullptr;  // null until opened and after close()
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

struct GltfFileState {
  // A node to be: an object, a merged run, or a group (site, zone, pipeline placeholder). Its
  // name and extras are JSON text in `text` at [text_offset, + text_bytes).
  struct Record {
    int32_t parent = -1;
    int32_t mesh = GltfFile::kNoMesh;
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
    float min[3], max[3];  // the box of its vertices (metres, the mesh's frame) where has_box
    uint32_t triangles = 0, lines = 0;
    bool has_box = false;
    // Quantized: model = node * (centre + grid_scale * q / 32767) for each int16 position q.
    bool quantized = false;
    glm::dvec3 centre{0.0};
    double grid_scale = 1;
  };
  // Each distinct geometry's primitives up to their material (meshes of another colour reuse
  // its accessors), with its box and quantization.
  struct Geometry {
    std::string triangles, lines;  // {"attributes":..,"indices":N (empty: no such primitive)
    MeshInfo info;
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
  std::unordered_map<MeshKey, Geometry, MeshKeyHash> geometries;
  std::vector<MeshInfo> mesh_info;
  std::map<uint32_t, int> materials;
  std::vector<Record> records;
  std::map<std::string, int, std::less<>> sites;
  std::map<std::pair<int, std::string>, int> zones;
  std::unordered_map<uint64_t, int> pipelines;
  std::vector<uint64_t> pipeline_ids_unnamed;

  ~GltfFileState() { close_parts(); }
  Part* parts[7] = {&vertices, &quantized, &indices, &accessors, &meshes_text, &text, &nodes};

  // gltf_file.cpp: files, materials, nodes.
  void close_parts();
  void remove_all();  // every temporary file (not the finished ones)
  void note_failure(const Part& part);
  int material(Colour colour);  // its index, made on first use
  // A node's placement relative to the origin with `mesh`'s dequantization folded in.
  void placement(int mesh, const glm::dvec3& position, const glm::quat& q, glm::vec3& scale,
                 glm::dvec3& translation) const;
  // ,"translation":[..] and, where not the identity, ,"rotation" and ,"scale".
  std::string transform_json(const glm::dvec3& position, const glm::quat& q, glm::vec3 scale, int mesh) const;
  // Counts a placed mesh into `summary`: triangles, lines, and the bounds of its box.
  void count(int mesh, const glm::dvec3& position, const glm::quat& rotation, const glm::vec3& scale,
             GltfFileSummary& summary) const;
  void append_node(const std::string& json);
  // Writes a leaf node now (no GPU instancing): an object's or a run's.
  void stream_node(int parent, const std::string& name_and_extras, int mesh, const glm::dvec3& position,
                   const glm::quat& rotation, const glm::vec3& scale, bool is_object);
  int add_record(int parent, const std::string& name_and_extras);
  void set_text(Record& r, const std::string& name_and_extras);
  int group(std::string_view source, std::string_view zone);  // the site's or zone's record
  int pipeline(uint64_t id, int parent);                      // the pipeline's record, a placeholder at first

  // gltf_buffers.cpp: vertex and index data, quantization, accessors.
  // Writes `data`'s vertices and indices and their accessors: its box, its grid (quantized
  // where the grid's error is within quantization_error_m and not `stretched`), its
  // primitives up to their material.
  Geometry write_geometry(const MeshData& data, bool stretched);
  // Appends an accessor (JSON text); returns its index.
  uint64_t accessor(const std::string& json);
  // A float accessor of `count` elements of `type` ("VEC3", "VEC4") in the instance view at
  // `offset_floats` floats.
  uint64_t instance_accessor(size_t offset_floats, size_t count, const char* type);

 private:
  // Writes vertices and indices, their accessors; returns the primitive's JSON up to its
  // material ({"attributes":..,"indices":N). `info` has the mesh's box and quantization.
  std::string primitive(const std::vector<GltfVertex>& vs, const std::vector<uint32_t>& is, int mode,
                        const MeshInfo& info);
};

}  // namespace plantview::detail::gltf
