// Occlusion culling: the software depth buffer against an independent ray-cast oracle, and the
// renderer with occlusion on against itself with it off (on whatever EGL offers: llvmpipe in
// CI): a wall hides a row of pumps (not drawn, not uploaded) and they appear the frame the wall
// is out of the way; what was drawn last frame hides what comes into view behind it (the two
// phases), until it is uncovered; the exact test drops an object whose parts are hidden though
// its bounds span a gap; along a random path the object-id buffers agree and no visible object
// is missing (coarse and exact tests); the CPU time is the sum of its parts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include <glm/gtc/matrix_transform.hpp>

#include "frame_plan.h"
#include "occlusion/occlusion.h"
#include "occlusion/occlusion_buffer.h"
#include "occlusion/occlusion_occluders.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

using detail::OcclusionBuffer;
using test::TempDir;

// --- the buffer, without GL ---------------------------------------------------------------------

struct ViewBox {
  glm::vec3 min, max;
  std::vector<glm::vec3> corners() const {
    std::vector<glm::vec3> c;
    for (int i = 0; i < 8; ++i)
      c.push_back({i & 1 ? max.x : min.x, i & 2 ? max.y : min.y, i & 4 ? max.z : min.z});
    return c;
  }
};

// The distance along the ray from the eye (origin) through direction `d` to where it enters
// `box`, or infinity (slab test: independent of the buffer's projection and rasterisation).
float ray_enters(const glm::vec3& d, const ViewBox& box) {
  float t0 = 0, t1 = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (box.min[a] > 0 || box.max[a] < 0) return std::numeric_limits<float>::infinity();
      continue;
    }
    float ta = box.min[a] / d[a], tb = box.max[a] / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 ? t0 : std::numeric_limits<float>::infinity();
}

TEST(OcclusionBuffer, BoxBehindAWallIsHiddenAndOneBesideItIsNot) {
  OcclusionBuffer buffer;
  buffer.begin(1280, 720, 1.0f, 16.0f / 9.0f, 0.05f);
  const ViewBox wall{{-5, -3, -10.5f}, {5, 3, -10}};
  ASSERT_TRUE(buffer.add_convex(wall.corners()));
  EXPECT_TRUE(buffer.hidden({-1, -1, -20}, {1, 1, -18}));      // behind it
  EXPECT_FALSE(buffer.hidden({-1, -1, -9}, {1, 1, -8}));       // in front of it
  EXPECT_FALSE(buffer.hidden({6, -1, -20}, {12, 1, -18}));     // reaching past its edge
  EXPECT_FALSE(buffer.hidden({-1, -1, -10.4f}, {1, 1, -9.9f})); // overlapping it in depth
  EXPECT_FALSE(buffer.hidden({-1, -1, -20}, {1, 1, 0.5f}));     // reaching behind the eye
}

// One cell where nothing was drawn, in drawn depth at 5 m everywhere else (at the buffer's
// corners and inside): a box behind whose rectangle takes in that cell is visible, one beside
// it is hidden, a wide one is visible only if the cell lies within it; filled, both hidden.
TEST(OcclusionBuffer, OneOpenCellShowsWhatIsBehindIt) {
  const float focal = 1.0f, aspect = 16.0f / 9.0f, near_m = 0.05f;
  OcclusionBuffer buffer;
  buffer.begin(1280, 720, focal, aspect, near_m);
  const uint32_t w = buffer.width(), h = buffer.height();
  const float sx = 0.5f * float(w) * focal / aspect, sy = 0.5f * float(h) * focal;
  // A box 18..20 m ahead whose rectangle spans cells [i - r, i + r] x [j - r, j + r] (less
  // the spill: r >= 1 keeps cell (i, j) inside).
  const auto box_at = [&](int i, int j, float r) {
    const float d = 18.0f;  // its near face: the rectangle's extreme uses the nearer depth
    const float x0 = (float(i) + 0.5f - r - 0.5f * float(w)) / sx, x1 = (float(i) + 0.5f + r - 0.5f * float(w)) / sx;
    const float y0 = (float(j) + 0.5f - r - 0.5f * float(h)) / sy, y1 = (float(j) + 0.5f + r - 0.5f * float(h)) / sy;
    // Each extreme at the depth that makes it extreme: inside [x0 * d, x1 * d] at 18 m and
    // within it at 20 m too, for x of either sign.
    const float lo_x = std::max(x0 * d, x0 * 20.0f), hi_x = std::min(x1 * d, x1 * 20.0f);
    const float lo_y = std::max(y0 * d, y0 * 20.0f), hi_y = std::min(y1 * d, y1 * 20.0f);
    return ViewBox{{lo_x, lo_y, -20.0f}, {hi_x, hi_y, -d}};
  };
  const std::vector<std::pair<uint32_t, uint32_t>> holes = {
      {0, 0}, {7, 7}, {8, 8}, {43, 36}, {w / 2, h / 2}, {w - 1, 0}, {w - 1, h - 1}};
  for (const auto& [hi, hj] : holes) {
    std::vector<float> depth(size_t(w) * h, near_m / 5.0f);
    depth[size_t(hj) * w + hi] = 0;  // nothing drawn there
    buffer.load_device_depth(depth);
    const ViewBox over = box_at(int(hi), int(hj), 2.0f);
    const ViewBox beside = box_at(int(hi) + (hi + 20 < w ? 12 : -12), int(hj), 2.0f);
    const ViewBox wide = box_at(int(w / 2), int(h / 2), float(std::min(w, h)) / 2 - 4);
    EXPECT_FALSE(buffer.hidden(over.min, over.max)) << "hole at " << hi << "," << hj;
    EXPECT_TRUE(buffer.hidden(beside.min, beside.max)) << "hole at " << hi << "," << hj;
    const bool hole_in_wide = std::abs(int(hi) - int(w / 2)) < int(std::min(w, h) / 2) - 4 &&
                              std::abs(int(hj) - int(h / 2)) < int(std::min(w, h) / 2) - 4;
    EXPECT_EQ(buffer.hidden(wide.min, wide.max), !hole_in_wide) << "hole at " << hi << "," << hj;
    depth[size_t(hj) * w + hi] = near_m / 5.0f;
    buffer.load_device_depth(depth);
    EXPECT_TRUE(buffer.hidden(over.min, over.max)) << "filled at " << hi << "," << hj;
    EXPECT_TRUE(buffer.hidden(wide.min, wide.max)) << "filled at " << hi << "," << hj;
  }
}

