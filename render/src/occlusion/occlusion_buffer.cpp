// Occlusion buffer: inner-conservative rasterisation of convex silhouettes and bounds tests
// (rules in occlusion_buffer.h).
#include "occlusion/occlusion_buffer.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace plantview::detail {

namespace {

constexpr float kFar = std::numeric_limits<float>::infinity();

double cross(const glm::vec2& o, const glm::vec2& a, const glm::vec2& b) {
  return double(a.x - o.x) * double(b.y - o.y) - double(a.y - o.y) * double(b.x - o.x);
}

// Andrew's monotone chain: the convex hull of `points` (sorted here), counter-clockwise,
// without collinear points. Fewer than 3 corners: no area.
void convex_hull(std::vector<glm::vec2>& points, std::vector<glm::vec2>& hull) {
  std::sort(points.begin(), points.end(), [](const glm::vec2& a, const glm::vec2& b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
  });
  hull.assign(2 * points.size(), glm::vec2(0.0f));
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], points[i - 1]) <= 0) --k;
    hull[k++] = points[i - 1];
  }
  hull.resize(k > 1 ? k - 1 : k);  // the last point repeats the first
}

}  // namespace

void OcclusionBuffer::begin(uint32_t image_width, uint32_t image_height, float focal,
                            float aspect, float near_m) {
  if (image_width >= image_height) {
    width_ = std::min(image_width, kMaxCells);
    height_ = std::max<uint32_t>(1, uint32_t(std::lround(double(width_) * image_height / image_width)));
  } else {
    height_ = std::min(image_height, kMaxCells);
    width_ = std::max<uint32_t>(1, uint32_t(std::lround(double(height_) * image_width / image_height)));
  }
  sx_ = 0.5f * float(width_) * focal / aspect;
  sy_ = 0.5f * float(height_) * focal;
  near_m_ = near_m;
  spill_cells_ = float(kSpillPixels * double(width_) / double(image_width));
  cells_.assign(size_t(width_) * height_, kFar);
}

glm::vec2 OcclusionBuffer::to_cells(const glm::vec3& p) const {
  const float d = -p.z;
  return {p.x / d * sx_ + 0.5f * float(width_), p.y / d * sy_ + 0.5f * float(height_)};
}

bool OcclusionBuffer::add_convex(std::span<const glm::vec3> view_points) {
  if (view_points.size() < 3) return false;
  float far_m = 0;
  glm::vec2 bounds_lo(kFar), bounds_hi(-kFar);
  projected_.clear();
  for (const glm::vec3& p : view_points) {
    if (-p.z <= near_m_) return false;
    far_m = std::max(far_m, -p.z);
    projected_.push_back(to_cells(p));
    bounds_lo = glm::min(bounds_lo, projected_.back());
    bounds_hi = glm::max(bounds_hi, projected_.back());
  }
  // Most pieces are small on screen or off it: left before the hull, most of a piece's cost.
  if (!holds_a_cell(bounds_lo, bounds_hi)) return false;
  convex_hull(projected_, hull_);
  if (hull_.size() < 3) return false;
  float y_min = hull_[0].y, y_max = hull_[0].y;
  for (const glm::vec2& c : hull_) {
    y_min = std::min(y_min, c.y);
    y_max = std::max(y_max, c.y);
  }
  const int row_first = std::max(0, int(std::floor(y_min)));
  const int row_last = std::min(int(height_) - 1, int(std::ceil(y_max)) - 1);
  if (row_first > row_last) return false;
  // Per row, the cells [i, i+1] x [j, j+1] wholly inside every edge: each edge's function is
  // smallest at the cell corner farthest against its normal. Only the edges that span one of a
  // row's corner heights can bind there (along a convex hull's side, the edge beside a height
  // is the innermost), so each edge is applied to the rows its height span touches, with a row
  // of slack each way: two rows per side of the hull rather than every edge on every row.
  row_lo_.assign(size_t(row_last - row_first + 1), 0.0);
  row_hi_.assign(size_t(row_last - row_first + 1), double(width_) - 1);
  for (size_t e = 0; e < hull_.size(); ++e) {
    const glm::vec2& a = hull_[e];
    const glm::vec2& b = hull_[(e + 1) % hull_.size()];
    const double ea = -(double(b.y) - a.y), eb = double(b.x) - a.x;
    const double ec = -(ea * a.x + eb * a.y);
    const double margin = 1e-4 * (std::abs(ea) + std::abs(eb));
    const int j_first = std::max(row_first, int(std::floor(std::min(a.y, b.y))) - 2);
    const int j_last = std::min(row_last, int(std::ceil(std::max(a.y, b.y))) + 1);
    for (int j = j_first; j <= j_last; ++j) {
      double& lo = row_lo_[size_t(j - row_first)];
      double& hi = row_hi_[size_t(j - row_first)];
      const double r = margin - (eb * j + std::min(eb, 0.0) + ec + std::min(ea, 0.0));
      if (ea > 0) lo = std::max(lo, std::ceil(r / ea));
      else if (ea < 0) hi = std::min(hi, std::floor(r / ea));
      else if (r > 0) hi = -1;
    }
  }
  bool covered = false;
  for (int j = row_first; j <= row_last; ++j) {
    const double lo = row_lo_[size_t(j - row_first)], hi = row_hi_[size_t(j - row_first)];
    if (lo > hi) continue;
    float* row = cells_.data() + size_t(j) * width_;
    for (int i = int(lo); i <= int(hi); ++i) row[i] = std::min(row[i], far_m);
    covered = true;
  }
  return covered;
}

