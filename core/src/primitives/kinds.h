// Internal: the contract between the generic tessellation driver (tessellate.cpp) and the one
// file per primitive kind (box.cpp, cylinder.cpp, ...). Not part of the public API.
//
// Each kind provides four functions:
//   void plan(const K&, MeshPlan& plan, TemplateKey& key);
//       Fills plan.topology, closed, level_count, vertex_count, segments and the LOCAL errors of
//       each level (error_m and straddled_error_m, in the shape's own metres; the driver scales
//       them by the placement). A kind that does not fit its vertices copies error_m.
//       Sets key to the shape's template (kind, flags, segment counts); the driver fetches or
//       builds the template and fills plan.indices. Must be cheap and allocation-free.
//       A shape without volume sets vertex_count = 0 and leaves key.kind = kNoTemplate.
//   void build_template(const TemplateKey& key, TemplateBuilder& out);
//       Writes the index arrays of every level, level 0 first, into `out`. Runs once per key.
//   void write(const K&, const MeshPlan& plan, const VertexSink& sink);
//       Writes plan.vertex_count vertices through the sink, fitted to sink.fit_level (on the
//       surface when negative). Allocation-free; stack arrays only.
//   Aabb bounds(const K&);
//       Analytic local bounds.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <concepts>
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

// pack_normal, inline for the per-vertex path (the public function forwards here). The rounding
// takes the sign by copysign, not by a branch: around a ring the components change sign at places
// a branch predictor cannot learn.
inline uint32_t pack_unit_normal(const glm::vec3& n) {
  auto component = [](float v) -> uint32_t {
    v = std::min(std::max(v * 511.0f, -511.0f), 511.0f);
    return static_cast<uint32_t>(static_cast<int32_t>(v + std::copysign(0.5f, v))) & 0x3ffu;
  };
  return component(n.x) | component(n.y) << 10 | component(n.z) << 20;
}

// The packing of -n, from the packing of n: the rounding is symmetric, so this is exact.
inline uint32_t negate_packed_normal(uint32_t packed) {
  auto field = [packed](int shift) { return ((0x400u - (packed >> shift)) & 0x3ffu) << shift; };
  return field(0) | field(10) | field(20);
}

// Unit circle samples: kUnitCircle[i] = (cos, sin)(2*pi*i / kCircleSamples). A circle of N
// segments (N a power of two up to kCircleSamples) uses every (kCircleSamples / N)-th entry, so
// every level samples exactly the same angles. The quadrants are exact quarter turns of the first
// (sample i + N/2 is exactly -sample i), the axes exact.
inline constexpr uint32_t kCircleSamples = 1024;
extern const std::array<glm::vec2, kCircleSamples + 1> kUnitCircle;  // filled at static init
inline glm::vec2 circle_sample(uint32_t i, uint32_t segments) {
  return kUnitCircle[(i * (kCircleSamples / segments)) % kCircleSamples];
}

// 1 - cos, in its one spelling. The sagitta of a chord of a circle of radius r whose half-angle
// at the centre is x is r(1 - cos x); it is computed as 2r sin^2(x/2), because 1 - cos x cancels
// to nothing in float at fine steps. Every error figure and dish ring goes through these, so
// that they round alike: r(1 - cos x) is (2r * s) * s, and 1 - cos x is chord_sagitta(1, x).
template <std::floating_point T>
T sagitta_from_half_sine(T radius, T half_sine) {  // half_sine = sin(x / 2)
  return T(2) * radius * half_sine * half_sine;
}
template <std::floating_point T>
T chord_sagitta(T radius, T half_angle_rad) {
  return sagitta_from_half_sine(radius, T(std::sin(T(0.5) * half_angle_rad)));
}
template <std::floating_point T>
T one_minus_cos(T x) {
  return chord_sagitta(T(1), x);
}

// Sagitta of one of `segments` equal chords of a circle of radius r (segments a power of two,
// 4 to kCircleSamples / 4): r(1 - cos(pi/N)), with sin(pi/2N) read from the sample table, as
// planning runs for every primitive streamed.
inline float segment_sagitta(float radius_m, uint32_t segments) {
  assert(segments >= 4 && segments <= kCircleSamples / 4);
  return sagitta_from_half_sine(radius_m, kUnitCircle[kCircleSamples / (4 * segments)].y);
}

// Fitting (primitives.h, write_vertices). A curve whose inscribed polygon dips up to
// x * W inside it (W: the radius that deficit is measured against, x relative) straddles it when
// its vertices are moved out by the scale 2 / (2 - x): they then lie W x / (2 - x) outside, and
// the deepest point of the polygon, W (1 - s (1 - x)), as far inside. For a circle of N
// segments x = 1 - cos(pi/N), s = 2 / (1 + cos(pi/N)).
inline float straddle_scale(float relative_deficit) { return 2.0f / (2.0f - relative_deficit); }
// W x / (2 - x), computed without s - 1 (which cancels in float at fine steps).
inline float straddled_deficit(float radius_m, float relative_deficit) {
  return radius_m * relative_deficit / (2.0f - relative_deficit);
}
// The relative deficit of a circle of `segments` chords, 1 - cos(pi/N).
inline float ring_deficit(uint32_t segments) { return segment_sagitta(1.0f, segments); }

