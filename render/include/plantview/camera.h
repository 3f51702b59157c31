// plantview/camera.h: cameras, their text and JSON forms, and camera paths through a plant.
//
// Units: metres (model space, double precision), angles in degrees where the name says _deg.
// Threads: plain values and pure functions, callable from any thread; make_camera_path(store)
// reads the store through a view of its own on the calling thread.
// Errors: fallible calls return false and fill `error` with what is wrong and where ("camera:
// 'fov' needs 1 number", "camera path: camera 3: 'eye' is missing").
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/model.h"

namespace plantview {

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

// Parses "eye=X,Y,Z,target=X,Y,Z[,up=X,Y,Z][,fov=DEG]" (the --camera form). Rejects unknown
// keys, missing or non-finite numbers, and cameras validate_camera rejects.
bool parse_camera(std::string_view text, Camera& out, std::string& error);
std::string format_camera(const Camera& camera);  // the form parse_camera reads, exactly
// A camera that frames the whole of `bounds` from above one corner, for an image of `aspect`
// (width / height). Empty bounds give the default Camera.
Camera default_camera(const DAabb& bounds, double aspect);

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

// A camera path: what `plantview path` writes and `render --path` reads. JSON: a list of
// {"eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov": deg} ("up" and "fov" optional).
// The parser rejects an empty list and names the first bad camera by its index.
std::string camera_path_json(const std::vector<Camera>& cameras);
bool parse_camera_path(std::string_view json, std::vector<Camera>& out, std::string& error);

enum class PathKind { walkthrough, orbit };
bool parse_path_kind(std::string_view name, PathKind& kind);
// A path of `frames` cameras (none for frames <= 0 or empty bounds). orbit: around the plant's
// bounds, looking at their centre. walkthrough: starts outside the plant, approaches it and
// walks into it at eye height along the gaps between its equipment (the objects of class
// equipment, given by their bounds), like Zhou et al.'s Fig. 6 run.
std::vector<Camera> make_camera_path(PathKind kind, int frames, const DAabb& plant_bounds,
                                     const std::vector<DAabb>& equipment_bounds);
// The same for a store's plant: its bounds, and the bounds of its equipment (every object is
// read once). False with a message if the store cannot be read or holds no geometry.
bool make_camera_path(PathKind kind, int frames, const Store& store, std::vector<Camera>& out,
                      std::string& error);

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
// `per` is overview|equipment|pipeline|area. The writer keeps the views' and attributes' order;
// the parser reads that order back. The parser rejects: text that is not JSON, a version other
// than 1, an unknown `per` or `kind`, a missing or mistyped field, an unknown key (a misspelt
// field is an error, not a default), an unsafe or repeated name, a camera validate_camera
// rejects, an aspect that is not a positive number, and an empty list. The error names the
// view by index and name and the field: "views file: view 3 ('P-101A'): 'camera.eye' must be a
// list of 3 numbers". On failure `out` is unchanged.
std::string review_views_json(const std::vector<ReviewView>& views, std::string_view per);
bool parse_review_views(std::string_view json, std::vector<ReviewView>& out, std::string& error);
// True for the kinds a view (and `per`) may name: overview, equipment, pipeline, area.
bool is_review_kind(std::string_view kind);
// True if `name` is safe as a file name: 1..200 of [A-Za-z0-9._-], not starting with '.'.
bool is_safe_view_name(std::string_view name);

}  // namespace plantview
