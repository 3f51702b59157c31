// The narrow phase (plantview/clash.h): the overlapping parts of two objects, their contact
// points and depth, and, when nothing overlaps deeper than the tolerance, the clearance.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_map>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/cone.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/narrowphase/collision.h>

#include "clash/clash_internal.h"
#include "measure/measure_internal.h"

namespace plantview::clash_detail {

namespace {

using Mesh = fcl::BVHModel<fcl::OBBRSSd>;
constexpr int kRimPoints = 32;

struct Contact {
  fcl::Vector3d point;
  double depth_m = 0;
};

// The points that stand for a part's surface in the vertex depth (frame coordinates): a
// mesh's vertices on the surface, a box's corners, points on a cylinder's or cone's rims and a cone's apex.
std::vector<fcl::Vector3d> part_points(MeasureShapes::Impl& set, MeasurePart& part) {
  std::vector<fcl::Vector3d> out;
  const fcl::CollisionGeometryd& g = set.geometry(part);
  const auto rim = [&](double radius, double z) {
    for (int i = 0; i < kRimPoints; ++i) {
      const double t = 2 * std::numbers::pi * i / kRimPoints;
      out.push_back(part.transform * fcl::Vector3d(radius * std::cos(t), radius * std::sin(t), z));
    }
  };
  if (part.mesh) {
    // The tessellation's vertices on the true surface (the mesh's are fitted to straddle it).
    const Primitive& primitive = set.primitives[part.primitive];
    const PrimitiveTriangles on_surface =
        primitive_triangles(primitive, plan_mesh(primitive), part.mesh_level, kOnSurface);
    out.reserve(on_surface.positions.size());
    for (const glm::vec3& p : on_surface.positions) out.push_back(part.transform * fcl::Vector3d(p.x, p.y, p.z));
  } else if (const auto* box = dynamic_cast<const fcl::Boxd*>(&g)) {
    for (int i = 0; i < 8; ++i)
      out.push_back(part.transform * fcl::Vector3d((i & 1 ? 0.5 : -0.5) * box->side[0],
                                                   (i & 2 ? 0.5 : -0.5) * box->side[1],
                                                   (i & 4 ? 0.5 : -0.5) * box->side[2]));
  } else if (const auto* cylinder = dynamic_cast<const fcl::Cylinderd*>(&g)) {
    rim(cylinder->radius, -0.5 * cylinder->lz);
    rim(cylinder->radius, 0.5 * cylinder->lz);
  } else if (const auto* cone = dynamic_cast<const fcl::Coned*>(&g)) {
    rim(cone->radius, -0.5 * cone->lz);
    out.push_back(part.transform * fcl::Vector3d(0, 0, 0.5 * cone->lz));
  }
  return out;
}

fcl::Vector3d closest_on_triangle(const fcl::Vector3d& p, const fcl::Vector3d& a, const fcl::Vector3d& b,
                                  const fcl::Vector3d& c) {
  // Ericson, Real-Time Collision Detection 5.1.5.
  const fcl::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const fcl::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const fcl::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// A mesh's triangles with their bounds (the mesh's frame), made once per part and pair.
struct TriangleSet {
  std::vector<fcl::Vector3d> corners;  // three a triangle
  std::vector<fcl::AABBd> bounds;
};

template <typename BV>
void triangle_set(const fcl::BVHModel<BV>& mesh, TriangleSet& out) {
  out.corners.reserve(size_t(mesh.num_tris) * 3);
  out.bounds.reserve(size_t(mesh.num_tris));
  for (int t = 0; t < mesh.num_tris; ++t) {
    const fcl::Triangle& tri = mesh.tri_indices[t];
    const fcl::Vector3d &v0 = mesh.vertices[tri[0]], &v1 = mesh.vertices[tri[1]], &v2 = mesh.vertices[tri[2]];
    out.corners.insert(out.corners.end(), {v0, v1, v2});
    fcl::AABBd box(v0, v1);
    box += v2;
    out.bounds.push_back(box);
  }
}

// How deep a point (the mesh's frame) lies behind a mesh: the distance to its nearest triangle
// when behind that triangle (outward winding), else 0.
double depth_in_mesh(const TriangleSet& mesh, const fcl::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  double depth = 0;
  for (size_t t = 0; t < mesh.bounds.size(); ++t) {
    // The triangle's bounds are no nearer than the best: it cannot be nearer.
    const fcl::AABBd& b = mesh.bounds[t];
    const double gap = (b.min_ - p).cwiseMax(p - b.max_).cwiseMax(0.0).squaredNorm();
    if (gap >= best * best) continue;
    const fcl::Vector3d &v0 = mesh.corners[3 * t], &v1 = mesh.corners[3 * t + 1], &v2 = mesh.corners[3 * t + 2];
    const fcl::Vector3d q = closest_on_triangle(p, v0, v1, v2);
    const double d = (p - q).norm();
    if (d < best) {
      best = d;
      depth = (p - q).dot((v1 - v0).cross(v2 - v0)) < 0 ? d : 0.0;
    }
  }
  return depth;
}

struct Query {
  MeasureShapes::Impl* a = nullptr;
  MeasureShapes::Impl* b = nullptr;
  std::vector<Contact> contacts;
  double error_m = 0;
  std::unordered_map<const MeasurePart*, TriangleSet> triangles;  // meshes' triangles, once
};

// How deep a point (frame coordinates) lies inside a part: the distance to its surface, 0
// outside. Exact kinds analytically; a mesh by its nearest triangle, inside when behind it.
double depth_inside(MeasureShapes::Impl& set, MeasurePart& part, const fcl::Vector3d& p_frame,
                    std::unordered_map<const MeasurePart*, TriangleSet>& triangles) {
  const fcl::AABBd& box = part.proxy->getAABB();
  if ((p_frame.array() < box.min_.array()).any() || (p_frame.array() > box.max_.array()).any()) return 0;
  const fcl::CollisionGeometryd& g = set.geometry(part);
  const fcl::Vector3d p = part.transform.inverse() * p_frame;
  if (part.mesh) {
    auto [it, added] = triangles.try_emplace(&part);
    if (added) {
      if (set.collide_only)
        triangle_set(static_cast<const fcl::BVHModel<fcl::AABBd>&>(g), it->second);
      else
        triangle_set(static_cast<const Mesh&>(g), it->second);
    }
    return depth_in_mesh(it->second, p);
  }
  if (const auto* b = dynamic_cast<const fcl::Boxd*>(&g)) {
    const fcl::Vector3d h = b->side * 0.5;
    const fcl::Vector3d room = h - p.cwiseAbs();
    return std::max(0.0, room.minCoeff());
  }
  const double rho = std::hypot(p.x(), p.y());
  if (const auto* c = dynamic_cast<const fcl::Cylinderd*>(&g))
    return std::max(0.0, std::min(c->radius - rho, 0.5 * c->lz - std::abs(p.z())));
  if (const auto* c = dynamic_cast<const fcl::Coned*>(&g)) {
    const double radius_here = c->radius * (0.5 * c->lz - p.z()) / c->lz;
    const double lateral = (radius_here - rho) * c->lz / std::hypot(c->lz, c->radius);
    return std::max(0.0, std::min({lateral, p.z() + 0.5 * c->lz, 0.5 * c->lz - p.z()}));
  }
  if (const auto* s = dynamic_cast<const fcl::Sphered*>(&g)) return std::max(0.0, s->radius - p.norm());
  return 0;  // a line (capsule of radius 0) has no inside
}

// The depth of two overlapping parts (clash.h).
double part_depth(Query& q, MeasurePart& pa, MeasurePart& pb, double ccd_depth_m) {
  if (!pa.mesh && !pb.mesh && ccd_depth_m > 0) return ccd_depth_m;
  double depth = 0;
  for (const fcl::Vector3d& p : part_points(*q.a, pa)) depth = std::max(depth, depth_inside(*q.b, pb, p, q.triangles));
  for (const fcl::Vector3d& p : part_points(*q.b, pb)) depth = std::max(depth, depth_inside(*q.a, pa, p, q.triangles));
  return depth;
}

bool owns(const MeasureShapes::Impl& set, const MeasurePart* part) {
  return !set.parts.empty() && part >= set.parts.data() && part < set.parts.data() + set.parts.size();
}

bool collide_pair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto& q = *static_cast<Query*>(data);
  auto* pa = static_cast<MeasurePart*>(o1->getUserData());
  auto* pb = static_cast<MeasurePart*>(o2->getUserData());
  if (!owns(*q.a, pa)) std::swap(pa, pb);
  fcl::CollisionRequestd request(1, true);
  request.gjk_solver_type = fcl::GST_LIBCCD;
  fcl::CollisionResultd result;
  fcl::collide(&q.a->geometry(*pa), pa->transform, &q.b->geometry(*pb), pb->transform, request, result);
  if (result.numContacts() == 0) return false;
  const fcl::Contactd& c = result.getContact(0);
  q.contacts.push_back({c.pos, part_depth(q, *pa, *pb, std::max(0.0, c.penetration_depth))});
  q.error_m = std::max(q.error_m, pa->error_m + pb->error_m);
  return false;
}

}  // namespace

std::optional<PairClash> narrow_phase(const MeasureShapes& a, const MeasureShapes& b, double tolerance_m,
                                      double clearance_m) {
  Query q;
  q.a = &a.impl();
  q.b = &b.impl();
  q.a->manager.collide(&q.b->manager, &q, collide_pair);
  const glm::dvec3 origin = a.frame_origin_m();
  PairClash out;
  double depth = 0;
  for (const Contact& c : q.contacts) depth = std::max(depth, c.depth_m);
  if (depth > tolerance_m) {
    // The places: deepest first, each at least kClashPointSpacingM from those kept.
    std::sort(q.contacts.begin(), q.contacts.end(), [](const Contact& x, const Contact& y) {
      if (x.depth_m != y.depth_m) return x.depth_m > y.depth_m;
      return std::lexicographical_compare(x.point.data(), x.point.data() + 3, y.point.data(), y.point.data() + 3);
    });
    std::vector<fcl::Vector3d> kept;
    for (const Contact& c : q.contacts) {
      if (kept.size() >= kClashMaxPoints) break;
      bool near = false;
      for (const fcl::Vector3d& k : kept) near = near || (k - c.point).norm() < kClashPointSpacingM;
      if (!near) kept.push_back(c.point);
    }
    out.kind = ClashKind::hard;
    out.depth_m = depth;
    out.error_m = q.error_m;
    for (const fcl::Vector3d& k : kept) out.points_m.push_back(origin + glm::dvec3(k.x(), k.y(), k.z()));
    return out;
  }
  if (!(clearance_m > 0)) return std::nullopt;
  out.kind = ClashKind::clearance;
  if (!q.contacts.empty()) {  // touching, or shallower than the tolerance
    out.distance_m = 0;
    out.error_m = q.error_m;
    const fcl::Vector3d& p = q.contacts.front().point;
    out.points_m.push_back(origin + glm::dvec3(p.x(), p.y(), p.z()));
    return out;
  }
  const Clearance c = measure_clearance(a, b);
  if (!(c.distance_m < clearance_m)) return std::nullopt;
  out.distance_m = c.distance_m;
  out.error_m = c.error_m;
  out.points_m.push_back((c.point_a_m + c.point_b_m) * 0.5);
  return out;
}

uint64_t clash_id(uint64_t id_a, uint64_t id_b, const glm::dvec3& point_m) {
  if (id_b < id_a) std::swap(id_a, id_b);
  uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](uint64_t v) {
    for (int i = 0; i < 8; ++i) {
      h ^= (v >> (8 * i)) & 0xff;
      h *= 1099511628211ull;
    }
  };
  mix(id_a);
  mix(id_b);
  for (int i = 0; i < 3; ++i) mix(uint64_t(int64_t(std::floor(point_m[i] / kClashIdGridM))));
  return h;
}

}  // namespace plantview::clash_detail
