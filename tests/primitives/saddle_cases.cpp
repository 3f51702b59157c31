// Saddle cases: a vessel saddle, a pipe support, a half-circle cradle, a shallow cradle under a
// large radius, the two clamps (radius to width/2, height to the cradle depth), and degenerate
// sizes. 8A + 4 triangles at A arc segments.
#include <cmath>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

// The true surface of the block [-L/2, L/2] x [-W/2, W/2] x [0, H] under the cylinder of radius R
// about the axis (y, z) = (0, H + sqrt(R^2 - W^2/4)): the cradle (`arc_steps` angles, each at
// five x), both ends below the arc, the bottom and the two sides. Parameters already clamped.
void sample_saddle(float l, float w, float h, float r, int arc_steps, std::vector<glm::vec3>& out) {
  const float beta = std::asin(w / (2 * r));
  const float axis_z = h + std::sqrt(r * r - w * w / 4);
  const int flat = 8;
  for (int i = 0; i <= arc_steps; ++i) {
    const float t = -beta + 2 * beta * float(i) / float(arc_steps);
    const float y = r * std::sin(t), z = axis_z - r * std::cos(t);
    for (int k = 0; k <= 4; ++k) out.push_back({-l / 2 + l * float(k) / 4, y, z});
    if (i % 8 == 0) {
      for (int k = 0; k < flat; ++k) {
        const float zz = z * float(k) / flat;
        out.push_back({-l / 2, y, zz});
        out.push_back({l / 2, y, zz});
      }
    }
  }
  for (int i = 0; i <= flat; ++i) {
    for (int k = 0; k <= flat; ++k) {
      const float x = -l / 2 + l * float(i) / flat;
      out.push_back({x, -w / 2 + w * float(k) / flat, 0});
      out.push_back({x, -w / 2, h * float(k) / flat});
      out.push_back({x, w / 2, h * float(k) / flat});
    }
  }
}

// Triangle counts from a_max arc segments down to a_min.
std::vector<uint32_t> saddle_counts(uint32_t a_max, uint32_t a_min) {
  std::vector<uint32_t> counts;
  for (uint32_t a = a_max; a >= a_min; a /= 2) counts.push_back(8 * a + 4);
  return counts;
}

// The Saddle as given, and the clamped block the sampler sees.
PrimitiveCase saddle_case(std::string name, Saddle given, glm::vec3 at, float clamped_radius,
                          float clamped_height, uint32_t a_max, uint32_t a_min) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = given;
  c.primitive.placement.translation_m = at;
  const float l = given.length_m, w = given.width_m;
  const int arc_steps = int(8 * a_max);
  c.sample_surface = [=](std::vector<glm::vec3>& out) {
    sample_saddle(l, w, clamped_height, clamped_radius, arc_steps, out);
  };
  c.expected_elements = saddle_counts(a_max, a_min);
  return c;
}

PrimitiveCase degenerate_saddle(std::string name, Saddle s) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = s;
  c.primitive.placement.translation_m = {-5, 2, 0};
  c.degenerate = true;
  return c;
}

std::vector<PrimitiveCase> saddle_cases() {
  std::vector<PrimitiveCase> cases;
  // Fields: length (x), width (y), height (z), cradle radius.
  // 3 m vessel: 128 circle segments, beta = asin(0.8): 128 * 0.927 / pi = 37.8 -> 64 arc segments.
  cases.push_back(saddle_case("saddle_vessel_3m", Saddle{0.3f, 2.4f, 1.0f, 1.5f}, {10, 5, 0}, 1.5f,
                              1.0f, 64, 2));
  // 0.4 m pipe: 32 circle segments, beta = asin(0.75): 32 * 0.848 / pi = 8.6 -> 16.
  cases.push_back(saddle_case("saddle_pipe_support", Saddle{0.1f, 0.3f, 0.25f, 0.2f}, {1, -2, 3},
                              0.2f, 0.25f, 16, 2));
  // Half-circle cradle: beta = pi/2, half of the circle's 32 segments.
  cases.push_back(saddle_case("saddle_half_circle", Saddle{0.2f, 1.0f, 0.8f, 0.5f}, {0, 0, 2}, 0.5f,
                              0.8f, 16, 2));
  // Shallow cradle: a 10 m circle has 256 segments, beta = asin(0.05): 256 * 0.05 / pi = 4.1 -> 8.
  cases.push_back(saddle_case("saddle_shallow_cradle", Saddle{0.4f, 0.5f, 0.3f, 5.0f}, {3, 3, -1},
                              5.0f, 0.3f, 8, 1));
  // Radius below width/2: clamped to the half-circle of radius 0.4.
  cases.push_back(saddle_case("saddle_radius_clamped", Saddle{0.2f, 0.8f, 0.6f, 0.1f}, {0, 7, 0},
                              0.4f, 0.6f, 16, 2));
  // Thin web: R = 0.5 and W = 0.6 make a 0.1 m deep cradle in a 0.12 m block. 32 circle
  // segments, beta = asin(0.6): 32 * 0.644 / pi = 6.6 -> 8, floor 4 * 0.644 / pi -> 1.
  cases.push_back(saddle_case("saddle_thin_web", Saddle{0.25f, 0.6f, 0.12f, 0.5f}, {-2, 0, 1}, 0.5f,
                              0.12f, 8, 1));
  // Thin plate: a 2 cm saddle plate under a 1.6 m vessel; 64 circle segments, beta = asin(0.75):
  // 64 * 0.848 / pi = 17.3 -> 32, floor 4 * 0.848 / pi -> 2.
  cases.push_back(saddle_case("saddle_thin_plate", Saddle{0.02f, 1.2f, 0.6f, 0.8f}, {4, -4, 0},
                              0.8f, 0.6f, 32, 2));

  cases.push_back(degenerate_saddle("saddle_zero_length", Saddle{0.0f, 1.0f, 1.0f, 0.5f}));
  cases.push_back(degenerate_saddle("saddle_zero_width", Saddle{0.3f, 0.0f, 1.0f, 0.5f}));
  // Height clamped to the depth: the cradle touches the ground along a line (not a manifold).
  cases.push_back(degenerate_saddle("saddle_zero_height", Saddle{0.3f, 1.0f, 0.0f, 0.5f}));
  cases.push_back(degenerate_saddle("saddle_nan", Saddle{NAN, 1.0f, NAN, NAN}));
  cases.push_back(degenerate_saddle("saddle_negative", Saddle{-0.3f, -1.0f, -1.0f, -0.5f}));
  cases.push_back(degenerate_saddle("saddle_infinite_radius", Saddle{0.3f, 1.0f, 0.5f, INFINITY}));
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(saddle_cases)
}  // namespace plantview::testing
