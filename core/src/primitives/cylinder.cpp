// Cylinder: two rings of N side vertices (radial normals) and two caps of N vertices (axial
// normals), so that shading is smooth around and sharp at the rims. The same template serves the
// snout (snout.cpp), whose rings are merely moved, scaled and tilted.
//
// Vertex layout at level 0 with N segments:
//   [0, N) bottom ring, [N, 2N) top ring, [2N, 3N) bottom cap, [3N, 4N) top cap;
//   vertex i of each block lies at angle 2*pi*i/N.
// Level l uses every 2^l-th vertex of each block: side quads, and caps fanned from vertex 0.
// Fitted to level l, both rings (and the caps that copy them) have radius r s_l.

#include "kinds.h"

namespace plantview::detail {

void build_ring_solid_template(const TemplateKey& key, TemplateBuilder& out) {
  const uint32_t n0 = key.a_max;
  for (uint32_t level = 0; level < halving_levels(key.a_max, key.a_min); ++level) {
    const uint32_t n = segments_at(key.a_max, key.a_min, level);
    const uint32_t step = n0 / n;
    out.begin_level();
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t a = i * step, b = ((i + 1) % n) * step;
      out.quad(a, b, n0 + b, n0 + a);
    }
    for (uint32_t k = 1; k + 1 < n; ++k) {
      out.triangle(2 * n0, 2 * n0 + (k + 1) * step, 2 * n0 + k * step);
      out.triangle(3 * n0, 3 * n0 + k * step, 3 * n0 + (k + 1) * step);
    }
  }
}

// Shared with snout.cpp: levels and errors of a ring solid of N_max segments.
void plan_ring_solid(float max_radius_m, float diameter_for_rule_m, MeshPlan& plan,
                     TemplateKey& key) {
  const SegmentExponents e = segment_exponents(diameter_for_rule_m);
  const uint32_t n_max = 1u << e.n_max, n_min = 1u << e.n_min;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = uint8_t(e.n_max - e.n_min + 1);
  plan.vertex_count = 4 * n_max;
  plan.segments = {uint16_t(n_max), 0};
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const uint32_t n = segments_at(n_max, n_min, l);
    plan.error_m[l] = segment_sagitta(max_radius_m, n);
    plan.straddled_error_m[l] = straddled_deficit(max_radius_m, ring_deficit(n));
  }
  key.kind = uint8_t(PrimitiveKind::cylinder);
  key.a_max = uint16_t(n_max);
  key.a_min = uint16_t(n_min);
}

// Shared with snout.cpp: the scale of a ring solid's rings for the sink's fit level (1 when on
// the surface).
float ring_solid_fit_scale(const MeshPlan& plan, const VertexSink& sink) {
  if (!sink.fitted()) return 1.0f;
  const uint32_t n_max = plan.segments[0], n_min = n_max >> (plan.level_count - 1u);
  return straddle_scale(ring_deficit(segments_at(n_max, n_min, uint32_t(sink.fit_level))));
}

void plan(const Cylinder& c, MeshPlan& plan, TemplateKey& key) {
  const float r = sane(c.radius_m), h = sane(c.height_m);
  if (r == 0.0f || h == 0.0f) return;  // no volume: empty mesh
  plan_ring_solid(r, 2.0f * r, plan, key);
}

void build_template_Cylinder(const TemplateKey& key, TemplateBuilder& out) {
  build_ring_solid_template(key, out);
}

void write(const Cylinder& c, const MeshPlan& plan, const VertexSink& sink) {
  const float r = sane(c.radius_m) * ring_solid_fit_scale(plan, sink), h2 = 0.5f * sane(c.height_m);
  const uint32_t n = plan.segments[0];
  const AffineRing radial{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, true};
  sink.put_ring(0, n, AffineRing{{0, 0, -h2}, {r, 0, 0}, {0, r, 0}}, radial);
  sink.put_ring(n, n, AffineRing{{0, 0, h2}, {r, 0, 0}, {0, r, 0}}, radial);
  sink.copy_positions(0, 2 * n, n, sink.unit_normal({0, 0, -1}));
  sink.copy_positions(n, 3 * n, n, sink.unit_normal({0, 0, 1}));
}

Aabb bounds(const Cylinder& c) {
  const float r = sane(c.radius_m), h2 = 0.5f * sane(c.height_m);
  return {{-r, -r, -h2}, {r, r, h2}};
}

}  // namespace plantview::detail
