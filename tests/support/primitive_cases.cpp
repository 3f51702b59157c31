#include "primitive_cases.h"

#include <algorithm>
#include <cmath>

namespace plantview::testing {

namespace {
std::vector<CaseFactory>& factories() {
  static std::vector<CaseFactory> list;
  return list;
}

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
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
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
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

LevelMesh tessellate_level(const Primitive& primitive, const MeshPlan& plan, uint32_t level) {
  std::vector<PackedVertex> vertices(plan.vertex_count);
  write_vertices(primitive, plan, glm::dvec3(0.0), vertices);
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
  // Triangle bounds let most triangles be skipped once a close one is found.
  struct Tri {
    glm::dvec3 a, b, c, lo, hi;
  };
  std::vector<Tri> tris;
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    Tri tri{mesh.positions[mesh.indices[t]], mesh.positions[mesh.indices[t + 1]],
            mesh.positions[mesh.indices[t + 2]], {}, {}};
    tri.lo = glm::min(tri.a, glm::min(tri.b, tri.c));
    tri.hi = glm::max(tri.a, glm::max(tri.b, tri.c));
    tris.push_back(tri);
  }
  double worst = 0.0;
  for (const glm::vec3& pf : points) {
    const glm::dvec3 p(pf);
    double best2 = INFINITY;
    for (const Tri& tri : tris) {
      const glm::dvec3 d = glm::max(glm::max(tri.lo - p, p - tri.hi), glm::dvec3(0.0));
      if (glm::dot(d, d) >= best2) continue;
      const glm::dvec3 q = closest_on_triangle(p, tri.a, tri.b, tri.c);
      best2 = std::min(best2, glm::dot(q - p, q - p));
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
