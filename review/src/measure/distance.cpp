// The distance query: object A's parts against object B's, pruned nearest-first by the two
// broadphase trees, each surviving pair measured by FCL (plantview/measure.h).
#include <cassert>
#include <cmath>
#include <limits>

#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>

#include "measure/measure_internal.h"

namespace plantview {

namespace {

struct Query {
  MeasureShapes::Impl* a = nullptr;
  MeasureShapes::Impl* b = nullptr;
  fcl::DistanceRequestd request;
  double best_m = std::numeric_limits<double>::infinity();
  MeasurePart* best_a = nullptr;
  MeasurePart* best_b = nullptr;
  fcl::Vector3d point_a{0, 0, 0}, point_b{0, 0, 0};
  bool overlapping = false;
  double penetration_m = 0;
  // Every tessellated pair measured: the gap between its bounds and its two parts' errors.
  std::vector<std::pair<double, double>> tessellated;
};

// The distance between two boxes (0 when they meet).
double bounds_gap(const fcl::AABBd& x, const fcl::AABBd& y) {
  return (x.min_ - y.max_).cwiseMax(y.min_ - x.max_).cwiseMax(0.0).norm();
}

// How far a point lies outside a part's bounds.
double bounds_gap(const MeasurePart& part, const fcl::Vector3d& p) {
  const fcl::AABBd& box = part.proxy->getAABB();
  return (p - p.cwiseMax(box.min_).cwiseMin(box.max_)).norm();
}

// FCL 0.7 answers the nearest points of a shape-mesh pair mesh first whatever the order asked,
// and a sphere's (or the mesh's) in its own frame; every other pair in the query's order and
// frame. So the points are taken in the reading (order, frame) under which they lie `d` apart
// and each within its own part's bounds.
void read_points(const MeasurePart& pa, const MeasurePart& pb, double d, fcl::Vector3d& a, fcl::Vector3d& b) {
  if (pa.mesh == pb.mesh) return;
  const fcl::Vector3d n0 = a, n1 = b;
  double best = std::numeric_limits<double>::infinity();
  for (int reading = 0; reading < 8; ++reading) {
    const bool swap = reading & 1, shape_local = reading & 2, mesh_local = reading & 4;
    fcl::Vector3d u = swap ? n1 : n0, v = swap ? n0 : n1;
    fcl::Vector3d& shape_point = pa.mesh ? v : u;
    fcl::Vector3d& mesh_point = pa.mesh ? u : v;
    if (shape_local) shape_point = (pa.mesh ? pb : pa).transform * shape_point;
    if (mesh_local) mesh_point = (pa.mesh ? pa : pb).transform * mesh_point;
    const double miss = std::abs((v - u).norm() - d) + bounds_gap(pa, u) + bounds_gap(pb, v);
    if (miss < best - 1e-12) {
      best = miss;
      a = u;
      b = v;
    }
  }
}

bool owns(const MeasureShapes::Impl& set, const MeasurePart* part) {
  return !set.parts.empty() && part >= set.parts.data() && part < set.parts.data() + set.parts.size();
}

// Where two overlapping parts touch, and how deep (0 where FCL cannot tell: meshes).
void contact(Query& q, MeasurePart& pa, MeasurePart& pb) {
  fcl::CollisionRequestd request(1, true);
  request.gjk_solver_type = fcl::GST_LIBCCD;  // its MPR reports the depth of convex pairs
  fcl::CollisionResultd result;
  fcl::collide(&q.a->geometry(pa), pa.transform, &q.b->geometry(pb), pb.transform, request, result);
  if (result.numContacts() > 0) {
    const fcl::Contactd& c = result.getContact(0);
    q.point_a = q.point_b = c.pos;
    q.penetration_m = (pa.mesh || pb.mesh) ? 0.0 : std::max(0.0, c.penetration_depth);
  }
}

// The broadphase's callback for a pair of proxies: measures the pair, keeps the nearest, and
// stops at the first overlap. `dist` is the bound the broadphase prunes by.
bool measure_pair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data, double& dist) {
  auto& q = *static_cast<Query*>(data);
  auto* p1 = static_cast<MeasurePart*>(o1->getUserData());
  auto* p2 = static_cast<MeasurePart*>(o2->getUserData());
  if (!owns(*q.a, p1)) std::swap(p1, p2);
  assert(owns(*q.a, p1) && owns(*q.b, p2));
  if (p1->error_m + p2->error_m > 0)
    q.tessellated.emplace_back(bounds_gap(p1->proxy->getAABB(), p2->proxy->getAABB()), p1->error_m + p2->error_m);
  fcl::DistanceResultd result;
  fcl::distance(&q.a->geometry(*p1), p1->transform, &q.b->geometry(*p2), p2->transform, q.request, result);
  const double d = result.min_distance;
  if (d <= 0) {
    q.overlapping = true;
    q.best_m = 0;
    q.best_a = p1;
    q.best_b = p2;
    q.point_a = result.nearest_points[0];
    q.point_b = result.nearest_points[1];
    q.penetration_m = 0;
    contact(q, *p1, *p2);
    dist = 0;
    return true;
  }
  if (d < q.best_m) {
    q.best_m = d;
    q.best_a = p1;
    q.best_b = p2;
    q.point_a = result.nearest_points[0];
    q.point_b = result.nearest_points[1];
    read_points(*p1, *p2, d, q.point_a, q.point_b);
  }
  dist = q.best_m;
  return false;
}

}  // namespace

