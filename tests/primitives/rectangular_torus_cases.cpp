// Rectangular torus cases: duct bends and rings of 45 to 360 degrees, a sector of a cylinder
// (zero inner radius), and degenerate ones.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <tuple>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// The true surface: the walls rho = inner and rho = outer, the annular top and bottom, and for an
// open sweep the two end rectangles. Only the sweep is curved, so lines along it (8 samples per
// finest sweep segment) on every face, the outer wall's rims included, find the deviation; a grid
// on each end rectangle checks the caps.
void sample_rectangular_torus(float inner, float outer, float height, float angle,
                              uint32_t sweep_segments, bool closed, std::vector<glm::vec3>& out) {
  const float h2 = height / 2, mid = (inner + outer) / 2;
  const std::tuple<float, float> lines[] = {{outer, -h2}, {outer, 0}, {outer, h2},
                                            {inner, 0},   {mid, h2},  {mid, -h2}};
  const uint32_t along = 8 * sweep_segments;
  for (auto [rho, z] : lines) {
    for (uint32_t j = 0; j <= along; ++j) {
      const float a = angle * float(j) / float(along);
      out.push_back({rho * std::cos(a), rho * std::sin(a), z});
    }
  }
  if (closed) return;
  for (float a : {0.0f, angle}) {
    for (int i = 0; i <= 4; ++i) {
      for (int k = 0; k <= 4; ++k) {
        const float rho = inner + (outer - inner) * float(i) / 4;
        out.push_back({rho * std::cos(a), rho * std::sin(a), -h2 + height * float(k) / 4});
      }
    }
  }
}

// primitives.h: 8S + 4 triangles open, 8S closed; S halves per level down to its floor, and the
// level count comes from the size rule on the outer diameter.
std::vector<uint32_t> rectangular_torus_counts(uint32_t levels, uint32_t sweep_segments,
                                               uint32_t sweep_floor, bool closed) {
  std::vector<uint32_t> counts;
  for (uint32_t l = 0, s = sweep_segments; l < levels; ++l, s = std::max(s / 2, sweep_floor)) {
    counts.push_back(8 * s + (closed ? 0 : 4));
  }
  return counts;
}

struct RectangularTorusCase {
  const char* name;
  float inner, outer, height, angle;
  uint32_t levels, sweep_segments, sweep_floor;  // documented by the size rule
  bool closed;
  glm::vec3 at;
};

PrimitiveCase rectangular_torus_case(const RectangularTorusCase& t) {
  PrimitiveCase c;
  c.name = t.name;
  c.primitive.shape = RectangularTorus{t.inner, t.outer, t.height, t.angle};
  c.primitive.placement.translation_m = t.at;
  const float angle = t.closed ? 2 * kPi : t.angle;
  c.sample_surface = [t, angle](std::vector<glm::vec3>& out) {
    sample_rectangular_torus(t.inner, t.outer, t.height, angle, t.sweep_segments, t.closed, out);
  };
  c.expected_elements =
      rectangular_torus_counts(t.levels, t.sweep_segments, t.sweep_floor, t.closed);
  return c;
}

std::vector<PrimitiveCase> rectangular_torus_cases() {
  // Sweep segments: the power of two >= N(outer diameter) * angle/2pi, at most 256; levels
  // n_max - 1 of the same size rule.
  const RectangularTorusCase typical[] = {
      // 2 m outer diameter: N = 64, 5 levels, 64/4 = 16.
      {"rectangular_torus_duct_bend_90deg", 0.5f, 1.0f, 0.4f, kPi / 2, 5, 16, 1, false, {4, 5, 6}},
      // 0.8 m: N = 32, 32/8 = 4, floor 1.
      {"rectangular_torus_small_45deg", 0.2f, 0.4f, 0.1f, kPi / 4, 4, 4, 1, false, {-1, 0, 2}},
      // 8 m: N = 256, 7 levels, 256/2 = 128, floor 2.
      {"rectangular_torus_half_ring_8m", 3.0f, 4.0f, 0.5f, kPi, 7, 128, 2, false, {20, 0, 0}},
      // Inner radius 0: a 270-degree sector of a 1 m cylinder; 32 * 3/4 = 24 -> 32, floor 4.
      {"rectangular_torus_cylinder_sector", 0.0f, 0.5f, 1.0f, 1.5f * kPi, 4, 32, 4, false,
       {0, -3, 1}},
      // 4 m ring: N = 128, 6 levels, no caps.
      {"rectangular_torus_ring_360deg", 1.5f, 2.0f, 0.3f, 2 * kPi, 6, 128, 4, true, {1, 1, 1}},
      // A full cylinder built as a ring with zero inner radius.
      {"rectangular_torus_ring_solid", 0.0f, 0.4f, 0.2f, 2 * kPi, 4, 32, 4, true, {0, 0, 0}},
  };
  std::vector<PrimitiveCase> cases;
  for (const RectangularTorusCase& t : typical) cases.push_back(rectangular_torus_case(t));

  PrimitiveCase rotated = rectangular_torus_case(
      {"rectangular_torus_rotated", 0.5f, 1.0f, 0.4f, kPi / 2, 5, 16, 1, false, {-3, 8, 2}});
  rotated.primitive.placement.linear = rotation_about({0, 1, 1}, 2.0f);
  cases.push_back(rotated);

  for (auto [name, inner, outer, height, angle] :
       {std::tuple{"rectangular_torus_inner_equals_outer", 0.5f, 0.5f, 0.2f, kPi / 2},
        std::tuple{"rectangular_torus_inner_beyond_outer", 0.8f, 0.5f, 0.2f, kPi / 2},
        std::tuple{"rectangular_torus_zero_height", 0.2f, 0.5f, 0.0f, kPi / 2},
        std::tuple{"rectangular_torus_zero_angle", 0.2f, 0.5f, 0.2f, 0.0f},
        std::tuple{"rectangular_torus_negative", -0.2f, -0.5f, -0.2f, -1.0f},
        std::tuple{"rectangular_torus_nan_outer", 0.2f, NAN, 0.2f, kPi / 2},
        std::tuple{"rectangular_torus_nan_angle", 0.2f, 0.5f, 0.2f, NAN},
        std::tuple{"rectangular_torus_infinite_outer", 0.2f, INFINITY, 0.2f, kPi / 2},
        std::tuple{"rectangular_torus_huge", 0.0f, 3e38f, 3e38f, kPi / 2}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = RectangularTorus{inner, outer, height, angle};
    c.degenerate = true;
    cases.push_back(c);
  }
  // A NaN inner radius reads as zero: still a valid sector.
  PrimitiveCase nan_inner;
  nan_inner.name = "rectangular_torus_nan_inner";
  nan_inner.primitive.shape = RectangularTorus{NAN, 0.5f, 0.2f, kPi / 2};
  nan_inner.expected_elements = rectangular_torus_counts(4, 8, 1, false);
  nan_inner.degenerate = true;
  cases.push_back(nan_inner);
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(rectangular_torus_cases)
}  // namespace plantview::testing
