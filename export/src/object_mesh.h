// Object meshes for glTF export: an object's primitives in a frame of its own (so that objects
// equal up to a rigid transform share one mesh), the level a tolerance picks, the key that
// names a mesh, and the tessellation itself (core's templates, then meshoptimizer's orders).
//
// Rules
//   - The canonical frame of an object is its first primitive's: translation at that
//     primitive's, rotation the orthonormalised (Gram-Schmidt, right-handed) columns of its
//     linear part; scale and mirroring stay in the primitives. model = rotation * canonical +
//     position_m. No primitive: the object's origin and no rotation.
//   - An object of one box, or one cylinder, placed without scale (its canonical linear part
//     the identity) is made of the unit shape (a 1 m box; a cylinder 1 m high) scaled by the
//     node: `scale` holds the sizes (the cylinder's height), so that every pipe of a diameter
//     shares one mesh. Under a node's scale readers transform normals by the inverse
//     transpose, which keeps the faces' and the cylinder's normals exact.
//   - The mesh key hashes (128 bits) what the mesh is made of: the level, the colour, each
//     primitive's shape (facet groups: their vertices and triangulation) and canonical
//     placement, the latter rounded to 1e-5 (linear) and 0.1 mm (translation). Objects that
//     agree to that rounding share the first one's mesh.
//   - Levels: a mesh is made of each primitive at a level of its own (PrimitiveLevels). With a
//     tolerance, each primitive's coarsest level whose error is at most the tolerance, so the
//     object's error is at most it too; a level chosen for the whole object (the renderer's
//     rule) applies to every primitive, clamped to each one's coarsest. Each primitive's
//     vertices are fitted to its level (primitives.h, "Fitted vertices"): its error is then
//     straddled_error_m, about half the error_m the tolerance is held to.
// Units: metres. Threads: any; MeshBuilder is one per thread.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "plantview/model.h"
#include "plantview/primitives.h"

namespace plantview::detail::gltf {

struct CanonicalObject {
  glm::dvec3 position_m{0.0};   // model space
  glm::dquat rotation{1, 0, 0, 0};
  glm::vec3 scale{1.0f};              // along the canonical axes
  bool unit_shape = false;            // made of a unit shape: nodes stretch its mesh by any scale
  std::vector<Primitive> primitives;  // placements in the canonical frame
  std::vector<MeshPlan> plans;        // plan_mesh of each
};

// Fills `out` from `object` (reusing its vectors).
void canonicalise(const Object& object, CanonicalObject& out);

// A level per primitive.
using PrimitiveLevels = std::vector<uint8_t>;
// Each primitive's coarsest level whose error is at most tolerance_m (all 0 for tolerance_m <= 0).
void levels_for_tolerance(const CanonicalObject& object, double tolerance_m, PrimitiveLevels& out);
// `level` for every primitive, clamped to each one's coarsest.
void levels_for_object(const CanonicalObject& object, uint8_t level, PrimitiveLevels& out);

struct MeshKey {
  uint64_t a = 0, b = 0;
  bool operator==(const MeshKey&) const = default;
};
struct MeshKeyHash {
  size_t operator()(const MeshKey& k) const { return size_t(k.a); }
};
MeshKey mesh_key(const CanonicalObject& object, const PrimitiveLevels& levels, Colour colour);

// One vertex as written to the glTF buffer: position (canonical frame, metres) and unit normal.
struct GltfVertex {
  float position[3];
  float normal[3];
};
static_assert(sizeof(GltfVertex) == 24);

// A mesh: triangles and lines, each over vertices of their own, in meshoptimizer's orders.
struct MeshData {
  std::vector<GltfVertex> triangle_vertices, line_vertices;
  std::vector<uint32_t> triangles, lines;  // indices, 3 and 2 per element
  bool empty() const { return triangles.empty() && lines.empty(); }
};

// What a mesh's data is (vertices, indices, lines), hashed: meshes of different colours with
// the same geometry share its accessors.
MeshKey geometry_key(const MeshData& data);

class MeshBuilder {
 public:
  // Tessellates `object` at `levels` into `out` (replacing what was there).
  void build(const CanonicalObject& object, const PrimitiveLevels& levels, MeshData& out);

 private:
  std::vector<PackedVertex> packed_;
  std::vector<GltfVertex> tri_vertices_, line_vertices_;
  std::vector<uint32_t> tri_indices_, line_indices_, remap_;
};

}  // namespace plantview::detail::gltf
