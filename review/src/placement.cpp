// Where a review view's eye may stand: outside every other object's bounds, with no wall,
// column or vessel between it and the subject, found through the store's spatial index.
#include <algorithm>
#include <array>
#include <cmath>

#include "views_internal.h"

namespace plantview::views {

namespace {

// Visits the bounds (model space) of every object in the spatial index whose box may meet the
// query: `test` decides for each node's box (top nodes, then the blocks' nodes) and each
// object's box. A block that cannot be read is skipped, the first such error kept in `error`.
template <typename Test, typename Visit>
void for_each_box(const ReadView& view, const Test& test, const Visit& visit, std::string& error) {
  const auto top = view.spatial_top();
  if (top.empty()) return;
  const glm::dvec3 origin = view.spatial_origin();
  const auto box = [&](const float mn[3], const float mx[3]) {
    DAabb b;
    b.min = origin + glm::dvec3(mn[0], mn[1], mn[2]);
    b.max = origin + glm::dvec3(mx[0], mx[1], mx[2]);
    return b;
  };
  std::vector<uint32_t> top_stack{0}, stack;
  while (!top_stack.empty()) {
    const SpatialNode& t = top[top_stack.back()];
    top_stack.pop_back();
    if (!test(box(t.min, t.max))) continue;
    if (t.count == 0) {
      top_stack.push_back(t.first);
      top_stack.push_back(t.first + 1);
      continue;
    }
    std::string why;
    const auto block = view.spatial_block(t.first, why);
    if (!block) {
      if (error.empty()) error = why;
      continue;
    }
    stack.assign(1, 0);
    while (!stack.empty()) {
      const SpatialNode& node = block->nodes[stack.back()];
      stack.pop_back();
      if (!test(box(node.min, node.max))) continue;
      if (node.count == 0) {
        stack.push_back(node.first);
        stack.push_back(node.first + 1);
        continue;
      }
      for (uint32_t i = node.first; i < node.first + node.count; ++i) {
        float mn[3], mx[3];
        entry_bounds(node, block->entries[i], mn, mx);
        const DAabb b = box(mn, mx);
        if (test(b)) visit(block->entries[i].slot, b);
      }
    }
  }
}

bool contains(const DAabb& b, const glm::dvec3& p, double margin_m) {
  return p.x > b.min.x - margin_m && p.x < b.max.x + margin_m && p.y > b.min.y - margin_m &&
         p.y < b.max.y + margin_m && p.z > b.min.z - margin_m && p.z < b.max.z + margin_m;
}

// Where the segment from + t (to - from), t in [0, 1], is inside `b`: [enter, leave], or
// enter > leave when it misses (slabs).
std::pair<double, double> clip_segment(const DAabb& b, const glm::dvec3& from, const glm::dvec3& to) {
  double enter = 0.0, leave = 1.0;
  const glm::dvec3 d = to - from;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12) {
      if (from[a] < b.min[a] || from[a] > b.max[a]) return {1.0, 0.0};
      continue;
    }
    double t0 = (b.min[a] - from[a]) / d[a], t1 = (b.max[a] - from[a]) / d[a];
    if (t0 > t1) std::swap(t0, t1);
    enter = std::max(enter, t0);
    leave = std::min(leave, t1);
  }
  return {enter, leave};
}

double second_largest_side(const DAabb& b) {
  std::array<double, 3> s{b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z};
  std::sort(s.begin(), s.end());
  return s[1];
}

bool excluded_slot(std::span<const uint32_t> excluded, uint32_t slot) {
  return std::binary_search(excluded.begin(), excluded.end(), slot);
}

glm::dvec3 centre_of(const DAabb& b) { return 0.5 * (b.min + b.max); }

// The widest field of view a moved-in eye may use (degrees): wider distorts the subject.
constexpr double kMaxWidenedFovDeg = 90.0;
// How far an eye keeps from other objects' bounds (metres).
constexpr double kEyeMarginM = 0.3;

}  // namespace

bool Occluders::eye_inside(const glm::dvec3& eye_m, double margin_m,
                           std::span<const uint32_t> excluded) const {
  bool inside = false;
  for_each_box(
      view_, [&](const DAabb& b) { return !inside && contains(b, eye_m, margin_m); },
      [&](uint32_t slot, const DAabb&) { inside = inside || !excluded_slot(excluded, slot); },
      error_);
  return inside;
}