TEST(OcclusionBuffer, WhatItCallsHiddenIsHiddenForEveryRayThroughIt) {
  // Random box occluders and random boxes; for every box the buffer calls hidden, rays from the
  // eye through points spread over the box's surface must enter an occluder first.
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float focal = 1.0f / std::tan(glm::radians(25.0f)), aspect = 16.0f / 9.0f;
  int hidden_boxes = 0, visible_boxes = 0;
  for (int scene = 0; scene < 40; ++scene) {
    OcclusionBuffer buffer;
    buffer.begin(1280, 720, focal, aspect, 0.05f);
    std::vector<ViewBox> occluders;
    for (int o = 0; o < 6; ++o) {
      const glm::vec3 c(u(rng) * 16 - 8, u(rng) * 10 - 5, -(4 + u(rng) * 20));
      const glm::vec3 h(0.5f + u(rng) * 4, 0.5f + u(rng) * 3, 0.2f + u(rng) * 2);
      occluders.push_back({c - h, c + h});
      buffer.add_convex(occluders.back().corners());
    }
    for (int b = 0; b < 60; ++b) {
      const glm::vec3 c(u(rng) * 20 - 10, u(rng) * 12 - 6, -(5 + u(rng) * 40));
      const glm::vec3 h(0.1f + u(rng) * 2, 0.1f + u(rng) * 2, 0.1f + u(rng) * 2);
      const ViewBox box{c - h, c + h};
      if (!buffer.hidden(box.min, box.max)) {
        ++visible_boxes;
        continue;
      }
      ++hidden_boxes;
      const int n = 12;
      for (int face = 0; face < 6; ++face) {
        for (int i = 0; i <= n; ++i) {
          for (int j = 0; j <= n; ++j) {
            glm::vec3 p;
            const int axis = face / 2;
            p[axis] = face % 2 ? box.max[axis] : box.min[axis];
            const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
            p[a1] = box.min[a1] + (box.max[a1] - box.min[a1]) * float(i) / n;
            p[a2] = box.min[a2] + (box.max[a2] - box.min[a2]) * float(j) / n;
            // Only points on the screen matter (the image shows nothing else).
            const float x = focal / aspect * p.x / -p.z, y = focal * p.y / -p.z;
            if (std::abs(x) > 1 || std::abs(y) > 1) continue;
            const float t_point = glm::length(p);
            float t_occluder = std::numeric_limits<float>::infinity();
            for (const auto& o : occluders) t_occluder = std::min(t_occluder, ray_enters(p / t_point, o));
            ASSERT_LT(t_occluder, t_point) << "scene " << scene << " box " << b << " point " << p.x
                                           << "," << p.y << "," << p.z << " is visible";
          }
        }
      }
    }
  }
  // The scenes hide some boxes and show others: the check above has something to check.
  EXPECT_GT(hidden_boxes, 100);
  EXPECT_GT(visible_boxes, 100);
}

// --- a box's place on screen ---------------------------------------------------------------------

// Random cameras (kilometres from the spatial origin, as plants lie) and random boxes: the
// projected bounds hold every corner's projection (worked out here in double precision from
// the camera itself) and its nearest distance, and are no wider than the corners span but for
// rounding.
TEST(ProjectedBox, HoldsEveryCornerAndIsNoWiderThanTheCornersSpan) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const glm::dvec3 origin_m(2300.0, -1700.0, 40.0);
  int checked = 0;
  for (int view = 0; view < 50; ++view) {
    Camera camera;
    camera.eye_m = origin_m + glm::dvec3(u(rng) * 200 - 100, u(rng) * 200 - 100, u(rng) * 30);
    camera.target_m = camera.eye_m + glm::dvec3(u(rng) * 2 - 1, u(rng) * 2 - 1, u(rng) * 0.6 - 0.3);
    camera.fov_deg = 30 + u(rng) * 60;
    const detail::FrameView fv = detail::make_frame_view(camera, 1280, 720, origin_m);
    const glm::dvec3 forward = glm::normalize(camera.target_m - camera.eye_m);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, camera.up));
    const glm::dvec3 up = glm::cross(right, forward);
    for (int b = 0; b < 40; ++b) {
      const glm::dvec3 centre = camera.eye_m + forward * (3 + u(rng) * 60) +
                                right * (u(rng) * 40 - 20) + up * (u(rng) * 20 - 10);
      const glm::dvec3 half(0.05 + u(rng) * 6, 0.05 + u(rng) * 6, 0.05 + u(rng) * 3);
      float mn[3], mx[3];
      for (int a = 0; a < 3; ++a) {
        mn[a] = float(centre[a] - half[a] - origin_m[a]);
        mx[a] = float(centre[a] + half[a] - origin_m[a]);
      }
      // Rounding's allowance (float rotation and corners, a hair of 1e-5 of their size): a
      // corner's x / d shifted by a hair over its distance, twice over.
      const glm::dvec3 offset = centre - camera.eye_m;
      const double hair = 2e-5 * (std::abs(offset.x) + std::abs(offset.y) + std::abs(offset.z) + half.x + half.y + half.z) + 2e-5;
      double lo_x = 1e30, hi_x = -1e30, lo_y = 1e30, hi_y = -1e30, near_d = 1e30;
      double lo_x_allowed = 1e30, hi_x_allowed = -1e30, lo_y_allowed = 1e30, hi_y_allowed = -1e30;
      bool in_front = true;
      for (int c = 0; c < 8; ++c) {
        const glm::dvec3 p = origin_m + glm::dvec3(c & 1 ? mx[0] : mn[0], c & 2 ? mx[1] : mn[1], c & 4 ? mx[2] : mn[2]) -
                             camera.eye_m;
        const double d = glm::dot(p, forward), x = glm::dot(p, right) / d, y = glm::dot(p, up) / d;
        in_front = in_front && d > 0.1;
        lo_x = std::min(lo_x, x), hi_x = std::max(hi_x, x), lo_y = std::min(lo_y, y), hi_y = std::max(hi_y, y);
        near_d = std::min(near_d, d);
        const double sx = 2 * hair * (1 + std::abs(x)) / (d - hair) + 1e-5;
        const double sy = 2 * hair * (1 + std::abs(y)) / (d - hair) + 1e-5;
        lo_x_allowed = std::min(lo_x_allowed, x - sx), hi_x_allowed = std::max(hi_x_allowed, x + sx);
        lo_y_allowed = std::min(lo_y_allowed, y - sy), hi_y_allowed = std::max(hi_y_allowed, y + sy);
      }
      if (!in_front) continue;
      const detail::ProjectedBounds pb = detail::project_box(fv, mn, mx);
      EXPECT_LE(pb.x0, lo_x);
      EXPECT_GE(pb.x1, hi_x);
      EXPECT_LE(pb.y0, lo_y);
      EXPECT_GE(pb.y1, hi_y);
      EXPECT_LE(pb.near_d, near_d);
      EXPECT_GE(pb.x0, lo_x_allowed);
      EXPECT_LE(pb.x1, hi_x_allowed);
      EXPECT_GE(pb.y0, lo_y_allowed);
      EXPECT_LE(pb.y1, hi_y_allowed);
      EXPECT_GE(pb.near_d, near_d - hair);
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
}

