// Cameras: the --camera text form, the default view, camera-path JSON and path generation.
#include <algorithm>
#include <array>
#include <cassert>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "plantview/camera.h"
#include "plantview/store.h"

namespace plantview {

namespace {

bool parse_number(std::string_view text, double& out) {
  if (text.empty()) return false;
  if (text.front() == '+') text.remove_prefix(1);
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && end == text.data() + text.size() && std::isfinite(out);
}

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

bool validate_camera(const Camera& c, std::string& error) {
  if (!finite(c.eye_m) || !finite(c.target_m) || !finite(c.up) || !std::isfinite(c.fov_deg)) {
    error = "camera: eye, target, up and fov must be finite numbers";
    return false;
  }
  const glm::dvec3 view = c.target_m - c.eye_m;
  if (glm::length(view) < 1e-6) {
    error = "camera: the eye is on the target";
    return false;
  }
  if (glm::length(c.up) < 1e-9 || glm::length(glm::cross(view, c.up)) < 1e-9 * glm::length(view) * glm::length(c.up)) {
    error = "camera: 'up' is zero or along the view direction";
    return false;
  }
  if (!(c.fov_deg > 0.0 && c.fov_deg < 179.0)) {
    error = "camera: fov must be in (0, 179) degrees";
    return false;
  }
  return true;
}

glm::dvec3 default_up(const glm::dvec3& view_direction) {
  const double length = glm::length(view_direction);
  const glm::dvec3 z(0, 0, 1);
  if (length > 0 && glm::length(glm::cross(view_direction / length, z)) >= 1e-6) return z;
  return {0, 1, 0};
}

bool parse_camera(std::string_view text, Camera& out, std::string& error) {
  // Tokens split on commas; a token "key=number" starts a key, bare numbers continue it.
  Camera camera;
  bool have_eye = false, have_target = false, have_up = false;
  std::vector<std::pair<std::string, std::vector<double>>> fields;
  size_t at = 0;
  while (at <= text.size()) {
    const size_t comma = std::min(text.find(',', at), text.size());
    std::string_view token = text.substr(at, comma - at);
    at = comma + 1;
    const size_t eq = token.find('=');
    if (eq != std::string_view::npos) {
      fields.emplace_back(std::string(token.substr(0, eq)), std::vector<double>{});
      token.remove_prefix(eq + 1);
    }
    if (fields.empty()) {
      error = "camera: expected key=value, got '" + std::string(token) + "'";
      return false;
    }
    double v = 0;
    if (!parse_number(token, v)) {
      error = "camera: '" + fields.back().first + "' has a bad number '" + std::string(token) + "'";
      return false;
    }
    fields.back().second.push_back(v);
    if (comma == text.size()) break;
  }
  for (const auto& field : fields) {
    const std::string& key = field.first;  // (not structured bindings: clang 14 cannot capture those)
    const std::vector<double>& values = field.second;
    const auto vec = [&](glm::dvec3& v) {
      if (values.size() != 3) {
        error = "camera: '" + key + "' needs 3 numbers, got " + std::to_string(values.size());
        return false;
      }
      v = {values[0], values[1], values[2]};
      return true;
    };
    if (key == "eye") {
      if (!vec(camera.eye_m)) return false;
      have_eye = true;
    } else if (key == "target") {
      if (!vec(camera.target_m)) return false;
      have_target = true;
    } else if (key == "up") {
      if (!vec(camera.up)) return false;
      have_up = true;
    } else if (key == "fov") {
      if (values.size() != 1) {
        error = "camera: 'fov' needs 1 number";
        return false;
      }
      camera.fov_deg = values[0];
    } else {
      error = "camera: unknown key '" + key + "' (eye, target, up, fov)";
      return false;
    }
  }
  if (!have_eye || !have_target) {
    error = "camera: eye=X,Y,Z and target=X,Y,Z are required";
    return false;
  }
  if (!have_up) camera.up = default_up(camera.target_m - camera.eye_m);
  if (!validate_camera(camera, error)) return false;
  out = camera;
  return true;
}

std::string format_camera(const Camera& c) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "eye=%.17g,%.17g,%.17g,target=%.17g,%.17g,%.17g,up=%.17g,%.17g,%.17g,fov=%.17g",
                c.eye_m.x, c.eye_m.y, c.eye_m.z, c.target_m.x, c.target_m.y, c.target_m.z, c.up.x,
                c.up.y, c.up.z, c.fov_deg);
  return buf;
}

