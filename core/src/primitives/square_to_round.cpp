// Square-to-round: the ruled surface joining a rectangle (bottom) to a circle (top) at equal
// perimeter parameters, closed by a flat rectangle and a flat disc.
//
// Parameterisation: N points on each curve. Point i of the circle lies at angle
// 2*pi*i/N + pi/4; point i of the rectangle lies on side k = i / (N/4) (side k runs from corner k
// to corner k + 1; corners at (+x, +y), (-x, +y), (-x, -y), (+x, -y), counter-clockwise), at the
// fraction (i mod N/4) / (N/4) of it. So corner k faces the circle's 45 + 90k degree point at
// every level.
//
// Vertex layout at level 0 with N segments (q = N/4):
//   [0, N + 4) bottom ring (side normals): side k holds q + 1 points, corner k to corner k + 1,
//     at k(q + 1) + m; a corner appears twice, once with each side's normal (the surface creases
//     along the line from a rectangle corner);
//   [N + 4, 2N + 4) top ring (side normals), point i at N + 4 + i;
//   [2N + 4, 3N + 4) bottom face, rectangle point i (normal -z);
//   [3N + 4, 4N + 4) top face, circle point i (normal +z).
// Level l uses every 2^l-th point of each curve: N >> l side quads, the top face fanned from
// point 0, and the bottom face as a strip zig-zagging between the two chains that run from
// corner 0 to corner 2 (no triangle has all three points on one side of the rectangle).
// 4N + 4 vertices; 4N - 4 triangles (2N side, N - 2 per face).
//
// Error: the side quads twist (the rectangle's chords and the circle's are not parallel), so each
// level's error is measured on its quads (ruled_ring_deviation in snout.cpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <span>

#include "kinds.h"

namespace plantview::detail {

// snout.cpp: the error of a ring of ruled quads.
using RuledQuad = std::array<glm::vec3, 6>;  // b0, b1, t0, t1, bm, tm
float ruled_ring_deviation(std::span<const RuledQuad> quads);

namespace {

// Index offset of the circle's pi/4 in kUnitCircle.
constexpr uint32_t kEighthTurn = kCircleSamples / 8;

struct SquareToRoundShape {
  glm::vec3 bottom_centre{0}, top_centre{0};
  glm::vec3 corners[5]{};  // relative to bottom_centre, corner 0 repeated at the end
  float radius_m = 0;
  bool empty = true;

  // Rectangle point at perimeter index i of n (n a multiple of 4, i < n).
  glm::vec3 rectangle(uint32_t i, uint32_t n) const {
    const uint32_t q = n / 4, k = i / q, m = i % q;
    const glm::vec3 along = corners[k + 1] - corners[k];
    return bottom_centre + corners[k] + (float(m) / float(q)) * along;
  }
  // Circle direction (cos, sin) at kUnitCircle index `sample` before the eighth-turn shift.
  static glm::vec2 circle_direction(uint32_t sample) {
    return kUnitCircle[(sample + kEighthTurn) % kCircleSamples];
  }
  glm::vec3 circle(glm::vec2 direction) const {
    return top_centre + glm::vec3(radius_m * direction, 0.0f);
  }
};

SquareToRoundShape shape_of(const SquareToRound& s) {
  SquareToRoundShape out;
  const float x2 = 0.5f * sane(s.bottom_x_m), y2 = 0.5f * sane(s.bottom_y_m);
  const float h2 = 0.5f * sane(s.height_m);
  const float ox2 = 0.5f * finite_or_zero(s.offset_x_m), oy2 = 0.5f * finite_or_zero(s.offset_y_m);
  out.radius_m = sane(s.top_radius_m);
  out.bottom_centre = {-ox2, -oy2, -h2};
  out.top_centre = {ox2, oy2, h2};
  out.corners[0] = {x2, y2, 0};
  out.corners[1] = {-x2, y2, 0};
  out.corners[2] = {-x2, -y2, 0};
  out.corners[3] = {x2, -y2, 0};
  out.corners[4] = out.corners[0];
  const bool flat_bottom = x2 == 0.0f || y2 == 0.0f;
  out.empty = h2 == 0.0f || (flat_bottom && out.radius_m == 0.0f);
  return out;
}

}  // namespace

void plan(const SquareToRound& s, MeshPlan& plan, TemplateKey& key) {
  const SquareToRoundShape shape = shape_of(s);
  if (shape.empty) return;  // no volume: empty mesh
  // The segments serve both curves: the size rule takes the larger of the circle's diameter and
  // the rectangle's longer side.
  const float size_m = std::max({2.0f * shape.radius_m, sane(s.bottom_x_m), sane(s.bottom_y_m)});
  const SegmentExponents e = segment_exponents(size_m);
  const uint32_t n_max = 1u << e.n_max, n_min = 1u << e.n_min;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(halving_levels(n_max, n_min));
  plan.vertex_count = 4 * n_max + 4;
  plan.segments = {uint16_t(n_max), 0};

  float previous = 0.0f;
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const uint32_t n = segments_at(n_max, n_min, l), step = kCircleSamples / n;
    std::array<RuledQuad, 256> quads;  // n <= 256
    for (uint32_t i = 0; i < n; ++i) {
      const glm::vec3 b0 = shape.rectangle(i, n), b1 = shape.rectangle((i + 1) % n, n);
      const glm::vec3 t0 = shape.circle(shape.circle_direction(i * step));
      const glm::vec3 t1 = shape.circle(shape.circle_direction((i + 1) * step));
      const glm::vec3 tm = shape.circle(shape.circle_direction(i * step + step / 2));
      // The rectangle is straight between samples: its middle point is the chord's.
      quads[i] = {b0, b1, t0, t1, 0.5f * (b0 + b1), tm};
    }
    previous = std::max(previous, ruled_ring_deviation(std::span(quads.data(), n)));
    plan.error_m[l] = previous;  // coarser levels never report less
    // Never fitted: the quads' twist, not the circle's chords, sets the error (measured: fitting
    // the circle gains under 10% at fine levels and loses at the coarsest).
    plan.straddled_error_m[l] = previous;
  }
  key.kind = uint8_t(PrimitiveKind::square_to_round);
  key.a_max = uint16_t(n_max);
  key.a_min = uint16_t(n_min);
}

