// plantview/primitives.h: the parametric primitives of a plant model and their multi-resolution
// tessellation (Zhou et al. 2012, section 3).
//
// A plant object is built from a few kinds of parametric primitives. Only their parameters are
// stored; triangles are made on demand, at the level of detail a view needs.
//
// Units and frames
//   - Every length is in metres, every angle in radians.
//   - Each shape is defined in its own local frame (documented per kind below). A Placement maps it
//     to the model: model = linear * local + translation_m. `linear` may rotate, scale and mirror.
//   - Tessellated positions are written relative to a caller-chosen origin (an object's origin,
//     in double precision) so that kilometre-scale coordinates keep sub-millimetre precision.
//
// Multi-resolution templates
//   - A curved shape is cut into N = 2^n segments in each curved direction. Level 0 is the finest;
//     level l uses N >> l segments (never fewer than the kind's minimum). Every level samples the
//     same curve parameters at every 2^l-th position, so the vertex set of a coarser level is a
//     subset of level 0's: one vertex array serves all levels, and a level is an index range.
//   - The index arrays depend only on the kind and its segment counts; they are built once per
//     shape in a process-wide template cache and shared by every primitive of that shape.
//   - Each level reports its geometric error in metres (model units, after the placement's scale):
//     an upper bound of the distance between the mesh and the true surface, at most about twice
//     the true figure. For a circle of radius r in N segments that is the sagitta r(1 - cos(pi/N))
//     (error_m, on-surface vertices); the same rule holds for straddled_error_m (vertices fitted
//     to that level, below).
//   - Flat kinds (box, pyramid, prism, line, facet group) have one level and zero error.
//
// Fitted vertices (straddling polygons)
//   - With every vertex on the true surface each polygon is inscribed: its error is one-sided.
//     write_vertices can instead fit the vertices to one level l: in each curved direction they
//     move outward by the scale s_l = 2 / (1 + cos(pi/N_l)) (N_l: level l's segments in that
//     direction; for other deficits x, s = 2 / (2 - x)), so that level l's polygons straddle the
//     surface: vertices r(s_l - 1) outside, the deepest points as far inside,
//     r(1 - cos)/(1 + cos): about half the error for the same triangles (straddled_error_m[l]).
//   - Fitting moves vertices, never changes which vertices a level uses: the nesting holds, and a
//     coarser level l > b drawn from vertices fitted to b errs at most error_m[l] (its chords'
//     midpoints dip r(1 - s_b cos(pi/N_l)) <= r(1 - cos(pi/N_l)) inside, its vertices stick
//     r(s_b - 1) <= r(1 - cos(pi/N_l)) out). A level finer than the fit (l < b) errs at most
//     error_m[l] + straddled_error_m[b] (the vertices are off the surface by up to the latter);
//     draw it from vertices fitted to it instead.
//   - Per kind: cylinder and snout scale their end rings about the end centres; circular torus
//     its tube rings (tube s) and its stations' distance from the axis (sweep s); rectangular
//     torus its stations (sweep s); the sphere scales about its centre (s = 2 / (1 + cos^2));
//     the elliptical dish scales about its base centre (vessel heads from 2:1 to hemispheres
//     only; its base ring stays in its plane). Never moved (straddled_error_m = error_m), as measurement showed no gain:
//     twisted snouts and square-to-rounds (the side quads' twist dominates their error),
//     spherical dishes (the base ring is held on the rim), elliptical dishes flatter than 2:1 or
//     taller than a hemisphere, saddles (the cradle ends on the side
//     edges); nor flat kinds, lines and facet groups. Caps copy their rim, so a fitted solid
//     stays watertight.
//   - Where parts meet: two primitives of the same radius and segment count fitted to the same
//     level get the same s and meet as before (a pipe run of cylinders). An elbow's end ring is
//     also pushed away from the bend axis by the sweep's s, so it meets the next cylinder with a
//     gap or overlap of at most its level's straddled error; a square-to-round or twisted snout
//     (never fitted) meets a fitted cylinder with a step of the cylinder's straddled error. Any
//     gap between parts stays within the level's (straddled) error; on-surface vertices (kOnSurface) never reach outside
//     the shape, which occluders need.
//   - The bounds (local_bounds, model_bounds) are the analytic ones; a fitted mesh may reach
//     outside them by up to straddled_error_m of its fit level.
//
// Segment counts (the size rule)
//   For a curved direction of diameter D: n_max = 5 (32 segments) up to D = 1 m, one more per
//   doubling of D, at most 8 (256 segments); n_min = 2 (4 segments). This extends Zhou's rule
//   (4 to 32 segments for D <= 1 m) so that large vessels keep a sub-millimetre to few-millimetre
//   error at the finest level. See segment_exponents().
//
// Kinds of Zhou et al. (Fig. 2) and RVM, and how they map here
//   box                      -> Box
//   prism (regular n-gon)    -> Prism
//   wedge, rect. frustum     -> Pyramid (a zero-size top side gives a wedge, a zero top a pyramid)
//   cylinder                 -> Cylinder
//   sheared cylinder         -> Snout with equal radii and end shears
//   eccentric cone           -> Snout with an offset
//   concentric cone          -> Snout
//   square-to-round          -> SquareToRound
//   torus                    -> CircularTorus
//   rectangular torus        -> RectangularTorus
//   sphere                   -> Sphere
//   saddle                   -> Saddle (vessel saddle support: a block with a cylindrical cradle)
//   elliptical head (oval)   -> EllipticalDish
//   RVM spherical dish       -> SphericalDish
//   RVM line                 -> Line
//   RVM facet group          -> FacetGroup (polygons with holes, triangulated once)
//
// Threads: every function here is safe to call from any thread. The template cache is filled
// lazily under a lock; the spans it hands out stay valid for the life of the process.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <variant>
#include <vector>

