#include "hlod.h"

#include <algorithm>
#include <cmath>

namespace plantview::detail {

namespace {

// A line through `origin` along unit `direction`.
struct Line3 {
  glm::dvec3 origin, direction;
  double distance(const glm::dvec3& p) const {
    const glm::dvec3 d = p - origin;
    return glm::length(d - direction * glm::dot(d, direction));
  }
  double along(const glm::dvec3& p) const { return glm::dot(p - origin, direction); }
};

// The model-space points that define a member's axis: centreline ends and connection points.
void axis_points(const Object& o, std::vector<glm::dvec3>& points) {
  points.clear();
  for (const auto& s : o.centreline) {
    points.push_back(o.origin_m + glm::dvec3(s.start_m));
    points.push_back(o.origin_m + glm::dvec3(s.end_m));
  }
  for (const auto& c : o.connections) points.push_back(o.origin_m + glm::dvec3(c.position_m));
}

float member_diameter(const Object& o) {
  float d = 0;
  for (const auto& s : o.centreline) d = std::max(d, s.diameter_m);
  if (d == 0)
    for (const auto& c : o.connections) d = std::max(d, c.diameter_m);
  return d;
}

// How far the member's primitives reach from the line.
double radial_extent(const Object& o, const Line3& line) {
  double extent = 0;
  for (const Primitive& p : o.primitives) {
    const glm::dvec3 t = o.origin_m + glm::dvec3(p.placement.translation_m);
    const glm::dmat3 m(p.placement.linear);
    const double scale = glm::length(m[0]);
    if (const auto* c = std::get_if<Cylinder>(&p.shape)) {
      const glm::dvec3 half = m * glm::dvec3(0, 0, c->height_m / 2);
      extent = std::max(extent, std::max(line.distance(t - half), line.distance(t + half)) +
                                    c->radius_m * scale);
    } else if (const auto* s = std::get_if<Snout>(&p.shape)) {
      const glm::dvec3 lo = t + m * glm::dvec3(-s->offset_x_m / 2, -s->offset_y_m / 2, -s->height_m / 2);
      const glm::dvec3 hi = t + m * glm::dvec3(s->offset_x_m / 2, s->offset_y_m / 2, s->height_m / 2);
      extent = std::max(extent, std::max(line.distance(lo) + s->radius_bottom_m * scale,
                                         line.distance(hi) + s->radius_top_m * scale));
    } else {
      const Aabb b = model_bounds(p);
      if (b.empty()) continue;
      for (int corner = 0; corner < 8; ++corner) {
        const glm::dvec3 q = o.origin_m + glm::dvec3(corner & 1 ? b.max.x : b.min.x,
                                                     corner & 2 ? b.max.y : b.min.y,
                                                     corner & 4 ? b.max.z : b.min.z);
        extent = std::max(extent, line.distance(q));
      }
    }
  }
  return extent;
}

struct Open {
  Line3 line{};
  double t_min = 0, t_max = 0;
  float diameter_m = 0;
  double extent_m = 0;
  PipelineRun run;
};

// What find_runs needs of a member: its axis points, its diameter, whether it may lie in a run
// at all, and the line through its two farthest-apart points (has_own_line: false where they
// are closer than the tolerance).
struct MemberAxis {
  std::vector<glm::dvec3> points;
  float diameter_m = 0;
  double tolerance_m = 0;
  bool straight = false;
  bool has_own_line = false;
  Line3 own_line{};
  double own_length_m = 0;
  bool fits(const Line3& line) const {
    for (const auto& p : points)
      if (line.distance(p) > tolerance_m) return false;
    return true;
  }
};

void member_axis(const Object& o, MemberAxis& a) {
  axis_points(o, a.points);
  a.diameter_m = member_diameter(o);
  a.straight = o.connections.size() <= 2 && !a.points.empty() && a.diameter_m > 0;
  // Every connection at one diameter: a reducer changes it.
  for (const auto& c : o.connections)
    if (c.diameter_m > 0 && std::abs(c.diameter_m - a.diameter_m) > 0.02f * a.diameter_m)
      a.straight = false;
  a.tolerance_m = std::max(0.001, 0.01 * double(a.diameter_m));
  a.has_own_line = false;
  if (!a.straight) return;
  glm::dvec3 p = a.points.front(), q = a.points.front();
  for (const auto& x : a.points)
    if (glm::length(x - p) > glm::length(q - p)) q = x;
  if (glm::length(q - p) <= a.tolerance_m) return;
  a.own_line = {p, glm::normalize(q - p)};
  a.own_length_m = glm::length(q - p);
  a.has_own_line = true;
}

// A member that ends every run: not straight, or with a line of its own that its points do
// not fit (an elbow).
bool ends_runs(const MemberAxis& a) { return !a.straight || (a.has_own_line && !a.fits(a.own_line)); }

}  // namespace

bool ends_runs(const Object& member) {
  MemberAxis a;
  member_axis(member, a);
  return ends_runs(a);
}

void find_runs(const std::vector<std::pair<uint32_t, const Object*>>& branch,
               std::vector<PipelineRun>& out) {
  MemberAxis axis;
  bool open = false;
  Open current;
  const auto close = [&] {
    if (open && current.run.members.size() >= 2) {
      current.run.start_m = current.line.origin + current.line.direction * current.t_min;
      current.run.end_m = current.line.origin + current.line.direction * current.t_max;
      current.run.diameter_m = current.diameter_m;
      current.run.merge_error_m =
          float(std::max(0.0, current.extent_m - 0.5 * double(current.diameter_m)));
      out.push_back(std::move(current.run));
    }
    open = false;
    current = Open{};
  };
  for (const auto& [slot, object] : branch) {
    const Object& o = *object;
    member_axis(o, axis);
    if (ends_runs(axis)) {
      close();
      continue;
    }
    if (open && std::abs(axis.diameter_m - current.diameter_m) <= 0.02f * current.diameter_m &&
        axis.fits(current.line)) {
      for (const auto& p : axis.points) {
        current.t_min = std::min(current.t_min, current.line.along(p));
        current.t_max = std::max(current.t_max, current.line.along(p));
      }
      current.extent_m = std::max(current.extent_m, radial_extent(o, current.line));
      current.run.members.push_back(slot);
      current.run.bounds.extend(object_bounds(o));
      continue;
    }
    close();
    // Start a run on this member's own line.
    if (!axis.has_own_line) continue;
    open = true;
    current.line = axis.own_line;
    current.diameter_m = axis.diameter_m;
    current.t_min = 0;
    current.t_max = axis.own_length_m;
    current.extent_m = radial_extent(o, current.line);
    current.run.members.push_back(slot);
    current.run.bounds.extend(object_bounds(o));
    current.run.colour = o.colour;
  }
  close();
}

Primitive merged_cylinder(const PipelineRun& run, const glm::dvec3& origin_m) {
  const glm::dvec3 axis = run.end_m - run.start_m;
  const double length = glm::length(axis);
  const glm::dvec3 z = length > 0 ? axis / length : glm::dvec3(0, 0, 1);
  const glm::dvec3 helper = std::abs(z.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0);
  const glm::dvec3 x = glm::normalize(glm::cross(helper, z));
  const glm::dvec3 y = glm::cross(z, x);
  Primitive p;
  p.placement.linear = glm::mat3(glm::vec3(x), glm::vec3(y), glm::vec3(z));
  p.placement.translation_m = glm::vec3(0.5 * (run.start_m + run.end_m) - origin_m);
  p.shape = Cylinder{0.5f * run.diameter_m, float(length)};
  return p;
}

}  // namespace plantview::detail
