// Internal: the contract between the generic tessellation driver (tessellate.cpp) and the one
// file per primitive kind (box.cpp, cylinder.cpp, ...). Not part of the public API.
//
// Each kind provides four functions:
//   void plan(const K&, MeshPlan& plan, TemplateKey& key);
//       Fills plan.topology, closed, level_count, vertex_count, segments and the LOCAL error of
//       each level (error_m, in the shape's own metres; the driver scales it by the placement).
//       Sets key to the shape's template (kind, flags, segment counts); the driver fetches or
//       builds the template and fills plan.indices. Must be cheap and allocation-free.
//       A shape without volume sets vertex_count = 0 and leaves key.kind = kNoTemplate.
//   void build_template(const TemplateKey& key, TemplateBuilder& out);
//       Writes the index arrays of every level, level 0 first, into `out`. Runs once per key.
//   void write(const K&, const MeshPlan& plan, const VertexSink& sink);
//       Writes plan.vertex_count vertices through the sink. Allocation-free; stack arrays only.
//   Aabb bounds(const K&);
//       Analytic local bounds.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <vector>

#include "plantview/primitives.h"

namespace plantview::detail {

inline constexpr uint8_t kNoTemplate = 0xff;

// Identifies a shared index template. Two primitives with equal keys have identical index arrays.
struct TemplateKey {
  uint8_t kind = kNoTemplate;
  uint8_t flags = 0;          // kind-specific (closed ring, degenerate faces...)
  uint16_t a_max = 0, a_min = 0;  // segment counts of the first curved direction, level 0 and floor
  uint16_t b_max = 0, b_min = 0;  // second direction (0 if none)
  uint64_t packed() const {
    return uint64_t(kind) | uint64_t(flags) << 8 | uint64_t(a_max) << 16 | uint64_t(a_min) << 28 |
           uint64_t(b_max) << 40 | uint64_t(b_min) << 52;
  }
};

// Segments of a halving direction at a level: max >> level, never below the floor.
inline uint32_t segments_at(uint32_t max_segments, uint32_t min_segments, uint32_t level) {
  uint32_t n = max_segments >> level;
  return n < min_segments ? min_segments : n;
}

// Number of levels of a direction halving from max_segments down to min_segments (powers of two).
inline uint32_t halving_levels(uint32_t max_segments, uint32_t min_segments) {
  return uint32_t(std::countr_zero(max_segments) - std::countr_zero(min_segments)) + 1u;
}

// Collects a template's per-level index arrays.
class TemplateBuilder {
 public:
  void begin_level() { level_begin_.push_back(static_cast<uint32_t>(indices_.size())); }
  void triangle(uint32_t a, uint32_t b, uint32_t c) {
    indices_.push_back(a);
    indices_.push_back(b);
    indices_.push_back(c);
  }
  // Two triangles (a, b, c) and (a, c, d) of a quad given counter-clockwise seen from outside.
  void quad(uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
    triangle(a, b, c);
    triangle(a, c, d);
  }
  void line(uint32_t a, uint32_t b) {
    indices_.push_back(a);
    indices_.push_back(b);
  }
  const std::vector<uint32_t>& indices() const { return indices_; }
  const std::vector<uint32_t>& level_begin() const { return level_begin_; }

 private:
  std::vector<uint32_t> indices_;
  std::vector<uint32_t> level_begin_;
};

// pack_normal, inline for the per-vertex path (the public function forwards here).
inline uint32_t pack_unit_normal(const glm::vec3& n) {
  auto component = [](float v) -> uint32_t {
    v = std::min(std::max(v, -1.0f), 1.0f) * 511.0f;
    return static_cast<uint32_t>(static_cast<int32_t>(v + (v >= 0.0f ? 0.5f : -0.5f))) & 0x3ffu;
  };
  return component(n.x) | component(n.y) << 10 | component(n.z) << 20;
}

// Transforms local positions and normals to model space (relative to the caller's origin) and
// packs them. Prepared once per primitive by the driver.
struct VertexSink {
  glm::mat3 linear{1.0f};
  glm::vec3 translation_m{0.0f};   // placement translation minus origin, already in float
  glm::mat3 normal_matrix{1.0f};   // inverse transpose of linear
  bool preserves_unit_normals = false;  // normal_matrix is a rotation (placement is a similarity)
  PackedVertex* out = nullptr;

