// FCL shapes from primitives: exact FCL primitives where a kind maps to one under its placement,
// else a bounding-volume tree of the on-surface tessellation (plantview/measure.h).
#include <algorithm>
#include <cassert>
#include <cmath>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/cone.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/sphere.h>

#include "measure/measure_internal.h"

namespace plantview {

namespace {

// The placement as rotation * diag(scale) (a proper rotation; a mirror is folded into x, about
// which every exact kind is symmetric). False when the axes are not orthogonal (a shear).
bool rotation_and_scale(const glm::mat3& linear, fcl::Matrix3d& rotation, glm::dvec3& scale) {
  glm::dvec3 axis[3];
  for (int i = 0; i < 3; ++i) {
    axis[i] = glm::dvec3(linear[i]);
    scale[i] = glm::length(axis[i]);
    if (!(scale[i] > 0) || !std::isfinite(scale[i])) return false;
    axis[i] /= scale[i];
  }
  for (int i = 0; i < 3; ++i)
    if (std::abs(glm::dot(axis[i], axis[(i + 1) % 3])) > 1e-5) return false;
  if (glm::dot(glm::cross(axis[0], axis[1]), axis[2]) < 0) axis[0] = -axis[0];
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) rotation(r, c) = axis[c][r];
  return true;
}

bool near_equal(double a, double b) { return std::abs(a - b) <= 1e-6 * std::max(std::abs(a), std::abs(b)); }

}  // namespace

namespace {

// A line is a segment: a capsule of radius 0 along it (any placement: a line stays a line).
std::shared_ptr<fcl::CollisionGeometryd> segment(const Line& line, const Placement& placement,
                                                 const glm::dvec3& offset_m, fcl::Transform3d& transform) {
  const glm::dvec3 axis(placement.linear[0]);
  const glm::dvec3 a = axis * double(line.start_x_m), b = axis * double(line.end_x_m);
  const double length = glm::length(b - a);
  if (!(length > 0) || !std::isfinite(length)) return nullptr;
  const glm::dvec3 z = (b - a) / length;
  const glm::dvec3 x = glm::normalize(std::abs(z.x) < 0.9 ? glm::cross(glm::dvec3(1, 0, 0), z)
                                                           : glm::cross(glm::dvec3(0, 1, 0), z));
  const glm::dvec3 y = glm::cross(z, x);
  const glm::dvec3 centre = offset_m + glm::dvec3(placement.translation_m) + (a + b) * 0.5;
  transform = fcl::Transform3d::Identity();
  for (int r = 0; r < 3; ++r) {
    transform.linear()(r, 0) = x[r];
    transform.linear()(r, 1) = y[r];
    transform.linear()(r, 2) = z[r];
  }
  transform.translation() = fcl::Vector3d(centre.x, centre.y, centre.z);
  auto shape = std::make_shared<fcl::Capsuled>(0.0, length);
  shape->computeLocalAABB();
  return shape;
}

}  // namespace

std::shared_ptr<fcl::CollisionGeometryd> exact_shape(const Primitive& primitive,
                                                     const glm::dvec3& offset_m,
                                                     fcl::Transform3d& transform) {
  if (const auto* line = std::get_if<Line>(&primitive.shape))
    return segment(*line, primitive.placement, offset_m, transform);
  fcl::Matrix3d rotation;
  glm::dvec3 s(1.0);
  if (!rotation_and_scale(primitive.placement.linear, rotation, s)) return nullptr;
  std::shared_ptr<fcl::CollisionGeometryd> shape;
  bool flip_z = false;  // a cone with its apex at -z: turned half about x
  if (const auto* box = std::get_if<Box>(&primitive.shape)) {
    if (box->size_x_m > 0 && box->size_y_m > 0 && box->size_z_m > 0)
      shape = std::make_shared<fcl::Boxd>(box->size_x_m * s.x, box->size_y_m * s.y, box->size_z_m * s.z);
  } else if (const auto* cylinder = std::get_if<Cylinder>(&primitive.shape)) {
    if (near_equal(s.x, s.y) && cylinder->radius_m > 0 && cylinder->height_m > 0)
      shape = std::make_shared<fcl::Cylinderd>(cylinder->radius_m * s.x, cylinder->height_m * s.z);
  } else if (const auto* snout = std::get_if<Snout>(&primitive.shape)) {
    const bool straight = snout->offset_x_m == 0 && snout->offset_y_m == 0 &&
                          snout->bottom_shear_x_rad == 0 && snout->bottom_shear_y_rad == 0 &&
                          snout->top_shear_x_rad == 0 && snout->top_shear_y_rad == 0;
    const double rb = snout->radius_bottom_m, rt = snout->radius_top_m, h = snout->height_m;
    if (straight && near_equal(s.x, s.y) && h > 0) {
      if (rb > 0 && rb == rt) shape = std::make_shared<fcl::Cylinderd>(rb * s.x, h * s.z);
      else if (rb > 0 && rt == 0) shape = std::make_shared<fcl::Coned>(rb * s.x, h * s.z);
      else if (rt > 0 && rb == 0) {
        shape = std::make_shared<fcl::Coned>(rt * s.x, h * s.z);
        flip_z = true;
      }
    }
  } else if (const auto* sphere = std::get_if<Sphere>(&primitive.shape)) {
    if (near_equal(s.x, s.y) && near_equal(s.x, s.z) && sphere->radius_m > 0)
      shape = std::make_shared<fcl::Sphered>(sphere->radius_m * s.x);
  }
  if (!shape) return nullptr;
  if (flip_z) rotation = rotation * fcl::Matrix3d(fcl::Vector3d(1, -1, -1).asDiagonal());
  shape->computeLocalAABB();
  const glm::dvec3 t = offset_m + glm::dvec3(primitive.placement.translation_m);
  transform = fcl::Transform3d::Identity();
  transform.linear() = rotation;
  transform.translation() = fcl::Vector3d(t.x, t.y, t.z);
  return shape;
}

