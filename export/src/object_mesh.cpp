// Object meshes for glTF export (rules in object_mesh.h).
#include "object_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include <meshoptimizer.h>


namespace plantview::detail::gltf {

namespace {

// The rotation part of a linear map: its columns orthonormalised, right-handed. Identity when
// the columns are (nearly) dependent.
glm::dmat3 rotation_of(const glm::mat3& linear) {
  const glm::dvec3 x(linear[0]), y(linear[1]);
  const double lx = glm::length(x);
  if (!(lx > 1e-12)) return glm::dmat3(1.0);
  const glm::dvec3 c0 = x / lx;
  glm::dvec3 c1 = y - glm::dot(y, c0) * c0;
  double l1 = glm::length(c1);
  if (!(l1 > 1e-12 * std::max(1.0, glm::length(y)))) {
    // y along x (or zero): any axis across x.
    const glm::dvec3 other = std::abs(c0.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    c1 = glm::cross(c0, other);
    l1 = glm::length(c1);
  }
  c1 /= l1;
  return glm::dmat3(c0, c1, glm::cross(c0, c1));
}

// 64-bit mixing of words (splitmix64's finaliser), seeded: two seeds give the key's halves.
struct Hasher {
  uint64_t a = 0x9e3779b97f4a7c15ull, b = 0xc2b2ae3d27d4eb4full;
  static uint64_t mix(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  void word(uint64_t w) {
    a = mix(a ^ w) + 0x632be59bd9b4e019ull;
    b = mix(b + w * 0xff51afd7ed558ccdull) ^ 0x85ebca6b0c2b2ae3ull;
  }
  void bytes(const void* data, size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    uint64_t w = 0;
    size_t i = 0;
    for (; i + 8 <= size; i += 8) {
      std::memcpy(&w, p + i, 8);
      word(w);
    }
    w = 0;
    std::memcpy(&w, p + i, size - i);
    word(w ^ (uint64_t(size) << 56));
  }
  void quantised(float value, double step) { word(uint64_t(int64_t(std::llround(double(value) / step)))); }
};

// A lone box or cylinder without scale becomes the unit shape, its sizes moved to `scale`
// (the cylinder's radius stays: it decides the segment counts and the error).
bool unit_shape(Primitive& p, glm::vec3& scale) {
  const glm::mat3& c = p.placement.linear;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (std::abs(c[i][j] - (i == j ? 1.0f : 0.0f)) > 1e-6f) return false;
  constexpr float kMin = 1e-6f;
  if (Box* box = std::get_if<Box>(&p.shape)) {
    if (box->size_x_m < kMin || box->size_y_m < kMin || box->size_z_m < kMin) return false;
    scale = glm::vec3(box->size_x_m, box->size_y_m, box->size_z_m);
    *box = Box{1, 1, 1};
  } else if (Cylinder* cylinder = std::get_if<Cylinder>(&p.shape)) {
    if (cylinder->height_m < kMin) return false;
    scale = glm::vec3(1, 1, cylinder->height_m);
    cylinder->height_m = 1;
  } else {
    return false;
  }
  // The shape's centre scales with it: placed at the node's origin it stays there.
  p.placement.translation_m /= scale;
  return true;
}

}  // namespace

void canonicalise(const Object& object, CanonicalObject& out) {
  out.primitives.clear();
  out.plans.clear();
  out.scale = glm::vec3(1.0f);
  out.unit_shape = false;
  if (object.primitives.empty()) {
    out.position_m = object.origin_m;
    out.rotation = glm::dquat(1, 0, 0, 0);
    return;
  }
  const Placement& first = object.primitives.front().placement;
  const glm::dmat3 rotation = rotation_of(first.linear);
  const glm::dmat3 inverse = glm::transpose(rotation);
  out.position_m = object.origin_m + glm::dvec3(first.translation_m);
  out.rotation = glm::normalize(glm::quat_cast(rotation));
  for (const Primitive& p : object.primitives) {
    Primitive& c = out.primitives.emplace_back(p);
    c.placement.linear = glm::mat3(inverse * glm::dmat3(p.placement.linear));
    c.placement.translation_m =
        glm::vec3(inverse * (glm::dvec3(p.placement.translation_m) - glm::dvec3(first.translation_m)));
  }
  if (out.primitives.size() == 1) out.unit_shape = unit_shape(out.primitives.front(), out.scale);
  // Plans after every copy is in place: a facet group's plan points into its primitive.
  for (const Primitive& c : out.primitives) out.plans.push_back(plan_mesh(c));
}

void levels_for_tolerance(const CanonicalObject& object, double tolerance_m, PrimitiveLevels& out) {
  out.assign(object.plans.size(), 0);
  if (!(tolerance_m > 0)) return;
  for (size_t i = 0; i < object.plans.size(); ++i) {
    const MeshPlan& plan = object.plans[i];
    out[i] = uint8_t(plan.coarsest_level_within(tolerance_m));
  }
}

void levels_for_object(const CanonicalObject& object, uint8_t level, PrimitiveLevels& out) {
  out.resize(object.plans.size());
  for (size_t i = 0; i < object.plans.size(); ++i) out[i] = uint8_t(object.plans[i].clamp_level(level));
}

MeshKey mesh_key(const CanonicalObject& object, const PrimitiveLevels& levels, Colour colour) {
  Hasher h;
  h.bytes(levels.data(), levels.size());
  h.word(uint64_t(colour.r) | uint64_t(colour.g) << 8 | uint64_t(colour.b) << 16 | uint64_t(colour.a) << 24);
  h.word(object.primitives.size());
  for (const Primitive& p : object.primitives) {
    h.word(uint64_t(p.kind()));
    std::visit(
        [&](const auto& shape) {
          using T = std::decay_t<decltype(shape)>;
          if constexpr (std::is_same_v<T, FacetGroup>) {
            h.bytes(shape.vertices.data(), shape.vertices.size() * sizeof(FacetVertex));
            h.bytes(shape.triangles.data(), shape.triangles.size() * sizeof(uint32_t));
          } else {
            h.bytes(&shape, sizeof(T));
          }
        },
        p.shape);
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) h.quantised(p.placement.linear[c][r], 1e-5);
    for (int a = 0; a < 3; ++a) h.quantised(p.placement.translation_m[a], 1e-4);
  }
  return MeshKey{h.a, h.b};
}

MeshKey geometry_key(const MeshData& data) {
  Hasher h;
  h.bytes(data.triangle_vertices.data(), data.triangle_vertices.size() * sizeof(GltfVertex));
  h.bytes(data.triangles.data(), data.triangles.size() * sizeof(uint32_t));
  h.bytes(data.line_vertices.data(), data.line_vertices.size() * sizeof(GltfVertex));
  h.bytes(data.lines.data(), data.lines.size() * sizeof(uint32_t));
  return MeshKey{h.a, h.b};
}

void MeshBuilder::build(const CanonicalObject& object, const PrimitiveLevels& levels, MeshData& out) {
  tri_vertices_.clear();
  line_vertices_.clear();
  tri_indices_.clear();
  line_indices_.clear();
  // 1. Tessellate every primitive at its level, from core's templates.
  for (size_t i = 0; i < object.primitives.size(); ++i) {
    const MeshPlan& plan = object.plans[i];
    const uint32_t level = levels[i];
    if (plan.vertex_count == 0) continue;
    packed_.resize(plan.vertex_count);
    // Fitted to the level drawn (primitives.h): within its straddled error, under error_m.
    write_vertices(object.primitives[i], plan, glm::dvec3(0.0), packed_, level);
    const bool lines = plan.topology == Topology::lines;
    std::vector<GltfVertex>& vertices = lines ? line_vertices_ : tri_vertices_;
    std::vector<uint32_t>& indices = lines ? line_indices_ : tri_indices_;
    const uint32_t base = uint32_t(vertices.size());
    for (const PackedVertex& v : packed_) {
      glm::vec3 n = unpack_normal(v.normal);
      const float length = glm::length(n);
      n = length > 1e-6f ? n / length : glm::vec3(0, 0, 1);
      vertices.push_back({{v.position_m.x, v.position_m.y, v.position_m.z}, {n.x, n.y, n.z}});
    }
    const size_t at = indices.size();
    indices.resize(at + plan.index_count(level));
    write_indices(plan, level, base, std::span<uint32_t>(indices).subspan(at));
  }
  // 2. Triangles: vertex-cache order, then vertex-fetch order, which also drops the vertices
  //    the level does not use.
  out.triangles.resize(tri_indices_.size());
  out.triangle_vertices.clear();
  if (!tri_indices_.empty()) {
    meshopt_optimizeVertexCache(out.triangles.data(), tri_indices_.data(), tri_indices_.size(),
                                tri_vertices_.size());
    remap_.resize(tri_vertices_.size());
    const size_t unique = meshopt_optimizeVertexFetchRemap(remap_.data(), out.triangles.data(),
                                                           out.triangles.size(), tri_vertices_.size());
    out.triangle_vertices.resize(unique);
    meshopt_remapVertexBuffer(out.triangle_vertices.data(), tri_vertices_.data(), tri_vertices_.size(),
                              sizeof(GltfVertex), remap_.data());
    meshopt_remapIndexBuffer(out.triangles.data(), out.triangles.data(), out.triangles.size(), remap_.data());
  }
  // 3. Lines: the vertices they use, in first-use order.
  out.lines.resize(line_indices_.size());
  out.line_vertices.clear();
  remap_.assign(line_vertices_.size(), UINT32_MAX);
  for (size_t i = 0; i < line_indices_.size(); ++i) {
    uint32_t& to = remap_[line_indices_[i]];
    if (to == UINT32_MAX) {
      to = uint32_t(out.line_vertices.size());
      out.line_vertices.push_back(line_vertices_[line_indices_[i]]);
    }
    out.lines[i] = to;
  }
}

}  // namespace plantview::detail::gltf
