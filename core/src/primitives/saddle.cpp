// Saddle: a block whose top is a cylindrical cradle about an axis parallel to x. The cross-section
// (yz plane) is sampled at the A + 1 points of the cradle arc, extruded along x.
//
// Vertex layout at level 0 with A arc segments (K = A + 1; arc point j at angle
// beta * (2j - A) / A from the lowest point, y increasing with j):
//   [0, K) cradle at x = -L/2, [K, 2K) cradle at x = +L/2 (normals toward the axis);
//   [2K, 3K) end x = -L/2 at the arc, [3K, 4K) the same end at z = 0 below each arc point;
//   [4K, 5K), [5K, 6K) likewise for the end x = +L/2 (normals along x);
//   [6K, 7K) bottom below the arc points at x = -L/2, [7K, 8K) at x = +L/2 (normal -z);
//   [8K, 8K + 4) side y = -W/2, [8K + 4, 8K + 8) side y = +W/2, each (x, z) = (-L/2, 0),
//   (L/2, 0), (L/2, H), (-L/2, H).
// A height at or below the cradle depth is raised to it; the cradle then touches the ground along
// y = 0, where (A even) four faces meet: a pinched solid, not a manifold.
// Level l uses every 2^l-th arc point: the cradle, the bottom and both ends as strips of A >> l
// quads (the ends' quads are the vertical trapezoids under the arc), and the two side rectangles.
// 8(A + 1) + 8 vertices, 8A + 4 triangles.
//
// Arc segments: the cradle gets the segment angle of a full circle of its diameter (the size
// rule), rounded to a power of two: A = 2^ceil(log2(N * beta / pi)) for N = 2^n_max, at least 1;
// the floor likewise from 2^n_min.
//
// Error: the arc's sagitta R(1 - cos(beta / A)), capped by the block: a cradle point is never
// further than L/2 from an end, nor than half the height of the chord above it from the mesh (the
// bottom face lies below it, the chord above), so a thin plate or a thin web reports no more than
// L/2 or H/2.
#include <algorithm>
#include <bit>
#include <cmath>
#include <initializer_list>
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

namespace {

constexpr uint32_t kMaxArcSegments = 128;  // half of the largest full circle (256 segments)

// The block after clamping: the cradle radius at least width/2, the height at least the depth.
struct SaddleShape {
  float length_m = 0, width_m = 0, height_m = 0, radius_m = 0;
  float half_angle_rad = 0;  // beta: half the angle the cradle arc subtends at its axis
  bool empty = true;
};

SaddleShape shape_of(const Saddle& s) {
  SaddleShape out;
  out.length_m = sane(s.length_m);
  out.width_m = sane(s.width_m);
  out.radius_m = std::max(sane(s.cradle_radius_m), 0.5f * out.width_m);
  out.empty = out.length_m == 0.0f || out.width_m == 0.0f;
  if (out.empty) return out;
  out.half_angle_rad = std::asin(std::min(0.5f * out.width_m / out.radius_m, 1.0f));
  const float depth = chord_sagitta(out.radius_m, out.half_angle_rad);  // R(1 - cos beta)
  out.height_m = std::max(sane(s.height_m), depth);
  return out;
}

// Arc segments matching a full circle of 2^exponent segments.
uint32_t arc_segments(float half_angle_rad, uint32_t exponent) {
  const float wanted = float(1u << exponent) * half_angle_rad / std::numbers::pi_v<float>;
  // The tolerance keeps a half-circle cradle at exactly half the circle's segments.
  const float whole = std::ceil(wanted - 1e-3f);
  return std::bit_ceil(uint32_t(std::clamp(whole, 1.0f, float(kMaxArcSegments))));
}

}  // namespace

void plan(const Saddle& s, MeshPlan& plan, TemplateKey& key) {
  const SaddleShape shape = shape_of(s);
  if (shape.empty) return;  // no volume: empty mesh
  const SegmentExponents e = segment_exponents(2.0f * shape.radius_m);
  const uint32_t a_max = arc_segments(shape.half_angle_rad, e.n_max);
  const uint32_t a_min = std::min(arc_segments(shape.half_angle_rad, e.n_min), a_max);
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(halving_levels(a_max, a_min));
  plan.vertex_count = 8 * (a_max + 1) + 8;
  plan.segments = {uint16_t(a_max), 0};
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const float sagitta = chord_sagitta(  // R(1 - cos(beta / A))
        shape.radius_m, shape.half_angle_rad / float(segments_at(a_max, a_min, l)));
    plan.error_m[l] = std::min({sagitta, 0.5f * shape.length_m, 0.5f * shape.height_m});
    // Never fitted: the cradle's ends lie on the side faces' edges, which scaling would tear.
    plan.straddled_error_m[l] = plan.error_m[l];
  }
  key.kind = uint8_t(PrimitiveKind::saddle);
  key.a_max = uint16_t(a_max);
  key.a_min = uint16_t(a_min);
}

