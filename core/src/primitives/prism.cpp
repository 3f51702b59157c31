// Prism: a right prism over a regular polygon of n = 3..64 corners (Prism::sides, clamped),
// flat-shaded: every side face has its own four vertices and normal, each cap its own corners.
// One level, no error (the mesh is the shape). The template key holds n (a_max).
//
// Vertex layout (6n vertices): corner i lies at angle 2*pi*i/n on the circumradius.
//   [0, 4n) side faces, face i owning b_i b_{i+1} t_{i+1} t_i (counter-clockwise from outside);
//   [4n, 5n) bottom cap corners b_i, [5n, 6n) top cap corners t_i.
// Triangles: two per side face, caps fanned from corner 0 (n - 2 each): 4n - 4 in all.
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

namespace {

constexpr uint32_t kMinSides = 3, kMaxSides = 64;

uint32_t sides_of(const Prism& p) {
  return p.sides < kMinSides ? kMinSides : p.sides > kMaxSides ? kMaxSides : p.sides;
}

// The n unit-circle corners; every face and cap reads them from here, so shared edges match.
void unit_corners(uint32_t n, glm::vec2 (&out)[kMaxSides]) {
  for (uint32_t i = 0; i < n; ++i) {
    const double a = 2.0 * std::numbers::pi * double(i) / double(n);
    out[i] = {float(std::cos(a)), float(std::sin(a))};
  }
}

}  // namespace

void plan(const Prism& p, MeshPlan& plan, TemplateKey& key) {
  if (sane(p.radius_m) == 0.0f || sane(p.height_m) == 0.0f) return;
  const uint32_t n = sides_of(p);
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = 1;
  plan.vertex_count = 6 * n;
  plan.error_m[0] = 0.0f;
  key.kind = uint8_t(PrimitiveKind::prism);
  key.a_max = key.a_min = uint16_t(n);
}

void build_template_Prism(const TemplateKey& key, TemplateBuilder& out) {
  const uint32_t n = key.a_max;
  out.begin_level();
  for (uint32_t i = 0; i < n; ++i) out.quad(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3);
  const uint32_t bottom = 4 * n, top = 5 * n;
  for (uint32_t k = 1; k + 1 < n; ++k) {
    out.triangle(bottom, bottom + k + 1, bottom + k);
    out.triangle(top, top + k, top + k + 1);
  }
}

void write(const Prism& p, const MeshPlan&, const VertexSink& sink) {
  const uint32_t n = sides_of(p);
  const float r = sane(p.radius_m), h2 = 0.5f * sane(p.height_m);
  glm::vec2 unit[kMaxSides];
  unit_corners(n, unit);
  const uint32_t down = sink.normal({0, 0, -1}), up = sink.normal({0, 0, 1});
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t j = (i + 1) % n;
    const glm::vec3 b0(r * unit[i], -h2), b1(r * unit[j], -h2);
    const glm::vec3 t0(r * unit[i], h2), t1(r * unit[j], h2);
    // The side's outward normal bisects its two corners.
    const glm::vec2 mid = unit[i] + unit[j];
    const uint32_t side = sink.normal({mid, 0.0f});
    sink.put(4 * i, b0, side);
    sink.put(4 * i + 1, b1, side);
    sink.put(4 * i + 2, t1, side);
    sink.put(4 * i + 3, t0, side);
    sink.put(4 * n + i, b0, down);
    sink.put(5 * n + i, t0, up);
  }
}

Aabb bounds(const Prism& p) {
  const uint32_t n = sides_of(p);
  const float r = sane(p.radius_m), h2 = 0.5f * sane(p.height_m);
  glm::vec2 unit[kMaxSides];
  unit_corners(n, unit);
  glm::vec2 lo = r * unit[0], hi = lo;
  for (uint32_t i = 1; i < n; ++i) {
    lo = glm::min(lo, r * unit[i]);
    hi = glm::max(hi, r * unit[i]);
  }
  return {{lo, -h2}, {hi, h2}};
}

}  // namespace plantview::detail