  // The packed model-space normal of a local normal (need not be unit length; zero gives +z).
  uint32_t normal(const glm::vec3& local_normal) const {
    glm::vec3 n = normal_matrix * local_normal;
    float len2 = glm::dot(n, n);
    if (!(len2 > 1e-30f)) return pack_unit_normal(glm::vec3(0, 0, 1));
    return pack_unit_normal(n * (1.0f / std::sqrt(len2)));
  }
  // As normal(), for a local normal the caller knows to be of unit length: skips the
  // normalisation when the placement is a similarity (the usual case), which is the hot path.
  uint32_t unit_normal(const glm::vec3& local_unit_normal) const {
    if (!preserves_unit_normals) return normal(local_unit_normal);
    return pack_unit_normal(normal_matrix * local_unit_normal);
  }
  void put(uint32_t i, const glm::vec3& local_position, uint32_t packed_normal) const {
    out[i].position_m = linear * local_position + translation_m;
    out[i].normal = packed_normal;
  }
  void put(uint32_t i, const glm::vec3& local_position, const glm::vec3& local_normal) const {
    put(i, local_position, normal(local_normal));
  }
};

// Unit circle samples: kUnitCircle[i] = (cos, sin)(2*pi*i / kCircleSamples). A circle of N
// segments (N a power of two up to kCircleSamples) uses every (kCircleSamples / N)-th entry, so
// every level samples exactly the same angles.
inline constexpr uint32_t kCircleSamples = 1024;
extern const std::array<glm::vec2, kCircleSamples + 1> kUnitCircle;  // filled at static init
inline glm::vec2 circle_sample(uint32_t i, uint32_t segments) {
  return kUnitCircle[(i * (kCircleSamples / segments)) % kCircleSamples];
}

// Non-finite and negative parameters read as zero.
inline float sane(float v) { return std::isfinite(v) && v > 0.0f ? v : 0.0f; }
// Non-finite read as zero, sign kept (offsets, shears).
inline float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

// Sagitta of a chord spanning half_angle_rad on each side of its midpoint, on radius r.
inline float sagitta(float radius_m, float half_angle_rad) {
  return radius_m * (1.0f - std::cos(half_angle_rad));
}

#define PLANTVIEW_KIND_HOOKS(K)                                                 \
  void plan(const K&, MeshPlan& plan, TemplateKey& key);                        \
  void build_template_##K(const TemplateKey& key, TemplateBuilder& out);        \
  void write(const K&, const MeshPlan& plan, const VertexSink& sink);           \
  Aabb bounds(const K&);

PLANTVIEW_KIND_HOOKS(Box)
PLANTVIEW_KIND_HOOKS(Pyramid)
PLANTVIEW_KIND_HOOKS(Prism)
PLANTVIEW_KIND_HOOKS(Cylinder)
PLANTVIEW_KIND_HOOKS(Snout)
PLANTVIEW_KIND_HOOKS(SquareToRound)
PLANTVIEW_KIND_HOOKS(CircularTorus)
PLANTVIEW_KIND_HOOKS(RectangularTorus)
PLANTVIEW_KIND_HOOKS(Sphere)
PLANTVIEW_KIND_HOOKS(EllipticalDish)
PLANTVIEW_KIND_HOOKS(SphericalDish)
PLANTVIEW_KIND_HOOKS(Saddle)
PLANTVIEW_KIND_HOOKS(Line)
PLANTVIEW_KIND_HOOKS(FacetGroup)

#undef PLANTVIEW_KIND_HOOKS

}  // namespace plantview::detail