Clearance measure_clearance(const MeasureShapes& a, const MeasureShapes& b) {
  assert(!a.empty() && !b.empty());
  assert(a.frame_origin_m() == b.frame_origin_m());
  assert(!a.collide_only() && !b.collide_only());
  Query q;
  q.a = &a.impl();
  q.b = &b.impl();
  q.request.enable_nearest_points = true;
  q.request.enable_signed_distance = false;  // depth from collide() instead: see contact()
  q.request.gjk_solver_type = fcl::GST_INDEP;
  q.a->manager.distance(&q.b->manager, &q, measure_pair);
  Clearance c;
  assert(q.best_a && q.best_b);
  c.overlapping = q.overlapping;
  c.distance_m = q.overlapping ? 0.0 : q.best_m;
  c.penetration_m = q.penetration_m;
  const glm::dvec3 origin = a.frame_origin_m();
  c.point_a_m = origin + glm::dvec3(q.point_a.x(), q.point_a.y(), q.point_a.z());
  c.point_b_m = origin + glm::dvec3(q.point_b.x(), q.point_b.y(), q.point_b.z());
  // The true nearest pair lies within bounds no farther apart than the answer, and every pair
  // whose bounds are that near was measured (the trees prune only farther ones): the answer is
  // off by at most the errors of the pair it came from and of those pairs.
  c.error_m = q.best_a->error_m + q.best_b->error_m;
  for (const auto& [gap, error] : q.tessellated)
    if (gap <= c.distance_m + 1e-9) c.error_m = std::max(c.error_m, error);
  c.analytic = c.error_m == 0;
  c.primitive_a = q.best_a->primitive;
  c.primitive_b = q.best_b->primitive;
  return c;
}

bool measure_objects(const Object& a, const Object& b, Clearance& out, std::string& error) {
  const auto label = [](const Object& o) {
    return o.name.empty() ? "object " + std::to_string(o.id) : "'" + o.name + "'";
  };
  MeasureShapes shapes_a(a.primitives, a.origin_m, a.origin_m);
  if (shapes_a.empty()) {
    error = label(a) + " has no geometry to measure (no primitive with a surface)";
    return false;
  }
  MeasureShapes shapes_b(b.primitives, b.origin_m, a.origin_m);
  if (shapes_b.empty()) {
    error = label(b) + " has no geometry to measure (no primitive with a surface)";
    return false;
  }
  out = measure_clearance(shapes_a, shapes_b);
  return true;
}

}  // namespace plantview