bool OcclusionBuffer::may_cover(std::span<const glm::vec3> view_points) const {
  glm::vec2 lo(kFar), hi(-kFar);
  for (const glm::vec3& p : view_points) {
    assert(-p.z > near_m_);
    const glm::vec2 c = to_cells(p);
    lo = glm::min(lo, c);
    hi = glm::max(hi, c);
  }
  return holds_a_cell(lo, hi);
}

bool OcclusionBuffer::holds_a_cell(const glm::vec2& lo, const glm::vec2& hi) const {
  // Only a whole cell inside the silhouette is covered (add_convex), and the silhouette lies
  // within its points' bounds.
  return std::max(std::ceil(lo.x), 0.0f) + 1 <= std::min(std::floor(hi.x), float(width_)) &&
         std::max(std::ceil(lo.y), 0.0f) + 1 <= std::min(std::floor(hi.y), float(height_));
}

void OcclusionBuffer::load_device_depth(std::span<const float> reversed_depth) {
  assert(reversed_depth.size() == cells_.size());
  // distance = near / depth; the float division and the depth buffer's own rounding are a few
  // ulps: the cell is taken 1e-5 nearer (1 mm at 100 m).
  constexpr float kNearer = 1.0f - 1e-5f;
  for (size_t i = 0; i < cells_.size(); ++i) {
    const float d = reversed_depth[i];
    cells_[i] = d > 0 ? near_m_ / d * kNearer : kFar;
  }
}

void OcclusionBuffer::merge_nearest(const OcclusionBuffer& other) {
  assert(other.width_ == width_ && other.height_ == height_);
  for (size_t i = 0; i < cells_.size(); ++i) cells_[i] = std::min(cells_[i], other.cells_[i]);
}

bool OcclusionBuffer::hidden(const glm::vec3& mn, const glm::vec3& mx) const {
  const float near_d = -mx.z, far_d = -mn.z;
  // The box's extreme x / d and y / d: each end over the nearer or farther face, whichever
  // makes it extreme.
  return hidden(ProjectedBounds{mn.x / (mn.x <= 0 ? near_d : far_d), mx.x / (mx.x >= 0 ? near_d : far_d),
                                mn.y / (mn.y <= 0 ? near_d : far_d), mx.y / (mx.y >= 0 ? near_d : far_d),
                                near_d});
}

bool OcclusionBuffer::hidden(const ProjectedBounds& b) const {
  if (!(b.near_d > near_m_) || cells_.empty()) return false;
  const float cx0 = b.x0 * sx_ + 0.5f * float(width_) - spill_cells_;
  const float cx1 = b.x1 * sx_ + 0.5f * float(width_) + spill_cells_;
  const float cy0 = b.y0 * sy_ + 0.5f * float(height_) - spill_cells_;
  const float cy1 = b.y1 * sy_ + 0.5f * float(height_) + spill_cells_;
  if (!(cx1 >= 0 && cy1 >= 0 && cx0 <= float(width_) && cy0 <= float(height_))) return false;
  const int i0 = std::max(0, int(std::floor(cx0))), i1 = std::min(int(width_) - 1, int(std::floor(cx1)));
  const int j0 = std::max(0, int(std::floor(cy0))), j1 = std::min(int(height_) - 1, int(std::floor(cy1)));
  for (int j = j0; j <= j1; ++j) {
    const float* row = cells_.data() + size_t(j) * width_;
    for (int i = i0; i <= i1; ++i)
      if (!(row[i] < b.near_d)) return false;
  }
  return true;
}

}  // namespace plantview::detail
