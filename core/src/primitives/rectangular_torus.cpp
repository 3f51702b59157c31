// Rectangular torus: the rectangle [inner, outer] x [-h/2, h/2] swept through S segments about
// z. Each face is flat across the section and smooth along the sweep, so every station carries
// two vertices per face; open sweeps are closed by flat end caps.
//
// Vertex layout at level 0 with S sweep segments:
//   stations j = 0..S (0..S-1 for a closed ring) at sweep angle angle*j/S, 8 vertices each at
//   [8j, 8j + 8): inner wall bottom, top; outer wall bottom, top; top face inner, outer; bottom
//   face inner, outer;
//   open sweeps then add the start cap [8(S+1), 8(S+1) + 4) and the end cap [8(S+1) + 4, 8(S+2)),
//   each inner bottom, outer bottom, outer top, inner top, at the places of their end station.
// Level l uses every 2^l-th station (never fewer than the sweep floor).
#include <numbers>

#include "kinds.h"

namespace plantview::detail {

// Shared with circular_torus.cpp, which defines them.
bool is_closed_ring(float angle_rad);
uint32_t sweep_floor(float angle_rad);
uint32_t sweep_segments(double wanted, uint32_t floor);
void sweep_directions(float angle_rad, uint32_t segments, uint32_t stations, glm::vec2* out);
float sweep_sagitta(float radius_m, float angle_rad, uint32_t segments);
Aabb swept_band_bounds(float rho_min, float rho_max, float angle_rad, float half_height_m);

namespace {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr uint8_t kClosedRing = 1;  // TemplateKey::flags: the sweep closes on itself, no caps

// Offsets of a station's vertices.
enum : uint32_t {
  kInnerBottom, kInnerTop, kOuterBottom, kOuterTop, kTopInner, kTopOuter, kBottomInner,
  kBottomOuter, kPerStation
};

struct RectTorusParams {
  float inner_m = 0, outer_m = 0, half_height_m = 0, angle_rad = 0;
  bool closed = false;
  SegmentExponents rule;  // of the outer diameter: sets the level count
  uint32_t sweep_max = 0, sweep_min = 0;
};

// The sanitised shape and its segment counts; outer_m == 0 means an empty mesh.
RectTorusParams params_of(const RectangularTorus& t) {
  RectTorusParams p;
  p.inner_m = sane(t.inner_radius_m);
  p.outer_m = sane(t.outer_radius_m);
  p.half_height_m = 0.5f * sane(t.height_m);
  p.angle_rad = sane(t.angle_rad);
  if (p.inner_m >= p.outer_m || p.half_height_m == 0.0f || p.angle_rad == 0.0f ||
      !std::isfinite(4.0f * p.outer_m) || !std::isfinite(4.0f * p.half_height_m)) {
    p.outer_m = 0.0f;
    return p;
  }
  p.closed = is_closed_ring(p.angle_rad);
  if (p.closed) p.angle_rad = 2.0f * kPi;
  p.rule = segment_exponents(2.0f * p.outer_m);
  p.sweep_min = sweep_floor(p.angle_rad);
  p.sweep_max = sweep_segments(
      double(1u << p.rule.n_max) * (p.angle_rad / (2.0 * std::numbers::pi)), p.sweep_min);
  return p;
}

}  // namespace

void plan(const RectangularTorus& t, MeshPlan& plan, TemplateKey& key) {
  const RectTorusParams p = params_of(t);
  if (p.outer_m == 0.0f) return;  // no volume: empty mesh
  const uint32_t stations = p.closed ? p.sweep_max : p.sweep_max + 1;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(p.rule.n_max - p.rule.n_min + 1);
  plan.vertex_count = kPerStation * stations + (p.closed ? 0 : 8);
  plan.segments = {uint16_t(p.sweep_max), 0};
  // The section is exact; only the sweep's chords cut in, deepest on the outer wall.
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const uint32_t s = segments_at(p.sweep_max, p.sweep_min, l);
    plan.error_m[l] = sweep_sagitta(p.outer_m, p.angle_rad, s);
    plan.straddled_error_m[l] = straddled_deficit(p.outer_m, sweep_sagitta(1.0f, p.angle_rad, s));
  }
  key.kind = uint8_t(PrimitiveKind::rectangular_torus);
  key.flags = p.closed ? kClosedRing : 0;
  key.a_max = uint16_t(p.sweep_max);
  key.a_min = uint16_t(p.sweep_min);
  key.b_max = uint16_t(1u << p.rule.n_max);  // the level count, as segments of the size rule
  key.b_min = uint16_t(1u << p.rule.n_min);
}