TEST(ProjectedBox, ABoxTurnedToTheViewIsHiddenBehindAWallItsViewBoundsOverhang) {
  // The eye at the origin looks along (1, 1, 0) at a box 8 m x 0.4 m x 1 m along the x axis,
  // 20 m ahead: turned 45 degrees to the view. A wall 4 m wide and 3 m tall 10 m ahead, from
  // 2.5 m left of the view's axis to 1.5 m right of it. The box's corners lie behind the wall
  // on screen (from 0.17 left to 0.13 right in x / d; the wall spans 0.25 left to 0.15 right),
  // but its bounds in view space are 5.9 m wide and deep, and their near face spans 0.17 to
  // either side.
  Camera camera;
  camera.eye_m = {0, 0, 0};
  camera.target_m = glm::dvec3(1, 1, 0);
  camera.fov_deg = 50;
  const detail::FrameView fv = detail::make_frame_view(camera, 1280, 720, glm::dvec3(0.0));
  OcclusionBuffer buffer;
  buffer.begin(1280, 720, fv.focal, fv.aspect, 0.05f);
  const ViewBox wall{{-2.5f, -1.5f, -10.2f}, {1.5f, 1.5f, -10}};
  buffer.add_convex(wall.corners());
  const glm::dvec3 centre = glm::normalize(glm::dvec3(1, 1, 0)) * 20.0;
  const float mn[3] = {float(centre.x - 4), float(centre.y - 0.2), -0.5f};
  const float mx[3] = {float(centre.x + 4), float(centre.y + 0.2), 0.5f};
  EXPECT_TRUE(buffer.hidden(detail::project_box(fv, mn, mx)));
  // Its bounds in view space, as the test took them before: not hidden.
  const glm::mat3 r(fv.rotation);
  glm::vec3 c(0.0f), e(0.0f);
  for (int a = 0; a < 3; ++a) c += r[a] * (0.5f * (mn[a] + mx[a]));
  for (int row = 0; row < 3; ++row)
    for (int a = 0; a < 3; ++a) e[row] += std::abs(r[a][row]) * 0.5f * (mx[a] - mn[a]);
  EXPECT_FALSE(buffer.hidden(c - e, c + e));
}

