// Sphere: a UV sphere of N segments around z and N/2 bands from pole to pole, radial normals.
//
// Vertex layout at level 0 with N segments:
//   [0] north pole (+z); then N/2 - 1 rings from north to south, ring j (1-based) at polar angle
//   2*pi*j/N, vertex i of a ring at azimuth 2*pi*i/N: index 1 + (j - 1) * N + i; last the south
//   pole. 2 + (N/2 - 1) * N vertices.
// Level l uses every 2^l-th ring and every 2^l-th vertex of it: N >> l segments and half as many
// bands, fans at the poles and quads between rings.
//
// Error: a facet's centre lies furthest inside; the facets next to the equator are the worst, at
// r sin^2(pi/N) (the square of the half-segment's sine: both directions' sagittas together).
// Fitted, every vertex scales about the centre by 2 / (2 - sin^2(pi/N)).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

namespace {
constexpr uint32_t kMinSegments = 4;  // an octahedron
}  // namespace

void plan(const Sphere& s, MeshPlan& plan, TemplateKey& key) {
  const float r = sane(s.radius_m);
  if (r == 0.0f) return;  // no volume: empty mesh
  const SegmentExponents e = segment_exponents(2.0f * r);
  const uint32_t n_max = 1u << e.n_max, n_min = std::max(1u << e.n_min, kMinSegments);
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(halving_levels(n_max, n_min));
  plan.vertex_count = 2 + (n_max / 2 - 1) * n_max;
  plan.segments = {uint16_t(n_max), uint16_t(n_max / 2)};
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const float half = std::sin(std::numbers::pi_v<float> / float(segments_at(n_max, n_min, l)));
    plan.error_m[l] = r * half * half;
    plan.straddled_error_m[l] = straddled_deficit(r, half * half);
  }
  key.kind = uint8_t(PrimitiveKind::sphere);
  key.a_max = uint16_t(n_max);
  key.a_min = uint16_t(n_min);
}

void build_template_Sphere(const TemplateKey& key, TemplateBuilder& out) {
  const uint32_t n0 = key.a_max;
  const uint32_t north = 0, south = 1 + (n0 / 2 - 1) * n0;
  for (uint32_t level = 0; level < halving_levels(key.a_max, key.a_min); ++level) {
    const uint32_t n = segments_at(key.a_max, key.a_min, level);
    const uint32_t step = n0 / n, bands = n / 2;
    // Vertex i of the level's ring k (1 .. bands - 1).
    auto ring = [&](uint32_t k, uint32_t i) { return 1 + (k * step - 1) * n0 + (i % n) * step; };
    out.begin_level();
    for (uint32_t i = 0; i < n; ++i) {
      out.triangle(north, ring(1, i), ring(1, i + 1));
      for (uint32_t k = 1; k + 1 < bands; ++k) {
        out.quad(ring(k + 1, i), ring(k + 1, i + 1), ring(k, i + 1), ring(k, i));
      }
      out.triangle(south, ring(bands - 1, i + 1), ring(bands - 1, i));
    }
  }
}

void write(const Sphere& s, const MeshPlan& plan, const VertexSink& sink) {
  float r = sane(s.radius_m);
  const uint32_t n = plan.segments[0];
  if (sink.fitted()) {  // every vertex scales about the centre, by the deficit sin^2(pi/N)
    const uint32_t fit_n = segments_at(n, n >> (plan.level_count - 1u), uint32_t(sink.fit_level));
    const float half = std::sin(std::numbers::pi_v<float> / float(fit_n));
    r *= straddle_scale(half * half);
  }
  sink.put(0, {0, 0, r}, sink.unit_normal({0, 0, 1}));
  for (uint32_t j = 1; j < n / 2; ++j) {
    const glm::vec2 polar = circle_sample(j, n);  // (cos, sin) of the polar angle
    // The unit normal at azimuth (c, s) is (sin c, sin s, cos); the position is r times it.
    const AffineRing unit{{0, 0, polar.x}, {polar.y, 0, 0}, {0, polar.y, 0}, true};
    const AffineRing position{r * unit.centre, r * unit.along_c, r * unit.along_s};
    sink.put_ring(1 + (j - 1) * n, n, position, unit);
  }
  sink.put(plan.vertex_count - 1, {0, 0, -r}, sink.unit_normal({0, 0, -1}));
}

Aabb bounds(const Sphere& s) {
  const float r = sane(s.radius_m);
  return {glm::vec3(-r), glm::vec3(r)};
}

}  // namespace plantview::detail
