// Overviews: the camera that frames a whole plant, the boxes it is fitted to (from the spatial
// index, no object decoded) and the grid merge that keeps a fit to a few thousand boxes
// (plantview/camera.h).
#include <algorithm>
#include <cmath>

#include "plantview/camera.h"
#include "plantview/store.h"

namespace plantview {

namespace {

// Plants up to this many objects are fitted to their objects' bounds, larger ones to their
// spatial blocks' (reading every block of 40 M objects twice would take seconds).
constexpr uint64_t kOverviewExactObjects = 1u << 20;

// Cubic cells over `all`, at most `max_cells` (>= 1) of them.
struct MergeGrid {
  DAabb all;
  double cell_m = 1;
  glm::ivec3 cells{1};
  static MergeGrid over(const DAabb& all, size_t max_cells);
  size_t size() const { return size_t(cells.x) * size_t(cells.y) * size_t(cells.z); }
  // The cell of the box's centre (clamped into the grid).
  size_t cell_of(const DAabb& b) const;
};

MergeGrid MergeGrid::over(const DAabb& all, size_t max_cells) {
  MergeGrid g;
  g.all = all;
  const glm::dvec3 extent = glm::max(all.max - all.min, glm::dvec3(1e-3));
  g.cell_m = std::cbrt(extent.x * extent.y * extent.z / double(max_cells));
  for (;; g.cell_m *= 1.1) {
    g.cells = glm::ivec3(glm::ceil(extent / g.cell_m));
    if (uint64_t(g.cells.x) * uint64_t(g.cells.y) * uint64_t(g.cells.z) <= max_cells) break;
  }
  return g;
}

size_t MergeGrid::cell_of(const DAabb& b) const {
  const glm::ivec3 c = glm::clamp(glm::ivec3((0.5 * (b.min + b.max) - all.min) / cell_m),
                                  glm::ivec3(0), cells - 1);
  return (size_t(c.z) * size_t(cells.y) + size_t(c.y)) * size_t(cells.x) + size_t(c.x);
}

}  // namespace

std::vector<DAabb> merge_boxes_on_grid(std::vector<DAabb> boxes, size_t max_cells) {
  if (boxes.size() <= max_cells) return boxes;
  DAabb all;
  for (const DAabb& b : boxes) all.extend(b);
  const MergeGrid grid = MergeGrid::over(all, max_cells);
  std::vector<DAabb> merged(grid.size());
  for (const DAabb& b : boxes) merged[grid.cell_of(b)].extend(b);
  std::erase_if(merged, [](const DAabb& b) { return b.empty(); });
  return merged;
}

Camera default_camera(std::span<const DAabb> boxes, double aspect) {
  if (std::all_of(boxes.begin(), boxes.end(), [](const DAabb& b) { return b.empty(); })) return Camera{};
  return fit_camera(boxes, isometric_direction(), std::max(aspect, 1e-3), Camera{}.fov_deg,
                    kOverviewFill);
}

Camera default_camera(const DAabb& bounds, double aspect) {
  return default_camera(std::span<const DAabb>(&bounds, 1), aspect);
}

// Up to kOverviewExactObjects objects: two passes over the index, block after block (memory:
// max_boxes boxes, not the plant's): the union of the objects' bounds, then each object's
// bounds into its cell of the grid over it. Beyond, the top's block leaves stand for their
// objects (no block is read: milliseconds at any size). Where the index cannot be read, the
// top's root bounds stand for the plant.
std::vector<DAabb> overview_boxes(const ReadView& view, size_t max_boxes) {
  max_boxes = std::max<size_t>(max_boxes, 1);
  const glm::dvec3 origin = view.spatial_origin();
  if (view.spatial_objects() > kOverviewExactObjects) {
    std::vector<DAabb> boxes;
    for (const SpatialNode& node : view.spatial_top()) {
      if (node.count == 0) continue;
      DAabb& b = boxes.emplace_back();
      b.min = origin + glm::dvec3(node.min[0], node.min[1], node.min[2]);
      b.max = origin + glm::dvec3(node.max[0], node.max[1], node.max[2]);
    }
    return merge_boxes_on_grid(std::move(boxes), max_boxes);
  }
  const auto object_box = [&](const SpatialNode& leaf, const SpatialEntry& entry) {
    float mn[3], mx[3];
    entry_bounds(leaf, entry, mn, mx);
    DAabb b;
    b.min = origin + glm::dvec3(mn[0], mn[1], mn[2]);
    b.max = origin + glm::dvec3(mx[0], mx[1], mx[2]);
    return b;
  };
  const auto root_box = [&]() -> std::vector<DAabb> {
    const auto top = view.spatial_top();
    if (top.empty()) return {};
    DAabb b;
    b.min = origin + glm::dvec3(top[0].min[0], top[0].min[1], top[0].min[2]);
    b.max = origin + glm::dvec3(top[0].max[0], top[0].max[1], top[0].max[2]);
    return {b};
  };
  std::vector<DAabb> boxes;
  DAabb all;
  bool many = false;
  std::string error;
  if (!view.for_each_spatial_entry(
          [&](const SpatialNode& leaf, const SpatialEntry& entry) {
            const DAabb b = object_box(leaf, entry);
            all.extend(b);
            if (!many) {
              boxes.push_back(b);
              many = boxes.size() > max_boxes;
              if (many) std::vector<DAabb>().swap(boxes);
            }
            return true;
          },
          error))
    return root_box();
  if (!many) return boxes;
  const MergeGrid grid = MergeGrid::over(all, max_boxes);
  boxes.assign(grid.size(), DAabb{});
  if (!view.for_each_spatial_entry(
          [&](const SpatialNode& leaf, const SpatialEntry& entry) {
            const DAabb b = object_box(leaf, entry);
            boxes[grid.cell_of(b)].extend(b);
            return true;
          },
          error))
    return root_box();
  std::erase_if(boxes, [](const DAabb& b) { return b.empty(); });
  return boxes;
}

}  // namespace plantview
