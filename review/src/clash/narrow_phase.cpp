// The narrow phase (plantview/clash.h): the overlapping parts of two objects, their contact
// points and depth, and, when nothing overlaps deeper than the tolerance, the clearance.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_map>

#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/cone.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/narrowphase/collision.h>

#include "clash/clash_internal.h"
#include "measure/measure_internal.h"

namespace plantview::clash_detail {

namespace {

constexpr int kRimPoints = 32;

struct Contact {
  fcl::Vector3d point;
  double depth_m = 0;
};

// Whether a mesh part's inside is known exactly (measure_internal.h: MeasurePart::solid), and
// its local frame: the placement's columns orthogonal and of one length (a mirror allowed).
void find_solid(const Primitive& primitive, const glm::dvec3& object_offset_m, MeasurePart& part) {
  const auto* torus = std::get_if<CircularTorus>(&primitive.shape);
  const auto* dish = std::get_if<SphericalDish>(&primitive.shape);
  if (!torus && !dish) return;
  glm::dvec3 axis[3];
  double scale = 0;
  for (int i = 0; i < 3; ++i) {
    axis[i] = glm::dvec3(primitive.placement.linear[i]);
    const double length = glm::length(axis[i]);
    if (!(length > 0) || !std::isfinite(length)) return;
    if (i > 0 && std::abs(length - scale) > 1e-6 * scale) return;
    scale = length;
    axis[i] /= length;
  }
  for (int i = 0; i < 3; ++i)
    if (std::abs(glm::dot(axis[i], axis[(i + 1) % 3])) > 1e-5) return;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) part.axes(r, c) = axis[r][c];
  const glm::dvec3 t = object_offset_m + glm::dvec3(primitive.placement.translation_m);
  part.origin = fcl::Vector3d(t.x, t.y, t.z);
  if (torus) {
    if (!(torus->tube_radius_m > 0) || !(torus->angle_rad > 0)) return;
    part.solid = MeasurePart::Solid::circular_torus;
    part.size[0] = double(torus->bend_radius_m) * scale;
    part.size[1] = double(torus->tube_radius_m) * scale;
    part.size[2] = double(torus->angle_rad);
  } else {
    const double b = double(dish->base_radius_m) * scale, h = double(dish->height_m) * scale;
    if (!(b > 0) || !(h > 0)) return;
    part.solid = MeasurePart::Solid::spherical_dish;
    part.size[0] = (b * b + h * h) / (2 * h);  // the sphere's radius
    part.size[1] = h - part.size[0];           // its centre's z
  }
}

// The points that stand for a part's surface in the vertex depth (frame coordinates), made
// once per part: a mesh's tessellation vertices on the true surface (the mesh's own are fitted
// to straddle it), a box's corners, points on a cylinder's or cone's rims and a cone's apex.
const std::vector<fcl::Vector3d>& part_points(MeasureShapes::Impl& set, MeasurePart& part) {
  if (part.has_surface_points) return part.surface_points;
  part.has_surface_points = true;
  std::vector<fcl::Vector3d>& out = part.surface_points;
  const auto rim = [&](double radius, double z) {
    for (int i = 0; i < kRimPoints; ++i) {
      const double t = 2 * std::numbers::pi * i / kRimPoints;
      out.push_back(part.transform * fcl::Vector3d(radius * std::cos(t), radius * std::sin(t), z));
    }
  };
  if (part.mesh) {
    const Primitive& primitive = set.primitives[part.primitive];
    find_solid(primitive, set.object_offset_m, part);
    const MeshPlan plan = plan_mesh(primitive);
    std::vector<PackedVertex> vertices(plan.vertex_count);
    write_vertices(primitive, plan, glm::dvec3(0.0), vertices, kOnSurface);
    out.reserve(vertices.size());
    for (const PackedVertex& v : vertices)
      out.push_back(part.transform * fcl::Vector3d(v.position_m.x, v.position_m.y, v.position_m.z));
    return out;
  }
  const fcl::CollisionGeometryd& g = set.geometry(part);
  if (const auto* box = dynamic_cast<const fcl::Boxd*>(&g)) {
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

// A mesh part's triangles with their bounds (its own frame: relative to the object's origin),
// from the tessellation its mesh is built of (measure_internal.h), made once per part.
void triangle_set(MeasureShapes::Impl& set, MeasurePart& part) {
  const Primitive& primitive = set.primitives[part.primitive];
  const PrimitiveTriangles t = primitive_triangles(primitive, plan_mesh(primitive), part.mesh_level, part.mesh_level);
  part.triangle_corners.reserve(t.indices.size());
  part.triangle_bounds.reserve(t.indices.size() / 3);
  for (size_t i = 0; i + 2 < t.indices.size(); i += 3) {
    fcl::Vector3d v[3];
    for (int k = 0; k < 3; ++k) {
      const glm::vec3& p = t.positions[t.indices[i + k]];
      v[k] = fcl::Vector3d(p.x, p.y, p.z);
      part.triangle_corners.push_back(v[k]);
    }
    fcl::AABBd box(v[0], v[1]);
    box += v[2];
    part.triangle_bounds.push_back(box);
  }
}

// How deep a point (the mesh's frame) lies behind a mesh: the distance to its nearest triangle
// when behind that triangle (outward winding), else 0.
double depth_in_mesh(const MeasurePart& mesh, const fcl::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  double depth = 0;
  for (size_t t = 0; t < mesh.triangle_bounds.size(); ++t) {
    // The triangle's bounds are no nearer than the best: it cannot be nearer.
    const fcl::AABBd& b = mesh.triangle_bounds[t];
    const double gap = (b.min_ - p).cwiseMax(p - b.max_).cwiseMax(0.0).squaredNorm();
    if (gap >= best * best) continue;
    const fcl::Vector3d &v0 = mesh.triangle_corners[3 * t], &v1 = mesh.triangle_corners[3 * t + 1],
                        &v2 = mesh.triangle_corners[3 * t + 2];
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
};

// How deep a point (local coordinates) lies inside a circular torus or spherical dish part
// (MeasurePart::solid): its distance to the surface, 0 outside.
double depth_in_solid(const MeasurePart& part, const fcl::Vector3d& p) {
  if (part.solid == MeasurePart::Solid::spherical_dish) {
    const double radius = part.size[0], centre_z = part.size[1];
    return std::max(0.0, std::min(radius - (p - fcl::Vector3d(0, 0, centre_z)).norm(), p.z()));
  }
  const double bend = part.size[0], tube = part.size[1], angle = part.size[2];
  const double rho = std::hypot(p.x(), p.y());
  double depth = tube - std::hypot(rho - bend, p.z());
  if (depth <= 0) return 0;
  if (angle < 2 * std::numbers::pi - 1e-9) {  // open: inside the swept angle, short of each end cap
    double theta = std::atan2(p.y(), p.x());
    if (theta < 0) theta += 2 * std::numbers::pi;
    if (theta > angle) return 0;
    const auto to_cap = [rho](double from_cap) {
      return from_cap < std::numbers::pi / 2 ? rho * std::sin(from_cap) : rho;
    };
    depth = std::min({depth, to_cap(theta), to_cap(angle - theta)});
  }
  return std::max(0.0, depth);
}

// How deep a point (frame coordinates) lies inside a part: the distance to its surface, 0
// outside. Exact kinds and solid meshes analytically; other meshes by their nearest triangle,
// inside when behind it.
double depth_inside(MeasureShapes::Impl& set, MeasurePart& part, const fcl::Vector3d& p_frame) {
  const fcl::AABBd& box = part.proxy->getAABB();
  if ((p_frame.array() < box.min_.array()).any() || (p_frame.array() > box.max_.array()).any()) return 0;
  if (part.mesh) {
    part_points(set, part);  // finds the solid
    if (part.solid != MeasurePart::Solid::none) return depth_in_solid(part, part.axes * (p_frame - part.origin));
    if (part.triangle_bounds.empty()) triangle_set(set, part);
    return depth_in_mesh(part, p_frame - part.transform.translation());
  }
  const fcl::CollisionGeometryd& g = set.geometry(part);
  const fcl::Vector3d p = part.transform.linear().transpose() * (p_frame - part.transform.translation());
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

// The deepest point of either part inside the other (clash.h): its depth, and where it is.
Contact deepest_point(Query& q, MeasurePart& pa, MeasurePart& pb) {
  Contact deepest;
  for (const fcl::Vector3d& p : part_points(*q.a, pa))
    if (const double d = depth_inside(*q.b, pb, p); d > deepest.depth_m) deepest = {p, d};
  for (const fcl::Vector3d& p : part_points(*q.b, pb))
    if (const double d = depth_inside(*q.a, pa, p); d > deepest.depth_m) deepest = {p, d};
  return deepest;
}

bool owns(const MeasureShapes::Impl& set, const MeasurePart* part) {
  return !set.parts.empty() && part >= set.parts.data() && part < set.parts.data() + set.parts.size();
}

// The interval an exact part covers along the unit direction `d` (frame coordinates); false for
// a kind without one here.
bool projection(const fcl::CollisionGeometryd& g, const fcl::Transform3d& tf, const fcl::Vector3d& d, double& lo,
                double& hi) {
  const double centre = d.dot(tf.translation());
  const fcl::Vector3d local = tf.linear().transpose() * d;  // d in the part's axes
  const double along = std::abs(local.z()), across = std::sqrt(std::max(0.0, 1.0 - along * along));
  double half = 0;
  if (const auto* box = dynamic_cast<const fcl::Boxd*>(&g)) {
    half = 0.5 * (std::abs(local.x()) * box->side[0] + std::abs(local.y()) * box->side[1] +
                  std::abs(local.z()) * box->side[2]);
  } else if (const auto* cylinder = dynamic_cast<const fcl::Cylinderd*>(&g)) {
    half = along * 0.5 * cylinder->lz + across * cylinder->radius;
  } else if (const auto* sphere = dynamic_cast<const fcl::Sphered*>(&g)) {
    half = sphere->radius;
  } else if (const auto* cone = dynamic_cast<const fcl::Coned*>(&g)) {  // apex at +z, base at -z
    const double apex = centre + 0.5 * cone->lz * local.z(), base = centre - 0.5 * cone->lz * local.z();
    lo = std::min(apex, base - across * cone->radius);
    hi = std::max(apex, base + across * cone->radius);
    return true;
  } else {
    return false;
  }
  lo = centre - half;
  hi = centre + half;
  return true;
}

// An upper bound on two overlapping exact parts' penetration depth (the shortest move that
// parts them): their overlap along any direction parts them when moved by it. Directions: the
// frame's axes, both parts' axes and the cross products of their axes (two crossing cylinders:
// the exact depth). FCL's libccd depth is measured along the line between the parts' centres
// (MPR), not the shortest way out: two pipes laid along one route read metres deep there.
double overlap_bound(const MeasurePart& pa, const MeasurePart& pb) {
  const fcl::CollisionGeometryd& ga = *pa.geometry;
  const fcl::CollisionGeometryd& gb = *pb.geometry;
  std::array<fcl::Vector3d, 18> directions;
  size_t n = 0;
  for (int i = 0; i < 3; ++i) {
    directions[n++] = fcl::Vector3d::Unit(i);
    directions[n++] = pa.transform.linear().col(i);
    directions[n++] = pb.transform.linear().col(i);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const fcl::Vector3d normal = pa.transform.linear().col(i).cross(pb.transform.linear().col(j));
      if (normal.norm() > 1e-6 && n < directions.size()) directions[n++] = normal.normalized();
    }
  double bound = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < n; ++k) {
    const fcl::Vector3d& d = directions[k];
    double alo, ahi, blo, bhi;
    if (!projection(ga, pa.transform, d, alo, ahi) || !projection(gb, pb.transform, d, blo, bhi))
      return std::numeric_limits<double>::infinity();
    bound = std::min(bound, std::max(0.0, std::min(ahi - blo, bhi - alo)));
  }
  return bound;
}

bool collide_pair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto& q = *static_cast<Query*>(data);
  auto* pa = static_cast<MeasurePart*>(o1->getUserData());
  auto* pb = static_cast<MeasurePart*>(o2->getUserData());
  if (!owns(*q.a, pa)) std::swap(pa, pb);
  if (pa->mesh || pb->mesh) {
    // Where a mesh is involved the depth is the deepest sampled point, so the points alone say
    // whether the parts overlap: no mesh tree is built (its build was most of a run's time).
    const Contact deepest = deepest_point(q, *pa, *pb);
    if (deepest.depth_m > 0) {
      q.contacts.push_back(deepest);
      q.error_m = std::max(q.error_m, pa->error_m + pb->error_m);
    }
    return false;
  }
  fcl::CollisionRequestd request(1, true);
  request.gjk_solver_type = fcl::GST_LIBCCD;
  fcl::CollisionResultd result;
  fcl::collide(&q.a->geometry(*pa), pa->transform, &q.b->geometry(*pb), pb->transform, request, result);
  if (result.numContacts() == 0) return false;
  const fcl::Contactd& c = result.getContact(0);
  const double depth = c.penetration_depth > 0
                           ? std::min(c.penetration_depth, overlap_bound(*pa, *pb))
                           : deepest_point(q, *pa, *pb).depth_m;
  q.contacts.push_back({c.pos, depth});
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
