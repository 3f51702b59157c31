// Square-to-round cases: HVAC duct transitions (concentric, rectangular, offset, flat), a large
// one, its limits (a pyramid with a zero circle, a cone with a zero rectangle), and degenerate
// ones. 4N - 4 triangles at N segments.
#include <cmath>
#include <numbers>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// The true surface, by perimeter parameter t in [0, 1): the circle point
// top + r(cos 2 pi t, sin 2 pi t, 0) and the rectangle point at t, corners (+x, +y), (-x, +y),
// (-x, -y), (+x, -y) at t = 1/8, 3/8, 5/8, 7/8 and straight between; the lines joining them,
// the rectangle and the disc. `around` values of t, `along` steps on each line.
void sample_square_to_round(const SquareToRound& s, int around, int along,
                            std::vector<glm::vec3>& out) {
  const glm::vec3 bc(-s.offset_x_m / 2, -s.offset_y_m / 2, -s.height_m / 2);
  const glm::vec3 tc(s.offset_x_m / 2, s.offset_y_m / 2, s.height_m / 2);
  const float x = s.bottom_x_m / 2, y = s.bottom_y_m / 2, r = s.top_radius_m;
  const glm::vec3 corner[5] = {{x, y, 0}, {-x, y, 0}, {-x, -y, 0}, {x, -y, 0}, {x, y, 0}};
  for (int i = 0; i < around; ++i) {
    const float t = float(i) / float(around);
    const float u = std::fmod((t - 0.125f) * 4 + 4, 4.0f);
    const int k = std::min(int(u), 3);
    const glm::vec3 b = bc + corner[k] + (u - float(k)) * (corner[k + 1] - corner[k]);
    const glm::vec3 c = tc + r * glm::vec3(std::cos(2 * kPi * t), std::sin(2 * kPi * t), 0);
    for (int j = 0; j <= along; ++j) out.push_back(b + (c - b) * (float(j) / float(along)));
    if (i % 8 == 0) {
      for (float f : {0.3f, 0.7f}) {
        out.push_back(bc + f * (b - bc));
        out.push_back(tc + f * (c - tc));
      }
    }
  }
}

std::vector<uint32_t> counts(uint32_t n_max) {
  std::vector<uint32_t> out;
  for (uint32_t n = n_max; n >= 4; n /= 2) out.push_back(4 * n - 4);
  return out;
}

// n_max: segment_exponents of the larger of the circle's diameter and the rectangle's sides.
PrimitiveCase str_case(std::string name, SquareToRound s, glm::vec3 at, uint32_t n_max) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = s;
  c.primitive.placement.translation_m = at;
  const int around = int(8 * n_max), along = n_max <= 32 ? 8 : 4;
  c.sample_surface = [=](std::vector<glm::vec3>& out) {
    sample_square_to_round(s, around, along, out);
  };
  c.expected_elements = counts(n_max);
  return c;
}

PrimitiveCase degenerate_str(std::string name, SquareToRound s) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = s;
  c.primitive.placement.translation_m = {1, -1, 4};
  c.degenerate = true;
  return c;
}

std::vector<PrimitiveCase> square_to_round_cases() {
  std::vector<PrimitiveCase> cases;
  // Fields: bottom_x, bottom_y, top_radius, height, offset_x, offset_y.
  cases.push_back(str_case("square_to_round_square_duct", SquareToRound{0.5f, 0.5f, 0.25f, 0.4f},
                           {3, 2, 10}, 32));
  cases.push_back(str_case("square_to_round_rectangular_duct",
                           SquareToRound{0.6f, 0.4f, 0.2f, 0.5f}, {-1, 5, 2}, 32));
  cases.push_back(str_case("square_to_round_offset",
                           SquareToRound{0.8f, 0.5f, 0.3f, 0.6f, 0.2f, -0.1f}, {0, 0, 1}, 32));
  cases.push_back(
      str_case("square_to_round_flat", SquareToRound{1.0f, 1.0f, 0.3f, 0.1f}, {2, 2, 2}, 32));
  cases.push_back(str_case("square_to_round_circle_outside", SquareToRound{0.2f, 0.2f, 0.4f, 0.3f},
                           {5, -5, 0}, 32));
  // Rectangle side 2.4 m: 128 segments.
  cases.push_back(
      str_case("square_to_round_large", SquareToRound{2.4f, 1.8f, 1.0f, 1.5f}, {40, 60, 8}, 128));
  cases.push_back(
      str_case("square_to_round_pyramid", SquareToRound{0.5f, 0.4f, 0.0f, 0.5f}, {1, 1, 1}, 32));
  cases.push_back(str_case("square_to_round_cone", SquareToRound{0.0f, 0.0f, 0.3f, 0.5f, 0.1f},
                           {-2, 0, 3}, 32));

  cases.push_back(
      degenerate_str("square_to_round_zero_height", SquareToRound{0.5f, 0.5f, 0.2f, 0}));
  cases.push_back(degenerate_str("square_to_round_zero_ends", SquareToRound{0, 0, 0, 1.0f}));
  cases.push_back(
      degenerate_str("square_to_round_flat_rectangle", SquareToRound{0.5f, 0.0f, 0.2f, 0.5f}));
  cases.push_back(
      degenerate_str("square_to_round_nan", SquareToRound{NAN, 0.5f, NAN, 0.5f, NAN, INFINITY}));
  cases.push_back(
      degenerate_str("square_to_round_negative", SquareToRound{-0.5f, -0.5f, -0.2f, -0.5f}));
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(square_to_round_cases)
}  // namespace plantview::testing