void build_template_Saddle(const TemplateKey& key, TemplateBuilder& out) {
  const uint32_t a0 = key.a_max, k = a0 + 1;
  const uint32_t cradle_lo = 0, cradle_hi = k, end_lo_arc = 2 * k, end_lo_base = 3 * k,
                 end_hi_arc = 4 * k, end_hi_base = 5 * k, bottom_lo = 6 * k, bottom_hi = 7 * k,
                 side_lo = 8 * k, side_hi = 8 * k + 4;
  for (uint32_t level = 0; level < halving_levels(key.a_max, key.a_min); ++level) {
    const uint32_t step = a0 / segments_at(key.a_max, key.a_min, level);
    out.begin_level();
    for (uint32_t j = 0; j < a0; j += step) {
      const uint32_t p = j, q = j + step;  // arc points of this segment, y increasing
      out.quad(cradle_lo + p, cradle_hi + p, cradle_hi + q, cradle_lo + q);
      out.quad(bottom_lo + p, bottom_lo + q, bottom_hi + q, bottom_hi + p);
      out.quad(end_lo_base + p, end_lo_arc + p, end_lo_arc + q, end_lo_base + q);
      out.quad(end_hi_base + p, end_hi_base + q, end_hi_arc + q, end_hi_arc + p);
    }
    out.quad(side_lo, side_lo + 1, side_lo + 2, side_lo + 3);
    out.quad(side_hi, side_hi + 3, side_hi + 2, side_hi + 1);
  }
}

void write(const Saddle& s, const MeshPlan& plan, const VertexSink& sink) {
  const SaddleShape shape = shape_of(s);
  const uint32_t a = plan.segments[0], k = a + 1;
  const float x2 = 0.5f * shape.length_m, y2 = 0.5f * shape.width_m, h = shape.height_m;
  const float r = shape.radius_m, beta = shape.half_angle_rad;
  const uint32_t to_lo = sink.normal({-1, 0, 0}), to_hi = sink.normal({1, 0, 0}),
                 down = sink.normal({0, 0, -1});
  for (uint32_t j = 0; j <= a; ++j) {
    // Angle from the lowest point; exact negatives for mirrored j keep the arc symmetric.
    const float theta = beta * float(int32_t(2 * j) - int32_t(a)) / float(a);
    // z = H - R(cos theta - cos beta), the difference written as a product for precision; the
    // ends land exactly on the side edges (y = +-W/2, z = H).
    const float y = j == 0 ? -y2 : j == a ? y2 : r * std::sin(theta);
    const float z =
        h - 2.0f * r * std::sin(0.5f * (beta + theta)) * std::sin(0.5f * (beta - theta));
    const uint32_t cradle = sink.normal({0, -std::sin(theta), std::cos(theta)});
    sink.put(j, {-x2, y, z}, cradle);
    sink.put(k + j, {x2, y, z}, cradle);
    sink.put(2 * k + j, {-x2, y, z}, to_lo);
    sink.put(3 * k + j, {-x2, y, 0}, to_lo);
    sink.put(4 * k + j, {x2, y, z}, to_hi);
    sink.put(5 * k + j, {x2, y, 0}, to_hi);
    sink.put(6 * k + j, {-x2, y, 0}, down);
    sink.put(7 * k + j, {x2, y, 0}, down);
  }
  for (uint32_t side = 0; side < 2; ++side) {
    const float y = side == 0 ? -y2 : y2;
    const uint32_t normal = sink.normal({0, y, 0}), base = 8 * k + 4 * side;
    sink.put(base, {-x2, y, 0}, normal);
    sink.put(base + 1, {x2, y, 0}, normal);
    sink.put(base + 2, {x2, y, h}, normal);
    sink.put(base + 3, {-x2, y, h}, normal);
  }
}

Aabb bounds(const Saddle& s) {
  const SaddleShape shape = shape_of(s);
  const float x2 = 0.5f * shape.length_m, y2 = 0.5f * shape.width_m;
  return {{-x2, -y2, 0}, {x2, y2, shape.height_m}};
}

}  // namespace plantview::detail
