// Cylinder cases: a 0.2 m pipe part, a large vessel shell, degenerate ones.
#include <cmath>
#include <numbers>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// The true surface: side r(cos t, sin t, z) and both discs.
void sample_cylinder(float r, float h, std::vector<glm::vec3>& out) {
  const int around = 512, along = 6, radial = 6;
  for (int i = 0; i < around; ++i) {
    const float t = 2 * kPi * float(i) / around;
    for (int k = 0; k <= along; ++k) {
      out.push_back({r * std::cos(t), r * std::sin(t), -h / 2 + h * float(k) / along});
    }
    for (int k = 1; k <= radial; ++k) {
      const float rr = r * float(k) / radial;
      out.push_back({rr * std::cos(t), rr * std::sin(t), -h / 2});
      out.push_back({rr * std::cos(t), rr * std::sin(t), h / 2});
    }
  }
}

std::vector<uint32_t> ring_solid_counts(uint32_t n_max) {
  std::vector<uint32_t> counts;
  for (uint32_t n = n_max; n >= 4; n /= 2) counts.push_back(4 * n - 4);
  return counts;
}

PrimitiveCase cylinder_case(std::string name, float r, float h, glm::vec3 at,
                            std::vector<uint32_t> counts) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = Cylinder{r, h};
  c.primitive.placement.translation_m = at;
  c.sample_surface = [r, h](std::vector<glm::vec3>& out) { sample_cylinder(r, h, out); };
  c.expected_elements = std::move(counts);
  return c;
}

std::vector<PrimitiveCase> cylinder_cases() {
  std::vector<PrimitiveCase> cases;
  cases.push_back(cylinder_case("cylinder_pipe_0_2m", 0.1f, 1.5f, {1, 2, 3}, ring_solid_counts(32)));
  cases.push_back(cylinder_case("cylinder_vessel_3m", 1.5f, 6.0f, {0, 0, 0}, ring_solid_counts(128)));
  cases.push_back(cylinder_case("cylinder_disc_like", 0.4f, 0.01f, {0, 0, 0}, ring_solid_counts(32)));
  for (auto [name, r, h] : {std::tuple{"cylinder_zero_radius", 0.0f, 1.0f},
                            std::tuple{"cylinder_zero_height", 0.5f, 0.0f},
                            std::tuple{"cylinder_nan_radius", NAN, 1.0f},
                            std::tuple{"cylinder_negative", -1.0f, -1.0f}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = Cylinder{r, h};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(cylinder_cases)
}  // namespace plantview::testing
