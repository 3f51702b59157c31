// One glTF file being written: its node records, its meshes (vertex and index data streamed to
// temporary files as they come) and, at the end, the document and the file itself.
//
// Rules
//   - Nodes: a node per object, under its site, zone and pipeline nodes (made on first use); a
//     pipeline node made for a member gets its name and extras when the pipeline object is
//     added, or from name_pipeline() (the export looks up those not selected).
//   - Data: float vertices (24 bytes: position, normal) go to one temporary file, quantized
//     ones (12 bytes: int16 position, int8 normal, each padded to 4 bytes) to another, indices
//     (uint8 where a mesh has under 255 vertices, uint16 under 65,535, else uint32, each mesh's
//     padded to 4 bytes) to a third; finish() writes the binary chunk as [float vertices]
//     [quantized vertices][indices][instance transforms]. Buffer views are numbered as first
//     used (an empty one is invalid glTF).
//   - Document: the arrays that grow with the plant (accessors, meshes, nodes) are written as
//     JSON text to temporary files as they come. An object's node is written when it is added
//     (4 bytes stay, its number in its parent's children); group nodes (sites, zones,
//     pipelines, which learn their children as they come) and, with GPU instancing, every
//     object's node (80 bytes each: instances are grouped at the end) wait for finish();
//     tinygltf writes the rest (asset, materials, buffer views, scene, extensions) and
//     finish() splices the arrays in. (tinygltf's Model keeps every node and accessor as an
//     object of its own, about 8 kB an object of a plant with its extras: 350 MB for preset c,
//     far too much for plants a hundred times larger.)
//   - Files: everything is written beside the destination under temporary names; finish()
//     renames into place (a .gltf's .bin first), abandon() (and the destructor, unless
//     finished) removes them all.
//   - Errors: a failed write is reported by the next add_mesh() or finish(), naming the
//     temporary file and the system's reason (the first failure's); after one, finish() fails.
// Ownership: holds copies of what it writes; Objects passed in need live only for the call.
// Threads: one thread.
// Code: gltf_file.cpp (open, meshes, objects, runs, nodes), gltf_buffers.cpp (vertex and index
// data, quantization, accessors), gltf_finish.cpp (finish() in stages); what they share, the
// file's state, in gltf_file_state.h.
#pragma once

#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "object_mesh.h"

#include "plantview/gltf.h"
#include "plantview/model.h"

namespace plantview::detail::gltf {

struct GltfFileState;  // gltf_file_state.h

class GltfFile {
 public:
  GltfFile();
  ~GltfFile();
  GltfFile(const GltfFile&) = delete;
  GltfFile& operator=(const GltfFile&) = delete;

  // Starts the file `path` (.glb: binary; otherwise text with a .bin beside it), its positions
  // relative to origin_m (model space). False with the path and reason when its temporary files
  // cannot be made.
  // quantization_error_m > 0: meshes are written with KHR_mesh_quantization (positions as
  // normalized int16 on a grid of their own, normals as normalized int8, the dequantization in
  // the nodes' transforms) where the grid's worst error (half a step along each axis, as a
  // distance) is at most this; other meshes, and meshes nodes may stretch, stay float32.
  // share_geometry: meshes of different colours with the same vertices and indices share their
  // accessors (off to measure what sharing saves).
  bool open(const std::string& path, const glm::dvec3& origin_m, bool gpu_instancing, double quantization_error_m,
            bool share_geometry, std::string& error);
  // Room for this many nodes, so that a large file's node table is not copied as it grows.
  void reserve(size_t nodes);

  // The mesh already written for `key`: its index, kNoMesh (nothing to draw) or kUnknownMesh.
  static constexpr int kNoMesh = -1, kUnknownMesh = -2;
  int find_mesh(const MeshKey& key) const;
  // Writes `data` as a new mesh of `colour`'s material. `stretched`: nodes scale it by sizes of
  // their own (a unit shape), so a grid's error would grow with them: never quantized. Returns
  // its index (kNoMesh if empty), or kUnknownMesh with `error` set when a temporary file cannot
  // be written.
  int add_mesh(const MeshKey& key, const MeshData& data, Colour colour, bool stretched, std::string& error);

  // A node for `object`, placed at position_m (model space) with `rotation` and `scale`,
  // drawing `mesh` (kNoMesh: none). `zone` may be empty (no zone node).
  void add_object(const Object& object, std::string_view zone, const glm::dvec3& position_m,
                  const glm::dquat& rotation, const glm::vec3& scale, int mesh);
  // A node for a merged pipeline run (no object of its own) under pipeline `pipeline_id`.
  void add_run(std::string name, uint64_t pipeline_id, std::string_view source, std::string_view zone,
               const glm::dvec3& position_m, const glm::dquat& rotation, const glm::vec3& scale, int mesh);
  // Pipelines that members hang under but that were not added themselves.
  std::vector<uint64_t> unnamed_pipelines() const;
  void name_pipeline(const Object& pipeline);

  // Writes the rest of the document, then the file, and renames it into place. Fills `summary`
  // (path, counts, bytes, bounds).
  bool finish(GltfFileSummary& summary, std::string& error);
  // Removes every file this one made (finished or not).
  void abandon();

 private:
  std::unique_ptr<GltfFileState> state_;
};

}  // namespace plantview::detail::gltf