PrimitiveTriangles primitive_triangles(const Primitive& primitive, const MeshPlan& plan,
                                       uint32_t level, uint32_t fit_level) {
  PrimitiveTriangles out;
  if (plan.topology != Topology::triangles || plan.vertex_count == 0) return out;
  std::vector<PackedVertex> vertices(plan.vertex_count);
  write_vertices(primitive, plan, glm::dvec3(0.0), vertices, fit_level);
  out.positions.reserve(vertices.size());
  for (const PackedVertex& v : vertices) out.positions.push_back(v.position_m);
  out.indices.resize(plan.index_count(level));
  write_indices(plan, level, 0, std::span<uint32_t>(out.indices));
  out.closed = plan.closed;
  return out;
}

const fcl::CollisionGeometryd& MeasureShapes::Impl::geometry(MeasurePart& part) {
  if (part.geometry) return *part.geometry;
  assert(part.mesh);
  const Primitive& primitive = primitives[part.primitive];
  const PrimitiveTriangles triangles =
      primitive_triangles(primitive, plan_mesh(primitive), part.mesh_level, part.mesh_level);
  std::vector<fcl::Vector3d> points;
  points.reserve(triangles.positions.size());
  for (const glm::vec3& p : triangles.positions) points.emplace_back(p.x, p.y, p.z);
  std::vector<fcl::Triangle> faces;
  faces.reserve(triangles.indices.size() / 3);
  for (size_t i = 0; i + 2 < triangles.indices.size(); i += 3)
    faces.emplace_back(triangles.indices[i], triangles.indices[i + 1], triangles.indices[i + 2]);
  const auto build = [&](auto model) {
    model->beginModel(int(faces.size()), int(points.size()));
    model->addSubModel(points, faces);
    model->endModel();
    model->computeLocalAABB();
    part.geometry = std::move(model);
  };
  if (collide_only)
    build(std::make_shared<fcl::BVHModel<fcl::AABBd>>());
  else
    build(std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>());
  return *part.geometry;
}

MeasureShapes::MeasureShapes(std::span<const Primitive> primitives, const glm::dvec3& object_origin_m,
                             const glm::dvec3& frame_origin_m, double mesh_error_m, bool collide_only)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.collide_only = collide_only;
  m.frame_origin_m = frame_origin_m;
  m.object_offset_m = object_origin_m - frame_origin_m;
  m.primitives.assign(primitives.begin(), primitives.end());
  m.parts.reserve(m.primitives.size());
  for (uint32_t i = 0; i < m.primitives.size(); ++i) {
    const Primitive& primitive = m.primitives[i];
    const MeshPlan plan = plan_mesh(primitive);
    if (plan.vertex_count == 0 || plan.index_count(0) == 0) continue;
    MeasurePart part;
    part.primitive = i;
    part.geometry = exact_shape(primitive, m.object_offset_m, part.transform);
    if (!part.geometry && plan.topology != Topology::triangles) continue;  // a line of no length
    if (!part.geometry) {
      part.mesh = true;
      // Vertices fitted to the level: its polygons straddle the surface, about half the error
      // of inscribed ones for the same triangles (primitives.h).
      while (part.mesh_level + 1u < plan.level_count &&
             double(plan.straddled_error_m[part.mesh_level + 1]) <= mesh_error_m)
        ++part.mesh_level;
      part.error_m = plan.straddled_error_m[part.mesh_level];
      part.transform = fcl::Transform3d::Identity();
      part.transform.translation() = fcl::Vector3d(m.object_offset_m.x, m.object_offset_m.y, m.object_offset_m.z);
    }
    m.error_m = std::max(m.error_m, part.error_m);
    m.parts.push_back(std::move(part));
  }
  // Proxies: each part's analytic bounds as a box, grown by its error (a fitted mesh reaches
  // outside the shape by up to that).
  std::vector<fcl::CollisionObjectd*> proxies;
  proxies.reserve(m.parts.size());
  for (MeasurePart& part : m.parts) {
    const Aabb b = model_bounds(m.primitives[part.primitive]);
    const glm::dvec3 lo = glm::dvec3(b.min) + m.object_offset_m - part.error_m,
                     hi = glm::dvec3(b.max) + m.object_offset_m + part.error_m;
    const glm::dvec3 size = glm::max(hi - lo, glm::dvec3(1e-9)) + 2e-6, centre = (lo + hi) * 0.5;
    auto box = std::make_shared<fcl::Boxd>(size.x, size.y, size.z);
    part.proxy = std::make_unique<fcl::CollisionObjectd>(
        box, fcl::Matrix3d::Identity(), fcl::Vector3d(centre.x, centre.y, centre.z));
    part.proxy->setUserData(&part);
    proxies.push_back(part.proxy.get());
  }
  m.manager.registerObjects(proxies);
  m.manager.setup();
}

MeasureShapes::~MeasureShapes() = default;
MeasureShapes::MeasureShapes(MeasureShapes&&) noexcept = default;
MeasureShapes& MeasureShapes::operator=(MeasureShapes&&) noexcept = default;
size_t MeasureShapes::size() const { return impl_->parts.size(); }
const glm::dvec3& MeasureShapes::frame_origin_m() const { return impl_->frame_origin_m; }
double MeasureShapes::error_m() const { return impl_->error_m; }
bool MeasureShapes::collide_only() const { return impl_->collide_only; }

}  // namespace plantview
