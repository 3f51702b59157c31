// Elliptical dish (vessel head): the upper half of an ellipsoid of semi-axes r, r, h, as N
// segments around and B = N/4 latitude bands from the base ring to the apex, on a flat base disc.
// Shading is smooth over the dome and sharp at the base rim.
//
// Vertex layout at level 0 with N segments around and B bands (shared with spherical_dish.cpp):
//   rings k = 0..B-1 at [k*N, (k+1)*N), ring 0 on the base (z = 0), ring k at latitude
//   (pi/2)*k/B; vertex i of a ring at azimuth 2*pi*i/N;
//   the apex at B*N;
//   the base disc [B*N + 1, B*N + 1 + N), vertex i at the place of vertex i of ring 0.
// Level l uses every 2^l-th ring and every 2^l-th vertex of each (never fewer than 4 around and
// 1 band): band quads, apex triangles, and the disc fanned from its vertex 0.
#include <algorithm>
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

// The index template of a dish: a = segments around (floor 4), b = bands (floor 1).
void build_dish_template(const TemplateKey& key, TemplateBuilder& out) {
  const uint32_t n0 = key.a_max, b0 = key.b_max;
  const uint32_t apex = b0 * n0, disc = apex + 1;
  for (uint32_t level = 0; level < halving_levels(key.a_max, key.a_min); ++level) {
    const uint32_t n = segments_at(key.a_max, key.a_min, level);
    const uint32_t bands = segments_at(key.b_max, key.b_min, level);
    const uint32_t step = n0 / n, ring_step = b0 / bands;
    out.begin_level();
    for (uint32_t k = 0; k < bands; ++k) {
      const uint32_t ring = k * ring_step * n0, next = (k + 1) * ring_step * n0;
      for (uint32_t i = 0; i < n; ++i) {
        const uint32_t a = i * step, b = ((i + 1) % n) * step;
        if (k + 1 == bands) {
          out.triangle(ring + a, ring + b, apex);
        } else {
          out.quad(ring + a, ring + b, next + b, next + a);
        }
      }
    }
    for (uint32_t k = 1; k + 1 < n; ++k) out.triangle(disc, disc + (k + 1) * step, disc + k * step);
  }
}

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

struct EllipticalDishParams {
  float radius_m = 0, height_m = 0;
  SegmentExponents around;
};

// The sanitised shape; radius_m == 0 means an empty mesh.
EllipticalDishParams params_of(const EllipticalDish& d) {
  EllipticalDishParams p;
  p.radius_m = sane(d.base_radius_m);
  p.height_m = sane(d.height_m);
  if (p.radius_m == 0.0f || p.height_m == 0.0f || !std::isfinite(4.0f * p.radius_m) ||
      !std::isfinite(4.0f * p.height_m)) {
    p.radius_m = 0.0f;
    return p;
  }
  p.around = segment_exponents(2.0f * p.radius_m);
  return p;
}

// Both directions step 2*pi/N in angle. Around, chords cut deepest on the base ring. Along a
// meridian (an ellipse of semi-axes r, h) a chord of half-angle t centred at latitude b cuts
// (1 - cos t) r h / sqrt(h^2 cos^2 b + r^2 sin^2 b), deepest in the band nearest the flatter
// end: the base when h <= r, the apex otherwise. The two add within a band.
float error_at(float r, float h, uint32_t segments) {
  const float half_step = kPi / float(segments);
  const float c = std::cos(half_step), s = std::sin(half_step);
  const float flattest = h <= r ? std::sqrt(h * h * c * c + r * r * s * s)
                                : std::sqrt(h * h * s * s + r * r * c * c);
  return one_minus_cos(half_step) * (r + r * h / flattest);
}

