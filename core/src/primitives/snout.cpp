// Snout (cone frustum with end offsets and shears): the cylinder's vertex layout and template
// (cylinder.cpp), its rings moved, scaled and tilted.
//
// Vertex layout at level 0 with N segments:
//   [0, N) bottom ring, [N, 2N) top ring (side normals), [2N, 3N) bottom cap, [3N, 4N) top cap
//   (end-plane normals); vertex i of each block lies at angle 2*pi*i/N. A ring of radius 0 is N
//   coincident points (the apex of a cone).
//
// Error: the side is the ruled surface joining the two end curves at equal angles. Where its quads
// are planar (equal end slopes, or no offset and equal radii: every concentric, eccentric and
// sheared snout) the bound is the largest chord sagitta of an end curve, r(1 - cos(pi/N)) stretched
// by the end plane's slope, sqrt(1 + tan^2 shear_x + tan^2 shear_y). Otherwise the quads twist
// (unequal shears with an offset or a radius change): each level's error is measured on its quads
// (ruled_ring_deviation below, which square_to_round.cpp shares): tens of microseconds per
// snout, against a tenth of one for the closed form.
#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <span>

#include "kinds.h"

namespace plantview::detail {

// cylinder.cpp: the ring solid template and its plan.
void build_ring_solid_template(const TemplateKey& key, TemplateBuilder& out);
void plan_ring_solid(float max_radius_m, float diameter_for_rule_m, MeshPlan& plan,
                     TemplateKey& key);
float ring_solid_fit_scale(const MeshPlan& plan, const VertexSink& sink);

// Shared with square_to_round.cpp. One quad of a ruled surface joining a bottom curve to a top
// curve at equal parameters: the bottom curve's points at the quad's two ends (b0, b1), the top
// curve's (t0, t1), then both curves' points at its middle parameter (bm, tm). The mesh splits it
// into triangles (b0, b1, t1) and (b0, t1, t0).
using RuledQuad = std::array<glm::vec3, 6>;
// The error of a ring of at most 256 such quads (local metres): the largest distance between the
// surface and its triangles, over-reported by up to about 20% to cover the measurement's misses.
// Allocation-free; some 0.5 us per quad.
float ruled_ring_deviation(std::span<const RuledQuad> quads);

namespace {

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
glm::dvec3 closest_on_triangle(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  }
  const double sum = va + vb + vc;
  if (!(sum > 0)) return a;  // a degenerate triangle: its corners are close enough
  return a + ab * (vb / sum) + ac * (vc / sum);
}

// One end of the snout: the circle of `radius_m` about `centre` lifted onto the end plane
// z = centre.z + slope.x * (x - centre.x) + slope.y * (y - centre.y).
struct SnoutEnd {
  glm::vec3 centre{0};
  float radius_m = 0;
  glm::vec2 slope{0};

