// Occluder shapes: what of an object may stand in for it in the occlusion buffer
// (occlusion_buffer.h). No GL.
//
// Rules
//   - A shape is a list of convex pieces, each a few points that lie inside what is drawn of the
//     object at every level: a convex primitive's coarsest level (its vertices are a subset of
//     every finer level's, on the same convex surface, so its hull is inside each level's
//     mesh). Only kinds whose every level is a convex polyhedron are used: box, pyramid,
//     prism, cylinder, unsheared snout and sphere. Other kinds (tori, dishes, saddles, facet
//     groups, lines) simply add no piece.
//   - Boxes and cylinders are cut into slices along their length (kMaxSlices at most), each
//     slice convex and inside the solid: a slice's farthest point is nearer than the solid's.
//   - Opaque equipment, structures, pipes and other objects may occlude; components (flanges,
//     valves: small, and replaced by merged runs) do not, nor does a piece spanning under
//     kMinPieceM. Whether a pipe is drawn as its solid is decided per frame (occlusion.h): not
//     when drawn as its centreline or merged into a run.
//   - At most kMaxPieces pieces an object, the largest kept.
//   - Each piece keeps its primitive's bounds, so that it is left out when the drawn solid may
//     not hide what is behind it: when the bounds reach the near plane (the eye inside the
//     solid sees nothing of it, its back faces being culled), and when a section cuts them
//     (RenderOptions::section: what is drawn of the piece may be less than its shape).
// Units: metres, points relative to the object's origin (Known::origin_m).
// Threads: any (pure).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/model.h"
#include "plantview/primitives.h"

namespace plantview::detail {

struct OccluderShape {
  std::vector<glm::vec3> points;  // every piece's points, piece after piece
  std::vector<uint32_t> ends;     // piece p is points [ends[p - 1] (0 for p = 0), ends[p])
  // Piece p's primitive's bounds (min, max at 2p, 2p + 1): they hold every level's mesh. A
  // piece whose bounds reach the near plane is not used: the eye may be inside the drawn
  // solid (whose back faces are culled) or the near plane may cut it open.
  std::vector<glm::vec3> bounds;
  bool empty() const { return ends.empty(); }
};

inline constexpr size_t kMaxPieces = 64;
inline constexpr int kMaxSlices = 8;
inline constexpr float kMinPieceM = 0.25f;

// Whether an object of this class and colour may occlude (see the rules).
bool may_occlude(ObjectClass object_class, Colour colour);

// The occluder shape of an object's primitives (placed relative to the object's origin);
// `scratch` is reused.
void build_occluder_shape(std::span<const Primitive> primitives,
                          std::vector<PackedVertex>& scratch, OccluderShape& out);

}  // namespace plantview::detail