// Inner conservative rasterisation, cell by cell: a convex silhouette covers every cell whose
// corners all lie inside it, and no cell with a corner outside it (cells within a hair of its
// edges, where the buffer's float projection and margin decide, are left out of the check).
TEST(OcclusionBuffer, AConvexSilhouetteCoversExactlyTheCellsWhollyInsideIt) {
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const float focal = 1.0f / std::tan(glm::radians(30.0f)), aspect = 16.0f / 9.0f;
  OcclusionBuffer buffer;
  buffer.begin(1280, 720, focal, aspect, 0.05f);
  const double w = buffer.width(), h = buffer.height();
  const double sx = 0.5 * w * focal / aspect, sy = 0.5 * h * focal;
  constexpr double kHair = 1e-3;  // cells
  size_t covered_cells = 0, polygons_covering = 0, polygons_left_early = 0;
  for (int polygon = 0; polygon < 200; ++polygon) {
    // Points in cell coordinates: a cluster of 3 to 40 (or a rectangle's corners, whose hull has
    // horizontal and vertical edges), from a few cells to wider than the buffer.
    const double size = std::pow(10.0, -0.5 + 3.0 * u(rng));
    const double cx = -0.2 * w + 1.4 * w * u(rng), cy = -0.2 * h + 1.4 * h * u(rng);
    std::vector<glm::dvec2> cells;
    if (polygon % 4 == 0) {
      const double hw = size * u(rng), hh = size * u(rng);
      cells = {{cx - hw, cy - hh}, {cx + hw, cy - hh}, {cx + hw, cy + hh}, {cx - hw, cy + hh}};
    } else {
      const int n = 3 + int(u(rng) * 38);
      for (int i = 0; i < n; ++i) cells.push_back({cx + size * (u(rng) - 0.5), cy + size * (u(rng) - 0.5)});
    }
    const double d = 1 + 99 * u(rng);
    std::vector<glm::vec3> points;
    for (const glm::dvec2& c : cells)
      points.push_back(glm::vec3((c.x - 0.5 * w) / sx * d, (c.y - 0.5 * h) / sy * d, -d));
    buffer.begin(1280, 720, focal, aspect, 0.05f);
    buffer.add_convex(points);
    // The hull, counter-clockwise (monotone chain, in double).
    std::sort(cells.begin(), cells.end(), [](const glm::dvec2& a, const glm::dvec2& b) {
      return a.x < b.x || (a.x == b.x && a.y < b.y);
    });
    const auto turn = [](const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
      return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    std::vector<glm::dvec2> hull(2 * cells.size());
    size_t k = 0;
    for (size_t i = 0; i < cells.size(); ++i) {
      while (k >= 2 && turn(hull[k - 2], hull[k - 1], cells[i]) <= 0) --k;
      hull[k++] = cells[i];
    }
    for (size_t i = cells.size() - 1, t = k + 1; i > 0; --i) {
      while (k >= t && turn(hull[k - 2], hull[k - 1], cells[i - 1]) <= 0) --k;
      hull[k++] = cells[i - 1];
    }
    hull.resize(k - 1);
    // A corner's distance inside the hull (negative: outside).
    const auto inside_by = [&](double x, double y) {
      double least = std::numeric_limits<double>::infinity();
      for (size_t e = 0; e < hull.size(); ++e) {
        const glm::dvec2 a = hull[e], b = hull[(e + 1) % hull.size()];
        least = std::min(least, turn(a, b, {x, y}) / glm::length(b - a));
      }
      return least;
    };
    // Each corner of the grid once.
    const uint32_t bw = buffer.width(), bh = buffer.height();
    std::vector<double> corner((bw + 1) * size_t(bh + 1));
    for (uint32_t j = 0; j <= bh; ++j)
      for (uint32_t i = 0; i <= bw; ++i) corner[j * size_t(bw + 1) + i] = inside_by(i, j);
    bool any = false;
    for (uint32_t j = 0; j < bh; ++j) {
      for (uint32_t i = 0; i < bw; ++i) {
        const size_t c = j * size_t(bw + 1) + i;
        const double least = std::min({corner[c], corner[c + 1], corner[c + bw + 1], corner[c + bw + 2]});
        const bool covered = buffer.depth(i, j) < std::numeric_limits<float>::infinity();
        if (least > kHair) {
          ASSERT_TRUE(covered) << "polygon " << polygon << " cell " << i << "," << j;
        } else if (least < -kHair) {
          ASSERT_FALSE(covered) << "polygon " << polygon << " cell " << i << "," << j;
        }
        covered_cells += covered;
        any |= covered;
      }
    }
    polygons_covering += any;
    // What covers a cell passes the early test, by its points and by their bounding box (the
    // renderer asks it of a piece's bounds before transforming its points).
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (const glm::vec3& p : points) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    const std::array<glm::vec3, 8> box = {glm::vec3{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z},
                                          {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z},
                                          {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                                          {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}};
    if (any) {
      EXPECT_TRUE(buffer.may_cover(points)) << "polygon " << polygon;
      EXPECT_TRUE(buffer.may_cover(box)) << "polygon " << polygon;
    }
    polygons_left_early += !buffer.may_cover(points);
  }
  // Small, large and off-screen silhouettes: most cover cells, some none, and of those some
  // are left before their hull is built.
  EXPECT_GT(polygons_left_early, 0u);
  EXPECT_GT(polygons_covering, 50u);
  EXPECT_LT(polygons_covering, 200u);
  EXPECT_GT(covered_cells, 100000u);
}

// A silhouette whose bounds on screen, clipped to the buffer, hold no whole cell covers none,
// and is told so before its hull is built: smaller than a cell, a thin sliver, reaching less
// than a cell into the buffer from beside it, or off it.
TEST(OcclusionBuffer, ASilhouetteWhoseBoundsHoldNoWholeCellCoversNone) {
  const float focal = 1.0f, aspect = 16.0f / 9.0f;
  OcclusionBuffer buffer;
  buffer.begin(1280, 720, focal, aspect, 0.05f);
  const float w = float(buffer.width()), h = float(buffer.height());
  const float sx = 0.5f * w * focal / aspect, sy = 0.5f * h * focal;
  // A rectangle 10 m ahead spanning cells [x0, x1] x [y0, y1] (cell coordinates).
  const auto rectangle = [&](float x0, float y0, float x1, float y1) {
    const float d = 10.0f;
    const auto at = [&](float x, float y) {
      return glm::vec3((x - 0.5f * w) / sx * d, (y - 0.5f * h) / sy * d, -d);
    };
    return std::vector<glm::vec3>{at(x0, y0), at(x1, y0), at(x1, y1), at(x0, y1)};
  };
  const struct {
    const char* what;
    float x0, y0, x1, y1;
    bool covers;
  } cases[] = {
      {"smaller than a cell", 40.2f, 30.2f, 40.9f, 30.9f, false},
      {"a cell wide across two cells", 40.5f, 30.5f, 41.5f, 31.5f, false},
      {"a thin sliver", 10.0f, 30.2f, 200.0f, 30.9f, false},
      {"less than a cell into the left", -50.0f, 20.0f, 0.8f, 60.0f, false},
      {"less than a cell into the top", 20.0f, h - 0.6f, 60.0f, h + 40.0f, false},
      {"off the buffer", w + 1.0f, 10.0f, w + 90.0f, 50.0f, false},
      {"a cell and a little more", 39.9f, 29.9f, 41.1f, 31.1f, true},
      {"three cells into the left", -50.0f, 20.0f, 3.0f, 60.0f, true},
  };
  for (const auto& c : cases) {
    buffer.begin(1280, 720, focal, aspect, 0.05f);
    const std::vector<glm::vec3> points = rectangle(c.x0, c.y0, c.x1, c.y1);
    EXPECT_EQ(buffer.may_cover(points), c.covers) << c.what;
    EXPECT_EQ(buffer.add_convex(points), c.covers) << c.what;
  }
}

// Occluders rasterised by several workers, each into a buffer of its own, then merged: every
// cell equals what one buffer given them all holds, whichever worker took which occluder.
TEST(OcclusionBuffer, OccludersSplitOverBuffersAndMergedFillTheCellsOneBufferWould) {
  std::mt19937 rng(41);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float focal = 1.0f / std::tan(glm::radians(25.0f)), aspect = 16.0f / 9.0f;
  OcclusionBuffer whole, parts[3];
  whole.begin(1280, 720, focal, aspect, 0.05f);
  for (OcclusionBuffer& b : parts) b.begin(1280, 720, focal, aspect, 0.05f);
  size_t covering = 0;
  for (int o = 0; o < 300; ++o) {
    // A box somewhere in front of the eye, at 1 to 100 m, overlapping others at other depths.
    const float d = 1.0f + 99.0f * u(rng);
    const glm::vec3 centre((u(rng) - 0.5f) * d, (u(rng) - 0.5f) * 0.6f * d, -d);
    const glm::vec3 half = glm::vec3(u(rng), u(rng), u(rng)) * (0.02f + 0.3f * u(rng)) * d;
    const std::vector<glm::vec3> corners = ViewBox{centre - half, centre + half}.corners();
    covering += whole.add_convex(corners);
    parts[rng() % 3].add_convex(corners);
  }
  parts[0].merge_nearest(parts[1]);
  parts[0].merge_nearest(parts[2]);
  size_t covered = 0;
  for (uint32_t j = 0; j < whole.height(); ++j)
    for (uint32_t i = 0; i < whole.width(); ++i) {
      ASSERT_EQ(parts[0].depth(i, j), whole.depth(i, j)) << "cell " << i << "," << j;
      covered += whole.depth(i, j) < std::numeric_limits<float>::infinity();
    }
  EXPECT_GT(covering, 100u);  // the occluders overlap and cover much of the buffer
  EXPECT_GT(covered, whole.width() * whole.height() / 4);
}

// --- occluder shapes -------------------------------------------------------------------------

// Whether p lies inside (or on, within rounding) the closed convex mesh of `primitive` at
// `level`: on the inner side of every triangle's plane (the mesh as drawn: its own vertices and
// indices).
bool inside_mesh(const Primitive& primitive, uint32_t level, const glm::vec3& p) {
  const MeshPlan plan = plan_mesh(primitive);
  std::vector<PackedVertex> v(plan.vertex_count);
  write_vertices(primitive, plan, glm::dvec3(0.0), v);
  std::vector<uint32_t> idx(plan.index_count(level));
  write_indices(plan, level, 0, std::span<uint32_t>(idx));
  for (size_t t = 0; t + 2 < idx.size(); t += 3) {
    const glm::vec3 a = v[idx[t]].position_m, b = v[idx[t + 1]].position_m, c = v[idx[t + 2]].position_m;
    const glm::vec3 n = glm::cross(b - a, c - a);
    // Slivers (three nearly collinear cap vertices of a fine ring) have no reliable plane in
    // float; their neighbours span the same face.
    if (glm::length(n) < 1e-3f * glm::length(b - a) * glm::length(c - a)) continue;
    // Float rounding of long, thin triangles far from the origin: a relative margin.
    const float margin = 1e-5f * (glm::length(p) + glm::length(b - a) + glm::length(c - a));
    if (glm::dot(glm::normalize(n), p - a) > margin) return false;
  }
  return true;
}

TEST(OccluderShape, EveryPointLiesInsideEveryLevelOfTheDrawnMesh) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Primitive> primitives;
  for (int i = 0; i < 12; ++i) {
    // Random rotations (and a mirror now and then), sizes from a pipe to a vessel.
    const glm::vec3 axis = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0, 0, 1.5f));
    Placement placement;
    placement.linear = glm::mat3(glm::rotate(glm::mat4(1.0f), 3.0f * u(rng), axis));
    if (i % 5 == 4) placement.linear[0] = -placement.linear[0];
    placement.translation_m = {10 * u(rng), 10 * u(rng), 10 * u(rng)};
    const float size = 0.3f + 3 * (u(rng) + 1);
    primitives.push_back({placement, Cylinder{0.5f * size, size * (1.5f + 4 * (u(rng) + 1))}});
    primitives.push_back({placement, Box{size, 0.3f * size, 6 * size}});
    primitives.push_back({placement, Sphere{size}});
    primitives.push_back({placement, Snout{size, 0.6f * size, 2 * size, 0.2f * size, 0, 0, 0, 0, 0}});
  }
  std::vector<PackedVertex> scratch;
  for (const Primitive& primitive : primitives) {
    detail::OccluderShape shape;
    detail::build_occluder_shape(std::span(&primitive, 1), scratch, shape);
    ASSERT_FALSE(shape.empty()) << "kind " << int(primitive.kind());
    const MeshPlan plan = plan_mesh(primitive);
    for (uint32_t level = 0; level < plan.level_count; ++level)
      for (const glm::vec3& p : shape.points)
        ASSERT_TRUE(inside_mesh(primitive, level, p))
            << "kind " << int(primitive.kind()) << " level " << level << " point " << p.x << "," << p.y << "," << p.z;
  }
}

