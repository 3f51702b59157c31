// Circular torus cases: pipe elbows of 45, 90 and 180 degrees from 0.1 m to 2 m pipe, full rings,
// and degenerate ones.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <tuple>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// The true surface: the tube (R + r cos t)(cos a, sin a) + r sin t z for a in [0, angle], and for
// an open sweep the two end discs. The mesh deviates most midway between stations and between
// tube vertices, nearest the outside (t = 0); by the shape's symmetry the first sweep segment and
// the first tube segment of every power-of-two subdivision stand for all others. So: sweep lines
// (8 samples per finest sweep segment) at the mid tube angle pi/s of every subdivision s and on
// the four axes, and tube rings (8 samples per finest tube segment) at both ends and at the
// mid sweep angle angle/(2s) of every subdivision s.
void sample_torus(float bend, float tube, float angle, uint32_t sweep_segments,
                  uint32_t tube_segments, bool closed, std::vector<glm::vec3>& out) {
  auto point = [&](float a, float t) {
    const float rho = bend + tube * std::cos(t);
    return glm::vec3(rho * std::cos(a), rho * std::sin(a), tube * std::sin(t));
  };
  std::vector<float> tube_angles = {0, kPi / 2, kPi, 3 * kPi / 2};
  for (uint32_t s = 4; s <= tube_segments; s *= 2) tube_angles.push_back(kPi / float(s));
  const uint32_t along = 8 * sweep_segments;
  for (float t : tube_angles) {
    for (uint32_t j = 0; j <= along; ++j) out.push_back(point(angle * float(j) / float(along), t));
  }
  std::vector<float> sweep_angles = {0, angle};
  for (uint32_t s = 1; s <= sweep_segments; s *= 2) sweep_angles.push_back(angle / float(2 * s));
  const uint32_t around = 8 * tube_segments;
  for (float a : sweep_angles) {
    for (uint32_t i = 0; i < around; ++i) {
      out.push_back(point(a, 2 * kPi * float(i) / float(around)));
    }
  }
  if (closed) return;
  for (float a : {0.0f, angle}) {
    const glm::vec3 centre(bend * std::cos(a), bend * std::sin(a), 0);
    out.push_back(centre);
    for (float f : {1.0f / 3, 2.0f / 3}) {
      for (uint32_t i = 0; i < 2 * tube_segments; ++i) {
        const float t = kPi * float(i) / float(tube_segments);
        out.push_back(centre + f * (point(a, t) - centre));
      }
    }
  }
}

// primitives.h: 2*S*N + 2*(N - 2) triangles open, 2*S*N closed; per level N halves down to 4
// and S halves down to its floor.
std::vector<uint32_t> torus_counts(uint32_t tube_segments, uint32_t sweep_segments,
                                   uint32_t sweep_floor, bool closed) {
  std::vector<uint32_t> counts;
  for (uint32_t n = tube_segments, s = sweep_segments; n >= 4; n /= 2) {
    counts.push_back(2 * s * n + (closed ? 0 : 2 * (n - 2)));
    s = std::max(s / 2, sweep_floor);
  }
  return counts;
}

struct TorusCase {
  const char* name;
  float bend, tube, angle;
  uint32_t tube_segments, sweep_segments, sweep_floor;  // level 0, documented by the size rule
  bool closed;
  glm::vec3 at;
};

PrimitiveCase torus_case(const TorusCase& t) {
  PrimitiveCase c;
  c.name = t.name;
  c.primitive.shape = CircularTorus{t.bend, t.tube, t.angle};
  c.primitive.placement.translation_m = t.at;
  const float angle = t.closed ? 2 * kPi : t.angle;
  c.sample_surface = [t, angle](std::vector<glm::vec3>& out) {
    sample_torus(t.bend, t.tube, angle, t.sweep_segments, t.tube_segments, t.closed, out);
  };
  c.expected_elements = torus_counts(t.tube_segments, t.sweep_segments, t.sweep_floor, t.closed);
  return c;
}

