// Elliptical dish cases: 2:1 vessel heads of 1 to 4 m, a hemispherical and a tall head, a shallow
// one, and degenerate ones.
#include <cmath>
#include <numbers>
#include <string>
#include <tuple>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// The true surface: (r cos b cos t, r cos b sin t, h sin b) for latitude b in [0, pi/2], and the
// base disc. The mesh deviates most midway between vertices; by the shape's symmetry the first
// segment around of every power-of-two subdivision s stands for all others. So: meridians (8
// samples per finest band) at azimuth pi/s for every s and on the axes, and rings (8 samples per
// finest segment around) on the base, in the middle of the lowest finest band and at 45 degrees.
void sample_elliptical_dish(float r, float h, uint32_t around, uint32_t bands,
                            std::vector<glm::vec3>& out) {
  auto point = [&](float t, float b) {
    return glm::vec3(r * std::cos(b) * std::cos(t), r * std::cos(b) * std::sin(t), h * std::sin(b));
  };
  std::vector<float> azimuths = {0, kPi / 2, kPi, 3 * kPi / 2};
  for (uint32_t s = 4; s <= around; s *= 2) azimuths.push_back(kPi / float(s));
  const uint32_t up = 8 * bands;
  for (float t : azimuths) {
    for (uint32_t k = 0; k <= up; ++k) out.push_back(point(t, kPi / 2 * float(k) / float(up)));
  }
  const uint32_t ring = 8 * around;
  for (float b : {0.0f, kPi / float(4 * bands), kPi / 4}) {
    for (uint32_t i = 0; i < ring; ++i) out.push_back(point(2 * kPi * float(i) / float(ring), b));
  }
  out.push_back({0, 0, 0});
  for (float f : {1.0f / 3, 2.0f / 3}) {
    for (uint32_t i = 0; i < around; ++i) {
      out.push_back(f * point(2 * kPi * float(i) / float(around), 0));
    }
  }
}

// N around and B = N/4 bands: 2N triangles per band but N in the apex band, N - 2 in the base
// disc, so 2NB - 2; N halves per level down to 4.
std::vector<uint32_t> dish_counts(uint32_t around) {
  std::vector<uint32_t> counts;
  for (uint32_t n = around; n >= 4; n /= 2) counts.push_back(2 * n * (n / 4) - 2);
  return counts;
}

PrimitiveCase elliptical_dish_case(std::string name, float r, float h, uint32_t around,
                                   glm::vec3 at) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = EllipticalDish{r, h};
  c.primitive.placement.translation_m = at;
  c.sample_surface = [r, h, around](std::vector<glm::vec3>& out) {
    sample_elliptical_dish(r, h, around, around / 4, out);
  };
  c.expected_elements = dish_counts(around);
  return c;
}

std::vector<PrimitiveCase> elliptical_dish_cases() {
  std::vector<PrimitiveCase> cases;
  // N from the size rule on the base diameter.
  const std::tuple<const char*, float, float, uint32_t, glm::vec3> typical[] = {
      {"elliptical_dish_2to1_head_1m", 0.5f, 0.25f, 32, {1, 2, 3}},
      {"elliptical_dish_2to1_head_2m", 1.0f, 0.5f, 64, {-10, 4, 0}},
      {"elliptical_dish_2to1_head_4m", 2.0f, 1.0f, 128, {0, 0, 12}},
      {"elliptical_dish_hemisphere_1_5m", 0.75f, 0.75f, 64, {5, 5, 5}},
      {"elliptical_dish_tall", 0.3f, 0.9f, 32, {0, -2, 0}},
      {"elliptical_dish_shallow", 0.5f, 0.05f, 32, {0, 0, 0}},
  };
  for (const auto& [name, r, h, around, at] : typical) {
    cases.push_back(elliptical_dish_case(name, r, h, around, at));
  }
  PrimitiveCase rotated =
      elliptical_dish_case("elliptical_dish_rotated_bottom_head", 1.0f, 0.5f, 64, {3, 4, 1});
  rotated.primitive.placement.linear = rotation_about({1, 0, 0}, kPi);  // a vessel's bottom head
  cases.push_back(rotated);

  for (auto [name, r, h] : {std::tuple{"elliptical_dish_zero_radius", 0.0f, 0.5f},
                            std::tuple{"elliptical_dish_zero_height", 0.5f, 0.0f},
                            std::tuple{"elliptical_dish_negative", -0.5f, -0.25f},
                            std::tuple{"elliptical_dish_nan_radius", NAN, 0.25f},
                            std::tuple{"elliptical_dish_nan_height", 0.5f, NAN},
                            std::tuple{"elliptical_dish_infinite", INFINITY, 0.25f},
                            std::tuple{"elliptical_dish_huge", 3e38f, 3e38f}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = EllipticalDish{r, h};
    c.degenerate = true;
    cases.push_back(c);
  }
  // Extreme but finite proportions must stay valid.
  PrimitiveCase needle;
  needle.name = "elliptical_dish_needle";
  needle.primitive.shape = EllipticalDish{1e-6f, 1e3f};
  needle.expected_elements = dish_counts(32);
  needle.degenerate = true;
  cases.push_back(needle);
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(elliptical_dish_cases)
}  // namespace plantview::testing