void build_template_RectangularTorus(const TemplateKey& key, TemplateBuilder& out) {
  const bool closed = key.flags & kClosedRing;
  const uint32_t s0 = key.a_max;
  const uint32_t stations = closed ? s0 : s0 + 1;
  const uint32_t start_cap = kPerStation * stations, end_cap = start_cap + 4;
  for (uint32_t level = 0; level < halving_levels(key.b_max, key.b_min); ++level) {
    const uint32_t s = segments_at(key.a_max, key.a_min, level);
    const uint32_t step = s0 / s;
    out.begin_level();
    for (uint32_t j = 0; j < s; ++j) {
      const uint32_t a = kPerStation * (j * step);
      const uint32_t b = kPerStation * ((j + 1) * step % stations);
      out.quad(a + kInnerBottom, a + kInnerTop, b + kInnerTop, b + kInnerBottom);
      out.quad(a + kOuterBottom, b + kOuterBottom, b + kOuterTop, a + kOuterTop);
      out.quad(a + kTopInner, a + kTopOuter, b + kTopOuter, b + kTopInner);
      out.quad(a + kBottomInner, b + kBottomInner, b + kBottomOuter, a + kBottomOuter);
    }
    if (closed) continue;
    out.quad(start_cap, start_cap + 1, start_cap + 2, start_cap + 3);
    out.quad(end_cap, end_cap + 3, end_cap + 2, end_cap + 1);
  }
}

void write(const RectangularTorus& t, const MeshPlan& plan, const VertexSink& sink) {
  const RectTorusParams p = params_of(t);
  const uint32_t s = plan.segments[0];
  const uint32_t stations = p.closed ? s : s + 1;
  std::array<glm::vec2, 257> sweep;
  sweep_directions(p.angle_rad, s, stations, sweep.data());
  const uint32_t start_cap = kPerStation * stations, end_cap = start_cap + 4;
  const uint32_t up = sink.normal({0, 0, 1}), down = sink.normal({0, 0, -1});
  const uint32_t start_normal = sink.normal({0, -1, 0});
  const uint32_t end_normal = sink.normal({-sweep[s % stations].y, sweep[s % stations].x, 0});
  const float h2 = p.half_height_m;
  // Fitted, every station's distance from the axis scales by the sweep's s.
  const float fit =
      sink.fitted() ? straddle_scale(sweep_sagitta(
                          1.0f, p.angle_rad,
                          segments_at(p.sweep_max, p.sweep_min, uint32_t(sink.fit_level))))
                    : 1.0f;
  for (uint32_t j = 0; j < stations; ++j) {
    const glm::vec2 u = fit * sweep[j];
    const glm::vec2 inner = p.inner_m * u, outer = p.outer_m * u;
    const glm::vec3 corners[4] = {{inner, -h2}, {outer, -h2}, {outer, h2}, {inner, h2}};
    const uint32_t inward = sink.normal({-sweep[j], 0}), outward = sink.normal({sweep[j], 0});
    const uint32_t v = kPerStation * j;
    sink.put(v + kInnerBottom, corners[0], inward);
    sink.put(v + kInnerTop, corners[3], inward);
    sink.put(v + kOuterBottom, corners[1], outward);
    sink.put(v + kOuterTop, corners[2], outward);
    sink.put(v + kTopInner, corners[3], up);
    sink.put(v + kTopOuter, corners[2], up);
    sink.put(v + kBottomInner, corners[0], down);
    sink.put(v + kBottomOuter, corners[1], down);
    if (p.closed) continue;
    for (uint32_t c = 0; c < 4; ++c) {
      if (j == 0) sink.put(start_cap + c, corners[c], start_normal);
      if (j == s) sink.put(end_cap + c, corners[c], end_normal);
    }
  }
}

Aabb bounds(const RectangularTorus& t) {
  const RectTorusParams p = params_of(t);
  if (p.outer_m == 0.0f) return {};
  return swept_band_bounds(p.inner_m, p.outer_m, p.angle_rad, p.half_height_m);
}

}  // namespace plantview::detail
