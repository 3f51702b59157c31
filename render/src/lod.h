// Level-of-detail rules, free of GL so that tests can check them directly.
//
// Screen-space error: a length of e metres at distance d (to the nearest point of the object's
// bounds, at least the near plane) spans e * pixels_per_metre(d) pixels on an image of height H
// and vertical field of view fov: H / (2 tan(fov / 2) d). The level chosen is the coarsest
// whose error spans at most the allowed pixels. The focal length is derived here once, rounded
// to float as the projection matrix holds it, and the frame's view (frame_plan.h), culling,
// level choice and the tests all take it from here: what is chosen is what is drawn.
//
// The default pixel errors of stills (0.5 px) and interactive frames (1 px) are in render.h
// (kStillPixelError, kInteractivePixelError) with the measurements they come from.
//
// Distance (the papers' rules): Zhou et al. pick a LOD node by the distance to its bounds over
// its size; here level 0 holds up to 8 sizes away and each doubling of the distance beyond
// that coarsens one level. Su et al. draw a pipe as its centreline beyond d2, proportional to
// its radius: here 300 radii (a 0.2 m pipe becomes a line at 30 m); and merge a straight run
// of a pipeline into one cylinder beyond d1: here 100 radii.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <glm/glm.hpp>

namespace plantview::detail {

inline constexpr double kNearPlaneM = 0.05;
inline constexpr double kDistanceLevelRatio = 8.0;
inline constexpr double kCentrelineRadii = 300.0;
inline constexpr double kMergeRadii = 100.0;
// Screen-space policy: a tree node spanning fewer pixels than this (times the pixel error) is
// drawn as its box.
inline constexpr double kNodeProxyPixels = 3.0;

// The projection's focal length for a vertical field of view: 1 / tan(fov / 2), in half image
// heights.
inline float focal_length(double fov_deg) {
  return float(1.0 / std::tan(glm::radians(fov_deg) / 2.0));
}
// The same in pixels, for an image height_px high: what a metre spans at a distance of 1 m.
inline double focal_length_px(double fov_deg, uint32_t height_px) {
  return height_px * 0.5 * focal_length(fov_deg);
}
// Pixels a metre spans at distance_m (no nearer than the near plane).
inline double pixels_per_metre(double distance_m, double focal_px) {
  return focal_px / std::max(distance_m, kNearPlaneM);
}
inline double pixels_per_metre(double distance_m, double fov_deg, uint32_t height_px) {
  return pixels_per_metre(distance_m, focal_length_px(fov_deg, height_px));
}

// error_m[l] for l < level_count, non-increasing in precision (growing with l).
inline uint32_t choose_level_screen_space(const float* error_m, uint32_t level_count,
                                          double px_per_m, double pixel_error) {
  uint32_t level = 0;
  for (uint32_t l = 1; l < level_count; ++l) {
    if (double(error_m[l]) * px_per_m <= pixel_error) level = l;
    else break;
  }
  return level;
}

inline uint32_t choose_level_distance(uint32_t level_count, double distance_m, double size_m) {
  const double ratio = distance_m / std::max(size_m, 1e-3);
  if (ratio <= kDistanceLevelRatio || level_count <= 1) return 0;
  const double steps = std::floor(std::log2(ratio / kDistanceLevelRatio)) + 1.0;
  return uint32_t(std::min<double>(steps, level_count - 1));
}

}  // namespace plantview::detail