// Fitted: the ellipsoid scales about the base centre (the base ring stays in the base plane) so
// that the error, measured against the longer semi-axis, straddles: s = 2 / (2 - e / max(r, h)),
// the straddled deficit e / (2 - e / max(r, h)). Only vessel heads are fitted, from 2:1 heads
// (h = r / 2) to hemispheres: flatter or taller dishes' deepest and highest points lie at
// different ends of the meridian, and one scale gained a third at best there (measured).
bool is_fitted(float r, float h) { return h >= 0.5f * r && h <= r; }
float fit_scale(float r, float h, float error_m) {
  return is_fitted(r, h) ? straddle_scale(error_m / std::max(r, h)) : 1.0f;
}
float straddled_error(float r, float h, float error_m) {
  return is_fitted(r, h) ? straddled_deficit(std::max(r, h), error_m / std::max(r, h)) : error_m;
}

}  // namespace

void plan(const EllipticalDish& d, MeshPlan& plan, TemplateKey& key) {
  const EllipticalDishParams p = params_of(d);
  if (p.radius_m == 0.0f) return;  // no volume: empty mesh
  const uint32_t n_max = 1u << p.around.n_max, n_min = 1u << p.around.n_min;
  const float r = p.radius_m, h = p.height_m;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(p.around.n_max - p.around.n_min + 1);
  plan.vertex_count = (n_max / 4) * n_max + 1 + n_max;
  plan.segments = {uint16_t(n_max), uint16_t(n_max / 4)};
  // The error: error_at() above.
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    plan.error_m[l] = error_at(r, h, segments_at(n_max, n_min, l));
    plan.straddled_error_m[l] = straddled_error(r, h, plan.error_m[l]);
  }
  key.kind = uint8_t(PrimitiveKind::elliptical_dish);
  key.a_max = uint16_t(n_max);
  key.a_min = uint16_t(n_min);
  key.b_max = uint16_t(n_max / 4);
  key.b_min = uint16_t(n_min / 4);
}

void build_template_EllipticalDish(const TemplateKey& key, TemplateBuilder& out) {
  build_dish_template(key, out);
}

void write(const EllipticalDish& d, const MeshPlan& plan, const VertexSink& sink) {
  const EllipticalDishParams p = params_of(d);
  float r = p.radius_m, h = p.height_m;
  const uint32_t n = plan.segments[0], bands = plan.segments[1];
  if (sink.fitted()) {
    const float scale = fit_scale(
        r, h, error_at(r, h, segments_at(n, n >> (plan.level_count - 1u), uint32_t(sink.fit_level))));
    r *= scale;
    h *= scale;
  }
  const uint32_t apex = bands * n, disc = apex + 1;
  // Latitude (pi/2)*k/B = 2*pi*k/N: the circle samples serve both directions.
  for (uint32_t k = 0; k < bands; ++k) {
    const glm::vec2 lat = circle_sample(k, n);
    // Ring k: (r cos(lat) c, r cos(lat) s, h sin(lat)). Its normal is the ellipsoid's gradient
    // (x/r^2, y/r^2, z/h^2), scaled by r h to (h cos(lat) c, h cos(lat) s, r sin(lat)), whose
    // length is the same all round the ring: dividing by it once makes every normal unit.
    const float hc = h * lat.x, rs = r * lat.y, unit = 1.0f / std::sqrt(hc * hc + rs * rs);
    sink.put_ring(k * n, n, AffineRing{{0, 0, h * lat.y}, {r * lat.x, 0, 0}, {0, r * lat.x, 0}},
                  AffineRing{{0, 0, rs * unit}, {hc * unit, 0, 0}, {0, hc * unit, 0}, true});
  }
  sink.copy_positions(0, disc, n, sink.unit_normal({0, 0, -1}));
  sink.put(apex, {0, 0, h}, sink.unit_normal({0, 0, 1}));
}

Aabb bounds(const EllipticalDish& d) {
  const EllipticalDishParams p = params_of(d);
  return {{-p.radius_m, -p.radius_m, 0}, {p.radius_m, p.radius_m, p.height_m}};
}

}  // namespace plantview::detail