#include <glm/glm.hpp>

namespace plantview {

// ---------------------------------------------------------------------------------------------
// Shapes. Each is a plain parameter block in its local frame. Negative or non-finite parameters
// are treated as zero by the tessellator; a shape without volume gives an empty mesh (no NaN).

// Box centred at the origin, sides along the axes. Closed. 24 vertices, 12 triangles.
struct Box {
  float size_x_m = 0, size_y_m = 0, size_z_m = 0;
  bool operator==(const Box&) const = default;
};

// Rectangular frustum along z, centred: the bottom rectangle (bottom_x by bottom_y) lies at
// z = -height/2 centred at -offset/2, the top rectangle at z = +height/2 centred at +offset/2.
// A zero top gives a pyramid, a zero-length top side a wedge. Closed. 4 vertices per face with
// area (3 for a side whose top or bottom edge collapsed): 24 for a frustum, 18 for a wedge, 16 for
// a pyramid; 2 triangles per face with area (1 for such a side): 12, 8 and 6.
struct Pyramid {
  float bottom_x_m = 0, bottom_y_m = 0, top_x_m = 0, top_y_m = 0;
  float offset_x_m = 0, offset_y_m = 0, height_m = 0;
  bool operator==(const Pyramid&) const = default;
};

// Right prism along z, centred, over a regular polygon of `sides` (3..64) corners at
// circumradius radius_m, the first corner on +x. Closed. 6*sides vertices, 4*sides - 4 triangles.
struct Prism {
  uint32_t sides = 6;
  float radius_m = 0, height_m = 0;
  bool operator==(const Prism&) const = default;
};

// Cylinder along z, centred. Closed. Per level with N segments: 4N vertices at level 0,
// 4N - 4 triangles (2N side, N - 2 per cap).
struct Cylinder {
  float radius_m = 0, height_m = 0;
  bool operator==(const Cylinder&) const = default;
};

// Cone frustum along z, centred (RVM "snout"): the bottom circle (radius_bottom) at z = -height/2
// centred at -offset/2, the top circle at +height/2 centred at +offset/2. An end shear tilts that
// end's plane: z += tan(shear_x) * x + tan(shear_y) * y, measured from the end's centre.
// Closed. Same counts as Cylinder.
struct Snout {
  float radius_bottom_m = 0, radius_top_m = 0, height_m = 0;
  float offset_x_m = 0, offset_y_m = 0;
  float bottom_shear_x_rad = 0, bottom_shear_y_rad = 0;
  float top_shear_x_rad = 0, top_shear_y_rad = 0;
  bool operator==(const Snout&) const = default;
};

// Square-to-round transition along z, centred: the bottom rectangle at z = -height/2 centred at
// -offset/2, the top circle at +height/2 centred at +offset/2; a ruled surface joins them. The
// rectangle's corners lie at the circle's 45, 135, 225 and 315 degree samples at every level.
// Closed. 4N + 4 vertices, 4N - 4 triangles at N segments (2N side, N - 2 per end face).
struct SquareToRound {
  float bottom_x_m = 0, bottom_y_m = 0, top_radius_m = 0, height_m = 0;
  float offset_x_m = 0, offset_y_m = 0;
  bool operator==(const SquareToRound&) const = default;
};

// Circular torus (pipe elbow): a circle of tube_radius swept about z at distance bend_radius,
// from angle 0 (on +x) to angle_rad, counter-clockwise; 2*pi closes the ring. Closed (flat end
// caps when open). With S sweep and N tube segments: (S+1)*N + 2N vertices (S*N and no caps when
// closed), 2*S*N + 2*(N - 2) triangles (2*S*N when closed). N follows the size rule on the tube
// diameter; S = the power of two >= N * (angle / 2pi) * max(1, (R + r) / 2r), at most 256. The
// level count comes from the tube; S halves per level down to its floor (1 up to pi/2, 2 up to
// pi, 4 beyond).
struct CircularTorus {
  float bend_radius_m = 0, tube_radius_m = 0, angle_rad = 0;
  bool operator==(const CircularTorus&) const = default;
};

// Rectangular torus: the rectangle [inner_radius, outer_radius] x [-height/2, height/2] (in the xz
// plane) swept about z from angle 0 to angle_rad. Closed. With S sweep segments (the size rule on
// the outer diameter times angle / 2pi): 8(S+1) + 8 vertices, 8S + 4 triangles (8S vertices, no
// end caps and 8S triangles when closed).
struct RectangularTorus {
  float inner_radius_m = 0, outer_radius_m = 0, height_m = 0, angle_rad = 0;
  bool operator==(const RectangularTorus&) const = default;
};

// Sphere centred at the origin. Closed. With N segments around and N/2 bands from pole to pole:
// 2 + (N/2 - 1) * N vertices, 2N(N/2 - 1) triangles.
struct Sphere {
  float radius_m = 0;
  bool operator==(const Sphere&) const = default;
};

// Half-ellipsoid standing on the xy plane (base circle of base_radius at z = 0) rising to
// z = height: vessel heads. Closed by a flat base disc. With N segments around (the size rule on
// 2 * base_radius) and B = N/4 bands: B*N + N + 1 vertices, 2NB - 2 triangles.
struct EllipticalDish {
  float base_radius_m = 0, height_m = 0;
  bool operator==(const EllipticalDish&) const = default;
};

// Spherical cap standing on the xy plane (base circle of base_radius at z = 0) rising to
// z = height. Closed by a flat base disc. N segments around from the size rule on the widest
// diameter (2 * base_radius, or the sphere's beyond a hemisphere); B bands, the power of two
// nearest polar_angle * N / 2pi (at least 1): B*N + N + 1 vertices, 2NB - 2 triangles.
struct SphericalDish {
  float base_radius_m = 0, height_m = 0;
  bool operator==(const SphericalDish&) const = default;
};

// Vessel saddle support: a block length (x) by width (y) by height (z), standing on z = 0 and
// centred in x and y, whose top face is a cylindrical cradle of cradle_radius about an axis
// parallel to x, passing through both top side edges. The cradle radius is at least width/2;
// the block is at least as high as the cradle is deep. Closed. With A arc segments (the power of
// two >= N * beta / pi, beta = asin(width / (2 * cradle_radius)), N from the cradle diameter):
// 8(A+1) + 8 vertices, 8A + 4 triangles (cradle, bottom and both end strips, two sides).
struct Saddle {
  float length_m = 0, width_m = 0, height_m = 0, cradle_radius_m = 0;
  bool operator==(const Saddle&) const = default;
};

// A segment along x from start_x to end_x (RVM line). Topology::lines: 2 vertices, 2 indices.
struct Line {
  float start_x_m = 0, end_x_m = 0;
  bool operator==(const Line&) const = default;
};

// A polygon mesh (RVM facet group): polygons, each of one outer contour and any hole contours,
// with a normal per vertex. `triangles` holds its triangulation (indices into `vertices`, three
// per triangle), made once by triangulate() after the polygons are filled in. Not closed in
// general. Vertex count = vertices.size(), triangle count = triangles.size() / 3.
struct FacetVertex {
  glm::vec3 position_m{0};
  glm::vec3 normal{0, 0, 1};
  bool operator==(const FacetVertex&) const = default;
};
struct FacetGroup {
  std::vector<FacetVertex> vertices;      // all contours' vertices, contour after contour
  std::vector<uint32_t> contour_ends;     // contour c is vertices[contour_ends[c-1] .. contour_ends[c])
  std::vector<uint32_t> polygon_ends;     // polygon p is contours [polygon_ends[p-1] .. polygon_ends[p])
  std::vector<uint32_t> triangles;        // filled by triangulate()

