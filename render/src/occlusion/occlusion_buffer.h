// Occlusion buffer: a small depth buffer over the frame's image, filled either with occluders'
// silhouettes rasterised here (no GL) or with the farthest depth per cell of what a first phase
// drew (load_device_depth: the GL backend's depth reduction), and queried with bounds.
//
// Rules (what makes it conservative: nothing it calls hidden is visible in the drawn image)
//   - The buffer covers the image's normalised device square [-1, 1]^2 with width x height
//     cells (a few hundred a side); a cell holds a view distance in metres (along the view
//     axis), +infinity where no occluder covers it.
//   - An occluder is a convex solid given by points that lie inside what is drawn of it; its
//     silhouette is the convex hull of their projections. A cell takes the occluder's depth
//     only if the whole cell lies inside that hull (inner conservative rasterisation), and the
//     depth written is the occluder's farthest point: every covered cell holds a depth no
//     nearer than the occluder's surface there, and nearer ones win (min).
//   - Loaded from drawn depth: each cell holds the farthest depth drawn over every sample of
//     every pixel the cell overlaps (so that whatever lies behind it fails the depth test at
//     every sample it could reach), turned into a view distance a hair nearer (rounding).
//   - Bounds are hidden when every cell their projected rectangle, grown by kSpillPixels,
//     touches holds a depth strictly nearer than the bounds' nearest point. (What is drawn of
//     an object may reach past its bounds' projection: a centreline is a quad at least a pixel
//     wide with a pixel of feather on each side, up to 1.5 pixels beyond its axis.) Bounds reaching in front of the near
//     plane, and occluders that do, are never used (always visible / skipped).
// Units: metres (view space: x right, y up, looking down -z) and buffer cells.
// Ownership: owns its cells, reused frame after frame (no allocation once sized).
// Threads: one owner thread.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace plantview::detail {

// Where a solid lies on screen: the extremes of x / d and y / d over it (view space, d = -z),
// and its nearest view distance d.
struct ProjectedBounds {
  float x0, x1, y0, y1;
  float near_d;
};

class OcclusionBuffer {
 public:
  // Clears to +infinity at a size for an image of image_width x image_height: at most
  // kMaxCells wide and high, the image's aspect kept. focal is 1 / tan(fov / 2) (vertical),
  // aspect the image's width / height; near_m the near plane's distance.
  void begin(uint32_t image_width, uint32_t image_height, float focal, float aspect, float near_m);

  // Rasterises one convex occluder from its view-space points (inside the drawn solid).
  // Returns whether it covered at least one cell. Skipped if a point is nearer than the near
  // plane.
  bool add_convex(std::span<const glm::vec3> view_points);
  // Whether a convex occluder within the hull of these view-space points (all beyond the near
  // plane) may cover a cell: false when their bounds on screen, clipped to the buffer, hold no
  // whole cell. add_convex() asks it too; asking it first of a piece's bounding box spares
  // transforming the piece's points.
  bool may_cover(std::span<const glm::vec3> view_points) const;

  // Replaces the cells (after begin()) with drawn depth: `reversed_depth` holds width() x
  // height() values, rows bottom-up, each the farthest reversed depth (near_m / distance, 0
  // where nothing was drawn) over the pixels the cell overlaps.
  void load_device_depth(std::span<const float> reversed_depth);

  // Takes, cell by cell, the nearer of this buffer's depth and `other`'s (begun alike): what
  // both rasterised, as if into one.
  void merge_nearest(const OcclusionBuffer& other);

  // Whether the view-space box [min, max] is hidden behind what was rasterised.
  bool hidden(const glm::vec3& min, const glm::vec3& max) const;
  // Whether the cell that view-space point p (d = -p.z > 0) falls in holds a depth nearer than
  // d; true off the buffer. A box is hidden only if the cell of any point of it does (its
  // bounds' cells include that one): false here spares projecting its bounds.
  bool nearer_at(const glm::vec3& p) const {
    const float d = -p.z;
    const float x = p.x / d * sx_ + 0.5f * float(width_), y = p.y / d * sy_ + 0.5f * float(height_);
    if (!(x >= 0 && y >= 0 && x < float(width_) && y < float(height_))) return true;
    return cells_[size_t(y) * width_ + size_t(x)] < d;
  }
  // Whether what projects within `bounds` is hidden (the caller's bounds must contain the
  // projection of what it tests: conservative).
  bool hidden(const ProjectedBounds& bounds) const;

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  float depth(uint32_t x, uint32_t y) const { return cells_[size_t(y) * width_ + x]; }

  static constexpr uint32_t kMaxCells = 320;
  static constexpr double kSpillPixels = 1.5;  // image pixels (framebuffer ones when supersampled)

 private:
  // Buffer coordinates of a view-space point (d = -z > 0).
  glm::vec2 to_cells(const glm::vec3& p) const;
  // Whether bounds in buffer coordinates, clipped to the buffer, hold a whole cell.
  bool holds_a_cell(const glm::vec2& lo, const glm::vec2& hi) const;

  uint32_t width_ = 0, height_ = 0;
  float sx_ = 1, sy_ = 1;  // cells per unit of x / d and y / d
  float near_m_ = 0.05f;
  float spill_cells_ = 0;  // kSpillPixels in cells
  std::vector<float> cells_;
  // Scratch, reused.
  std::vector<glm::vec2> projected_, hull_;
  std::vector<double> row_lo_, row_hi_;  // add_convex(): each row's first and last cell covered
};

}  // namespace plantview::detail