// --- the renderer ------------------------------------------------------------------------------

Object make_object(const std::string& name, ObjectClass cls, glm::dvec3 origin,
                   std::vector<Primitive> primitives, Colour colour = {200, 120, 40, 255}) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = cls;
  o.colour = colour;
  o.origin_m = origin;
  o.primitives = std::move(primitives);
  return o;
}

std::unique_ptr<Store> make_store(const TempDir& dir, const std::vector<Object>& objects) {
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  EXPECT_TRUE(store) << error;
  if (!store) return nullptr;  // (the caller asserts)
  const IngestResult result = ingest_objects(*store, objects);
  EXPECT_TRUE(result) << result.error().message;
  return store;
}

std::unique_ptr<Renderer> make_renderer(const Store& store, bool occlusion,
                                        OcclusionTest test = OcclusionTest::automatic) {
  test::gl_context();
  RenderOptions options;
  options.vertex_budget_bytes = 16u << 20;
  options.occlusion = occlusion;
  options.occlusion_test = test;
  std::string error;
  auto r = Renderer::create(store, options, error);
  EXPECT_TRUE(r) << error;
  return r;
}

Camera look(glm::dvec3 eye, glm::dvec3 target) {
  Camera c;
  c.eye_m = eye;
  c.target_m = target;
  return c;
}