bool Occluders::segment_blocked(const glm::dvec3& from_m, const glm::dvec3& to_m, double min_side_m,
                                std::span<const uint32_t> excluded, double& first_hit_m) const {
  const double length_m = glm::length(to_m - from_m);
  double first = INFINITY;
  for_each_box(
      view_,
      [&](const DAabb& b) {
        const auto [enter, leave] = clip_segment(b, from_m, to_m);
        return enter <= leave && enter * length_m < first;
      },
      [&](uint32_t slot, const DAabb& b) {
        if (excluded_slot(excluded, slot) || second_largest_side(b) < min_side_m) return;
        first = std::min(first, clip_segment(b, from_m, to_m).first * length_m);
      },
      error_);
  first_hit_m = first;
  return std::isfinite(first);
}

Placement place_camera(const Occluders& occluders, const Subject& subject,
                       const std::vector<glm::dvec3>& directions, double aspect, double fov_deg,
                       double fill) {
  const glm::dvec3 centre = centre_of(subject.bounds);
  const glm::dvec3 size = subject.bounds.max - subject.bounds.min;
  // What hides a subject: anything at least a metre across both ways and a third of its size.
  const double min_side_m = std::max(1.0, 0.3 * std::max({size.x, size.y, size.z}));
  // The open line: from the eye to where the view ray enters the subject's bounds.
  const auto subject_entry = [&](const glm::dvec3& eye) {
    const auto [enter, leave] = clip_segment(subject.bounds, eye, centre);
    return eye + (enter <= leave ? enter : 1.0) * (centre - eye);
  };
  const auto clear = [&](const Camera& c) {
    double hit = 0;
    return !occluders.eye_inside(c.eye_m, kEyeMarginM, subject.slots) &&
           !occluders.segment_blocked(c.eye_m, subject_entry(c.eye_m), min_side_m, subject.slots, hit);
  };

  // Stages: the fitted eye of each direction in turn; then, direction by direction, the eye moved
  // in front of the first thing that hides the subject, the field of view widened to keep the
  // fill; else the first fit as it is (the renderer's highlight shows the subject through).
  Placement first;
  first.camera = fit_camera(subject.boxes, directions.front(), aspect, fov_deg, fill);
  for (size_t i = 0; i < directions.size(); ++i) {
    const Camera c = i == 0 ? first.camera : fit_camera(subject.boxes, directions[i], aspect, fov_deg, fill);
    if (clear(c)) return {c, i > 0, true};
  }
  for (size_t i = 0; i < directions.size(); ++i) {
    const glm::dvec3 view = glm::normalize(directions[i]);
    const Camera far = fit_camera(subject.boxes, view, aspect, fov_deg, fill);
    const glm::dvec3 entry = subject_entry(far.eye_m);
    double hit_m = 0;  // from the subject outward
    if (!occluders.segment_blocked(entry, far.eye_m, min_side_m, subject.slots, hit_m)) continue;
    // The eye's depth before the subject's centre (along the view) may be at most the
    // obstacle's, less a margin; a ray meeting the obstacle's face at a slant needs more of it
    // to keep kEyeMarginM away, so the margin grows until the eye is clear.
    const auto depth = [&](const Camera& c) { return glm::dot(centre - c.eye_m, view); };
    const Camera widest = fit_camera(subject.boxes, view, aspect, kMaxWidenedFovDeg, fill);
    for (int margins = 1; margins <= 4; ++margins) {
      const double allowed_m = glm::dot(centre - entry, view) + hit_m - margins * kEyeMarginM;
      if (allowed_m <= 0 || depth(widest) > allowed_m) break;
      Camera wide = widest;
      double lo = fov_deg, hi = kMaxWidenedFovDeg;  // depth falls as the field of view widens
      for (int step = 0; step < 30; ++step) {
        const double mid = 0.5 * (lo + hi);
        const Camera c = fit_camera(subject.boxes, view, aspect, mid, fill);
        if (depth(c) > allowed_m) lo = mid;
        else { hi = mid; wide = c; }
      }
      if (clear(wide)) return {wide, true, true};
    }
  }
  first.clear = false;
  return first;
}

}  // namespace plantview::views
