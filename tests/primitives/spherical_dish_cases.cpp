// Spherical dish cases: shallow and vessel-head caps, a hemisphere, caps beyond a hemisphere up to
// a near sphere, a very flat one, and degenerate ones.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <tuple>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// The true surface: the sphere of radius R = (r^2 + h^2)/2h centred at (0, 0, h - R), for polar
// angles a (from the apex) up to the base circle's, and the base disc. The mesh deviates most
// midway between vertices; by the shape's symmetry the first segment around of every
// power-of-two subdivision s stands for all others. So: meridians (8 samples per finest band) at
// azimuth pi/s for every s and on the axes, and rings (8 samples per finest segment around) on
// the base, in the middle of the lowest finest band and on the widest circle.
void sample_spherical_dish(float r, float h, uint32_t around, uint32_t bands,
                           std::vector<glm::vec3>& out) {
  const double sphere = (double(r) * r + double(h) * h) / (2.0 * h);
  const double polar_max = std::atan2(double(r), sphere - h);
  auto point = [&](double t, double a) {
    return glm::vec3(float(sphere * std::sin(a) * std::cos(t)),
                     float(sphere * std::sin(a) * std::sin(t)),
                     float(h - sphere * (1 - std::cos(a))));
  };
  std::vector<double> azimuths = {0, kPi / 2, kPi, 3 * kPi / 2};
  for (uint32_t s = 4; s <= around; s *= 2) azimuths.push_back(std::numbers::pi / s);
  const uint32_t down = 8 * bands;
  for (double t : azimuths) {
    for (uint32_t k = 0; k <= down; ++k) out.push_back(point(t, polar_max * k / down));
  }
  const uint32_t ring = 8 * around;
  const double widest = std::min(polar_max, std::numbers::pi / 2);
  for (double a : {polar_max, polar_max * (1 - 0.5 / bands), widest}) {
    for (uint32_t i = 0; i < ring; ++i) out.push_back(point(2 * std::numbers::pi * i / ring, a));
  }
  out.push_back({0, 0, 0});
  for (float f : {1.0f / 3, 2.0f / 3}) {
    for (uint32_t i = 0; i < around; ++i) {
      const float t = 2 * kPi * float(i) / float(around);
      out.push_back({f * r * std::cos(t), f * r * std::sin(t), 0});
    }
  }
}

// N around and B bands: 2NB - 2 triangles (2N per band but N in the apex band, N - 2 in the base
// disc); per level N halves down to 4 and B down to 1.
std::vector<uint32_t> dish_counts(uint32_t around, uint32_t bands) {
  std::vector<uint32_t> counts;
  for (uint32_t n = around, b = bands; n >= 4; n /= 2, b = std::max(b / 2, 1u)) {
    counts.push_back(2 * n * b - 2);
  }
  return counts;
}

PrimitiveCase spherical_dish_case(std::string name, float r, float h, uint32_t around,
                                  uint32_t bands, glm::vec3 at) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = SphericalDish{r, h};
  c.primitive.placement.translation_m = at;
  c.sample_surface = [r, h, around, bands](std::vector<glm::vec3>& out) {
    sample_spherical_dish(r, h, around, bands, out);
  };
  c.expected_elements = dish_counts(around, bands);
  return c;
}

std::vector<PrimitiveCase> spherical_dish_cases() {
  // N from the size rule on the widest diameter (the base, or the sphere beyond a hemisphere);
  // B the power of two nearest polar_max / (2 pi/N).
  std::vector<PrimitiveCase> cases;
  const std::tuple<const char*, float, float, uint32_t, uint32_t, glm::vec3> typical[] = {
      // R = 0.908, polar 0.583 rad: 2.97 -> 4 bands.
      {"spherical_dish_shallow_1m", 0.5f, 0.15f, 32, 4, {1, 2, 3}},
      // A 3 m head dished to R = 3 m: polar 0.521 rad, 128 around: 10.6 -> 8 bands.
      {"spherical_dish_vessel_head_3m", 1.5f, 0.4f, 128, 8, {0, 0, 9}},
      // Hemisphere: 64 around (2 m), polar pi/2: 16 bands.
      {"spherical_dish_hemisphere_2m", 1.0f, 1.0f, 64, 16, {-6, 2, 1}},
      // Beyond a hemisphere: R = 0.34, polar 2.06 rad: 10.5 -> 8 bands.
      {"spherical_dish_deep", 0.3f, 0.5f, 32, 8, {2, -1, 0}},
      // Nearly a sphere: R = 0.505 (1.01 m: 64 around), polar 2.94 rad: 30 -> 32 bands.
      {"spherical_dish_near_sphere", 0.1f, 1.0f, 64, 32, {0, 0, 0}},
      // Very flat: R = 50, polar 0.02 rad: one band.
      {"spherical_dish_very_flat", 1.0f, 0.01f, 64, 1, {4, 4, 0}},
  };
  for (const auto& [name, r, h, around, bands, at] : typical) {
    cases.push_back(spherical_dish_case(name, r, h, around, bands, at));
  }
  PrimitiveCase rotated =
      spherical_dish_case("spherical_dish_rotated", 0.5f, 0.15f, 32, 4, {-2, 7, 3});
  rotated.primitive.placement.linear = rotation_about({0, 1, 0}, kPi / 2);
  cases.push_back(rotated);

  for (auto [name, r, h] : {std::tuple{"spherical_dish_zero_radius", 0.0f, 0.5f},
                            std::tuple{"spherical_dish_zero_height", 0.5f, 0.0f},
                            std::tuple{"spherical_dish_negative", -0.5f, -0.25f},
                            std::tuple{"spherical_dish_nan_radius", NAN, 0.25f},
                            std::tuple{"spherical_dish_nan_height", 0.5f, NAN},
                            std::tuple{"spherical_dish_infinite", 0.5f, INFINITY},
                            std::tuple{"spherical_dish_huge", 3e38f, 3e38f}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = SphericalDish{r, h};
    c.degenerate = true;
    cases.push_back(c);
  }
  // Extreme but finite proportions must stay valid.
  for (auto [name, r, h] : {std::tuple{"spherical_dish_denormal_height", 1.0f, 1e-40f},
                            std::tuple{"spherical_dish_needle", 1e-7f, 1.0f}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = SphericalDish{r, h};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(spherical_dish_cases)
}  // namespace plantview::testing
