// plantview/camera.h: cameras, their text and JSON forms, camera fitting and camera paths
// through a plant. (Review views, the views file: plantview/review.h.)
//
// Units: metres (model space, double precision), angles in degrees where the name says _deg.
// Threads: plain values and pure functions, callable from any thread; make_camera_path(store)
// reads the store through a view of its own on the calling thread.
// Errors: fallible calls return false and fill `error` with what is wrong and where ("camera:
// 'fov' needs 1 number", "camera path: camera 3: 'eye' is missing").
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/model.h"

namespace plantview {

class ReadView;
class Store;

// A perspective camera in model space. `fov_deg` is the vertical field of view.
struct Camera {
  glm::dvec3 eye_m{0.0, -10.0, 0.0};
  glm::dvec3 target_m{0.0};
  glm::dvec3 up{0.0, 0.0, 1.0};
  double fov_deg = 50.0;
  bool operator==(const Camera&) const = default;
};

// What every camera the renderer is given must satisfy: finite numbers, an eye off the target
// (by 1 micrometre at least), an up neither zero nor along the view, and fov_deg in (0, 179).
// The parsers below apply it; a caller that builds a Camera from values of its own (a query's
// typed fields) calls it before rendering. False with the broken rule in `error`.
bool validate_camera(const Camera& camera, std::string& error);

// The up of a camera that is given none (every parser below, the HTTP query): +z, or +y (north
// at the top of the image) where the view along `view_direction` (any length) is vertical,
// a plan view from above or below, which +z cannot orient.
glm::dvec3 default_up(const glm::dvec3& view_direction);

// Parses "eye=X,Y,Z,target=X,Y,Z[,up=X,Y,Z][,fov=DEG]" (the --camera form; without up,
// default_up). Rejects unknown keys, missing or non-finite numbers, and cameras validate_camera
// rejects (an up given along the view among them).
bool parse_camera(std::string_view text, Camera& out, std::string& error);
std::string format_camera(const Camera& camera);  // the form parse_camera reads, exactly
// The overview of a plant for an image of `aspect` (width / height): fit_camera on its
// overview_boxes from the isometric direction (from the -x, -y, +z corner), 50 degrees,
// filling kOverviewFill of the binding axis. What `render` without --camera, the service and
// `views --per overview` use. No boxes (or only empty ones) give the default Camera.
Camera default_camera(std::span<const DAabb> boxes, double aspect);
// The same fitted to one box (the plant's bounds, when nothing finer is at hand).
Camera default_camera(const DAabb& bounds, double aspect);
// The boxes an overview is fitted to, from the store's spatial index (no object is decoded):
// every object's bounds when there are at most `max_boxes`, else the union of the objects'
// bounds in each cell of a grid over the plant of at most `max_boxes` cells. Plants of over a
// million objects use the bounds of the index's blocks (2,048 objects each) instead of their
// objects', read from the resident top in milliseconds. Model space, metres; empty for a
// store without geometry. Valid independently of the view.
std::vector<DAabb> overview_boxes(const ReadView& view, size_t max_boxes = 4096);
// Boxes merged into at most about `max_cells` (>= 1): each the union of the boxes whose centre
// lies in one cell of a grid of cubic cells over their union. Fewer boxes than that come back as
// they are. Keeps what fit_camera projects to a few thousand boxes.
std::vector<DAabb> merge_boxes_on_grid(std::vector<DAabb> boxes, size_t max_cells);
// From eye to target: the isometric direction (35.3 degrees down, from the -x, -y corner).
inline glm::dvec3 isometric_direction() { return {1.0, 1.0, -1.0}; }
// How much of the binding axis the subject's box fills: review views, overviews.
inline constexpr double kReviewFill = 0.75;
inline constexpr double kOverviewFill = 0.8;

// Fits a camera looking along `direction` (from eye towards target) so that `subject_bounds`
// projected fills `fill` (0..1) of the frame's width or height, whichever is tighter.
// The fit is exact for the box's 8 corners projected through the camera's perspective (not a
// bounding sphere): on the binding axis the corners span `fill` of the frame, on the other at
// most that, and the projected box is centred on both axes. `aspect` is width / height,
// `fov_deg` the vertical field of view; up is +z (+y when `direction` is vertical). The target
// is the point on the view axis at the depth of the box's centre. Preconditions (asserted):
// non-empty bounds, a non-zero finite direction, aspect > 0, fov_deg in (0, 179), fill in (0, 1].
Camera fit_camera(const DAabb& subject_bounds, const glm::dvec3& direction, double aspect,
                  double fov_deg, double fill);
// The same for a subject made of several boxes (its objects' bounds): the corners of every box
// are projected, so that a sparse subject (a plant, an area, a pipeline) fills the frame with
// what it holds rather than with its overall box's empty corners. Empty boxes are skipped; at
// least one must be non-empty. Cost: linear in the boxes (keep them to a few thousand).
Camera fit_camera(std::span<const DAabb> boxes, const glm::dvec3& direction, double aspect,
                  double fov_deg, double fill);

// A camera path: what `plantview path` writes and `render --path` reads. JSON: a list of
// {"eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov": deg} ("up" and "fov" optional;
// without up, default_up).
// The parser rejects an empty list and names the first bad camera by its index.
std::string camera_path_json(const std::vector<Camera>& cameras);
bool parse_camera_path(std::string_view json, std::vector<Camera>& out, std::string& error);

enum class PathKind { walkthrough, orbit };
bool parse_path_kind(std::string_view name, PathKind& kind);
// A path of `frames` cameras (none for frames <= 0 or empty bounds). orbit: around the plant's
// bounds, looking at their centre. walkthrough: starts outside the plant, approaches it and
// walks into it at eye height along the gaps between its equipment (the objects of class
// equipment, given by their bounds), like Zhou et al.'s Fig. 6 run. It never leaves the plant:
// the walk ends at its last aisle point inside, the last views turning to the plant's centre,
// so that every view sees some of the plant.
std::vector<Camera> make_camera_path(PathKind kind, int frames, const DAabb& plant_bounds,
                                     const std::vector<DAabb>& equipment_bounds);
// The same for a store's plant: its bounds, and the bounds of its equipment (every chunk of
// records is decompressed once, in slot order, and only the equipment is decoded: time linear
// in the plant, mostly decompression; memory: the equipment's bounds, 48 bytes an equipment
// item). `progress`, if given, is called on the calling thread with the fraction of
// the slots passed (0..1], non-decreasing, last with 1; an exception it throws propagates. False
// with a message if the store cannot be read or holds no geometry.
bool make_camera_path(PathKind kind, int frames, const Store& store, std::vector<Camera>& out,
                      std::string& error, const std::function<void(double fraction)>& progress = {});

}  // namespace plantview