std::vector<PrimitiveCase> circular_torus_cases() {
  // Sweep segments: the power of two >= N * angle/2pi * max(1, (R + r)/2r), at most 256.
  const TorusCase typical[] = {
      // DN200 long-radius elbow (R = 1.5 D): N = 32, 32 * 1/4 * 2 = 16.
      {"circular_torus_elbow_90deg_0_2m", 0.3f, 0.1f, kPi / 2, 32, 16, 1, false, {1, 2, 3}},
      // Short radius (R = 1.5 r): 32 * 1/4 * 1.25 = 10 -> 16.
      {"circular_torus_elbow_90deg_short", 0.15f, 0.1f, kPi / 2, 32, 16, 1, false, {-4, 0.5f, 2}},
      // DN100 45-degree elbow: 32 * 1/8 * 2 = 8.
      {"circular_torus_elbow_45deg_0_1m", 0.15f, 0.05f, kPi / 4, 32, 8, 1, false, {10, -3, 7}},
      // 180-degree return bend of 0.5 m pipe: 32 * 1/2 * 1.5 = 24 -> 32, floor 2.
      {"circular_torus_return_180deg_0_5m", 0.5f, 0.25f, kPi, 32, 32, 2, false, {0, 0, 5}},
      // 1 m pipe: still 32 around; 32 * 1/4 * 2 = 16.
      {"circular_torus_elbow_90deg_1m", 1.5f, 0.5f, kPi / 2, 32, 16, 1, false, {100, 200, 30}},
      // 2 m duct: 64 around, 5 levels; 64 * 1/4 * 2 = 32.
      {"circular_torus_elbow_90deg_2m", 3.0f, 1.0f, kPi / 2, 64, 32, 1, false, {-50, 20, 8}},
      // A short mitre-like bend: 32 * (0.1/2pi) * 2 = 1.02 -> 2.
      {"circular_torus_small_angle", 0.3f, 0.1f, 0.1f, 32, 2, 1, false, {0, 0, 0}},
      // Three-quarter turn: floor 4; 32 * 3/4 * 1.5 = 36 -> 64.
      {"circular_torus_270deg", 0.2f, 0.1f, 1.5f * kPi, 32, 64, 4, false, {2, 2, 2}},
      // Just short of a full turn stays open.
      {"circular_torus_almost_ring", 0.2f, 0.1f, 2 * kPi - 0.01f, 32, 64, 4, false, {0, 1, 0}},
      // Full ring: no caps, 32 * 1.5 = 48 -> 64.
      {"circular_torus_ring_360deg", 0.2f, 0.1f, 2 * kPi, 32, 64, 4, true, {3, -2, 1}},
      // Beyond a full turn reads as the ring.
      {"circular_torus_ring_beyond_full_turn", 0.2f, 0.1f, 7.0f, 32, 64, 4, true, {0, 0, 0}},
  };
  std::vector<PrimitiveCase> cases;
  for (const TorusCase& t : typical) cases.push_back(torus_case(t));

  // A rotated, translated elbow (the generic tests add their own poses on top).
  PrimitiveCase rotated = torus_case(
      {"circular_torus_elbow_rotated", 0.3f, 0.1f, kPi / 2, 32, 16, 1, false, {7, -8, 9}});
  rotated.primitive.placement.linear = rotation_about({1, 1, 0}, 1.1f);
  cases.push_back(rotated);

  // Self-intersecting (R < r) and spindle (R = 0) tori: finite and valid, not a proper solid.
  for (auto [name, bend] : {std::pair{"circular_torus_self_intersecting", 0.05f},
                            std::pair{"circular_torus_zero_bend", 0.0f},
                            std::pair{"circular_torus_infinite_bend", INFINITY}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = CircularTorus{bend, 0.1f, kPi / 2};
    c.expected_elements = torus_counts(32, 8, 1, false);  // (R + r)/2r < 1: 32 * 1/4 = 8
    c.degenerate = true;
    cases.push_back(c);
  }
  for (auto [name, bend, tube, angle] :
       {std::tuple{"circular_torus_zero_tube", 0.3f, 0.0f, kPi / 2},
        std::tuple{"circular_torus_zero_angle", 0.3f, 0.1f, 0.0f},
        std::tuple{"circular_torus_negative_angle", 0.3f, 0.1f, -kPi / 2},
        std::tuple{"circular_torus_negative_tube", 0.3f, -0.1f, kPi / 2},
        std::tuple{"circular_torus_nan_tube", 0.3f, NAN, kPi / 2},
        std::tuple{"circular_torus_nan_angle", 0.3f, 0.1f, NAN},
        std::tuple{"circular_torus_infinite_tube", 0.3f, INFINITY, kPi / 2},
        std::tuple{"circular_torus_huge", 3e38f, 3e38f, kPi / 2},
        std::tuple{"circular_torus_all_nan", NAN, NAN, NAN}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = CircularTorus{bend, tube, angle};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(circular_torus_cases)
}  // namespace plantview::testing
