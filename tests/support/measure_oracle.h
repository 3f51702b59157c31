// A brute-force distance oracle for the measure tests: every triangle of one object's finest
// on-surface tessellation, made 8 times finer than the renderer's (finer()), against every
// triangle of the other's (pairs of primitives whose
// bounds are farther apart than the best distance so far, and triangles likewise, are passed
// over: they cannot be nearer). Exact up to that tessellation's error (oracle_error_m of each
// object).
// Surfaces only: a solid wholly inside another is not seen as touching.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <variant>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/model.h"
#include "plantview/primitives.h"

namespace plantview::test {

struct OracleTriangle {
  glm::dvec3 p[3];
  glm::dvec3 lo, hi;
};
struct OraclePart {
  std::vector<OracleTriangle> triangles;
  glm::dvec3 lo{INFINITY}, hi{-INFINITY};
};

// The same primitive with its lengths `k` times larger under a placement `k` times smaller: the
// same solid, which the size rule cuts into up to 2^log2(k) times more segments (at most 256
// a direction). Angles and counts stay.
inline Primitive finer(const Primitive& primitive, float k) {
  Primitive p = primitive;
  p.placement.linear = primitive.placement.linear * (1.0f / k);
  std::visit(
      [k](auto& s) {
        using S = std::decay_t<decltype(s)>;
        if constexpr (std::is_same_v<S, Box>) {
          s.size_x_m *= k; s.size_y_m *= k; s.size_z_m *= k;
        } else if constexpr (std::is_same_v<S, Pyramid>) {
          s.bottom_x_m *= k; s.bottom_y_m *= k; s.top_x_m *= k; s.top_y_m *= k;
          s.offset_x_m *= k; s.offset_y_m *= k; s.height_m *= k;
        } else if constexpr (std::is_same_v<S, Prism>) {
          s.radius_m *= k; s.height_m *= k;
        } else if constexpr (std::is_same_v<S, Cylinder>) {
          s.radius_m *= k; s.height_m *= k;
        } else if constexpr (std::is_same_v<S, Snout>) {
          s.radius_bottom_m *= k; s.radius_top_m *= k; s.height_m *= k; s.offset_x_m *= k; s.offset_y_m *= k;
        } else if constexpr (std::is_same_v<S, SquareToRound>) {
          s.bottom_x_m *= k; s.bottom_y_m *= k; s.top_radius_m *= k; s.height_m *= k;
          s.offset_x_m *= k; s.offset_y_m *= k;
        } else if constexpr (std::is_same_v<S, CircularTorus>) {
          s.bend_radius_m *= k; s.tube_radius_m *= k;
        } else if constexpr (std::is_same_v<S, RectangularTorus>) {
          s.inner_radius_m *= k; s.outer_radius_m *= k; s.height_m *= k;
        } else if constexpr (std::is_same_v<S, Sphere>) {
          s.radius_m *= k;
        } else if constexpr (std::is_same_v<S, EllipticalDish> || std::is_same_v<S, SphericalDish>) {
          s.base_radius_m *= k; s.height_m *= k;
        } else if constexpr (std::is_same_v<S, Saddle>) {
          s.length_m *= k; s.width_m *= k; s.height_m *= k; s.cradle_radius_m *= k;
        } else if constexpr (std::is_same_v<S, Line>) {
          s.start_x_m *= k; s.end_x_m *= k;
        } else if constexpr (std::is_same_v<S, FacetGroup>) {
          for (FacetVertex& v : s.vertices) v.position_m *= k;
        }
      },
      p.shape);
  return p;
}

// The oracle's tessellation: level 0 of the primitive made `k` times finer (finer()).
inline constexpr float kOracleRefinement = 8.0f;

// The oracle's own error bound for an object: its parts' largest level-0 error at that refinement.
inline double oracle_error_m(const Object& object) {
  double e = 0;
  for (const Primitive& p : object.primitives) e = std::max(e, double(plan_mesh(finer(p, kOracleRefinement)).error_m[0]));
  return e;
}

// Level-0 on-surface triangles of each primitive made finer, relative to `frame_m`.
inline std::vector<OraclePart> oracle_parts(const Object& object, const glm::dvec3& frame_m) {
  std::vector<OraclePart> parts;
  for (const Primitive& original : object.primitives) {
    const Primitive primitive = finer(original, kOracleRefinement);
    const MeshPlan plan = plan_mesh(primitive);
    if (plan.topology != Topology::triangles || plan.vertex_count == 0) continue;
    std::vector<PackedVertex> v(plan.vertex_count);
    write_vertices(primitive, plan, glm::dvec3(0.0), v, kOnSurface);
    std::vector<uint32_t> idx(plan.index_count(0));
    write_indices(plan, 0, 0, std::span<uint32_t>(idx));
    OraclePart part;
    const glm::dvec3 shift = object.origin_m - frame_m;
    for (size_t i = 0; i + 2 < idx.size(); i += 3) {
      OracleTriangle t;
      for (int k = 0; k < 3; ++k) t.p[k] = glm::dvec3(v[idx[i + k]].position_m) + shift;
      t.lo = glm::min(t.p[0], glm::min(t.p[1], t.p[2]));
      t.hi = glm::max(t.p[0], glm::max(t.p[1], t.p[2]));
      part.lo = glm::min(part.lo, t.lo);
      part.hi = glm::max(part.hi, t.hi);
      part.triangles.push_back(t);
    }
    if (!part.triangles.empty()) parts.push_back(std::move(part));
  }
  return parts;
}

inline double box_gap(const glm::dvec3& alo, const glm::dvec3& ahi, const glm::dvec3& blo,
                      const glm::dvec3& bhi) {
  const glm::dvec3 d = glm::max(glm::dvec3(0.0), glm::max(blo - ahi, alo - bhi));
  return glm::length(d);
}

// Ericson, Real-Time Collision Detection 5.1.5 and 5.1.9.
inline glm::dvec3 closest_on_triangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                      const glm::dvec3& c) {
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
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

inline double segment_segment(const glm::dvec3& p1, const glm::dvec3& q1, const glm::dvec3& p2,
                              const glm::dvec3& q2) {
  const glm::dvec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = glm::dot(d1, d1), e = glm::dot(d2, d2), f = glm::dot(d2, r);
  double s = 0, t = 0;
  if (a <= 1e-30 && e <= 1e-30) return glm::length(r);
  if (a <= 1e-30) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = glm::dot(d1, r);
    if (e <= 1e-30) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = glm::dot(d1, d2), denom = a * e - b * b;
      s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return glm::length((p1 + d1 * s) - (p2 + d2 * t));
}

// Whether segment pq crosses triangle abc.
inline bool segment_crosses(const glm::dvec3& p, const glm::dvec3& q, const glm::dvec3& a,
                            const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 d = q - p, e1 = b - a, e2 = c - a, h = glm::cross(d, e2);
  const double det = glm::dot(e1, h);
  if (std::abs(det) < 1e-20) return false;
  const double inv = 1.0 / det;
  const glm::dvec3 s = p - a;
  const double u = glm::dot(s, h) * inv;
  if (u < 0 || u > 1) return false;
  const glm::dvec3 qq = glm::cross(s, e1);
  const double v = glm::dot(d, qq) * inv;
  if (v < 0 || u + v > 1) return false;
  const double t = glm::dot(e2, qq) * inv;
  return t >= 0 && t <= 1;
}

inline double triangle_triangle(const OracleTriangle& x, const OracleTriangle& y) {
  for (int i = 0; i < 3; ++i) {
    if (segment_crosses(x.p[i], x.p[(i + 1) % 3], y.p[0], y.p[1], y.p[2])) return 0;
    if (segment_crosses(y.p[i], y.p[(i + 1) % 3], x.p[0], x.p[1], x.p[2])) return 0;
  }
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    best = std::min(best, glm::length(x.p[i] - closest_on_triangle(x.p[i], y.p[0], y.p[1], y.p[2])));
    best = std::min(best, glm::length(y.p[i] - closest_on_triangle(y.p[i], x.p[0], x.p[1], x.p[2])));
    for (int j = 0; j < 3; ++j)
      best = std::min(best, segment_segment(x.p[i], x.p[(i + 1) % 3], y.p[j], y.p[(j + 1) % 3]));
  }
  return best;
}

inline double oracle_distance(const std::vector<OraclePart>& a, const std::vector<OraclePart>& b) {
  struct Pair {
    double gap;
    const OraclePart* a;
    const OraclePart* b;
  };
  std::vector<Pair> pairs;
  for (const OraclePart& pa : a)
    for (const OraclePart& pb : b) pairs.push_back({box_gap(pa.lo, pa.hi, pb.lo, pb.hi), &pa, &pb});
  std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) { return x.gap < y.gap; });
  double best = std::numeric_limits<double>::infinity();
  for (const Pair& pair : pairs) {
    if (pair.gap >= best) break;
    for (const OracleTriangle& ta : pair.a->triangles) {
      if (box_gap(ta.lo, ta.hi, pair.b->lo, pair.b->hi) >= best) continue;
      for (const OracleTriangle& tb : pair.b->triangles) {
        if (box_gap(ta.lo, ta.hi, tb.lo, tb.hi) >= best) continue;
        best = std::min(best, triangle_triangle(ta, tb));
        if (best == 0) return 0;
      }
    }
  }
  return best;
}

}  // namespace plantview::test