void build_template_SquareToRound(const TemplateKey& key, TemplateBuilder& out) {
  const uint32_t n0 = key.a_max, q0 = n0 / 4;
  const uint32_t top_ring = n0 + 4, bottom_face = 2 * n0 + 4, top_face = 3 * n0 + 4;
  // Bottom-ring vertex of perimeter point g as the start (or, at_end, the end) of a side segment.
  auto ring = [&](uint32_t g, bool at_end) {
    const uint32_t k = at_end ? (g + n0 - 1) / q0 % 4 : g / q0;  // the segment's side
    return k * (q0 + 1) + (g + n0 - k * q0) % n0;
  };
  for (uint32_t level = 0; level < halving_levels(key.a_max, key.a_min); ++level) {
    const uint32_t n = segments_at(key.a_max, key.a_min, level), step = n0 / n;
    out.begin_level();
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t g0 = i * step, g1 = (i + 1) * step;
      out.quad(ring(g0, false), ring(g1, true), top_ring + g1 % n0, top_ring + g0);
    }
    for (uint32_t k = 1; k + 1 < n; ++k) {
      out.triangle(top_face, top_face + k * step, top_face + (k + 1) * step);
    }
    // Bottom face, seen from below: the strip between points k and n - k of the level.
    auto p = [&](uint32_t i) { return bottom_face + (i % n) * step; };
    for (uint32_t k = 0; k < n / 2; ++k) {
      if (k + 1 < n / 2) out.triangle(p(k), p(n - k - 1), p(k + 1));
      if (k > 0) out.triangle(p(k), p(n - k), p(n - k - 1));
    }
  }
}

void write(const SquareToRound& s, const MeshPlan& plan, const VertexSink& sink) {
  const SquareToRoundShape shape = shape_of(s);
  const uint32_t n = plan.segments[0], q = n / 4, step = kCircleSamples / n;
  const uint32_t down = sink.normal({0, 0, -1}), up = sink.normal({0, 0, 1});
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t k = i / q, m = i % q;
    const glm::vec2 direction = shape.circle_direction(i * step);
    const glm::vec3 bottom = shape.rectangle(i, n), top = shape.circle(direction);
    const glm::vec3 ruling = top - bottom;
    const glm::vec3 along_circle(-direction.y, direction.x, 0.0f);
    // Side normals: along the curve crossed with the ruling; a curve shrunk to a point borrows the
    // other curve's direction (for the top ring, that of the side whose segment ends here).
    auto side_normal = [&](uint32_t side, const glm::vec3& along_top) {
      const glm::vec3 along = shape.corners[side + 1] - shape.corners[side];
      const bool straight = along != glm::vec3(0.0f);
      return glm::cross(straight ? along : along_top, ruling);
    };
    sink.put(k * (q + 1) + m, bottom, side_normal(k, along_circle));
    if (m == 0) {  // the corner again, closing the previous side
      const uint32_t previous = (k + 3) % 4;
      sink.put(previous * (q + 1) + q, bottom, side_normal(previous, along_circle));
    }
    const uint32_t ending_side = (i + n - 1) / q % 4;
    const glm::vec3 along_rectangle = shape.corners[ending_side + 1] - shape.corners[ending_side];
    sink.put(n + 4 + i, top,
             glm::cross(shape.radius_m > 0.0f ? along_circle : along_rectangle, ruling));
    sink.put(2 * n + 4 + i, bottom, down);
    sink.put(3 * n + 4 + i, top, up);
  }
}

Aabb bounds(const SquareToRound& s) {
  const SquareToRoundShape shape = shape_of(s);
  const glm::vec3 rectangle = shape.corners[0], circle(shape.radius_m, shape.radius_m, 0.0f);
  return {glm::min(shape.bottom_centre - rectangle, shape.top_centre - circle),
          glm::max(shape.bottom_centre + rectangle, shape.top_centre + circle)};
}

}  // namespace plantview::detail
