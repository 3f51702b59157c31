// plantview/measure.h: distances between objects (clearance, the two closest points) and the
// surface point under a picked pixel, computed on the objects' primitives.
//
// How distances are computed
//   - Each primitive becomes one distance shape. Kinds that FCL models exactly become FCL
//     primitives: Box (any orthogonal placement, scaled per axis), Cylinder (and a Snout with
//     equal radii, no offset and no shears; round in its placement), Snout with one zero radius
//     (a cone), Sphere (uniformly scaled). Every other kind, and those under a shearing or
//     unevenly scaling placement, becomes an FCL mesh (a bounding-volume tree of triangles) of
//     its tessellation with vertices fitted to the level (primitives.h: polygons straddling the
//     surface, about half the error of inscribed ones), at the coarsest level whose straddled
//     error is at most kMeasureMeshErrorM, or its finest level (some large dishes and elbows
//     stay above: up to about 2 mm in preset c). Flat kinds (box, pyramid, prism, facet group)
//     are exact as meshes. A line (RVM's, a pipe support drawn as a stroke) is its segment: an
//     FCL capsule of radius 0.
//   - A level's error bounds the distance between its mesh and the true surface (on either
//     side: an elbow's chords cut inside its bend), so a tessellated distance is within the two
//     parts' level errors of the true one. A Clearance states its bound as error_m: the largest
//     sum of two parts' errors over the pairs that could hold the true minimum (those whose
//     bounds are no farther apart than the answer; 0: all exact, method "analytic").
//   - Meshes are surfaces: a part wholly inside a tessellated part of the other object is not
//     seen as overlapping (FCL primitives are solids and are). Plant objects touch at their
//     surfaces, so this matters only for parts buried in others.
//   - Pairs are pruned by their bounds in a dynamic AABB tree per object (FCL's
//     DynamicAABBTreeCollisionManager), nearest first: only pairs whose bounds are nearer than
//     the best distance so far are measured, and a mesh is built the first time one of its
//     pairs is measured. Two objects of 5,000 primitives each: about 20 ms, nearly all of it
//     building their shapes (bench_measure; a query on built shapes takes under a millisecond).
//   - Overlap: distance_m = 0, the two points a point of contact (both the same), and
//     penetration_m the depth FCL reports for the overlapping pair (0 where it cannot tell:
//     meshes).
//
// Units: metres, model space (double precision); shapes are positioned relative to an origin
// given when they are built (an object's origin), so kilometre-scale coordinates keep their
// precision.
// Threads: MeasureShapes is used by one thread at a time (its meshes are built lazily); distinct
// instances on distinct threads are independent. The free functions are pure.
// Errors: measure_objects returns false with a message naming the object that has no geometry
// (no primitive, or only empty ones).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/camera.h"
#include "plantview/model.h"
#include "plantview/view_filters.h"

namespace plantview {

// The largest level error a tessellated part may have (metres), where its kind has such a level.
inline constexpr double kMeasureMeshErrorM = 0.0005;

// The distance shapes of a set of primitives (one object's, or any group's), built once and
// queried against other sets. Move-only.
class MeasureShapes {
 public:
  // The primitives of an object whose origin is object_origin_m (placements relative to it),
  // positioned relative to frame_origin_m. Two sets queried together must share frame_origin_m.
  // `collide_only`: meshes get axis-aligned bounding-volume trees, several times cheaper to
  // build, which answer overlap queries (FCL collide: the clash pass) but not distances
  // (measure_clearance asserts that neither set was made so).
  MeasureShapes(std::span<const Primitive> primitives, const glm::dvec3& object_origin_m,
                const glm::dvec3& frame_origin_m, double mesh_error_m = kMeasureMeshErrorM,
                bool collide_only = false);
  ~MeasureShapes();
  MeasureShapes(MeasureShapes&&) noexcept;
  MeasureShapes& operator=(MeasureShapes&&) noexcept;