  glm::vec3 at(glm::vec2 cs) const {
    return centre + radius_m * glm::vec3(cs.x, cs.y, slope.x * cs.x + slope.y * cs.y);
  }
  // at() as a ring, for the vertex sink.
  AffineRing ring() const {
    return {centre, radius_m * glm::vec3(1, 0, slope.x), radius_m * glm::vec3(0, 1, slope.y)};
  }
  // Direction of increasing angle along the end curve (per metre of radius).
  glm::vec3 tangent(glm::vec2 cs) const { return {-cs.y, cs.x, -slope.x * cs.y + slope.y * cs.x}; }
  // Stretch of the circle's sagitta by the tilt of the end plane (largest |d at / d radius|).
  float tilt_stretch() const { return std::sqrt(1.0f + glm::dot(slope, slope)); }
};

struct SnoutEnds {
  SnoutEnd bottom, top;
  bool empty = true;
};

SnoutEnds ends_of(const Snout& s) {
  SnoutEnds e;
  const float h2 = 0.5f * sane(s.height_m);
  const float ox2 = 0.5f * finite_or_zero(s.offset_x_m), oy2 = 0.5f * finite_or_zero(s.offset_y_m);
  e.bottom.centre = {-ox2, -oy2, -h2};
  e.top.centre = {ox2, oy2, h2};
  e.bottom.radius_m = sane(s.radius_bottom_m);
  e.top.radius_m = sane(s.radius_top_m);
  e.bottom.slope = {std::tan(finite_or_zero(s.bottom_shear_x_rad)),
                    std::tan(finite_or_zero(s.bottom_shear_y_rad))};
  e.top.slope = {std::tan(finite_or_zero(s.top_shear_x_rad)),
                 std::tan(finite_or_zero(s.top_shear_y_rad))};
  e.empty = h2 == 0.0f || (e.bottom.radius_m == 0.0f && e.top.radius_m == 0.0f);
  return e;
}

// Whether the side's quads are planar (equal end slopes, or no offset and equal radii: every
// concentric, eccentric and sheared snout); else they twist.
bool has_planar_quads(const SnoutEnds& e) {
  const bool same_circle = e.bottom.radius_m == e.top.radius_m &&
                           e.bottom.centre.x == e.top.centre.x &&
                           e.bottom.centre.y == e.top.centre.y;
  return e.bottom.slope == e.top.slope || same_circle;
}

// ruled_ring_deviation reports the measured deviation times this, which covers the measurement's
// misses: on random snouts and square-to-rounds the report lies within 1.02 to 1.2 of the true
// deviation.
constexpr float kTwistedQuadMargin = 1.1f;
// ruled_ring_deviation measures a quad unless its bound, times this, is below the worst measured.
constexpr double kBoundSlack = 1.05;
constexpr size_t kMaxRuledQuads = 256;  // the largest segment count

// The largest distance from a ruled quad's surface to its two triangles (b0, b1, t1) and
// (b0, t1, t0), roughly. The surface is the set of lines (rulings) joining the bottom curve to the
// top curve at equal parameters; it is modelled as the corners' bilinear patch plus each end
// curve's bulge, quadratic across the quad and exact at its middle.
//
// Along a ruling the distance to each triangle is convex (a triangle is a convex set), so the
// distance to the pair peaks at the ruling's ends or where the nearer triangle changes, which is
// near where the heights over the two planes are equal. The figure is the larger of the end
// curves' middle points and of those points on three rulings (a quarter, half and three quarters
// across): at most 8 point-to-triangle-pair distances.
double ruled_quad_deviation(const RuledQuad& quad) {
  const glm::dvec3 b0(quad[0]), b1(quad[1]), t0(quad[2]), t1(quad[3]), bm(quad[4]), tm(quad[5]);
  glm::dvec3 n1 = glm::cross(b1 - b0, t1 - b0), n2 = glm::cross(t1 - b0, t0 - b0);
  // A triangle without area (a curve shrunk to a point) lies on its partner's edge b0-t1.
  auto has_area = [](const glm::dvec3& n, const glm::dvec3& u, const glm::dvec3& v) {
    return glm::dot(n, n) > 1e-24 * glm::dot(u, u) * glm::dot(v, v);
  };
  const bool first = has_area(n1, b1 - b0, t1 - b0), second = has_area(n2, t1 - b0, t0 - b0);
  if (!first && !second) return 0.0;
  auto distance = [&](const glm::dvec3& p) {
    double nearest2 = INFINITY;
    if (first) {
      const glm::dvec3 q = closest_on_triangle(p, b0, b1, t1) - p;
      nearest2 = glm::dot(q, q);
    }
    if (second) {
      const glm::dvec3 q = closest_on_triangle(p, b0, t1, t0) - p;
      nearest2 = std::min(nearest2, glm::dot(q, q));
    }
    return std::sqrt(nearest2);
  };
  const glm::dvec3 e = b1 - b0, d = t0 - b0, w = t1 - t0 - e;
  const glm::dvec3 bulge_b = bm - 0.5 * (b0 + b1), bulge_t = tm - 0.5 * (t0 + t1);
  auto surface = [&](double s, double v) {
    return b0 + s * e + v * d + s * v * w +
           4.0 * s * (1.0 - s) * ((1.0 - v) * bulge_b + v * bulge_t);
  };
  double worst = std::max(distance(bm), distance(tm));
  if (!first || !second) return worst;  // one triangle: the distance peaks at the ends
  n1 = glm::normalize(n1);
  n2 = glm::normalize(n2);
  for (double s : {0.25, 0.5, 0.75}) {
    // The ruling p(v) = from + v * along; heights over the planes h_k = a_k + v * c_k.
    const glm::dvec3 from = surface(s, 0.0), along = surface(s, 1.0) - from;
    const double a1 = glm::dot(n1, from - b0), c1 = glm::dot(n1, along);
    const double a2 = glm::dot(n2, from - b0), c2 = glm::dot(n2, along);
    for (const double v : {(a2 - a1) / (c1 - c2), -(a1 + a2) / (c1 + c2)}) {
      if (v > 0.0 && v < 1.0) worst = std::max(worst, distance(from + v * along));  // not NaN
    }
  }
  return worst;
}

// A quick upper estimate of ruled_quad_deviation (never below it on random snouts and
// square-to-rounds, up to 8 times above): the larger end-curve bulge plus a quarter of the fold,
// the height of either triangle's fourth corner over the other's plane.
double ruled_quad_bound(const RuledQuad& quad) {
  const glm::vec3 &b0 = quad[0], &b1 = quad[1], &t0 = quad[2], &t1 = quad[3];
  const glm::vec3 bulge_b = quad[4] - 0.5f * (b0 + b1), bulge_t = quad[5] - 0.5f * (t0 + t1);
  const glm::vec3 w = t1 - t0 - b1 + b0;
  float fold = 0.0f;
  for (const glm::vec3& n : {glm::cross(b1 - b0, t1 - b0), glm::cross(t1 - b0, t0 - b0)}) {
    const float n_len = glm::length(n);
    if (n_len > 0.0f) fold = std::max(fold, std::abs(glm::dot(n, w)) / n_len);
  }
  return double(std::max(glm::length(bulge_b), glm::length(bulge_t)) + 0.25f * fold);
}

}  // namespace

