#include "primitive_mix.h"

#include <cmath>
#include <numbers>
#include <random>

namespace plantview::bench {

namespace {
constexpr float kPi = std::numbers::pi_v<float>;

struct Draw {
  std::mt19937 rng;
  float uniform(float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng); }
  // Diameters log-uniform over 0.05-1 m, with one in 20 a large part of 1-4 m.
  float diameter() {
    if (uniform(0, 1) < 0.05f) return uniform(1.0f, 4.0f);
    return 0.05f * std::pow(20.0f, uniform(0, 1));
  }
  Placement placement() {
    const glm::vec3 axis = glm::normalize(glm::vec3(uniform(-1, 1), uniform(-1, 1), uniform(0.1f, 1)));
    const float angle = uniform(0, 2 * kPi);
    const float c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    const glm::vec3 u = axis;
    Placement p;
    p.linear = glm::mat3(t * u.x * u.x + c, t * u.x * u.y + s * u.z, t * u.x * u.z - s * u.y,
                         t * u.x * u.y - s * u.z, t * u.y * u.y + c, t * u.y * u.z + s * u.x,
                         t * u.x * u.z + s * u.y, t * u.y * u.z - s * u.x, t * u.z * u.z + c);
    p.translation_m = {uniform(0, 120), uniform(0, 34), uniform(0, 31)};
    return p;
  }
};
}  // namespace

std::vector<Primitive> zhou_table1_mix(uint32_t seed, double fraction) {
  Draw d{std::mt19937(seed)};
  std::vector<Primitive> out;
  auto add = [&](int table_count, auto make) {
    const int n = int(std::lround(table_count * fraction));
    for (int i = 0; i < n; ++i) out.push_back(Primitive{d.placement(), make()});
  };
  // Table 1 counts, in its order.
  add(9269, [&] { float a = d.diameter(); return Shape(Box{a, d.uniform(0.5f, 2) * a, d.uniform(0.1f, 6)}); });
  add(134, [&] { float a = d.diameter(); return Shape(Prism{6, 0.5f * a, d.uniform(0.1f, 1)}); });
  add(1547, [&] { float a = d.diameter(); return Shape(Pyramid{a, a, 0, a, 0, 0, 0.5f * a}); });
  add(30354, [&] { float a = d.diameter(); return Shape(Cylinder{0.5f * a, d.uniform(0.05f, 6)}); });
  add(12638, [&] {  // sheared cylinders
    float a = d.diameter();
    return Shape(Snout{0.5f * a, 0.5f * a, d.uniform(0.05f, 3), 0, 0, d.uniform(-0.4f, 0.4f), 0, 0, d.uniform(-0.4f, 0.4f)});
  });
  add(3624, [&] {  // eccentric cones
    float a = d.diameter();
    return Shape(Snout{0.5f * a, 0.35f * a, a, 0.15f * a, 0, 0, 0, 0, 0});
  });
  add(6030, [&] { float a = d.diameter(); return Shape(Snout{0.5f * a, 0.35f * a, a, 0, 0, 0, 0, 0, 0}); });
  add(7881, [&] { float a = d.diameter(); return Shape(CircularTorus{1.5f * a, 0.5f * a, 0.5f * kPi}); });
  add(528, [&] { float a = d.diameter(); return Shape(RectangularTorus{a, 1.5f * a, 0.5f * a, 0.5f * kPi}); });
  add(2904, [&] { return Shape(Sphere{0.5f * d.diameter()}); });
  add(32, [&] { float a = d.uniform(0.3f, 1.0f); return Shape(Saddle{0.3f * a, a, 0.8f * a, 0.55f * a}); });
  add(389, [&] { float a = d.uniform(1.0f, 4.0f); return Shape(EllipticalDish{0.5f * a, 0.25f * a}); });
  return out;
}

}  // namespace plantview::bench
