// Circular torus (pipe elbow): a tube circle of N segments swept through S segments about z.
// Shading is smooth over the whole tube and sharp at the flat end caps.
//
// Vertex layout at level 0 with N tube and S sweep segments:
//   stations j = 0..S (0..S-1 for a closed ring), each a ring of N vertices at [j*N, (j+1)*N);
//     station j lies at sweep angle angle*j/S, vertex i of a ring at tube angle 2*pi*i/N
//     (i = 0 on the outside, i = N/4 on top);
//   open sweeps then add the start cap [(S+1)*N, (S+2)*N) and the end cap [(S+2)*N, (S+3)*N),
//     vertex i of a cap at the same place as vertex i of the end station it closes.
// Level l uses every 2^l-th station and every 2^l-th ring vertex (never fewer than the floors):
// side quads, and caps fanned from their vertex 0.
//
// The sweep helpers below are shared with rectangular_torus.cpp.
#include <algorithm>
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

namespace {
constexpr float kPi = std::numbers::pi_v<float>;
constexpr uint8_t kClosedRing = 1;  // TemplateKey::flags: the sweep closes on itself, no caps
}  // namespace

// An angle within 1e-4 rad of a full turn (or beyond) sweeps a closed ring.
bool is_closed_ring(float angle_rad) { return angle_rad >= 2.0f * kPi - 1e-4f; }

// Fewest sweep segments of any level: 1 up to a quarter turn, 2 up to a half, 4 beyond (so that
// a coarse level still encloses volume and a ring stays a ring).
uint32_t sweep_floor(float angle_rad) {
  if (angle_rad <= 0.5f * kPi + 1e-4f) return 1;
  if (angle_rad <= kPi + 1e-4f) return 2;
  return 4;
}

// Level-0 sweep segments: the power of two >= wanted (1e-5 relative slack absorbs float noise),
// clamped to [floor, 256]. NaN gives the floor.
uint32_t sweep_segments(double wanted, uint32_t floor) {
  uint32_t s = floor;
  while (s < 256 && double(s) < wanted * (1.0 - 1e-5)) s *= 2;
  return s;
}

// (cos, sin) of angle*j/segments for j = 0..stations-1, in double precision then rounded, so every
// station (and every cap that copies one) is placed by the same arithmetic.
void sweep_directions(float angle_rad, uint32_t segments, uint32_t stations, glm::vec2* out) {
  for (uint32_t j = 0; j < stations; ++j) {
    const double a = double(angle_rad) * double(j) / double(segments);
    out[j] = glm::vec2(float(std::cos(a)), float(std::sin(a)));
  }
}

// Sweep sagitta: the distance from an arc of angle_rad/segments at radius_m to its chord,
// r(1 - cos(angle / 2 segments)).
float sweep_sagitta(float radius_m, float angle_rad, uint32_t segments) {
  return chord_sagitta(radius_m, 0.5f * angle_rad / float(segments));
}

// Bounds of the points rho*(cos a, sin a, z) for a in [0, angle_rad], rho in [rho_min, rho_max]
// (rho_min may be negative: such points lie across the axis) and |z| <= half_height_m.
Aabb swept_band_bounds(float rho_min, float rho_max, float angle_rad, float half_height_m) {
  Aabb b{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
  auto add = [&](glm::vec2 u) {
    for (float rho : {rho_min, rho_max}) {
      b.min = glm::min(b.min, glm::vec3(rho * u, -half_height_m));
      b.max = glm::max(b.max, glm::vec3(rho * u, half_height_m));
    }
  };
  // Along a circle, x and y are extreme at the ends of the arc or on the axes.
  const float end_rad = std::min(angle_rad, 2.0f * kPi);
  add({1, 0});
  add({std::cos(end_rad), std::sin(end_rad)});
  static const glm::vec2 axes[4] = {{0, 1}, {-1, 0}, {0, -1}, {1, 0}};
  for (int q = 0; q < 4; ++q) {
    if (0.5f * kPi * float(q + 1) <= end_rad) add(axes[q]);
  }
  return b;
}

namespace {

struct TorusParams {
  float bend_m = 0, tube_m = 0, angle_rad = 0;
  bool closed = false;
  SegmentExponents tube;
  uint32_t sweep_max = 0, sweep_min = 0;
};

// The sanitised shape and its segment counts; tube_m == 0 means an empty mesh.
TorusParams params_of(const CircularTorus& t) {
  TorusParams p;
  p.bend_m = sane(t.bend_radius_m);
  p.tube_m = sane(t.tube_radius_m);
  p.angle_rad = sane(t.angle_rad);
  if (p.tube_m == 0.0f || p.angle_rad == 0.0f || !std::isfinite(4.0f * (p.bend_m + p.tube_m))) {
    p.tube_m = 0.0f;
    return p;
  }
  p.closed = is_closed_ring(p.angle_rad);
  if (p.closed) p.angle_rad = 2.0f * kPi;
  p.tube = segment_exponents(2.0f * p.tube_m);
  // The sweep gets as many segments per radian at the outer radius as the tube has.
  const double outer_per_tube = std::max(1.0, (double(p.bend_m) + p.tube_m) / (2.0 * p.tube_m));
  const double wanted =
      double(1u << p.tube.n_max) * (p.angle_rad / (2.0 * std::numbers::pi)) * outer_per_tube;
  p.sweep_min = sweep_floor(p.angle_rad);
  p.sweep_max = sweep_segments(wanted, p.sweep_min);
  return p;
}

}  // namespace

void plan(const CircularTorus& t, MeshPlan& plan, TemplateKey& key) {
  const TorusParams p = params_of(t);
  if (p.tube_m == 0.0f) return;  // no volume: empty mesh
  const uint32_t n_max = 1u << p.tube.n_max, n_min = 1u << p.tube.n_min;
  const uint32_t stations = p.closed ? p.sweep_max : p.sweep_max + 1;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(p.tube.n_max - p.tube.n_min + 1);
  plan.vertex_count = stations * n_max + (p.closed ? 0 : 2 * n_max);
  plan.segments = {uint16_t(n_max), uint16_t(p.sweep_max)};
  // Chords along the sweep cut deepest at the outer radius; the tube's own chords add to that.
  // Fitted, both straddle: the tube ring's by its own s, the sweep's at the fitted outer radius.
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const uint32_t n = segments_at(n_max, n_min, l), s = segments_at(p.sweep_max, p.sweep_min, l);
    plan.error_m[l] = sweep_sagitta(p.bend_m + p.tube_m, p.angle_rad, s) +
                      sweep_sagitta(p.tube_m, 2.0f * kPi, n);
    const float tube_deficit = ring_deficit(n), sweep_deficit = sweep_sagitta(1.0f, p.angle_rad, s);
    plan.straddled_error_m[l] =
        straddled_deficit(p.bend_m + straddle_scale(tube_deficit) * p.tube_m, sweep_deficit) +
        straddled_deficit(p.tube_m, tube_deficit);
  }
  key.kind = uint8_t(PrimitiveKind::circular_torus);
  key.flags = p.closed ? kClosedRing : 0;
  key.a_max = uint16_t(n_max);
  key.a_min = uint16_t(n_min);
  key.b_max = uint16_t(p.sweep_max);
  key.b_min = uint16_t(p.sweep_min);
}