  // Triangulates every polygon (ear clipping, holes bridged to their outer contour) into
  // `triangles`, replacing what was there. Degenerate contours (fewer than 3 vertices, zero area)
  // are skipped. Returns the number of polygons that were skipped in whole or in part.
  uint32_t triangulate();
  bool operator==(const FacetGroup&) const = default;
};

// The variant's alternatives are listed in PrimitiveKind order.
using Shape = std::variant<Box, Pyramid, Prism, Cylinder, Snout, SquareToRound, CircularTorus,
                           RectangularTorus, Sphere, EllipticalDish, SphericalDish, Saddle, Line,
                           FacetGroup>;

enum class PrimitiveKind : uint8_t {
  box, pyramid, prism, cylinder, snout, square_to_round, circular_torus, rectangular_torus,
  sphere, elliptical_dish, spherical_dish, saddle, line, facet_group,
};
inline constexpr int kPrimitiveKindCount = 14;
static_assert(std::variant_size_v<Shape> == kPrimitiveKindCount);

// Stable lower-case names ("box", "circular_torus"...), used in statistics, JSON and XML.
std::string_view kind_name(PrimitiveKind kind);
// Inverse of kind_name; returns false for an unknown name.
bool kind_from_name(std::string_view name, PrimitiveKind& kind);

// model = linear * local + translation_m. Columns of `linear` are the local axes in model space.
struct Placement {
  glm::mat3 linear{1.0f};
  glm::vec3 translation_m{0.0f};
  bool operator==(const Placement&) const = default;
};

struct Primitive {
  Placement placement;
  Shape shape;
  PrimitiveKind kind() const { return static_cast<PrimitiveKind>(shape.index()); }
  bool operator==(const Primitive&) const = default;
};

struct Aabb {
  glm::vec3 min{0}, max{0};
  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
};

// The analytic bounds of a shape in its local frame (not of its mesh: an on-surface mesh lies
// inside, a fitted one up to its straddled error outside).
Aabb local_bounds(const Shape& shape);
// The bounds in model space: local bounds through the placement.
Aabb model_bounds(const Primitive& primitive);

// ---------------------------------------------------------------------------------------------
// Tessellation.

inline constexpr int kMaxLevels = 8;

// One vertex as the renderer consumes it: 16 bytes. `position_m` is relative to the origin given
// to write_vertices. `normal` is packed as GL_INT_2_10_10_10_REV (signed normalised x, y, z in
// bits 0-9, 10-19, 20-29; w = 0), unit length in model space.
struct PackedVertex {
  glm::vec3 position_m;
  uint32_t normal;
};
static_assert(sizeof(PackedVertex) == 16);

uint32_t pack_normal(glm::vec3 unit_normal);
glm::vec3 unpack_normal(uint32_t packed);

enum class Topology : uint8_t { triangles, lines };

// What a primitive tessellates to: sizes, the index range of every level, and each level's error.
// Cheap to compute (no vertex is written). The index spans point into the template cache
// (valid for the process) or, for a facet group, into the primitive itself (valid while it lives
// unchanged).
struct MeshPlan {
  Topology topology = Topology::triangles;
  bool closed = false;           // a watertight solid with outward normals
  bool flip_winding = false;     // the placement mirrors: write_indices swaps each triangle's order
  uint8_t level_count = 1;       // levels 0 .. level_count-1; 1 for flat kinds
  uint32_t vertex_count = 0;     // vertices written by write_vertices, shared by every level
  std::array<std::span<const uint32_t>, kMaxLevels> indices{};  // per level, local vertex indices
  std::array<float, kMaxLevels> error_m{};                       // per level, model-space metres
  // Per level l, model-space metres: the error of level l drawn from vertices fitted to l
  // (write_vertices with fit_level = l), about half error_m[l] for curved kinds, error_m[l] for
  // kinds that are never fitted. Level l drawn from vertices fitted to b < l: at most error_m[l].
  std::array<float, kMaxLevels> straddled_error_m{};
  std::array<uint16_t, 2> segments{};  // level-0 segment counts of the curved directions (0: none)

