// The pick ray: the camera ray through a pixel, cast against one object's primitives (their
// finest on-surface tessellation), with sections applied (plantview/measure.h).
#include <algorithm>
#include <cmath>
#include <limits>

#include "measure/measure_internal.h"

namespace plantview {

Ray pixel_ray(const Camera& camera, uint32_t width, uint32_t height, uint32_t x, uint32_t y) {
  // The renderer's frame (frame_plan.cpp): glm::lookAt's right and up, the same fallback ups,
  // a vertical fov and the aspect width / height; pixel rows run from the top.
  const glm::dvec3 forward = glm::normalize(camera.target_m - camera.eye_m);
  glm::dvec3 up = camera.up;
  if (glm::length(glm::cross(forward, up)) < 1e-9 * glm::length(up)) up = glm::dvec3(0, 1, 0);
  if (glm::length(glm::cross(forward, up)) < 1e-9) up = glm::dvec3(1, 0, 0);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, up));
  const glm::dvec3 true_up = glm::cross(right, forward);
  const double tan_half = std::tan(glm::radians(camera.fov_deg) / 2.0);
  const double aspect = double(width) / double(height);
  const double ndc_x = 2.0 * (double(x) + 0.5) / double(width) - 1.0;
  const double ndc_y = 1.0 - 2.0 * (double(y) + 0.5) / double(height);
  Ray ray;
  ray.origin_m = camera.eye_m;
  ray.direction = glm::normalize(forward + right * (ndc_x * aspect * tan_half) + true_up * (ndc_y * tan_half));
  return ray;
}

namespace {

bool ray_hits_box(const Ray& ray, const glm::dvec3& lo, const glm::dvec3& hi) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double inv = 1.0 / ray.direction[a];
    double ta = (lo[a] - ray.origin_m[a]) * inv, tb = (hi[a] - ray.origin_m[a]) * inv;
    if (std::isnan(ta) || std::isnan(tb)) {  // along the slab's face
      if (ray.origin_m[a] < lo[a] || ray.origin_m[a] > hi[a]) return false;
      continue;
    }
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

struct Crossing {
  double t = 0;
  glm::dvec3 normal{0.0};  // the triangle's, unit, by its winding
  bool closed = false;     // of a closed solid (winding outward)
  uint32_t primitive = 0;
};

// Möller-Trumbore, in double, relative to the object's origin.
bool intersect(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& a, const glm::dvec3& b,
               const glm::dvec3& c, double& t) {
  const glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
  const double det = glm::dot(e1, p);
  if (std::abs(det) < 1e-18) return false;
  const double inv = 1.0 / det;
  const glm::dvec3 s = o - a;
  const double u = glm::dot(s, p) * inv;
  if (u < 0 || u > 1) return false;
  const glm::dvec3 q = glm::cross(s, e1);
  const double v = glm::dot(d, q) * inv;
  if (v < 0 || u + v > 1) return false;
  t = glm::dot(e2, q) * inv;
  return t > 0;
}

// Where the ray enters the part of space the section keeps, and the face's normal there
// (facing the ray's origin); t = -1 when the ray starts inside it.
struct Entry {
  double t = -1;
  glm::dvec3 normal{0.0};
};
Entry section_entry(const Section& section, const Ray& ray) {
  Entry e;
  for (const ClipPlane& plane : section.planes) {
    const double along = glm::dot(ray.direction, plane.normal);
    if (along >= 0) continue;  // moving into the removed side, or parallel: no entry
    const double t = glm::dot(plane.point_m - ray.origin_m, plane.normal) / along;
    if (t > e.t) {
      e.t = t;
      e.normal = plane.normal;  // into the removed side: towards the eye
    }
  }
  if (section.has_box) {
    for (int a = 0; a < 3; ++a) {
      if (ray.direction[a] == 0) continue;
      const bool up = ray.direction[a] > 0;  // entering through the min face
      const double face = up ? section.box.min[a] : section.box.max[a];
      const double t = (face - ray.origin_m[a]) / ray.direction[a];
      if (t > e.t) {
        e.t = t;
        e.normal = glm::dvec3(0.0);
        e.normal[a] = up ? -1.0 : 1.0;
      }
    }
  }
  return e;
}

}  // namespace

std::optional<SurfaceHit> cast_ray(const Object& object, const Ray& ray, const Section* section) {
  if (section && section->empty()) section = nullptr;
  // Relative to the object's origin, where the tessellation's positions are.
  Ray local = ray;
  local.origin_m = ray.origin_m - object.origin_m;
  std::vector<Crossing> crossings;
  for (uint32_t i = 0; i < object.primitives.size(); ++i) {
    const Primitive& primitive = object.primitives[i];
    const Aabb b = model_bounds(primitive);
    if (b.empty() || !ray_hits_box(local, glm::dvec3(b.min) - 1e-4, glm::dvec3(b.max) + 1e-4)) continue;
    const PrimitiveTriangles mesh = primitive_triangles(primitive, plan_mesh(primitive), 0);
    for (size_t k = 0; k + 2 < mesh.indices.size(); k += 3) {
      const glm::dvec3 p0(mesh.positions[mesh.indices[k]]), p1(mesh.positions[mesh.indices[k + 1]]),
          p2(mesh.positions[mesh.indices[k + 2]]);
      double t = 0;
      if (!intersect(local.origin_m, local.direction, p0, p1, p2, t)) continue;
      const glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
      const double len = glm::length(n);
      if (!(len > 0)) continue;
      crossings.push_back({t, n / len, mesh.closed, i});
    }
  }
  std::sort(crossings.begin(), crossings.end(), [](const Crossing& x, const Crossing& y) { return x.t < y.t; });
  const Entry entry = section ? section_entry(*section, ray) : Entry{};
  for (const Crossing& c : crossings) {
    const glm::dvec3 point = ray.origin_m + ray.direction * c.t;
    if (section && section_removes(*section, point)) continue;
    SurfaceHit hit;
    hit.primitive = c.primitive;
    const bool back = glm::dot(c.normal, ray.direction) > 0;
    if (section && c.closed && back && entry.t >= 0 && entry.t <= c.t) {
      // The inside of a cut solid: what shows is its cap on the cutting face.
      hit.distance_m = entry.t;
      hit.point_m = ray.origin_m + ray.direction * entry.t;
      hit.normal = entry.normal;
      hit.on_cut = true;
      return hit;
    }
    hit.distance_m = c.t;
    hit.point_m = point;
    hit.normal = back ? -c.normal : c.normal;
    return hit;
  }
  return std::nullopt;
}

}  // namespace plantview
