// plantview/camera.h: cameras, their text and JSON forms, and camera paths through a plant.
//
// Units: metres (model space, double precision), angles in degrees where the name says _deg.
// Threads: plain values and pure functions, callable from any thread; make_camera_path(store)
// reads the store through a view of its own on the calling thread.
// Errors: fallible calls return false and fill `error` with what is wrong and where ("camera:
// 'fov' needs 1 number", "camera path: camera 3: 'eye' is missing").
#pragma once

#include <string>
#include <string_view>
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

}  // namespace plantview
