#include "primitive_cases.h"

#include <algorithm>
#include <cmath>

namespace plantview::testing {

namespace {
std::vector<CaseFactory>& factories() {
  static std::vector<CaseFactory> list;
  return list;
}

// The test's own point-to-triangle distance, by another route than the tessellators' (snout.cpp
// uses Ericson's Voronoi-region walk): the distance to the triangle's plane when the point lies
// over the triangle, else the distance to the nearest edge segment. Sharing no code with what it
// measures, a mistake in one cannot hide in the other.
struct Triangle {
  glm::dvec3 a, b, c;
  glm::dvec3 normal;               // (b - a) x (c - a), not normalised
  double inverse_normal2;          // 1 / |normal|^2; 0 for a degenerate (collinear) triangle
  glm::dvec3 in_ab, in_bc, in_ca;  // in-plane edge normals, pointing into the triangle
};

Triangle triangle(glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  Triangle t{a, b, c, glm::cross(b - a, c - a), 0.0, {}, {}, {}};
  const double n2 = glm::dot(t.normal, t.normal);
  const double scale2 =
      std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
  if (n2 > 1e-24 * scale2 * scale2) t.inverse_normal2 = 1.0 / n2;
  t.in_ab = glm::cross(t.normal, b - a);
  t.in_bc = glm::cross(t.normal, c - b);
  t.in_ca = glm::cross(t.normal, a - c);
  return t;
}

// Squared distance from p to the segment ab: to the foot of the perpendicular, clamped to the
// segment's ends.
double distance2_to_segment(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b) {
  const glm::dvec3 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  const double t = len2 > 0.0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
  const glm::dvec3 d = p - (a + ab * t);
  return glm::dot(d, d);
}

double distance2_to_triangle(glm::dvec3 p, const Triangle& t) {
  if (t.inverse_normal2 == 0.0) {
    return std::min({distance2_to_segment(p, t.a, t.b), distance2_to_segment(p, t.b, t.c),
                     distance2_to_segment(p, t.c, t.a)});
  }
  const bool over_ab = glm::dot(p - t.a, t.in_ab) >= 0.0;
  const bool over_bc = glm::dot(p - t.b, t.in_bc) >= 0.0;
  const bool over_ca = glm::dot(p - t.c, t.in_ca) >= 0.0;
  if (over_ab && over_bc && over_ca) {
    const double h = glm::dot(p - t.a, t.normal);
    return h * h * t.inverse_normal2;
  }
  // Off the triangle: its nearest point lies on an edge whose outer side p is on.
  double best = INFINITY;
  if (!over_ab) best = std::min(best, distance2_to_segment(p, t.a, t.b));
  if (!over_bc) best = std::min(best, distance2_to_segment(p, t.b, t.c));
  if (!over_ca) best = std::min(best, distance2_to_segment(p, t.c, t.a));
  return best;
}
}  // namespace

bool register_cases(CaseFactory factory) {
  factories().push_back(factory);
  return true;
}

std::vector<PrimitiveCase> all_cases() {
  std::vector<PrimitiveCase> out;
  for (CaseFactory f : factories()) {
    for (auto& c : f()) out.push_back(std::move(c));
  }
  std::sort(out.begin(), out.end(),
            [](const PrimitiveCase& a, const PrimitiveCase& b) { return a.name < b.name; });
  return out;
}

LevelMesh tessellate_level(const Primitive& primitive, const MeshPlan& plan, uint32_t level,
                           uint32_t fit_level) {
  std::vector<PackedVertex> vertices(plan.vertex_count);
  write_vertices(primitive, plan, glm::dvec3(0.0), vertices, fit_level);
  LevelMesh mesh;
  mesh.positions.reserve(vertices.size());
  for (const PackedVertex& v : vertices) {
    mesh.positions.push_back(v.position_m);
    mesh.normals.push_back(unpack_normal(v.normal));
  }
  mesh.indices.resize(plan.index_count(level));
  write_indices(plan, level, 0, std::span<uint32_t>(mesh.indices));
  return mesh;
}

float max_distance_to_mesh(const std::vector<glm::vec3>& points, const LevelMesh& mesh) {
  // Triangle bounds (kept apart, as they are read most) let most triangles be skipped once a
  // close one is found.
  struct Bounds {
    glm::dvec3 lo, hi;
  };
  std::vector<Triangle> tris;
  std::vector<Bounds> bounds;
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const glm::dvec3 a = mesh.positions[mesh.indices[t]], b = mesh.positions[mesh.indices[t + 1]],
                     c = mesh.positions[mesh.indices[t + 2]];
    tris.push_back(triangle(a, b, c));
    bounds.push_back({glm::min(a, glm::min(b, c)), glm::max(a, glm::max(b, c))});
  }
  // Samples come in sweeps, so the previous sample's nearest triangle is a close first guess.
  if (tris.empty()) return points.empty() ? 0.0f : INFINITY;
  double worst = 0.0;
  size_t nearest = 0;
  for (const glm::vec3& pf : points) {
    const glm::dvec3 p(pf);
    double best2 = distance2_to_triangle(p, tris[nearest]);
    for (size_t t = 0; t < tris.size(); ++t) {
      const glm::dvec3 d = glm::max(glm::max(bounds[t].lo - p, p - bounds[t].hi), glm::dvec3(0.0));
      if (glm::dot(d, d) >= best2) continue;
      const double d2 = distance2_to_triangle(p, tris[t]);
      if (d2 < best2) {
        best2 = d2;
        nearest = t;
      }
    }
    worst = std::max(worst, std::sqrt(best2));
  }
  return float(worst);
}

glm::mat3 rotation_about(glm::vec3 axis, float angle_rad) {
  const glm::vec3 u = glm::normalize(axis);
  const float c = std::cos(angle_rad), s = std::sin(angle_rad), t = 1 - c;
  // Columns of the rotation matrix (Rodrigues).
  return glm::mat3(t * u.x * u.x + c, t * u.x * u.y + s * u.z, t * u.x * u.z - s * u.y,
                   t * u.x * u.y - s * u.z, t * u.y * u.y + c, t * u.y * u.z + s * u.x,
                   t * u.x * u.z + s * u.y, t * u.y * u.z - s * u.x, t * u.z * u.z + c);
}

}  // namespace plantview::testing