float ruled_ring_deviation(std::span<const RuledQuad> quads) {
  // Branch and bound: measure the quad of the largest bound, then every quad whose bound could
  // still beat the worst measured.
  std::array<double, kMaxRuledQuads> bound;
  const size_t count = std::min(quads.size(), bound.size());
  size_t top = 0;
  for (size_t i = 0; i < count; ++i) {
    bound[i] = ruled_quad_bound(quads[i]);
    if (bound[i] > bound[top]) top = i;
  }
  double worst = count > 0 ? ruled_quad_deviation(quads[top]) : 0.0;
  for (size_t i = 0; i < count; ++i) {
    if (i != top && kBoundSlack * bound[i] > worst) {
      worst = std::max(worst, ruled_quad_deviation(quads[i]));
    }
  }
  return kTwistedQuadMargin * float(worst);
}

void plan(const Snout& s, MeshPlan& plan, TemplateKey& key) {
  const SnoutEnds e = ends_of(s);
  if (e.empty) return;  // no volume: empty mesh
  const float r_max = std::max(e.bottom.radius_m, e.top.radius_m);
  plan_ring_solid(r_max, 2.0f * r_max, plan, key);

  const bool planar_quads = has_planar_quads(e);
  const float widest_m =
      std::max(e.bottom.radius_m * e.bottom.tilt_stretch(), e.top.radius_m * e.top.tilt_stretch());
  // Twisted quads: measure them (kUnitCircle holds the half-segment angles for
  // n <= kCircleSamples / 2).
  auto twisted_deviation = [&e](uint32_t n) {
    std::array<RuledQuad, kMaxRuledQuads> quads;
    const uint32_t step = kCircleSamples / n;
    const SnoutEnd &b = e.bottom, &t = e.top;
    for (uint32_t i = 0; i < n; ++i) {
      const glm::vec2 c0 = kUnitCircle[i * step], c1 = kUnitCircle[(i + 1) * step % kCircleSamples],
                      cm = kUnitCircle[i * step + step / 2];
      quads[i] = {b.at(c0), b.at(c1), t.at(c0), t.at(c1), b.at(cm), t.at(cm)};
    }
    return ruled_ring_deviation(std::span(quads.data(), n));
  };
  float previous = 0.0f, previous_straddled = 0.0f;
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    const uint32_t n = segments_at(key.a_max, key.a_min, l);
    float error = 0.0f, straddled = 0.0f;
    if (planar_quads) {
      error = segment_sagitta(widest_m, n);
      straddled = straddled_deficit(widest_m, ring_deficit(n));
    } else {
      // Never fitted: the quads' twist adds its own error, which moving the rings does not halve
      // (measured: a third off at best, worse than on the surface at worst).
      error = twisted_deviation(n);
      straddled = error;
    }
    previous = std::max(previous, error);  // coarser levels never report less
    previous_straddled = std::max(previous_straddled, straddled);
    plan.error_m[l] = previous;
    plan.straddled_error_m[l] = previous_straddled;
  }
}

