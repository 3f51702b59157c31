// Spherical dish: a cap of the sphere through the base circle (radius r at z = 0) and the apex
// (0, 0, h), of radius (r^2 + h^2)/(2h) centred below the apex, as N segments around and B polar
// bands on a flat base disc. B is the power of two that makes the polar step closest to 2*pi/N
// (at least 1); h > r gives more than a hemisphere. Shading is smooth over the cap and sharp at
// the base rim.
//
// Vertex layout at level 0 (the dish layout of elliptical_dish.cpp):
//   rings k = 0..B-1 at [k*N, (k+1)*N), ring 0 on the base (z = 0), ring k at polar angle
//   a_max*(B - k)/B from the apex, a_max the base ring's; vertex i at azimuth 2*pi*i/N;
//   the apex at B*N;
//   the base disc [B*N + 1, B*N + 1 + N), vertex i at the place of vertex i of ring 0.
// Level l uses every 2^l-th ring and every 2^l-th vertex of each (never fewer than 4 around and
// 1 band).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

// Shared with elliptical_dish.cpp, which defines it.
void build_dish_template(const TemplateKey& key, TemplateBuilder& out);

namespace {

struct SphericalDishParams {
  double radius_m = 0, height_m = 0;
  double sphere_m = 0;      // the sphere's radius
  double polar_max = 0;     // polar angle of the base ring from the apex, (0, pi)
  double widest_m = 0;      // the widest ring's radius: the base, or the equator if inside
  SegmentExponents around;
  uint32_t bands = 0;
};

// The sanitised shape and its segment counts; radius_m == 0 means an empty mesh.
SphericalDishParams params_of(const SphericalDish& d) {
  SphericalDishParams p;
  const float r = sane(d.base_radius_m), h = sane(d.height_m);
  if (r == 0.0f || h == 0.0f || !std::isfinite(4.0f * r) || !std::isfinite(4.0f * h)) return p;
  p.radius_m = r;
  p.height_m = h;
  p.sphere_m = (p.radius_m * p.radius_m + p.height_m * p.height_m) / (2.0 * p.height_m);
  p.polar_max = std::atan2(p.radius_m, p.sphere_m - p.height_m);
  p.widest_m = p.polar_max > 0.5 * std::numbers::pi ? p.sphere_m : p.radius_m;
  p.around = segment_exponents(float(2.0 * p.widest_m));
  // Bands: the power of two nearest (in ratio) to polar_max / (2*pi/N).
  const double wanted = p.polar_max * double(1u << p.around.n_max) / (2.0 * std::numbers::pi);
  p.bands = 1;
  while (double(p.bands) * std::numbers::sqrt2 < wanted) p.bands *= 2;
  return p;
}

}  // namespace

void plan(const SphericalDish& d, MeshPlan& plan, TemplateKey& key) {
  const SphericalDishParams p = params_of(d);
  if (p.radius_m == 0.0) return;  // no volume: empty mesh
  const uint32_t n_max = 1u << p.around.n_max, n_min = 1u << p.around.n_min;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(p.around.n_max - p.around.n_min + 1);
  plan.vertex_count = p.bands * n_max + 1 + n_max;
  plan.segments = {uint16_t(n_max), uint16_t(p.bands)};
  // Around, chords cut deepest on the widest ring, sideways: on the base rim that is the whole
  // error, inside the cap only its part along the normal (at most the sine of the widest polar
  // angle) adds to the meridian's, which cuts the same in every band.
  const double widest_sine = p.widest_m == p.sphere_m ? 1.0 : p.radius_m / p.sphere_m;
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const uint32_t n = segments_at(n_max, n_min, l), bands = segments_at(p.bands, 1, l);
    const double around = p.widest_m * one_minus_cos(std::numbers::pi / double(n));
    const double meridian = p.sphere_m * one_minus_cos(0.5 * p.polar_max / double(bands));
    plan.error_m[l] = float(std::max(around, meridian + widest_sine * around));
    // Never fitted: the base ring must stay in the base plane and on the rim, and scaling the
    // cap about its sphere's centre with the ring held there gained only a third (measured).
    plan.straddled_error_m[l] = plan.error_m[l];
  }
  key.kind = uint8_t(PrimitiveKind::spherical_dish);
  key.a_max = uint16_t(n_max);
  key.a_min = uint16_t(n_min);
  key.b_max = uint16_t(p.bands);
  key.b_min = 1;
}

void build_template_SphericalDish(const TemplateKey& key, TemplateBuilder& out) {
  build_dish_template(key, out);
}

void write(const SphericalDish& d, const MeshPlan& plan, const VertexSink& sink) {
  const SphericalDishParams p = params_of(d);
  const uint32_t n = plan.segments[0], bands = plan.segments[1];
  const uint32_t apex = bands * n, disc = apex + 1;
  for (uint32_t k = 0; k < bands; ++k) {
    const double polar = p.polar_max * double(bands - k) / double(bands);
    const glm::vec2 normal_rz(float(std::sin(polar)), float(std::cos(polar)));
    // The base ring is placed exactly; z = h - R(1 - cos) keeps flat dishes precise.
    const float ring_m = k == 0 ? float(p.radius_m) : float(p.sphere_m * std::sin(polar));
    const float z_m = k == 0 ? 0.0f : float(p.height_m - p.sphere_m * one_minus_cos(polar));
    sink.put_ring(k * n, n, AffineRing{{0, 0, z_m}, {ring_m, 0, 0}, {0, ring_m, 0}},
                  AffineRing{{0, 0, normal_rz.y}, {normal_rz.x, 0, 0}, {0, normal_rz.x, 0}, true});
  }
  sink.copy_positions(0, disc, n, sink.unit_normal({0, 0, -1}));
  sink.put(apex, {0, 0, float(p.height_m)}, sink.unit_normal({0, 0, 1}));
}

Aabb bounds(const SphericalDish& d) {
  const SphericalDishParams p = params_of(d);
  const float w = float(p.widest_m);
  return {{-w, -w, 0}, {w, w, float(p.height_m)}};
}

}  // namespace plantview::detail
