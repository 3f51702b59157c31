// Snout cases: concentric and eccentric reducers, sheared cylinders, cones, a large vessel
// reducer, snouts whose side quads twist (offset or radius change with unequal end shears), and
// degenerate ones. Counts as the cylinder's (4N - 4 triangles).
#include <cmath>
#include <numbers>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr float kDeg = kPi / 180.0f;

// The true surface: the end curves
//   bottom(t) = (rb cos t - ox/2, rb sin t - oy/2, -h/2 + tan(bsx) rb cos t + tan(bsy) rb sin t),
//   top(t)    = (rt cos t + ox/2, rt sin t + oy/2,  h/2 + tan(tsx) rt cos t + tan(tsy) rt sin t),
// the lines joining them at equal t, and the flat end discs they bound. `around` angles.
void sample_snout(const Snout& s, int around, std::vector<glm::vec3>& out) {
  const float bx = std::tan(s.bottom_shear_x_rad), by = std::tan(s.bottom_shear_y_rad);
  const float tx = std::tan(s.top_shear_x_rad), ty = std::tan(s.top_shear_y_rad);
  const glm::vec3 bc(-s.offset_x_m / 2, -s.offset_y_m / 2, -s.height_m / 2);
  const glm::vec3 tc(s.offset_x_m / 2, s.offset_y_m / 2, s.height_m / 2);
  auto bottom = [&](float c, float sn, float r) {
    return bc + glm::vec3(r * c, r * sn, bx * r * c + by * r * sn);
  };
  auto top = [&](float c, float sn, float r) {
    return tc + glm::vec3(r * c, r * sn, tx * r * c + ty * r * sn);
  };
  const int along = 4;
  for (int i = 0; i < around; ++i) {
    const float t = 2 * kPi * float(i) / float(around);
    const float c = std::cos(t), sn = std::sin(t);
    const glm::vec3 b = bottom(c, sn, s.radius_bottom_m), e = top(c, sn, s.radius_top_m);
    for (int k = 0; k <= along; ++k) out.push_back(b + (e - b) * (float(k) / along));
    if (i % 8 == 0) {
      for (float f : {0.3f, 0.7f}) {
        out.push_back(bottom(c, sn, f * s.radius_bottom_m));
        out.push_back(top(c, sn, f * s.radius_top_m));
      }
    }
  }
}

std::vector<uint32_t> ring_solid_counts(uint32_t n_max) {
  std::vector<uint32_t> counts;
  for (uint32_t n = n_max; n >= 4; n /= 2) counts.push_back(4 * n - 4);
  return counts;
}

// n_max: the documented level-0 segment count (segment_exponents of the larger diameter).
PrimitiveCase snout_case(std::string name, Snout s, glm::vec3 at, uint32_t n_max) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = s;
  c.primitive.placement.translation_m = at;
  const int around = int(8 * n_max);
  c.sample_surface = [s, around](std::vector<glm::vec3>& out) { sample_snout(s, around, out); };
  c.expected_elements = ring_solid_counts(n_max);
  return c;
}

PrimitiveCase degenerate_snout(std::string name, Snout s) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = s;
  c.primitive.placement.translation_m = {3, 1, -2};
  c.degenerate = true;
  return c;
}

std::vector<PrimitiveCase> snout_cases() {
  std::vector<PrimitiveCase> cases;
  // Fields: radius_bottom, radius_top, height, offset_x, offset_y, bottom shear x/y, top shear x/y.
  cases.push_back(
      snout_case("snout_concentric_reducer", Snout{0.15f, 0.1f, 0.3f}, {2, -1, 0.5f}, 32));
  cases.push_back(
      snout_case("snout_concentric_expander", Snout{0.05f, 0.1f, 0.15f}, {0, 4, 1}, 32));
  // Flat-bottomed eccentric reducer: offset = radius difference.
  cases.push_back(
      snout_case("snout_eccentric_reducer", Snout{0.25f, 0.15f, 0.4f, 0.0f, -0.1f}, {5, 5, 2}, 32));
  cases.push_back(snout_case("snout_eccentric_wide_offset", Snout{0.3f, 0.1f, 0.2f, 0.35f, 0.2f},
                             {-3, 0, 1}, 32));
  cases.push_back(snout_case("snout_sheared_cylinder_x",
                             Snout{0.2f, 0.2f, 1.0f, 0, 0, 10 * kDeg, 0, 0, 0}, {1, 1, 1}, 32));
  cases.push_back(snout_case(
      "snout_sheared_cylinder_both_ends",
      Snout{0.3f, 0.3f, 0.8f, 0, 0, 20 * kDeg, 15 * kDeg, -25 * kDeg, 30 * kDeg}, {0, -2, 7}, 32));
  cases.push_back(snout_case("snout_sheared_cylinder_parallel_ends",
                             Snout{0.1f, 0.1f, 0.5f, 0, 0, 30 * kDeg, 0, 30 * kDeg, 0}, {0, 0, 3},
                             32));
  cases.push_back(snout_case("snout_cone", Snout{0.3f, 0.0f, 0.5f}, {4, 3, 2}, 32));
  cases.push_back(
      snout_case("snout_cone_apex_down", Snout{0.0f, 0.4f, 0.3f, 0.1f, 0.0f}, {-1, -1, -1}, 32));
  cases.push_back(snout_case("snout_vessel_reducer", Snout{2.0f, 1.2f, 1.5f}, {30, 20, 5}, 128));
  // Unequal end shears with an offset or a radius change: the side quads twist.
  cases.push_back(snout_case("snout_twisted_reducer",
                             Snout{0.3f, 0.2f, 0.6f, 0.1f, 0.05f, 15 * kDeg, 0, 0, -20 * kDeg},
                             {2, 2, 2}, 32));
  cases.push_back(snout_case("snout_twisted_offset_cylinder",
                             Snout{0.2f, 0.2f, 0.5f, 0.15f, 0.0f, 0, 0, 25 * kDeg, 0}, {0, 1, 0},
                             32));
  cases.push_back(snout_case("snout_twisted_large",
                             Snout{0.9f, 0.6f, 1.2f, 0.3f, -0.2f, 0, 20 * kDeg, -10 * kDeg, 0},
                             {-20, 30, 5}, 64));

  cases.push_back(degenerate_snout("snout_zero_height", Snout{0.2f, 0.1f, 0.0f}));
  cases.push_back(degenerate_snout("snout_zero_radii", Snout{0.0f, 0.0f, 1.0f}));
  cases.push_back(degenerate_snout("snout_nan_radius", Snout{NAN, 0.1f, 1.0f}));
  cases.push_back(degenerate_snout("snout_negative", Snout{-0.2f, -0.1f, -1.0f}));
  cases.push_back(degenerate_snout("snout_nan_shear_and_offset",
                                   Snout{0.2f, 0.1f, 0.5f, NAN, INFINITY, NAN, 0, 0, -INFINITY}));
  cases.push_back(
      degenerate_snout("snout_right_angle_shear", Snout{0.2f, 0.2f, 0.5f, 0, 0, kPi / 2, 0, 0, 0}));
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(snout_cases)
}  // namespace plantview::testing