void build_template_Snout(const TemplateKey& key, TemplateBuilder& out) {
  build_ring_solid_template(key, out);
}

namespace {

// A side normal of the snout, the end curve's direction crossed with the ruling, as a quadratic
// in the circle sample (c, s): both factors are affine in it. Mapped to model space once per ring.
struct SideNormal {
  glm::vec3 c{0}, s{0}, cc{0}, ss{0}, cs{0};
  glm::vec3 at(glm::vec2 v) const {
    return v.x * c + v.y * s + (v.x * v.x) * cc + (v.y * v.y) * ss + (v.x * v.y) * cs;
  }
};

// The side normals along `curve` (the end's own, or for a point-like end the other end's), in
// model space through the sink's normal matrix.
SideNormal side_normal(const SnoutEnds& e, const SnoutEnd& curve, const VertexSink& sink) {
  // tangent = c t_c + s t_s (SnoutEnd::tangent); ruling = r_0 + c r_c + s r_s.
  const glm::vec3 t_c(0, 1, curve.slope.y), t_s(-1, 0, -curve.slope.x);
  const AffineRing bottom = e.bottom.ring(), top = e.top.ring();
  const glm::vec3 r_0 = top.centre - bottom.centre, r_c = top.along_c - bottom.along_c,
                  r_s = top.along_s - bottom.along_s;
  const glm::mat3& m = sink.normal_matrix;
  return {m * glm::cross(t_c, r_0), m * glm::cross(t_s, r_0), m * glm::cross(t_c, r_c),
          m * glm::cross(t_s, r_s), m * (glm::cross(t_c, r_s) + glm::cross(t_s, r_c))};
}

}  // namespace

void write(const Snout& s, const MeshPlan& plan, const VertexSink& sink) {
  SnoutEnds e = ends_of(s);
  // Fitted (planar quads only): both ends by one scale, as they have one segment count.
  const float fit = has_planar_quads(e) ? ring_solid_fit_scale(plan, sink) : 1.0f;
  e.bottom.radius_m *= fit;
  e.top.radius_m *= fit;
  const uint32_t n = plan.segments[0];
  // Side normals: along the end curve crossed with the ruling; a point-like end borrows the
  // other end's curve direction.
  const SideNormal bottom_normal =
      side_normal(e, e.bottom.radius_m > 0.0f ? e.bottom : e.top, sink);
  const SideNormal top_normal = side_normal(e, e.top.radius_m > 0.0f ? e.top : e.bottom, sink);
  sink.put_ring(0, n, e.bottom.ring(), [&bottom_normal](glm::vec2 cs) {
    return VertexSink::pack_normalised(bottom_normal.at(cs));
  });
  sink.put_ring(n, n, e.top.ring(), [&top_normal](glm::vec2 cs) {
    return VertexSink::pack_normalised(top_normal.at(cs));
  });
  // The caps, with the end planes' outward normals.
  sink.copy_positions(0, 2 * n, n, sink.normal({e.bottom.slope.x, e.bottom.slope.y, -1.0f}));
  sink.copy_positions(n, 3 * n, n, sink.normal({-e.top.slope.x, -e.top.slope.y, 1.0f}));
}

Aabb bounds(const Snout& s) {
  const SnoutEnds e = ends_of(s);
  Aabb box{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
  for (const SnoutEnd& end : {e.bottom, e.top}) {
    // The end curve's extent: r in x and y, r * |slope| in z about the centre.
    const glm::vec3 half(end.radius_m, end.radius_m, end.radius_m * glm::length(end.slope));
    box.min = glm::min(box.min, end.centre - half);
    box.max = glm::max(box.max, end.centre + half);
  }
  return box;
}

}  // namespace plantview::detail