void build_template_CircularTorus(const TemplateKey& key, TemplateBuilder& out) {
  const bool closed = key.flags & kClosedRing;
  const uint32_t n0 = key.a_max, s0 = key.b_max;
  const uint32_t stations = closed ? s0 : s0 + 1;
  const uint32_t start_cap = stations * n0, end_cap = start_cap + n0;
  for (uint32_t level = 0; level < halving_levels(key.a_max, key.a_min); ++level) {
    const uint32_t n = segments_at(key.a_max, key.a_min, level);
    const uint32_t s = segments_at(key.b_max, key.b_min, level);
    const uint32_t tube_step = n0 / n, sweep_step = s0 / s;
    out.begin_level();
    for (uint32_t j = 0; j < s; ++j) {
      const uint32_t ring0 = j * sweep_step * n0, ring1 = ((j + 1) * sweep_step % stations) * n0;
      for (uint32_t i = 0; i < n; ++i) {
        const uint32_t a = i * tube_step, b = ((i + 1) % n) * tube_step;
        out.quad(ring0 + a, ring1 + a, ring1 + b, ring0 + b);
      }
    }
    if (closed) continue;
    for (uint32_t k = 1; k + 1 < n; ++k) {
      out.triangle(start_cap, start_cap + k * tube_step, start_cap + (k + 1) * tube_step);
      out.triangle(end_cap, end_cap + (k + 1) * tube_step, end_cap + k * tube_step);
    }
  }
}

void write(const CircularTorus& t, const MeshPlan& plan, const VertexSink& sink) {
  const TorusParams p = params_of(t);
  const uint32_t n = plan.segments[0], s = plan.segments[1];
  const uint32_t stations = p.closed ? s : s + 1;
  std::array<glm::vec2, 257> sweep;
  sweep[0] = glm::vec2(1.0f, 0.0f);  // station 0 is angle 0 (sweep_directions agrees)
  sweep_directions(p.angle_rad, s, stations, sweep.data());
  // Station j is the tube circle about bend * u, u = sweep[j]: the sample (c, s) lies at
  // (bend + tube c) u + tube s z, with the unit normal c u + s z. Fitted, the tube radius scales
  // by the tube's s and the distance from the axis (u) by the sweep's.
  float tube_scale = 1.0f, sweep_scale = 1.0f;
  if (sink.fitted()) {
    const uint32_t level = uint32_t(sink.fit_level);
    tube_scale = straddle_scale(ring_deficit(segments_at(n, n >> (plan.level_count - 1u), level)));
    sweep_scale = straddle_scale(
        sweep_sagitta(1.0f, p.angle_rad, segments_at(p.sweep_max, p.sweep_min, level)));
  }
  const float tube_m = tube_scale * p.tube_m;
  for (uint32_t j = 0; j < stations; ++j) {
    const glm::vec3 u(sweep[j], 0.0f);
    sink.put_ring(j * n, n,
                  AffineRing{sweep_scale * p.bend_m * u, sweep_scale * tube_m * u, {0, 0, tube_m}},
                  AffineRing{{0, 0, 0}, u, {0, 0, 1}, true});
  }
  if (p.closed) return;
  const uint32_t start_cap = stations * n, end_cap = start_cap + n;
  sink.copy_positions(0, start_cap, n, sink.unit_normal({0, -1, 0}));
  sink.copy_positions(s * n, end_cap, n, sink.unit_normal({-sweep[s].y, sweep[s].x, 0}));
}

Aabb bounds(const CircularTorus& t) {
  const TorusParams p = params_of(t);
  if (p.tube_m == 0.0f) return {};
  return swept_band_bounds(p.bend_m - p.tube_m, p.bend_m + p.tube_m, p.angle_rad, p.tube_m);
}

}  // namespace plantview::detail
