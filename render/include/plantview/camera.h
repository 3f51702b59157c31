// plantview/camera.h: cameras, their text and JSON forms, camera fitting, review views (the
// views file) and camera paths through a plant.
//
// Units: metres (model space, double precision), angles in degrees where the name says _deg.
// Threads: plain values and pure functions, callable from any thread; make_camera_path(store)
// and make_review_views read the store through a view of their own on the calling thread.
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

// A review view: a named, fitted camera on one subject of the plant (an equipment item, a
// pipeline, an area, or the whole plant), what `plantview views` writes and `render --views`
// reads. `name` is unique in its file and safe as a file name ([A-Za-z0-9._-], not starting with
// '.'); `kind` is overview|equipment|pipeline|area; `aspect` is the width / height the camera was
// fitted for; `subject` lists the subject's store object ids (empty for an overview: the whole
// plant, nothing highlighted); `attributes` are the caption lines, in order (tag, type, ...).
struct ReviewView {
  std::string name, title, kind;
  Camera camera;
  double aspect = 16.0 / 9.0;
  std::vector<uint64_t> subject;
  std::vector<std::pair<std::string, std::string>> attributes;
};

// The views file. JSON:
//   {"version": 1, "per": "equipment",
//    "views": [{"name": "P-101A", "title": "Pump P-101A", "kind": "equipment",
//               "camera": {"eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov_deg": 50},
//               "aspect": 1.7778, "subject": [12, 13], "attributes": {"tag": "P-101A", ...}}]}
// `per` is overview|equipment|pipeline|area. The writer keeps the views' and attributes' order
// (the parser reads that order back) and writes text that is not UTF-8 (attribute values are
// bytes as the model gave them) with U+FFFD in place of each invalid sequence. The parser rejects: text that is not JSON, a version other
// than 1, an unknown `per` or `kind`, a missing or mistyped field, an unknown key (a misspelt
// field is an error, not a default), an unsafe or repeated name, a camera validate_camera
// rejects, an aspect that is not a positive number, and an empty list. The error names the
// view by index and name and the field: "views file: view 3 ('P-101A'): 'camera.eye' must be a
// list of 3 numbers". On failure `out` is unchanged.
std::string review_views_json(const std::vector<ReviewView>& views, std::string_view per);
bool parse_review_views(std::string_view json, std::vector<ReviewView>& out, std::string& error);
// Review views of a store's model (what `plantview views` writes):
//   per overview:  the whole plant (subject empty), as default_camera frames it;
//   per equipment: each object of class equipment; named by its Tag attribute, else its name;
//   per pipeline:  each pipeline object with every object that names it (pipes, components,
//                  supports): the whole line; named by its "Line number", else its name;
//   per area:      the objects of one RVM zone (the importer's "Zone" attribute), of one unit
//                  of a generated plant ("Unit 01", from the names' area field), else of one RVM
//                  site, else of one source file.
// Each subject's camera is fit_camera on its bounds (kReviewFill), from the isometric
// direction, or with sides = 4 from each side (4 views, names suffixed -N, -E, -S, -W by where
// the eye is). Where that eye would stand inside another object's bounds or a large object (a
// wall, a column, a vessel: 1 m across both ways and a third of the subject's size) lies between
// it and the subject, the other isometric quadrants (or, for a side, nearby directions) are
// tried, then the eye is moved in front of the obstacle with a field of view widened up to 90
// degrees to keep the fill; failing all, the first fit stays (highlighting shows the subject
// through what is in front).
// Names: the subject's name made safe (runs of other characters become '-', leading '-' and
// '.' dropped); repeats get -2, -3... in the order of the subjects' names and first ids, so the
// same store gives the same names. `select` (a shell glob, fnmatch) keeps the subjects whose
// view name or model name matches.
struct ReviewViewOptions {
  std::string per = "equipment";  // overview|equipment|pipeline|area
  std::string select;             // empty: every subject
  int sides = 1;                  // 1 or 4
  double aspect = 16.0 / 9.0;     // width / height of the images to come
  double fov_deg = 50.0;
  double fill = kReviewFill;      // (the overview uses kOverviewFill)
};
struct ReviewViewsSummary {
  uint64_t subjects = 0;    // of the kind, before `select`
  uint64_t moved = 0;       // views whose eye left the first fit to stand clear
  uint64_t obstructed = 0;  // views left at the first fit with no clear place found
};
// False with a message when the store cannot be read, holds no subject of the kind ("the store
// has no pipelines"), or `select` matches none. Preconditions (asserted): a known `per`, sides 1
// or 4, aspect > 0, fov_deg in (0, 179), fill in (0, 1]. `progress` (may be empty) gets the
// fraction done, on the calling thread.
bool make_review_views(const Store& store, const ReviewViewOptions& options,
                       std::vector<ReviewView>& out, ReviewViewsSummary& summary,
                       std::string& error,
                       const std::function<void(double fraction)>& progress = {});

// True for the kinds a view (and `per`) may name: overview, equipment, pipeline, area.
bool is_review_kind(std::string_view kind);
// True if `name` is safe as a file name: 1..200 of [A-Za-z0-9._-], not starting with '.'.
bool is_safe_view_name(std::string_view name);

}  // namespace plantview
