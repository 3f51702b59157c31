// Sphere cases: a small fitting, a 1 m ball, a 3 m spherical vessel away from the origin, and
// degenerate radii. 2N(N/2 - 1) triangles at N segments (primitives.h).
#include <cmath>
#include <numbers>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Points r(sin p cos a, sin p sin a, cos p) for a in [a0, a0 + span], p in [p0, p0 + span] on a
// (steps + 1)^2 grid.
void sample_patch(float r, float a0, float p0, float span, int steps, std::vector<glm::vec3>& out) {
  for (int i = 0; i <= steps; ++i) {
    const float a = a0 + span * float(i) / float(steps);
    for (int k = 0; k <= steps; ++k) {
      const float p = p0 + span * float(k) / float(steps);
      out.push_back(r *
                    glm::vec3(std::sin(p) * std::cos(a), std::sin(p) * std::sin(a), std::cos(p)));
    }
  }
}

// The true surface. The sphere and its tessellation share the symmetries of an octant (mirror
// planes x = 0, y = 0, z = 0 and x = y), so one octant holds every distinct deviation: sampled
// with `octant_steps` per quarter turn (8 per finest segment up to 32 segments), plus `fine_steps`
// over the 64th of a turn next to the equator, where facets deviate most.
void sample_sphere(float r, int octant_steps, int fine_steps, std::vector<glm::vec3>& out) {
  sample_patch(r, 0.0f, 0.0f, kPi / 2, octant_steps, out);
  if (fine_steps > 0) sample_patch(r, 0.0f, kPi / 2 - kPi / 32, kPi / 32, fine_steps, out);
}

std::vector<uint32_t> uv_sphere_counts(uint32_t n_max) {
  std::vector<uint32_t> counts;
  for (uint32_t n = n_max; n >= 4; n /= 2) counts.push_back(2 * n * (n / 2 - 1));
  return counts;
}

PrimitiveCase sphere_case(std::string name, float r, glm::vec3 at, uint32_t n_max) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = Sphere{r};
  c.primitive.placement.translation_m = at;
  // 8 samples per finest segment: octant-wide up to 32 segments, near the equator beyond.
  const int octant_steps = n_max <= 32 ? int(2 * n_max) : 32;
  const int fine_steps = n_max <= 32 ? 0 : int(n_max / 8);
  c.sample_surface = [=](std::vector<glm::vec3>& out) {
    sample_sphere(r, octant_steps, fine_steps, out);
  };
  c.expected_elements = uv_sphere_counts(n_max);
  return c;
}

std::vector<PrimitiveCase> sphere_cases() {
  std::vector<PrimitiveCase> cases;
  cases.push_back(sphere_case("sphere_fitting_0_1m", 0.05f, {1, 2, 3}, 32));
  cases.push_back(sphere_case("sphere_ball_1m", 0.5f, {-4, 0.5f, 2}, 32));
  cases.push_back(sphere_case("sphere_vessel_3m", 1.5f, {120, -40, 15}, 128));
  for (auto [name, r] : {std::pair{"sphere_zero_radius", 0.0f}, std::pair{"sphere_nan_radius", NAN},
                         std::pair{"sphere_negative_radius", -1.0f},
                         std::pair{"sphere_infinite_radius", INFINITY}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = Sphere{r};
    c.primitive.placement.translation_m = {2, 2, 2};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(sphere_cases)
}  // namespace plantview::testing