  // Level l clamped to this primitive's coarsest level: objects mix primitives of many level counts.
  uint32_t clamp_level(uint32_t level) const {
    return level < level_count ? level : level_count - 1u;
  }
  uint32_t index_count(uint32_t level) const {
    return static_cast<uint32_t>(indices[clamp_level(level)].size());
  }
  // The coarsest level whose error_m is at most max_error_m (levels coarsen in order; 0 when
  // none is): the renderer's screen-space rule with the error in metres, as exports use it.
  uint32_t coarsest_level_within(double max_error_m) const {
    uint32_t level = 0;
    while (level + 1u < level_count && double(error_m[level + 1]) <= max_error_m) ++level;
    return level;
  }
};

MeshPlan plan_mesh(const Primitive& primitive);

// fit_level for vertices on the true surface (every level's polygons inscribed).
inline constexpr uint32_t kOnSurface = 0xffffffffu;

// Writes the plan's vertex_count vertices (level 0, shared by all levels) into `out`, positions
// relative to origin_m (model space, metres). `out.size()` must be at least plan.vertex_count.
// With fit_level = l (clamped to the plan's levels) the vertices are fitted so that level l's
// polygons straddle the surface (its error: straddled_error_m[l]; see "Fitted vertices" above);
// with kOnSurface every vertex lies on the surface (error_m), as occluders and anything that must
// stay inside the shape need. Allocates nothing.
void write_vertices(const Primitive& primitive, const MeshPlan& plan, const glm::dvec3& origin_m,
                    std::span<PackedVertex> out, uint32_t fit_level = kOnSurface);

// Appends level `level`'s indices, offset by base_vertex (and with the winding flipped if the
// plan says so), to `out`, which must hold at least plan.index_count(level) entries. With 16-bit
// indices the caller guarantees base_vertex + vertex_count <= 65536. Returns the count written.
uint32_t write_indices(const MeshPlan& plan, uint32_t level, uint32_t base_vertex,
                       std::span<uint32_t> out);
uint32_t write_indices(const MeshPlan& plan, uint32_t level, uint32_t base_vertex,
                       std::span<uint16_t> out);

// The size rule: segment exponents (N = 2^n) for a curved direction of the given diameter.
struct SegmentExponents {
  uint8_t n_max = 5, n_min = 2;
};
SegmentExponents segment_exponents(float diameter_m);

// Triangle count of a level (index_count / 3), or line count for Topology::lines.
inline uint32_t element_count(const MeshPlan& plan, uint32_t level) {
  return plan.index_count(level) / (plan.topology == Topology::lines ? 2u : 3u);
}

}  // namespace plantview

namespace plantview {

// One representative primitive of every kind, sized like a plant part of the given diameter
// (a 0.2 m pipe part: a 0.2 m box, a 0.1 m radius cylinder, an elbow of bend radius 1.5 D...),
// at the origin. For statistics, demos and benchmarks. Index i holds PrimitiveKind(i).
std::vector<Primitive> representative_primitives(float diameter_m);

}  // namespace plantview
