// Box cases: structural steel (a 0.2 x 0.3 x 6 m beam), a plate, a rotated block away from the
// origin, and degenerate sizes. 12 triangles each (primitives.h).
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

// Points on the parallelogram p + s*a + t*b, s and t in [0, 1].
void sample_face(glm::vec3 p, glm::vec3 a, glm::vec3 b, std::vector<glm::vec3>& out) {
  const int steps = 8;
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; j <= steps; ++j) {
      out.push_back(p + a * (float(i) / steps) + b * (float(j) / steps));
    }
  }
}

// The true surface: the six faces of the box [-size/2, size/2].
void sample_box(glm::vec3 size, std::vector<glm::vec3>& out) {
  const glm::vec3 lo = -0.5f * size;
  const glm::vec3 ax(size.x, 0, 0), ay(0, size.y, 0), az(0, 0, size.z);
  sample_face(lo, ay, az, out);
  sample_face(lo + ax, ay, az, out);
  sample_face(lo, ax, az, out);
  sample_face(lo + ay, ax, az, out);
  sample_face(lo, ax, ay, out);
  sample_face(lo + az, ax, ay, out);
}

PrimitiveCase box_case(std::string name, glm::vec3 size, Placement placement) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = Box{size.x, size.y, size.z};
  c.primitive.placement = placement;
  c.sample_surface = [size](std::vector<glm::vec3>& out) { sample_box(size, out); };
  c.expected_elements = {12};
  return c;
}

Placement at(glm::vec3 translation_m, glm::mat3 linear = glm::mat3(1.0f)) {
  return {linear, translation_m};
}

std::vector<PrimitiveCase> box_cases() {
  constexpr float kPi = std::numbers::pi_v<float>;
  std::vector<PrimitiveCase> cases;
  // A 6 m steel beam 0.2 x 0.3 standing 40 m up in a pipe rack, 120 m from the origin.
  cases.push_back(box_case("box_steel_beam_6m", {0.2f, 0.3f, 6.0f}, at({120.0f, -35.5f, 40.0f})));
  // The same beam lying along the rack: rotated a quarter turn about y, then 30 degrees about z.
  cases.push_back(box_case("box_steel_beam_rotated", {0.2f, 0.3f, 6.0f},
                           at({12.0f, 8.0f, 6.5f}, rotation_about({0, 0, 1}, kPi / 6) *
                                                       rotation_about({0, 1, 0}, kPi / 2))));
  cases.push_back(box_case("box_floor_plate", {2.0f, 1.0f, 0.01f}, at({3.0f, 4.0f, 0.5f})));
  cases.push_back(box_case("box_unit_cube", {1.0f, 1.0f, 1.0f}, at({0, 0, 0})));
  // A concrete foundation block, scaled by the placement (1.5 in all directions).
  cases.push_back(box_case("box_foundation_scaled", {4.0f, 3.0f, 1.2f},
                           at({-20.0f, 15.0f, -0.6f}, glm::mat3(1.5f))));

  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (auto [name, size] : {std::pair{"box_zero_x", glm::vec3(0.0f, 1.0f, 1.0f)},
                            std::pair{"box_zero_z", glm::vec3(0.2f, 0.3f, 0.0f)},
                            std::pair{"box_all_zero", glm::vec3(0.0f)},
                            std::pair{"box_nan_y", glm::vec3(1.0f, nan, 1.0f)},
                            std::pair{"box_infinite_x", glm::vec3(inf, 1.0f, 1.0f)},
                            std::pair{"box_negative", glm::vec3(-0.2f, 0.3f, 6.0f)}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = Box{size.x, size.y, size.z};
    c.primitive.placement.translation_m = {1.0f, 2.0f, 3.0f};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(box_cases)
}  // namespace plantview::testing