std::set<uint64_t> ids_in(const Image& image) {
  std::set<uint64_t> ids(image.object_ids.begin(), image.object_ids.end());
  ids.erase(0);
  return ids;
}

TEST(Occlusion, AWallHidesARowOfPumpsUntilItIsOutOfTheWay) {
  // A wall 20 m long at y = 0; five pumps (a motor cylinder on a base box) 4 m behind it.
  std::vector<Object> objects;
  objects.push_back(make_object("wall", ObjectClass::structure, {0, 0, 3},
                                {Primitive{Placement{}, Box{20, 0.4f, 6}}}, {120, 120, 120, 255}));
  std::vector<uint64_t> pumps;
  for (int i = 0; i < 5; ++i) {
    Placement motor;
    motor.linear = glm::mat3(glm::vec3(0, 0, 1), glm::vec3(0, 1, 0), glm::vec3(-1, 0, 0));  // along x
    motor.translation_m = {0, 0, 0.9f};
    objects.push_back(make_object("P-10" + std::to_string(i), ObjectClass::equipment,
                                  {-8 + 4.0 * i, 4, 0},
                                  {Primitive{Placement{glm::mat3(1.0f), {0, 0, 0.25f}}, Box{1.6f, 0.8f, 0.5f}},
                                   Primitive{motor, Cylinder{0.35f, 1.4f}}}));
    pumps.push_back(objects.back().id);
  }
  TempDir dir;
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  auto r = make_renderer(*store, true);
  std::string error;
  Image image;
  FrameStats stats;

  // From the front of the wall: only the wall is drawn, and only it is uploaded.
  ASSERT_TRUE(r->render(look({0, -15, 2}, {0, 4, 1}), 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(ids_in(image), std::set<uint64_t>{objects[0].id});
  EXPECT_EQ(stats.objects_occluded, 5u);
  EXPECT_EQ(stats.objects_visible, 1u);
  EXPECT_EQ(stats.objects_resident, 1u);
  EXPECT_EQ(stats.objects_tessellated, 1u);
  EXPECT_GT(stats.ms.occlusion, 0.0);

  // From behind the pumps, the first frame: every pump is drawn (and the wall behind them).
  ASSERT_TRUE(r->render(look({0, 20, 2}, {0, 4, 1}), 320, 180, true, image, stats, error)) << error;
  const auto seen = ids_in(image);
  for (const uint64_t id : pumps) EXPECT_TRUE(seen.count(id)) << "pump " << id << " missing";
  EXPECT_EQ(stats.objects_occluded, 0u);
  EXPECT_EQ(stats.objects_tessellated, 5u);

  // And from above the wall's top (it no longer hides them): all drawn again.
  ASSERT_TRUE(r->render(look({0, -15, 30}, {0, 4, 0}), 320, 180, true, image, stats, error)) << error;
  const auto from_above = ids_in(image);
  for (const uint64_t id : pumps) EXPECT_TRUE(from_above.count(id)) << "pump " << id << " missing";
}

TEST(Occlusion, WhatWasDrawnLastFrameHidesWhatComesIntoViewBehindItUntilItIsUncovered) {
  // A column 6 m tall, and a pump 9 m behind it (policy none: nothing boxed or left out as
  // small; 320x180, so the column is under kOccluderMinPixels from 70 m).
  const std::vector<Object> objects = {
      make_object("column", ObjectClass::structure, {0, 0, 2}, {Primitive{Placement{}, Box{3, 1, 6}}},
                  {120, 120, 120, 255}),
      make_object("P-201", ObjectClass::equipment, {0, 9, 0.6}, {Primitive{Placement{}, Box{1.2f, 1.2f, 1.2f}}})};
  const uint64_t column = objects[0].id, pump = objects[1].id;
  TempDir dir;
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  test::gl_context();
  RenderOptions options;
  options.vertex_budget_bytes = 16u << 20;
  options.lod_policy = LodPolicy::none;
  std::string error;
  auto r = Renderer::create(*store, options, error);
  ASSERT_TRUE(r) << error;
  Image image;
  FrameStats stats;
  const Camera near_view = look({0, -20, 2}, {0, 0, 2}), far_view = look({0, -70, 2}, {0, 0, 2}),
               above = look({0, -70, 80}, {0, 0, 0});

  // Near: the column is among the largest on screen (phase 1) and hides the pump, which is
  // neither tessellated nor drawn.
  ASSERT_TRUE(r->render(near_view, 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(ids_in(image), std::set<uint64_t>{column});
  EXPECT_EQ(stats.objects_occluded, 1u);
  EXPECT_EQ(stats.objects_tessellated, 1u);

  // Far: the column spans a few pixels, but it was drawn last frame, so phase 1 draws it and
  // the pump, still behind it, is dropped again.
  ASSERT_TRUE(r->render(far_view, 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(ids_in(image), std::set<uint64_t>{column});
  EXPECT_EQ(stats.occluders, 1u);
  EXPECT_EQ(stats.objects_occluded, 1u);
  EXPECT_EQ(stats.objects_tessellated, 0u);
  EXPECT_EQ(stats.objects_resident, 1u);
  {
    // A first frame from there has nothing drawn before and no large object: the pump is
    // drawn (behind the column: the same image).
    auto fresh = Renderer::create(*store, options, error);
    ASSERT_TRUE(fresh) << error;
    Image fresh_image;
    FrameStats fresh_stats;
    ASSERT_TRUE(fresh->render(far_view, 320, 180, true, fresh_image, fresh_stats, error)) << error;
    EXPECT_EQ(fresh_stats.objects_occluded, 0u);
    EXPECT_EQ(fresh_stats.objects_tessellated, 2u);
    EXPECT_EQ(fresh_image.object_ids, image.object_ids);
  }

  // From above, the pump is uncovered: drawn in that very frame, as without occlusion.
  ASSERT_TRUE(r->render(above, 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(stats.objects_occluded, 0u);
  EXPECT_EQ(ids_in(image), (std::set<uint64_t>{column, pump}));
  options.occlusion = false;
  auto off = Renderer::create(*store, options, error);
  ASSERT_TRUE(off) << error;
  Image off_image;
  ASSERT_TRUE(off->render(above, 320, 180, true, off_image, stats, error)) << error;
  EXPECT_EQ(off_image.object_ids, image.object_ids);
}

// The exact test: an object of two parts, each behind a wall of its own, with a gap between
// the walls that its bounds span. The coarse test sees the gap through its bounds; the exact
// one tests its parts' bounds against the depth drawn, sample by sample, and drops it; also
// where a part reaches past the eye's plane, out of view.
TEST(Occlusion, AnObjectWhosePartsAreHiddenIsDroppedThoughItsBoundsSpanAGap) {
  const Colour grey{120, 120, 120, 255};
  const std::vector<Object> objects = {
      make_object("wall-west", ObjectClass::structure, {-3, 0, 3}, {Primitive{Placement{}, Box{4, 0.4f, 6}}}, grey),
      make_object("wall-east", ObjectClass::structure, {3, 0, 3}, {Primitive{Placement{}, Box{4, 0.4f, 6}}}, grey),
      make_object("E-301", ObjectClass::equipment, {0, 6, 1},
                  {Primitive{Placement{glm::mat3(1.0f), {-3, 0, 0}}, Box{1.5f, 1.5f, 1.5f}},
                   Primitive{Placement{glm::mat3(1.0f), {3, 0, 0}}, Box{1.5f, 1.5f, 1.5f}}})};
  TempDir dir;
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  std::string error;
  const Camera view = look({0, -12, 1.5}, {0, 6, 1.5});
  // Through the gap the ground shows: nothing of E-301 (each part lies behind its wall).
  auto off = make_renderer(*store, false);
  Image off_image;
  FrameStats stats;
  ASSERT_TRUE(off->render(view, 320, 180, true, off_image, stats, error)) << error;
  ASSERT_EQ(ids_in(off_image), (std::set<uint64_t>{objects[0].id, objects[1].id}));

  // (The coarse test alone keeps it, the exact test drops it.)
  auto coarse = make_renderer(*store, true, OcclusionTest::coarse);
  Image image;
  ASSERT_TRUE(coarse->render(view, 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(stats.objects_occluded, 0u);
  EXPECT_EQ(image.object_ids, off_image.object_ids);
  auto on = make_renderer(*store, true, OcclusionTest::exact);
  ASSERT_TRUE(on->render(view, 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(stats.objects_occluded, 1u);
  EXPECT_EQ(stats.objects_tessellated, 2u) << "E-301 is neither tessellated nor drawn";
  EXPECT_EQ(image.object_ids, off_image.object_ids);

  // The view of a variant of the objects, into `a` without occlusion and into `b` (with
  // `b_stats`) with the exact test.
  const auto render_variant = [&](const std::vector<Object>& variant, Image& a, Image& b,
                                  FrameStats& b_stats) {
    TempDir variant_dir;
    auto variant_store = make_store(variant_dir, variant);
    ASSERT_TRUE(variant_store);
    FrameStats a_stats;
    ASSERT_TRUE(make_renderer(*variant_store, false)->render(view, 320, 180, true, a, a_stats, error))
        << error;
    ASSERT_TRUE(make_renderer(*variant_store, true, OcclusionTest::exact)
                    ->render(view, 320, 180, true, b, b_stats, error))
        << error;
  };

  // A part right in front of the eye (nearer than twice the near plane) keeps the object,
  // though its other part is hidden.
  {
    std::vector<Object> with_near = objects;
    with_near[2].primitives.push_back(
        Primitive{Placement{glm::mat3(1.0f), {0.0f, -17.92f, 0.5f}}, Box{0.05f, 0.05f, 0.05f}});
    with_near[2].primitives.erase(with_near[2].primitives.begin() + 1);  // the east part
    Image a, b;
    ASSERT_NO_FATAL_FAILURE(render_variant(with_near, a, b, stats));
    ASSERT_TRUE(ids_in(a).count(with_near[2].id)) << "the near part shows";
    EXPECT_EQ(b.object_ids, a.object_ids);
  }

  // A part beside the eye, reaching from behind its plane to in front of it (the eye at
  // x = 0, y = -12): out of view, it is tested as any other (the test draws its faces
  // unclipped at the near plane, depth clamped), and the object, hidden elsewhere, is dropped;
  // in view, the object is kept.
  for (const float part_x : {-3.0f, -1.0f}) {
    SCOPED_TRACE("a part beside the eye at x = " + std::to_string(part_x));
    std::vector<Object> beside = objects;
    beside[2].primitives[1] =
        Primitive{Placement{glm::mat3(1.0f), {part_x, -18.0f, 0.5f}}, Box{0.5f, 4.0f, 0.5f}};
    Image a, b;
    ASSERT_NO_FATAL_FAILURE(render_variant(beside, a, b, stats));
    const bool in_view = part_x > -2;
    ASSERT_EQ(ids_in(a).count(beside[2].id), in_view ? 1u : 0u);
    EXPECT_EQ(stats.objects_occluded, in_view ? 0u : 1u);
    EXPECT_EQ(b.object_ids, a.object_ids);
  }

  // Seen from higher up, its parts show above the walls: drawn, as without occlusion.
  const Camera above = look({0, -12, 30}, {0, 6, 0});
  ASSERT_TRUE(off->render(above, 320, 180, true, off_image, stats, error)) << error;
  ASSERT_TRUE(ids_in(off_image).count(objects[2].id));
  ASSERT_TRUE(on->render(above, 320, 180, true, image, stats, error)) << error;
  EXPECT_EQ(stats.objects_occluded, 0u);
  EXPECT_EQ(image.object_ids, off_image.object_ids);
}

TEST(Occlusion, IdBuffersMatchWithoutOcclusionAlongARandomPath) {
  TempDir dir;
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  ASSERT_TRUE(store) << error;
  GenerateOptions g;
  g.preset = 'a';
  const IngestResult result = ingest_generated(*store, g);
  ASSERT_TRUE(result) << result.error().message;
  auto off = make_renderer(*store, false);
  // Random cameras inside the plant, at eye height, looking level-ish in random directions:
  // where occlusion matters most.
  const DAabb bounds = off->model_bounds();
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Camera> cameras;
  std::vector<Camera> walk;
  ASSERT_TRUE(make_camera_path(PathKind::walkthrough, 6, *store, walk, error)) << error;
  cameras = walk;
  for (int i = 0; i < 10; ++i) {
    const glm::dvec3 eye(bounds.min.x + u(rng) * (bounds.max.x - bounds.min.x),
                         bounds.min.y + u(rng) * (bounds.max.y - bounds.min.y), bounds.min.z + 1.7);
    const double a = u(rng) * 2 * M_PI;
    cameras.push_back(look(eye, eye + glm::dvec3(std::cos(a), std::sin(a), -0.05)));
  }
  for (const OcclusionTest test : {OcclusionTest::coarse, OcclusionTest::exact}) {
  SCOPED_TRACE(std::string(occlusion_test_name(test)) + " test");
  auto on = make_renderer(*store, true, test);
  // The same along the path with each next view expected (Renderer::expect): each frame's
  // cull and first phase made while the one before drew give the same frames.
  auto ahead = make_renderer(*store, true, test);
  uint64_t occluded = 0;
  for (size_t v = 0; v < cameras.size(); ++v) {
    Image a, b, c;
    FrameStats sa, sb, sc;
    ASSERT_TRUE(on->render(cameras[v], 320, 180, true, a, sa, error)) << error;
    ASSERT_TRUE(off->render(cameras[v], 320, 180, true, b, sb, error)) << error;
    if (v + 1 < cameras.size()) ahead->expect(cameras[v + 1]);
    ASSERT_TRUE(ahead->render(cameras[v], 320, 180, true, c, sc, error)) << error;
    EXPECT_EQ(sc.made_ahead, v > 0) << "view " << v;
    EXPECT_TRUE(a.rgba == c.rgba && a.object_ids == c.object_ids) << "view " << v;
    sa.ms = sc.ms = {};
    sc.made_ahead = false;
    EXPECT_EQ(sa.to_json(), sc.to_json()) << "view " << v;
    occluded += sa.objects_occluded;
    size_t same = 0;
    for (size_t p = 0; p < a.object_ids.size(); ++p) same += a.object_ids[p] == b.object_ids[p];
    EXPECT_GE(double(same), 0.9995 * double(a.object_ids.size())) << "view " << v;
    // Nothing visible without occlusion is missing at the end of the frame with it.
    const auto with = ids_in(a);
    for (const uint64_t id : ids_in(b)) EXPECT_TRUE(with.count(id)) << "view " << v << ": object " << id << " missing";
    EXPECT_LE(sa.triangles, sb.triangles) << "view " << v;
  }
  EXPECT_GT(occluded, 0u) << "the path hides nothing: the comparison checks nothing";
  }
}

TEST(Occlusion, CpuTimeIsTheSumOfItsParts) {
  TempDir dir;
  auto store = make_store(dir, {make_object("wall", ObjectClass::structure, {0, 0, 3},
                                            {Primitive{Placement{}, Box{20, 0.4f, 6}}}),
                                make_object("pump", ObjectClass::equipment, {0, 4, 1},
                                            {Primitive{Placement{}, Cylinder{0.4f, 1.0f}}})});
  ASSERT_TRUE(store);
  auto r = make_renderer(*store, true);
  std::string error;
  Image image;
  FrameStats s;
  ASSERT_TRUE(r->render(look({0, -15, 2}, {0, 4, 1}), 160, 90, false, image, s, error)) << error;
  EXPECT_GT(s.ms.cpu, 0.0);
  EXPECT_NEAR(s.ms.cpu, s.ms.cull + s.ms.occlusion + s.ms.choose + s.ms.stream, 1e-9);
  EXPECT_LE(s.ms.cpu + s.ms.depth_reduction, s.ms.total);
  EXPECT_GT(s.ms.depth_reduction, 0.0) << "a drawn frame with occlusion reduces its depth";
  EXPECT_NE(s.to_json().find("\"cpu\":"), std::string::npos);
  EXPECT_NE(s.to_json().find("\"depth_reduction\":"), std::string::npos);
  EXPECT_NE(s.to_json().find("\"objects_occluded\":1"), std::string::npos);
}

// Growing the GPU vertex arena is reported apart, as the part of stream it took: never in a
// frame that streams nothing new.
TEST(Occlusion, ArenaGrowthIsReportedAsPartOfStreamAndNotInAFrameThatStreamsNothing) {
  TempDir dir;
  std::vector<Object> objects;  // drawn in full: more vertices than the arena starts with
  for (int i = 0; i < 1600; ++i)
    objects.push_back(make_object("C-" + std::to_string(i), ObjectClass::equipment,
                                  {2.0 * (i % 40), 2.0 * (i / 40), 0.5},
                                  {Primitive{Placement{}, Cylinder{0.4f, 1.0f}}}));
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  test::gl_context();
  RenderOptions options;
  options.lod_policy = LodPolicy::none;
  std::string error;
  auto r = Renderer::create(*store, options, error);
  ASSERT_TRUE(r) << error;
  Image image;
  FrameStats first, again;
  const Camera above = look({40, -30, 60}, {40, 40, 0});
  ASSERT_TRUE(r->render(above, 320, 180, false, image, first, error)) << error;
  ASSERT_GT(first.arena_bytes_resident, 3u << 20) << "more than a grown arena starts with (2 MB)";
  // (A software renderer may map its whole budget at once and never grow: 0. The growth
  // itself is tested on the backend, RenderArena in test_render.cpp.)
  EXPECT_LE(first.ms.arena_growth, first.ms.stream);
  EXPECT_NE(first.to_json().find("\"arena_growth\":"), std::string::npos);
  ASSERT_TRUE(r->render(above, 320, 180, false, image, again, error)) << error;
  EXPECT_EQ(again.objects_tessellated, 0u);
  EXPECT_EQ(again.ms.arena_growth, 0.0) << "nothing new: the arena holds it all";
}

}  // namespace
}  // namespace plantview
