// Line cases: a pipe centreline (the "smart line" of a far pipeline), a segment drawn towards -x,
// and degenerate ones. One line each (primitives.h). The generic error test skips lines; the
// sampler is given anyway so that it would measure the segment if it did not.
#include <cmath>
#include <limits>
#include <numbers>
#include <tuple>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

PrimitiveCase line_case(std::string name, float start_x, float end_x, Placement placement) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = Line{start_x, end_x};
  c.primitive.placement = placement;
  c.sample_surface = [start_x, end_x](std::vector<glm::vec3>& out) {
    for (int i = 0; i <= 16; ++i)
      out.push_back({start_x + (end_x - start_x) * float(i) / 16, 0, 0});
  };
  c.expected_elements = {1};
  return c;
}

std::vector<PrimitiveCase> line_cases() {
  constexpr float kPi = std::numbers::pi_v<float>;
  std::vector<PrimitiveCase> cases;
  // A 12.5 m pipe run's centreline, turned to run along y, 30 m up.
  cases.push_back(line_case("line_pipe_centreline", 0.0f, 12.5f,
                            {rotation_about({0, 0, 1}, kPi / 2), {150.0f, -20.0f, 30.0f}}));
  cases.push_back(line_case("line_towards_negative_x", 3.0f, -2.0f, {glm::mat3(1.0f), {1, 2, 3}}));
  cases.push_back(line_case("line_short_offset", 0.25f, 0.3f, {glm::mat3(1.0f), {0, 0, 0}}));

  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (auto [name, start, end] :
       {std::tuple{"line_zero_length", 1.5f, 1.5f}, std::tuple{"line_nan_both", nan, nan},
        std::tuple{"line_nan_start", nan, 2.0f}, std::tuple{"line_infinite_end", 0.0f, inf}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = Line{start, end};
    c.primitive.placement.translation_m = {1.0f, 2.0f, 3.0f};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(line_cases)
}  // namespace plantview::testing