  // Parts with geometry (shapes without volume and lines of no length are left out).
  size_t size() const;
  bool empty() const { return size() == 0; }
  const glm::dvec3& frame_origin_m() const;
  // The largest stated error of a part (0 when every part is exact).
  double error_m() const;
  bool collide_only() const;

  struct Impl;
  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

// The minimum distance between two sets of shapes and where it is reached.
struct Clearance {
  double distance_m = 0;       // 0 when they overlap
  double penetration_m = 0;    // > 0 when they overlap and the depth is known
  bool overlapping = false;
  glm::dvec3 point_a_m{0.0};   // model space: the closest point on A
  glm::dvec3 point_b_m{0.0};   // and on B
  double error_m = 0;          // |distance_m - true distance| <= error_m
  bool analytic = true;        // error_m == 0: the answer came from exact parts only
  uint32_t primitive_a = 0;    // index of the closest primitive of A in the span it was built from
  uint32_t primitive_b = 0;
};

// The clearance between A and B, which share a frame origin (asserted) and are not empty
// (asserted). Reusable for any two groups of primitives (a later clash pass: object vs object).
Clearance measure_clearance(const MeasureShapes& a, const MeasureShapes& b);

// The clearance between two objects. False, naming the object (its name, else its id), when
// one has no geometry to measure.
bool measure_objects(const Object& a, const Object& b, Clearance& out, std::string& error);

// Measuring two objects of a store, as `plantview measure` and /api/measure do.
//
// An object is named by a word: all digits an id (or a name, if no object has that id), else a
// tag (name) as stored, else with the leading '/' plant names carry ("P-101A" finds "/P-101A"),
// as render --highlight and /api/objects read them.
struct StoreMeasurement {
  enum class Outcome {
    measured,
    unknown,      // no object has the word as id or tag (message names it)
    ambiguous,    // the tag names several objects (message says so: ask by id)
    no_geometry,  // an object has nothing to measure (message names it)
    failed,       // the store could not be read (message names it)
  } outcome = Outcome::failed;
  std::string message;
  Object a, b;       // without attributes
  Clearance clearance;
};
class ReadView;
StoreMeasurement measure_in_store(const ReadView& view, std::string_view a, std::string_view b);

// The answer as one JSON object (one line, no newline):
// {"a":{"id":"...","tag":"...","point_m":[x,y,z]},"b":{...},"distance_m":..,"dx_m":..,
//  "dy_m":..,"dz_m":..,"error_m":..,"method":"analytic"|"tessellated","overlapping":bool
//  [,"penetration_m":..]}. Ids are strings (64 bits), as /api/objects writes them; d = b - a.
std::string clearance_json(const Object& a, const Object& b, const Clearance& c);

// The pick ray: the camera ray through the centre of pixel (x, y) (0, 0 the top-left) of a
// width x height image, as the renderer projects (camera.h's Camera, vertical fov).
struct Ray {
  glm::dvec3 origin_m{0.0};
  glm::dvec3 direction{0, 0, -1};  // unit
};
Ray pixel_ray(const Camera& camera, uint32_t width, uint32_t height, uint32_t x, uint32_t y);

struct SurfaceHit {
  glm::dvec3 point_m{0.0};   // model space
  glm::dvec3 normal{0.0};    // unit, facing the ray's origin
  double distance_m = 0;     // along the ray
  uint32_t primitive = 0;    // index of the primitive hit (for a cut face: the cut solid's)
  bool on_cut = false;       // the point lies on a section plane or box face
};

// The first point of the object's surface along the ray that the section keeps (null section:
// none), each primitive cast against its finest on-surface tessellation (flat kinds exactly;
// curved ones within their level-0 error). Where the first kept surface is the inside of a cut
// closed solid, the hit is on the cutting plane or box face instead (normal against the ray).
// Empty when the ray misses.
std::optional<SurfaceHit> cast_ray(const Object& object, const Ray& ray,
                                   const Section* section = nullptr);

}  // namespace plantview
