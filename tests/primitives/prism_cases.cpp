// Prism cases: hexagonal and octagonal columns, a triangular prism, the 64-sided limit, side counts
// clamped into 3..64, and degenerate sizes. Counts (primitives.h): 4n - 4 triangles for n sides.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

// Points on the bilinear patch p00 p10 p11 p01.
void sample_patch(glm::vec3 p00, glm::vec3 p10, glm::vec3 p11, glm::vec3 p01,
                  std::vector<glm::vec3>& out) {
  const int steps = 6;
  for (int i = 0; i <= steps; ++i) {
    const float s = float(i) / steps;
    for (int j = 0; j <= steps; ++j) {
      const float t = float(j) / steps;
      out.push_back((1 - s) * (1 - t) * p00 + s * (1 - t) * p10 + s * t * p11 + (1 - s) * t * p01);
    }
  }
}

// The true surface: n side rectangles and both caps (sampled as triangles from the centre).
void sample_prism(uint32_t n, float r, float h, std::vector<glm::vec3>& out) {
  for (uint32_t i = 0; i < n; ++i) {
    const double a0 = 2 * std::numbers::pi * i / n, a1 = 2 * std::numbers::pi * (i + 1) / n;
    const glm::vec2 c0(r * std::cos(a0), r * std::sin(a0)), c1(r * std::cos(a1), r * std::sin(a1));
    sample_patch({c0, -h / 2}, {c1, -h / 2}, {c1, h / 2}, {c0, h / 2}, out);
    for (float z : {-h / 2, h / 2}) {
      const glm::vec3 centre(0, 0, z);
      sample_patch(centre, {c0, z}, {c1, z}, centre, out);
    }
  }
}

PrimitiveCase prism_case(std::string name, uint32_t sides, float r, float h, Placement placement) {
  const uint32_t n = std::clamp(sides, 3u, 64u);
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = Prism{sides, r, h};
  c.primitive.placement = placement;
  c.sample_surface = [n, r, h](std::vector<glm::vec3>& out) { sample_prism(n, r, h, out); };
  c.expected_elements = {4 * n - 4};
  return c;
}

std::vector<PrimitiveCase> prism_cases() {
  constexpr float kPi = std::numbers::pi_v<float>;
  std::vector<PrimitiveCase> cases;
  // A hexagonal column 0.3 m across corners, 2 m high, 80 m from the origin.
  cases.push_back(
      prism_case("prism_hexagon_column", 6, 0.15f, 2.0f, {glm::mat3(1.0f), {80.0f, 12.0f, 1.0f}}));
  cases.push_back(prism_case("prism_triangle", 3, 0.5f, 0.2f, {glm::mat3(1.0f), {0, 0, 0}}));
  // An octagonal pier, lying along x.
  cases.push_back(prism_case("prism_octagon_lying", 8, 0.6f, 3.0f,
                             {rotation_about({0, 1, 0}, kPi / 2), {-4.0f, 2.0f, 0.6f}}));
  cases.push_back(
      prism_case("prism_64_sides", 64, 1.0f, 0.5f, {glm::mat3(1.0f), {1.0f, 1.0f, 1.0f}}));
  cases.push_back(
      prism_case("prism_odd_7_sides", 7, 0.25f, 0.75f, {glm::mat3(2.0f), {3.0f, 0, -1.0f}}));
  // Side counts outside 3..64 are clamped.
  cases.push_back(
      prism_case("prism_sides_0_clamped_to_3", 0, 0.4f, 0.4f, {glm::mat3(1.0f), {0, 5, 0}}));
  cases.push_back(prism_case("prism_sides_1000_clamped_to_64", 1000, 0.4f, 0.4f,
                             {glm::mat3(1.0f), {0, -5, 0}}));

  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (auto [name, shape] : {std::pair{"prism_zero_radius", Prism{6, 0.0f, 1.0f}},
                             std::pair{"prism_zero_height", Prism{6, 1.0f, 0.0f}},
                             std::pair{"prism_nan_radius", Prism{6, nan, 1.0f}},
                             std::pair{"prism_negative", Prism{6, -1.0f, -1.0f}}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = shape;
    c.primitive.placement.translation_m = {1.0f, 1.0f, 1.0f};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(prism_cases)
}  // namespace plantview::testing