namespace {

// The camera's frame for a view along `forward` (unit): right and up as glm::lookAt makes them
// from the world up +z (+y when the view is vertical), so fitted projections match the renderer's.
struct ViewBasis {
  glm::dvec3 forward, right, up, world_up;
};

ViewBasis view_basis(const glm::dvec3& forward) {
  ViewBasis b;
  b.forward = forward;
  b.world_up = default_up(forward);
  b.right = glm::normalize(glm::cross(forward, b.world_up));
  b.up = glm::cross(b.right, forward);
  return b;
}

// Where along one image axis the eye sits (its lateral coordinate `e`, eye depth fixed at
// `eye_depth`) so that the corners' projections (a - e) / (c - eye_depth) span symmetrically
// about the axis. The sum of the largest and smallest projection falls as e grows: bisection.
double centre_axis(const std::vector<double>& lateral, const std::vector<double>& depth,
                   double eye_depth) {
  double lo = *std::min_element(lateral.begin(), lateral.end());
  double hi = *std::max_element(lateral.begin(), lateral.end());
  for (int iteration = 0; iteration < 64 && hi - lo > 1e-9 * std::max(1.0, std::abs(hi)); ++iteration) {
    const double e = 0.5 * (lo + hi);
    double most = -INFINITY, least = INFINITY;
    for (size_t i = 0; i < lateral.size(); ++i) {
      const double t = (lateral[i] - e) / (depth[i] - eye_depth);
      most = std::max(most, t);
      least = std::min(least, t);
    }
    (most + least > 0 ? lo : hi) = e;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

Camera fit_camera(const DAabb& bounds, const glm::dvec3& direction, double aspect, double fov_deg,
                  double fill) {
  return fit_camera(std::span<const DAabb>(&bounds, 1), direction, aspect, fov_deg, fill);
}

Camera fit_camera(std::span<const DAabb> boxes, const glm::dvec3& direction, double aspect,
                  double fov_deg, double fill) {
  assert(glm::length(direction) > 0 && std::isfinite(glm::length(direction)));
  assert(aspect > 0 && fov_deg > 0 && fov_deg < 179 && fill > 0 && fill <= 1);
  const ViewBasis basis = view_basis(glm::normalize(direction));
  // The corners in the camera's axes: x right, y up, z depth along the view.
  std::vector<double> x, y, z;
  DAabb all;
  for (const DAabb& b : boxes) {
    if (b.empty()) continue;
    all.extend(b);
    for (int corner = 0; corner < 8; ++corner) {
      const glm::dvec3 p(corner & 1 ? b.max.x : b.min.x, corner & 2 ? b.max.y : b.min.y,
                         corner & 4 ? b.max.z : b.min.z);
      x.push_back(glm::dot(p, basis.right));
      y.push_back(glm::dot(p, basis.up));
      z.push_back(glm::dot(p, basis.forward));
    }
  }
  assert(!all.empty());
  // A frustum narrowed to `fill` of the frame; the eye (ex, ey, ez) that puts the corners
  // exactly between its left and right planes is ex = (P + Q) / 2, ez = (Q - P) / (2 t) with
  // P = max(x - t z), Q = min(x + t z); the same for y. The axis with the smaller ez (farther
  // back) binds; the other is centred at that depth.
  const double tan_y = fill * std::tan(glm::radians(fov_deg) / 2.0);
  const double tan_x = tan_y * aspect;
  const auto tight = [&](const std::vector<double>& lateral, double t, double& centre) {
    double p = -INFINITY, q = INFINITY;
    for (size_t i = 0; i < lateral.size(); ++i) {
      p = std::max(p, lateral[i] - t * z[i]);
      q = std::min(q, lateral[i] + t * z[i]);
    }
    centre = 0.5 * (p + q);
    return (q - p) / (2.0 * t);
  };
  double ex = 0, ey = 0;  // set by tight()
  const double ez_x = tight(x, tan_x, ex);
  const double ez_y = tight(y, tan_y, ey);
  double ez = std::min(ez_x, ez_y);
  // Boxes of no extent across the view (a point, a flat plate seen edge-on) still get an eye
  // in front of them, past the near plane.
  const double nearest = *std::min_element(z.begin(), z.end());
  const double size_m = glm::length(all.max - all.min);
  ez = std::min(ez, nearest - std::max(0.1, 1e-3 * size_m));
  // The binding axis is centred already (the corners touch both narrowed planes); the other,
  // and both when the near-plane rule moved the eye back, are centred at the final depth.
  if (ez < ez_x) ex = centre_axis(x, z, ez);
  if (ez < ez_y) ey = centre_axis(y, z, ez);

  Camera c;
  c.fov_deg = fov_deg;
  c.up = basis.world_up;
  c.eye_m = ex * basis.right + ey * basis.up + ez * basis.forward;
  const glm::dvec3 centre = 0.5 * (all.min + all.max);
  const double target_depth = std::max(glm::dot(centre, basis.forward) - ez, 1.0);
  c.target_m = c.eye_m + target_depth * basis.forward;
  return c;
}

std::string camera_path_json(const std::vector<Camera>& cameras) {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& c : cameras) {
    list.push_back({{"eye", {c.eye_m.x, c.eye_m.y, c.eye_m.z}},
                    {"target", {c.target_m.x, c.target_m.y, c.target_m.z}},
                    {"up", {c.up.x, c.up.y, c.up.z}},
                    {"fov", c.fov_deg}});
  }
  return list.dump(1) + "\n";
}

bool parse_camera_path(std::string_view json, std::vector<Camera>& out, std::string& error) {
  const auto list = nlohmann::json::parse(json, nullptr, false);
  if (list.is_discarded() || !list.is_array()) {
    error = "camera path: not a JSON list of cameras";
    return false;
  }
  std::vector<Camera> cameras;
  for (size_t i = 0; i < list.size(); ++i) {
    const auto& item = list[i];
    const std::string where = "camera path: camera " + std::to_string(i);
    if (!item.is_object()) {
      error = where + " is not an object";
      return false;
    }
    Camera c;
    const auto vec = [&](const char* key, glm::dvec3& v, bool required) {
      if (!item.contains(key)) {
        if (required) error = where + ": '" + key + "' is missing";
        return !required;
      }
      const auto& a = item[key];
      if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() ||
          !a[2].is_number()) {
        error = where + ": '" + key + "' must be a list of 3 numbers";
        return false;
      }
      v = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
      return true;
    };
    if (!vec("eye", c.eye_m, true) || !vec("target", c.target_m, true))
      return false;
    c.up = default_up(c.target_m - c.eye_m);
    if (!vec("up", c.up, false)) return false;
    if (item.contains("fov")) {
      if (!item["fov"].is_number()) {
        error = where + ": 'fov' must be a number";
        return false;
      }
      c.fov_deg = item["fov"].get<double>();
    }
    std::string why;
    if (!validate_camera(c, why)) {
      error = where + ": " + why;
      return false;
    }
    cameras.push_back(c);
  }
  if (cameras.empty()) {
    error = "camera path: the list is empty";
    return false;
  }
  out = std::move(cameras);
  return true;
}

bool parse_path_kind(std::string_view name, PathKind& kind) {
  if (name == "walkthrough") kind = PathKind::walkthrough;
  else if (name == "orbit") kind = PathKind::orbit;
  else return false;
  return true;
}

std::vector<Camera> make_camera_path(PathKind kind, int frames, const DAabb& bounds,
                                     const std::vector<DAabb>& equipment) {
  std::vector<Camera> path;
  if (frames <= 0 || bounds.empty()) return path;
  const glm::dvec3 centre = 0.5 * (bounds.min + bounds.max);
  const glm::dvec3 size = bounds.max - bounds.min;
  const double radius = std::max(0.5 * glm::length(size), 1.0);
  if (kind == PathKind::orbit) {
    for (int i = 0; i < frames; ++i) {
      const double a = 2.0 * M_PI * i / frames;
      Camera c;
      c.target_m = centre;
      c.eye_m = centre + glm::dvec3(std::cos(a) * 1.6 * radius, std::sin(a) * 1.6 * radius,
                                    0.6 * radius);
      path.push_back(c);
    }
    return path;
  }

  // Walkthrough: waypoints from outside the plant at its -y side, down to eye height, then
  // along the aisle between equipment rows: the midpoints between consecutive equipment
  // centres, sorted along the plant's longer horizontal axis, kept clear of equipment bounds.
  const double eye_height_m = bounds.min.z + std::min(1.7, 0.5 * size.z + 0.1);
  const bool along_x = size.x >= size.y;
  std::vector<glm::dvec3> waypoints;
  // It starts where the overview of a 16:9 image stands (the plant filling the view).
  const Camera overview = default_camera(bounds, 16.0 / 9.0);
  waypoints.push_back(overview.eye_m);
  const glm::dvec3 entry = along_x ? glm::dvec3(bounds.min.x - 5.0, centre.y, eye_height_m)
                                   : glm::dvec3(centre.x, bounds.min.y - 5.0, eye_height_m);
  waypoints.push_back(entry);
  std::vector<glm::dvec3> centres;
  for (const auto& b : equipment)
    if (!b.empty()) centres.push_back(0.5 * (b.min + b.max));
  const int axis = along_x ? 0 : 1;
  std::sort(centres.begin(), centres.end(),
            [&](const glm::dvec3& a, const glm::dvec3& b) { return a[axis] < b[axis]; });
  const auto clear = [&](const glm::dvec3& p) {
    for (const auto& b : equipment) {
      if (p.x > b.min.x - 0.5 && p.x < b.max.x + 0.5 && p.y > b.min.y - 0.5 &&
          p.y < b.max.y + 0.5 && p.z > b.min.z && p.z < b.max.z)
        return false;
    }
    return true;
  };
  // About one waypoint per 8 equipment items, walking the aisle through the middle.
  const size_t step = std::max<size_t>(1, centres.size() / 12);
  for (size_t i = 0; i + step < centres.size(); i += step) {
    glm::dvec3 p = 0.5 * (centres[i] + centres[i + step]);
    p.z = eye_height_m;
    if (clear(p)) waypoints.push_back(p);
  }
  // The walk ends inside the plant, at its last aisle point (or its centre, at eye height): a
  // walk out of the far side looked out of the plant at nothing.
  if (waypoints.size() < 3) waypoints.push_back(glm::dvec3(centre.x, centre.y, eye_height_m));

  // Cameras evenly spaced along the polyline, each looking ahead along it.
  std::vector<double> at(waypoints.size(), 0.0);
  for (size_t i = 1; i < waypoints.size(); ++i)
    at[i] = at[i - 1] + glm::length(waypoints[i] - waypoints[i - 1]);
  const double total = std::max(at.back(), 1e-6);
  const auto point = [&](double s) {
    s = std::clamp(s, 0.0, total);
    size_t i = 1;
    while (i + 1 < at.size() && at[i] < s) ++i;
    const double span = std::max(at[i] - at[i - 1], 1e-9);
    return glm::mix(waypoints[i - 1], waypoints[i], std::clamp((s - at[i - 1]) / span, 0.0, 1.0));
  };
  const double look_ahead_m = std::max(10.0, 0.05 * total);
  // Where the path runs out of look-ahead, the view turns to the plant's centre (horizontally,
  // at eye height), wholly so at the last camera: the walk ends looking into the plant.
  const glm::dvec3 end = waypoints.back();
  glm::dvec3 final_look(centre.x - end.x, centre.y - end.y, 0.0);
  if (glm::length(final_look) < 1.0) final_look = end - waypoints[waypoints.size() - 2];
  final_look = glm::normalize(final_look);
  // On the approach (start to entry) the view turns from the overview's target to the way
  // ahead: from afar the plant fills the view rather than a corner of it.
  const double approach_m = std::max(at[1], 1e-6);
  const glm::dvec3 plant_middle = overview.target_m;
  for (int f = 0; f < frames; ++f) {
    const double s = frames == 1 ? 0.0 : total * f / (frames - 1);
    Camera c;
    c.eye_m = point(s);
    c.target_m = point(s + look_ahead_m);
    if (s < approach_m) {
      const glm::dvec3 ahead = glm::normalize(c.target_m - c.eye_m);
      const glm::dvec3 middle = glm::normalize(plant_middle - c.eye_m);
      c.target_m = c.eye_m + look_ahead_m * glm::normalize(glm::mix(middle, ahead, s / approach_m));
    }
    const double past_end = (s + look_ahead_m - total) / look_ahead_m;  // > 0: near the end
    if (past_end > 0.0) {
      glm::dvec3 ahead = c.target_m - c.eye_m;
      ahead = glm::length(ahead) > 1e-3 ? glm::normalize(ahead) : final_look;
      glm::dvec3 look = glm::mix(ahead, final_look, std::min(past_end, 1.0));
      if (glm::length(look) < 1e-3) look = final_look;
      c.target_m = c.eye_m + look_ahead_m * glm::normalize(look);
    }
    // Keep the view from pointing straight down or up.
    glm::dvec3 view = c.target_m - c.eye_m;
    const double horizontal = std::hypot(view.x, view.y);
    if (horizontal < 0.3 * std::abs(view.z)) {
      view.x += along_x ? 0.3 * std::abs(view.z) : 0.0;
      view.y += along_x ? 0.0 : 0.3 * std::abs(view.z);
      c.target_m = c.eye_m + view;
    }
    path.push_back(c);
  }
  return path;
}

bool make_camera_path(PathKind kind, int frames, const Store& store, std::vector<Camera>& out,
                      std::string& error, const std::function<void(double)>& progress) {
  auto view = store.read(error);
  if (!view) return false;
  const StoreInfo info = view->info();
  const DAabb bounds = info.statistics.bounds;
  if (bounds.empty()) {
    error = store.directory() + ": the store holds no geometry";
    return false;
  }
  // An orbit needs only the plant's bounds.
  std::vector<DAabb> equipment;
  if (kind == PathKind::walkthrough) {
    // Only the equipment is decoded (the other records are passed over by their class byte).
    // Progress by slots passed, reported every kProgressSlots of them.
    constexpr uint32_t kProgressSlots = 16384;
    const uint32_t total = std::max<uint32_t>(1, view->slot_count());
    uint32_t reported = 0;
    const bool ok = view->for_each_object_of_class(
        ObjectClass::equipment,
        [&](uint32_t slot, Object&& o) {
          equipment.push_back(object_bounds(o));
          if (progress && slot - reported >= kProgressSlots) {
            reported = slot;
            progress(double(std::min(slot, total)) / double(total));
          }
          return true;
        },
        false, error);
    if (!ok) return false;
  }
  if (progress) progress(1.0);
  out = make_camera_path(kind, frames, bounds, equipment);
  return true;
}

}  // namespace plantview
