// The measure library's insides (plantview/measure.h): one distance part per primitive, the
// broadphase over an object's parts, and the tessellation both the parts and the pick ray use.
#pragma once

#include <memory>
#include <vector>

#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/math/bv/AABB.h>
#include <fcl/geometry/collision_geometry.h>
#include <fcl/narrowphase/collision_object.h>

#include "plantview/measure.h"
#include "plantview/primitives.h"

namespace plantview {

// One primitive's distance shape. `geometry` is an FCL primitive from the start, or the mesh
// built on first use (mesh == true); `proxy` holds the part's bounds in the broadphase.
struct MeasurePart {
  uint32_t primitive = 0;              // index into Impl::primitives
  bool mesh = false;
  double error_m = 0;                  // 0 for exact parts
  uint32_t mesh_level = 0;             // the tessellation level a mesh is built at, fitted to it
  fcl::Transform3d transform = fcl::Transform3d::Identity();  // to the frame (mesh: translation only)
  std::shared_ptr<fcl::CollisionGeometryd> geometry;           // null until a mesh is built
  std::unique_ptr<fcl::CollisionObjectd> proxy;
  // The clash narrow phase's per-part caches (clash/narrow_phase.cpp), filled on first use by
  // the thread that uses the shapes: the points that stand for the surface (frame coordinates)
  // and a mesh's triangles (corners three a triangle, and their bounds; the part's own frame).
  std::vector<fcl::Vector3d> surface_points;
  bool has_surface_points = false;
  std::vector<fcl::Vector3d> triangle_corners;
  std::vector<fcl::AABBd> triangle_bounds;
  // A mesh part whose inside is known exactly (clash depth): a circular torus or a spherical
  // dish under an orthogonal placement of equal scales. `axes` maps frame to local coordinates
  // (rows: the unit axes, a mirror kept), `origin` is the local origin in the frame; sizes are
  // scaled. Filled with the surface points.
  enum class Solid : uint8_t { none, circular_torus, spherical_dish } solid = Solid::none;
  fcl::Matrix3d axes = fcl::Matrix3d::Identity();
  fcl::Vector3d origin = fcl::Vector3d::Zero();
  double size[3] = {0, 0, 0};  // torus: bend radius, tube radius, angle; dish: sphere radius, centre z
};

struct MeasureShapes::Impl {
  glm::dvec3 frame_origin_m{0.0};
  glm::dvec3 object_offset_m{0.0};     // the object's origin relative to the frame
  std::vector<Primitive> primitives;
  std::vector<MeasurePart> parts;
  double error_m = 0;
  bool collide_only = false;  // meshes are BVHModel<AABBd> (else BVHModel<OBBRSSd>)
  fcl::DynamicAABBTreeCollisionManagerd manager;

  // The part's geometry, building its mesh if it has none yet.
  const fcl::CollisionGeometryd& geometry(MeasurePart& part);
};

// The exact FCL shape of a primitive under its placement (offset: the object's origin relative
// to the frame), or null when the kind or the placement has none (then a mesh is used).
std::shared_ptr<fcl::CollisionGeometryd> exact_shape(const Primitive& primitive,
                                                     const glm::dvec3& offset_m,
                                                     fcl::Transform3d& transform);

// A primitive's triangles at `level`, the vertices on the surface (kOnSurface) or fitted to a
// level (write_vertices): positions relative to the object's origin (float), three indices a
// triangle, outward winding for closed kinds. Empty for lines and shapes without volume.
struct PrimitiveTriangles {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  bool closed = false;
};
PrimitiveTriangles primitive_triangles(const Primitive& primitive, const MeshPlan& plan,
                                       uint32_t level, uint32_t fit_level = kOnSurface);

}  // namespace plantview