// A ring of a shape as a function of the unit circle sample cs = (c, s) it stands at:
// centre + c * along_c + s * along_s, in local coordinates. Cylinders, snouts, tori, spheres and
// dishes are stacks of rings whose positions (and mostly normals) are of this form; the sink maps
// the three vectors through the placement once per ring instead of mapping every vertex.
struct AffineRing {
  glm::vec3 centre{0}, along_c{0}, along_s{0};
  bool unit_length = false;  // as normals: every sample has unit length (no normalisation needed)
  glm::vec3 at(glm::vec2 cs) const { return centre + cs.x * along_c + cs.y * along_s; }
};

// Transforms local positions and normals to model space (relative to the caller's origin) and
// packs them. Prepared once per primitive by the driver.
struct VertexSink {
  glm::mat3 linear{1.0f};
  glm::vec3 translation_m{0.0f};   // placement translation minus origin, already in float
  glm::mat3 normal_matrix{1.0f};   // inverse transpose of linear
  bool preserves_unit_normals = false;  // normal_matrix is a rotation (placement is a similarity)
  int fit_level = -1;  // the level the vertices are fitted to, clamped; -1: on the surface
  PackedVertex* out = nullptr;

  bool fitted() const { return fit_level >= 0; }

  // Packs a model-space normal of any length (zero gives +z).
  static uint32_t pack_normalised(const glm::vec3& n) {
    const float len2 = glm::dot(n, n);
    if (!(len2 > 1e-30f)) return pack_unit_normal(glm::vec3(0, 0, 1));
    return pack_unit_normal(n * (1.0f / std::sqrt(len2)));
  }
  // The packed model-space normal of a local normal (need not be unit length; zero gives +z).
  uint32_t normal(const glm::vec3& local_normal) const {
    return pack_normalised(normal_matrix * local_normal);
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

  // Writes a ring of `segments` vertices to [first, first + segments): vertex i at the position
  // of circle_sample(i, segments), with the packed normal normal_of(sample) (inlined: no call per
  // vertex). `segments` is a power of two, 2 to kCircleSamples.
  template <typename PackedNormalOf>
  void put_ring(uint32_t first, uint32_t segments, const AffineRing& position,
                PackedNormalOf normal_of) const {
    const glm::vec3 centre = linear * position.centre + translation_m;
    const glm::vec3 along_c = linear * position.along_c, along_s = linear * position.along_s;
    const uint32_t step = kCircleSamples / segments;
    PackedVertex* v = out + first;
    for (uint32_t i = 0; i < segments; ++i) {
      const glm::vec2 cs = kUnitCircle[i * step];
      v[i].position_m = centre + cs.x * along_c + cs.y * along_s;
      v[i].normal = normal_of(cs);
    }
  }
  // As above with one normal for the whole ring (caps, discs).
  void put_ring(uint32_t first, uint32_t segments, const AffineRing& position,
                uint32_t packed_normal) const {
    put_ring(first, segments, position, [packed_normal](glm::vec2) { return packed_normal; });
  }
  // As above with local normals of the same form.
  void put_ring(uint32_t first, uint32_t segments, const AffineRing& position,
                const AffineRing& local_normal) const {
    const AffineRing n{normal_matrix * local_normal.centre, normal_matrix * local_normal.along_c,
                       normal_matrix * local_normal.along_s, local_normal.unit_length};
    if (!local_normal.unit_length || !preserves_unit_normals) {
      put_ring(first, segments, position,
               [&n](glm::vec2 cs) { return pack_normalised(n.at(cs)); });
    } else if (local_normal.centre != glm::vec3(0.0f)) {
      put_ring(first, segments, position,
               [&n](glm::vec2 cs) { return pack_unit_normal(n.at(cs)); });
    } else {
      put_mirrored_ring(first, segments, position, n);
    }
  }
  // A ring whose unit normals are linear in the sample (cylinder sides, torus stations, the bulk
  // of a plant): sample i + N/2 is sample i negated, so vertex i + N/2 mirrors vertex i through
  // the centre and its packed normal is the negation of vertex i's. Half the float work.
  void put_mirrored_ring(uint32_t first, uint32_t segments, const AffineRing& position,
                         const AffineRing& model_normal) const {
    const glm::vec3 centre = linear * position.centre + translation_m;
    const glm::vec3 along_c = linear * position.along_c, along_s = linear * position.along_s;
    assert(segments >= 2);
    const uint32_t half = segments / 2, step = kCircleSamples / segments;
    PackedVertex* v = out + first;
    for (uint32_t i = 0; i < half; ++i) {
      const glm::vec2 cs = kUnitCircle[i * step];
      const glm::vec3 d = cs.x * along_c + cs.y * along_s;
      const uint32_t normal =
          pack_unit_normal(cs.x * model_normal.along_c + cs.y * model_normal.along_s);
      v[i] = {centre + d, normal};
      v[half + i] = {centre - d, negate_packed_normal(normal)};
    }
  }
  // Repeats vertices [from, from + count) at [to, to + count) with another normal: a cap or a disc
  // that shares its rim with the side, bit for bit.
  void copy_positions(uint32_t from, uint32_t to, uint32_t count, uint32_t packed_normal) const {
    for (uint32_t i = 0; i < count; ++i) {
      out[to + i].position_m = out[from + i].position_m;
      out[to + i].normal = packed_normal;
    }
  }
};

// Non-finite and negative parameters read as zero.
inline float sane(float v) { return std::isfinite(v) && v > 0.0f ? v : 0.0f; }
// Non-finite read as zero, sign kept (offsets, shears).
inline float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

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
