// Occluder shapes from primitives (rules in occlusion_occluders.h).
#include "occlusion/occlusion_occluders.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace plantview::detail {

namespace {

// Kinds whose every level is a convex polyhedron with its vertices on the true convex surface
// (or exact): their coarsest level lies inside every finer one.
bool convex_at_every_level(const Shape& shape) {
  if (std::holds_alternative<Box>(shape) || std::holds_alternative<Pyramid>(shape) ||
      std::holds_alternative<Prism>(shape) || std::holds_alternative<Cylinder>(shape) ||
      std::holds_alternative<Sphere>(shape))
    return true;
  // A sheared end tilts its plane differently from the other: side quads are not planar.
  if (const Snout* s = std::get_if<Snout>(&shape))
    return s->bottom_shear_x_rad == 0 && s->bottom_shear_y_rad == 0 && s->top_shear_x_rad == 0 &&
           s->top_shear_y_rad == 0;
  return false;
}

// Closes the piece of the points added since the last one: pulled 0.5% towards their centre,
// so that rounding (these points are computed apart from the mesh's own vertices, which many
// of them coincide with) never puts one outside the drawn solid.
void add_piece(OccluderShape& out, const glm::vec3& min, const glm::vec3& max) {
  const size_t first = out.ends.empty() ? 0 : out.ends.back();
  glm::vec3 centre(0.0f);
  for (size_t p = first; p < out.points.size(); ++p) centre += out.points[p];
  centre /= float(out.points.size() - first);
  for (size_t p = first; p < out.points.size(); ++p)
    out.points[p] = centre + (out.points[p] - centre) * 0.995f;
  out.ends.push_back(uint32_t(out.points.size()));
  out.bounds.push_back(min);
  out.bounds.push_back(max);
}

// Boxes and cylinders, long ones cut into slices along their length (at most kMaxSlices, each
// about as long as it is wide, overlapping the next by half): a slice's farthest point is
// nearer than the whole solid's, so the buffer holds tighter depths. A cylinder's slices are its coarsest level's square (the
// samples on its axes, on the circle at every level). False for other kinds.
bool add_slices(const Primitive& primitive, OccluderShape& out) {
  glm::vec3 half(0.0f);
  std::array<glm::vec2, 4> ring{};
  int ring_size = 0;
  if (const Box* b = std::get_if<Box>(&primitive.shape)) {
    half = 0.5f * glm::vec3(b->size_x_m, b->size_y_m, b->size_z_m);
  } else if (const Cylinder* c = std::get_if<Cylinder>(&primitive.shape)) {
    half = {c->radius_m, c->radius_m, 0.5f * c->height_m};
    ring = {glm::vec2(1, 0), glm::vec2(0, 1), glm::vec2(-1, 0), glm::vec2(0, -1)};
    ring_size = 4;
  } else {
    return false;
  }
  if (!(half.x > 0 && half.y > 0 && half.z > 0)) return true;  // no volume: nothing drawn
  // The longest local axis is cut (cylinders: only along z, the round section stays whole).
  int axis = 2;
  if (ring_size == 0) axis = half.x >= half.y && half.x >= half.z ? 0 : (half.y >= half.z ? 1 : 2);
  const float width = ring_size ? half.x : std::max(half[(axis + 1) % 3], half[(axis + 2) % 3]);
  const int slices = std::clamp(int(std::ceil(half[axis] / std::max(width, 1e-6f))), 1, kMaxSlices);
  const Aabb bounds = model_bounds(primitive);
  for (int s = 0; s < slices; ++s) {
    const float lo = -half[axis] + 2 * half[axis] * float(s) / float(slices);
    // Each slice overlaps the next by half a slice: cells on the line where two slices meet
    // are wholly inside neither, and the overlap covers them.
    const float hi = std::min(half[axis], -half[axis] + 2 * half[axis] * (float(s) + 1.5f) / float(slices));
    const auto put = [&](glm::vec3 local) {
      out.points.push_back(primitive.placement.linear * local + primitive.placement.translation_m);
    };
    if (ring_size) {
      for (const float z : {lo, hi})
        for (int k = 0; k < ring_size; ++k) put({ring[k].x * half.x, ring[k].y * half.y, z});
    } else {
      for (int corner = 0; corner < 8; ++corner) {
        glm::vec3 p(corner & 1 ? half.x : -half.x, corner & 2 ? half.y : -half.y,
                    corner & 4 ? half.z : -half.z);
        p[axis] = corner & (1 << axis) ? hi : lo;
        put(p);
      }
    }
    add_piece(out, bounds.min, bounds.max);
  }
  return true;
}

}  // namespace

bool may_occlude(ObjectClass object_class, Colour colour) {
  return colour.a == 255 && (object_class == ObjectClass::equipment ||
                             object_class == ObjectClass::structure ||
                             object_class == ObjectClass::other || object_class == ObjectClass::pipe);
}

void build_occluder_shape(std::span<const Primitive> primitives,
                          std::vector<PackedVertex>& scratch, OccluderShape& out) {
  out.points.clear();
  out.ends.clear();
  out.bounds.clear();
  // The largest pieces first, by the extent of their bounds.
  std::vector<std::pair<float, uint32_t>> order;
  for (uint32_t i = 0; i < primitives.size(); ++i) {
    if (!convex_at_every_level(primitives[i].shape)) continue;
    const Aabb b = model_bounds(primitives[i]);
    if (b.empty()) continue;
    const glm::vec3 size = b.max - b.min;
    const float extent = std::max({size.x, size.y, size.z});
    if (extent >= kMinPieceM) order.emplace_back(extent, i);
  }
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (order.size() > kMaxPieces) order.resize(kMaxPieces);
  for (const auto& [extent, i] : order) {
    if (out.ends.size() >= kMaxPieces) break;
    const Primitive& primitive = primitives[i];
    if (add_slices(primitive, out)) continue;
    const MeshPlan plan = plan_mesh(primitive);
    if (plan.topology != Topology::triangles || !plan.closed || plan.vertex_count == 0) continue;
    scratch.resize(plan.vertex_count);
    // On the surface: an occluder must never reach outside its object.
    write_vertices(primitive, plan, glm::dvec3(0.0), scratch, kOnSurface);
    // The coarsest level's vertices (each once: vertices repeat per face with their normals).
    const size_t first = out.points.size();
    for (const uint32_t v : plan.indices[plan.level_count - 1]) {
      const glm::vec3 p = scratch[v].position_m;
      if (std::find(out.points.begin() + std::ptrdiff_t(first), out.points.end(), p) == out.points.end())
        out.points.push_back(p);
    }
    if (out.points.size() - first < 4) {
      out.points.resize(first);
      continue;
    }
    const Aabb b = model_bounds(primitive);
    add_piece(out, b.min, b.max);
  }
}

}  // namespace plantview::detail
