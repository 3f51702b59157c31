// Frame plan: view, cull and choose (rules in frame_plan.h).
#include "frame_plan.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include "decoded_objects.h"
#include "lod.h"
#include "plantview/store.h"

namespace plantview {

std::string_view lod_policy_name(LodPolicy policy) {
  switch (policy) {
    case LodPolicy::screen_space: return "screen-space";
    case LodPolicy::distance: return "distance";
    case LodPolicy::none: return "none";
  }
  return "?";
}

bool parse_lod_policy(std::string_view name, LodPolicy& policy) {
  if (name == "screen-space" || name == "screen_space" || name == "sse") policy = LodPolicy::screen_space;
  else if (name == "distance") policy = LodPolicy::distance;
  else if (name == "none") policy = LodPolicy::none;
  else return false;
  return true;
}

namespace detail {

FrameView make_frame_view(const Camera& camera, uint32_t width, uint32_t height,
                          const glm::dvec3& spatial_origin_m) {
  FrameView v;
  v.eye_m = camera.eye_m;
  v.spatial_origin_m = spatial_origin_m;
  v.shift_m = glm::vec3(spatial_origin_m - camera.eye_m);
  v.width = width;
  v.height = height;
  // Eye-relative matrices: the eye is the origin of everything drawn.
  const glm::dvec3 forward = glm::normalize(camera.target_m - camera.eye_m);
  // An up along the view (looking straight down, say) falls back to +y, then +x.
  glm::dvec3 up = camera.up;
  if (glm::length(glm::cross(forward, up)) < 1e-9 * glm::length(up)) up = glm::dvec3(0, 1, 0);
  if (glm::length(glm::cross(forward, up)) < 1e-9) up = glm::dvec3(1, 0, 0);
  v.rotation = glm::mat4(glm::lookAt(glm::dvec3(0.0), forward, up));
  v.focal = focal_length(camera.fov_deg);
  v.aspect = float(width) / float(height);
  v.focal_px = focal_length_px(camera.fov_deg, height);
  glm::mat4 projection(0.0f);  // infinite far plane, reversed depth: near -> 1, infinity -> 0
  projection[0][0] = v.focal / v.aspect;
  projection[1][1] = v.focal;
  projection[2][3] = -1.0f;
  projection[3][2] = float(kNearPlaneM);
  v.view_projection = projection * v.rotation;
  const glm::mat4 m = glm::transpose(v.view_projection);  // rows as columns
  v.planes = {m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] - m[2]};
  return v;
}

namespace {

// A frustum plane's value (inside where >= 0) at the corner of a box relative to the spatial
// origin that lies farthest along its normal (`along`), or farthest against it.
float plane_at_corner(const glm::vec4& pl, const glm::vec3& shift_m, const float mn[3],
                      const float mx[3], bool along) {
  const glm::vec3 p((pl.x > 0) == along ? mx[0] : mn[0], (pl.y > 0) == along ? mx[1] : mn[1],
                    (pl.z > 0) == along ? mx[2] : mn[2]);
  return pl.x * (p.x + shift_m.x) + pl.y * (p.y + shift_m.y) + pl.z * (p.z + shift_m.z) + pl.w;
}

}  // namespace

bool FrameView::outside(const float mn[3], const float mx[3]) const {
  for (const glm::vec4& pl : planes)
    if (plane_at_corner(pl, shift_m, mn, mx, true) < 0) return true;
  return false;
}

bool FrameView::inside(const float mn[3], const float mx[3]) const {
  for (const glm::vec4& pl : planes)
    if (plane_at_corner(pl, shift_m, mn, mx, false) < 0) return false;
  return true;
}

double FrameView::nearest_distance_m(const float mn[3], const float mx[3]) const {
  glm::dvec3 nearest;
  for (int a = 0; a < 3; ++a)
    nearest[a] = std::clamp(0.0, double(mn[a]) + shift_m[a], double(mx[a]) + shift_m[a]);
  return glm::length(nearest);
}

bool FramePlan::cull(const ReadView& view, const FrameView& frame_view,
                     const RenderOptions& options, FrameStats& stats, std::string& error) {
  if (!find_visible(view, frame_view, options, stats, error)) return false;
  order();
  return true;
}

bool FramePlan::find_visible(const ReadView& view, const FrameView& frame_view,
                             const RenderOptions& options, FrameStats& stats, std::string& error) {
  const bool subpixel_culling = options.subpixel_culling && options.lod_policy == LodPolicy::screen_space;
  const double base_px = kNodeProxyPixels * options.pixel_error;
  blocks_.begin_cull();
  visible_.clear();
  node_boxes_.clear();
  candidates_.clear();
  pending_items_ = 0;
  stats.objects_subpixel = stats.objects_in_node_proxies = 0;
  section_ = options.section.empty() ? nullptr : &options.section;
  section_origin_m_ = frame_view.spatial_origin_m;
  clipped_ = 0;
  // Nodes are opened largest on screen first; the first that does not fit stops the opening,
  // and it and all the rest (no larger than it) are drawn whole.
  double whole_below_px = base_px;
  bool stopped = false;
  item_bound_ = subpixel_culling && frustum_objects_at_most(view, frame_view, kMaxCompleteItems)
                    ? kMaxCompleteItems
                    : kMaxDrawnItems;
  fresh_.clear();
  if (!view.spatial_top().empty()) consider_top(view, 0, frame_view, subpixel_culling);
  push_fresh();
  while (!candidates_.empty()) {
    std::pop_heap(candidates_.begin(), candidates_.end());
    const Candidate c = candidates_.back();
    candidates_.pop_back();
    pending_items_ -= c.items;
    if (c.boxable && (stopped || c.px < base_px)) {
      draw_whole(view, c, frame_view, stats);
      continue;
    }
    if (!subpixel_culling && c.block == kTopNode && visible_.size() >= kMaxObjectsAnyPolicy) {
      // Policy none or distance on a plant of millions: the rest of the view as proxies.
      if (!stopped) whole_below_px = c.px;
      stopped = true;
      draw_whole(view, c, frame_view, stats);
      continue;
    }
    const bool bounded = !stopped && c.boxable && c.px < kMaxNodeProxyPixels;
    bool fits = true;
    if (!open(view, c, frame_view, options, subpixel_culling, bounded, fits, stats, error))
      return false;
    if (!fits) {
      stopped = true;
      whole_below_px = c.px;
      draw_whole(view, c, frame_view, stats);
    }
  }
  blocks_.end_cull();
  stats.node_proxy_pixels = subpixel_culling || stopped ? whole_below_px : 0;
  stats.objects_visible = visible_.size();
  stats.objects_clipped = clipped_;
  stats.objects_culled = view.spatial_objects() - visible_.size() - stats.objects_subpixel -
                         stats.objects_in_node_proxies - clipped_;
  stats.node_proxies = node_boxes_.size();
  stats.spatial_blocks_walked = blocks_.walked();
  stats.spatial_blocks_held = blocks_.held();
  return true;
}

bool FramePlan::clipped(const float mn[3], const float mx[3]) const {
  if (!section_) return false;
  DAabb bounds;
  for (int a = 0; a < 3; ++a) {
    bounds.min[a] = section_origin_m_[a] + double(mn[a]);
    bounds.max[a] = section_origin_m_[a] + double(mx[a]);
  }
  return section_removes_all(*section_, bounds);
}

bool FramePlan::occlude(const ReadView& view, DecodedObjects& objects, const FrameView& frame_view,
                        const RenderOptions& options, FrameStats& stats, std::string& error) {
  // With a highlight, whatever hides the subject is drawn see-through: nothing may be left out.
  if (!options.occlusion || !options.highlight_ids.empty()) return true;
  if (!occlusion_.apply(view, blocks_, objects, frame_view, options, visible_, node_boxes_, stats,
                        error))
    return false;
  stats.objects_visible = visible_.size();
  stats.node_proxies = node_boxes_.size();
  return true;
}

bool FramePlan::first_phase(DecodedObjects& objects, const FrameView& frame_view,
                            const RenderOptions& options, uint64_t frame, bool exact,
                            FrameStats& stats, std::string& error) {
  if (!occlusion_.split(objects, frame_view, options, frame, exact, visible_, second_visible_, stats, error))
    return false;
  second_boxes_.swap(node_boxes_);
  node_boxes_.clear();
  return true;
}

void FramePlan::second_phase(const FrameView& frame_view, uint64_t frame,
                             std::span<const float> reversed_depth, FrameStats& stats) {
  const size_t drawn = visible_.size();
  occlusion_.test_rest(blocks_, frame_view, frame, visible_, reversed_depth, second_visible_,
                       second_boxes_, stats);
  take_set_aside(drawn, stats);
}

bool FramePlan::defer_smaller(DecodedObjects& objects, const FrameView& frame_view,
                              const RenderOptions& options, bool& third, std::string& error) {
  if (!occlusion_.defer_smaller(objects, frame_view, options, visible_, second_visible_, third,
                                error))
    return false;
  if (third) {
    second_boxes_.swap(node_boxes_);
    node_boxes_.clear();
  }
  return true;
}

void FramePlan::third_phase(const FrameView& frame_view, std::span<const float> reversed_depth,
                            FrameStats& stats) {
  const size_t drawn = drawn_before_ + visible_.size();
  occlusion_.test_later(blocks_, frame_view, reversed_depth, second_visible_, second_boxes_, stats);
  take_set_aside(drawn, stats);
}

void FramePlan::take_set_aside(size_t drawn, FrameStats& stats) {
  visible_.swap(second_visible_);
  node_boxes_.swap(second_boxes_);
  drawn_before_ = drawn;
  stats.objects_visible = drawn + visible_.size();
  stats.node_proxies = node_boxes_.size();
}

bool FramePlan::box_test_inputs(DecodedObjects& objects, const FrameView& frame_view,
                                const RenderOptions& options, std::vector<glm::vec4>& boxes,
                                std::string& error) {
  return occlusion_.box_test_inputs(objects, frame_view, options, visible_, boxes, error);
}

void FramePlan::drop_unseen(std::span<const uint32_t> seen, FrameStats& stats) {
  occlusion_.drop_unseen(seen, visible_, stats);
  stats.objects_visible = drawn_before_ + visible_.size();
}

void FramePlan::order() {
  // Sorted as packed keys (the pixels spanned, as float bits inverted: non-negative floats
  // order as their bits; then the slot, so that the order does not depend on the walk's), then
  // the objects moved once into that order.
  order_keys_.clear();
  for (uint32_t i = 0; i < visible_.size(); ++i) {
    const VisibleObject& v = visible_[i];
    const uint32_t px_bits = std::bit_cast<uint32_t>(float(v.px_per_m * v.extent_m()));
    order_keys_.push_back({uint64_t(~px_bits) << 32 | v.slot, i});
  }
  radix_sort(order_keys_, order_scratch_);
  ordered_.clear();
  for (const auto& [key, i] : order_keys_) ordered_.push_back(visible_[i]);
  visible_.swap(ordered_);
}

namespace {

// Pixels the largest side of a node's box spans, seen from the frame's eye.
double node_pixels(const SpatialNode& node, const FrameView& frame_view) {
  const double extent_m = std::max({node.max[0] - node.min[0], node.max[1] - node.min[1], node.max[2] - node.min[2]});
  return extent_m * frame_view.focal_px /
         std::max(frame_view.nearest_distance_m(node.min, node.max), kNearPlaneM);
}

// Objects beneath a node of a block (block-local subtree walk; nodes inside a block are few).
uint64_t objects_beneath(const SpatialBlock& block, uint32_t node, std::vector<uint32_t>& stack) {
  uint64_t objects = 0;
  stack.assign(1, node);
  while (!stack.empty()) {
    const SpatialNode& n = block.nodes[stack.back()];
    stack.pop_back();
    if (n.count) objects += n.count;
    else stack.insert(stack.end(), {n.first, n.first + 1});
  }
  return objects;
}

// Walks the top's nodes that meet the frustum, depth first, each with visit(t, node): kBeneath
// goes on beneath it, kPast leaves its subtree, kStop ends the walk (and returns false).
enum class TopStep { kBeneath, kPast, kStop };
template <class F>
bool walk_top_in_frustum(std::span<const SpatialNode> top, const FrameView& frame_view,
                         std::vector<uint32_t>& stack, const F& visit) {
  if (top.empty()) return true;
  stack.assign(1, 0);
  while (!stack.empty()) {
    const uint32_t t = stack.back();
    stack.pop_back();
    const SpatialNode& node = top[t];
    if (frame_view.outside(node.min, node.max)) continue;
    const TopStep step = visit(t, node);
    if (step == TopStep::kStop) return false;
    if (step == TopStep::kBeneath && node.count == 0) stack.insert(stack.end(), {node.first, node.first + 1});
  }
  return true;
}

}  // namespace

void FramePlan::blocks_ahead(const ReadView& view, const FrameView& frame_view,
                             const RenderOptions& options, std::vector<uint32_t>& blocks) {
  blocks.clear();
  const std::span<const SpatialNode> top = view.spatial_top();
  // After a first frame the cull meets a few new blocks a frame, and where it stops opening
  // (the view's items bound it) only the walk knows: read ahead, blocks it would not read cost
  // more than reading its few in parallel saves (x100 walk, measured).
  if (top.empty() || !blocks_.first_cull()) return;
  // As find_visible() opens them: a top leaf drawn whole below base_px (subpixel culling),
  // else walked whole.
  const bool subpixel_culling = options.subpixel_culling && options.lod_policy == LodPolicy::screen_space;
  const double base_px = kNodeProxyPixels * options.pixel_error;
  ahead_.clear();
  walk_top_in_frustum(top, frame_view, stack_, [&](uint32_t t, const SpatialNode& node) {
    const double px = node_pixels(node, frame_view);
    const bool boxable = subpixel_culling && view.spatial_top_objects()[t] > 1;
    if (boxable && px < base_px) return TopStep::kPast;  // drawn whole, and all beneath it
    if (!options.section.empty()) {
      DAabb bounds;
      for (int a = 0; a < 3; ++a) {
        bounds.min[a] = frame_view.spatial_origin_m[a] + double(node.min[a]);
        bounds.max[a] = frame_view.spatial_origin_m[a] + double(node.max[a]);
      }
      if (section_removes_all(options.section, bounds)) return TopStep::kPast;  // clipped
    }
    if (node.count != 0) ahead_.push_back({px, node.first});
    return TopStep::kBeneath;
  });
  const size_t kept = std::min(ahead_.size(), kMaxFrameBlocksHeld);
  std::partial_sort(ahead_.begin(), ahead_.begin() + ptrdiff_t(kept), ahead_.end(),
                    [](const Ahead& a, const Ahead& b) { return a.px > b.px; });
  for (size_t i = 0; i < kept; ++i) blocks.push_back(ahead_[i].block);
}

bool FramePlan::frustum_objects_at_most(const ReadView& view, const FrameView& frame_view,
                                        uint64_t limit) {
  const std::span<const SpatialNode> top = view.spatial_top();
  const std::span<const uint32_t> objects = view.spatial_top_objects();
  uint64_t total = 0;
  return walk_top_in_frustum(top, frame_view, stack_, [&](uint32_t t, const SpatialNode& node) {
    // A whole subtree that fits is counted at once (its objects bound those in the frustum).
    if (total + objects[t] <= limit) {
      total += objects[t];
      return TopStep::kPast;
    }
    return node.count != 0 ? TopStep::kStop : TopStep::kBeneath;  // a top leaf that does not fit
  });
}

void FramePlan::consider_top(const ReadView& view, uint32_t t, const FrameView& frame_view,
                             bool subpixel_culling) {
  const SpatialNode& node = view.spatial_top()[t];
  if (frame_view.outside(node.min, node.max)) return;
  if (clipped(node.min, node.max)) {
    clipped_ += view.spatial_top_objects()[t];
    return;
  }
  Candidate c{node_pixels(node, frame_view), kTopNode, t, 1, false};
  c.boxable = subpixel_culling && view.spatial_top_objects()[t] > 1;
  if (c.boxable) {
    c.items = 0;
    for (const ProxyBox& b : view.spatial_proxy(t))
      c.items += !frame_view.outside(b.min, b.max) && !clipped(b.min, b.max);
  }
  fresh_.push_back(c);
}

void FramePlan::consider_block_node(const SpatialBlock& block, uint32_t block_index, uint32_t n,
                                    const FrameView& frame_view, bool subpixel_culling) {
  const SpatialNode& node = block.nodes[n];
  if (frame_view.outside(node.min, node.max)) return;
  if (clipped(node.min, node.max)) {
    clipped_ += objects_beneath(block, n, count_stack_);
    return;
  }
  fresh_.push_back({node_pixels(node, frame_view), block_index, n, 1,
                    subpixel_culling && node.count != 1});
}

void FramePlan::push_fresh() {
  for (const Candidate& c : fresh_) {
    candidates_.push_back(c);
    std::push_heap(candidates_.begin(), candidates_.end());
    pending_items_ += c.items;
  }
  fresh_.clear();
}

// Tree-level HLOD: a whole node that spans only a few pixels is drawn as boxes instead of its
// objects (which are then not even decoded, nor their block read for a top node), so that the
// cost of a far view of a huge plant is bounded by the image, not by the plant.
void FramePlan::draw_whole(const ReadView& view, const Candidate& c, const FrameView& frame_view,
                           FrameStats& stats) {
  if (c.block == kTopNode) {
    // The far-field proxy: boxes whose union is the node's bounds, in its objects' colours.
    for (const ProxyBox& b : view.spatial_proxy(c.node)) {
      if (frame_view.outside(b.min, b.max) || clipped(b.min, b.max)) continue;
      node_boxes_.push_back({{b.min[0], b.min[1], b.min[2]}, {b.max[0], b.max[1], b.max[2]}, b.colour});
    }
    stats.objects_in_node_proxies += view.spatial_top_objects()[c.node];
    return;
  }
  const SpatialBlock& block = blocks_.at(c.block);
  const SpatialNode& node = block.nodes[c.node];
  node_boxes_.push_back({{node.min[0], node.min[1], node.min[2]},
                         {node.max[0], node.max[1], node.max[2]},
                         kNodeBoxColour});
  stats.objects_in_node_proxies += objects_beneath(block, c.node, count_stack_);
}

bool FramePlan::open(const ReadView& view, const Candidate& c, const FrameView& frame_view,
                     const RenderOptions& options, bool subpixel_culling, bool bounded,
                     bool& fits, FrameStats& stats, std::string& error) {
  fresh_.clear();
  const size_t visible_before = visible_.size(), subpixel_before = stats.objects_subpixel;
  const uint64_t clipped_before = clipped_;
  const SpatialBlock* block = nullptr;
  uint32_t block_index = c.block, n = c.node;
  if (c.block == kTopNode) {
    const SpatialNode& node = view.spatial_top()[c.node];
    if (node.count == 0) {
      consider_top(view, node.first, frame_view, subpixel_culling);
      consider_top(view, node.first + 1, frame_view, subpixel_culling);
    } else {
      // A leaf of the top is a block, whose root has the leaf's bounds.
      block_index = node.first;
      n = 0;
      if (!subpixel_culling) return walk_block(view, block_index, frame_view, options, stats, error);
      if (bounded && blocks_.held() >= kMaxFrameBlocksHeld) {
        fits = false;
        return true;
      }
      if (!(block = blocks_.get(view, block_index, error))) return false;
    }
  } else {
    block = &blocks_.at(c.block);
  }
  if (block) {
    const SpatialNode& node = block->nodes[n];
    if (node.count == 0) {
      consider_block_node(*block, block_index, node.first, frame_view, subpixel_culling);
      consider_block_node(*block, block_index, node.first + 1, frame_view, subpixel_culling);
    } else {
      take_leaf(*block, block_index, n, frame_view, options, subpixel_culling, stats);
    }
  }
  size_t fresh_items = 0;
  for (const Candidate& f : fresh_) fresh_items += f.items;
  if (bounded && items() + fresh_items > item_bound_) {
    fresh_.clear();
    visible_.resize(visible_before);
    stats.objects_subpixel = subpixel_before;
    clipped_ = clipped_before;
    fits = false;
    return true;
  }
  push_fresh();
  if (block && visible_.size() > visible_before) blocks_.needed(block_index);
  return true;
}
size_t FramePlan::take_leaf(const SpatialBlock& block, uint32_t block_index, uint32_t n,
                            const FrameView& frame_view, const RenderOptions& options,
                            bool subpixel_culling, FrameStats& stats) {
  const SpatialNode& node = block.nodes[n];
  const size_t before = visible_.size();
  // A leaf wholly in the frustum holds only objects in it (their bounds lie within the leaf's).
  const bool all_inside = frame_view.inside(node.min, node.max);
  for (uint32_t e = node.first; e < node.first + node.count; ++e) {
    VisibleObject v{block.entries[e].slot, {}, {}, 0.0, 0.0, block_index, n};
    entry_bounds(node, block.entries[e], v.min, v.max);
    if (!all_inside && frame_view.outside(v.min, v.max)) continue;
    if (clipped(v.min, v.max)) {
      clipped_ += 1;
      continue;
    }
    v.distance_m = frame_view.nearest_distance_m(v.min, v.max);
    v.px_per_m = pixels_per_metre(v.distance_m, frame_view.focal_px);
    // Screen-space policy: an object whose whole extent is under the pixel error is left out
    // (it is not even decoded); that is what keeps far views of huge plants cheap.
    if (subpixel_culling && v.px_per_m * v.extent_m() < options.pixel_error) {
      stats.objects_subpixel += 1;
      continue;
    }
    visible_.push_back(v);
  }
  return visible_.size() - before;
}

bool FramePlan::walk_block(const ReadView& view, uint32_t block_index,
                           const FrameView& frame_view, const RenderOptions& options,
                           FrameStats& stats, std::string& error) {
  const SpatialBlock* block = blocks_.get(view, block_index, error);
  if (!block) return false;
  size_t taken = 0;
  stack_.assign(1, 0);
  while (!stack_.empty()) {
    const uint32_t n = stack_.back();
    stack_.pop_back();
    const SpatialNode& node = block->nodes[n];
    // The block's root was tested as its top node.
    if (n != 0 && frame_view.outside(node.min, node.max)) continue;
    if (n != 0 && clipped(node.min, node.max)) {
      clipped_ += objects_beneath(*block, n, count_stack_);
      continue;
    }
    if (node.count == 0) {
      stack_.push_back(node.first);
      stack_.push_back(node.first + 1);
      continue;
    }
    taken += take_leaf(*block, block_index, n, frame_view, options, false, stats);
  }
  if (taken) blocks_.needed(block_index);
  else blocks_.release(block_index);
  return true;
}

bool drawn_as_centreline(const Known& k, const RenderOptions& options, double distance_m,
                         double px_per_m) {
  if (!options.centrelines || !k.has_centreline) return false;
  switch (options.lod_policy) {
    case LodPolicy::none: return false;
    // A line stands for a pipe as wide as the pipe's diameter, but flat: its error is about
    // that width, so a finer pixel error than a pixel (stills) keeps thicker pipes solid.
    case LodPolicy::screen_space:
      return k.pipe_diameter_m * px_per_m < std::min(1.0, options.pixel_error);
    case LodPolicy::distance: return distance_m > kCentrelineRadii * 0.5 * k.pipe_diameter_m;
  }
  return false;
}

RunDecisionInputs decide_run(const PipelineRun& run, const FrameView& frame_view,
                             const RenderOptions& options) {
  float mn[3], mx[3];
  for (int a = 0; a < 3; ++a) {
    mn[a] = float(run.bounds.min[a] - frame_view.spatial_origin_m[a]);
    mx[a] = float(run.bounds.max[a] - frame_view.spatial_origin_m[a]);
  }
  RunDecisionInputs d;
  d.distance_m = frame_view.nearest_distance_m(mn, mx);
  d.px_per_m = pixels_per_metre(d.distance_m, frame_view.focal_px);
  d.merged = options.hlod && options.lod_policy != LodPolicy::none &&
             (options.lod_policy == LodPolicy::screen_space
                  ? run.merge_error_m * d.px_per_m <= options.pixel_error
                  : d.distance_m > kMergeRadii * 0.5 * run.diameter_m);
  return d;
}

uint32_t chosen_level(const Known& k, const RenderOptions& options, double distance_m,
                      double px_per_m, double size_m) {
  switch (options.lod_policy) {
    case LodPolicy::none: break;
    case LodPolicy::screen_space:
      return choose_level_screen_space(k.error_m.data(), k.level_count, px_per_m, options.pixel_error);
    case LodPolicy::distance:
      return choose_level_distance(k.level_count, distance_m, size_m);
  }
  return 0;
}

namespace {

// The level for one object or run by the policy, and whether it is drawn as its centreline.
void choose_level(const Known& k, const RenderOptions& options, double distance_m,
                  double px_per_m, double size_m, uint8_t& level, bool& centreline) {
  level = uint8_t(chosen_level(k, options, distance_m, px_per_m, size_m));
  centreline = drawn_as_centreline(k, options, distance_m, px_per_m);
}

}  // namespace

void FramePlan::choose(DecodedObjects& objects, const FrameView& frame_view,
                       const RenderOptions& options, uint64_t frame, FrameStats& stats) {
  draws_.clear();
  const bool merging = options.hlod && options.lod_policy != LodPolicy::none;
  const std::span<Known* const> known = objects.decoded();
  assert(known.size() == visible_.size());
  for (size_t i = 0; i < visible_.size(); ++i) {
    const VisibleObject& v = visible_[i];
    Known* k = known[i];
    if (i + kPrefetchAhead < known.size()) prefetch(known[i + kPrefetchAhead]);
    k->last_seen = frame;
    if (k->vertex_count == 0) continue;
    if (k->hidden) {
      stats.objects_hidden += 1;
      continue;
    }
    if (k->run >= 0 && merging) {
      // A run is decided by its first visible member; the others follow it.
      const uint32_t r = uint32_t(k->run);
      const PipelineRun& run = objects.run(r);
      RunDecision& decision = objects.decision(r);
      if (decision.frame != frame) {
        decision.frame = frame;
        const RunDecisionInputs inputs = decide_run(run, frame_view, options);
        const double d = inputs.distance_m, px = inputs.px_per_m;
        decision.merged = inputs.merged;
        if (decision.merged) {
          Known& rk = objects.know_run(r);
          rk.last_seen = frame;
          rk.style_value = k->style_value;  // colour by: its deciding member's (styles that
                                            // hide turn merging off)
          Draw& draw = draws_.emplace_back(Draw{kRunKeyBit | r, &rk, 0, false, nullptr, d, rk.order_key});
          draw.cut = !options.section.empty() && !section_keeps_all(options.section, run.bounds);
          choose_level(rk, options, d, px, glm::length(run.end_m - run.start_m), draw.level,
                       draw.centreline);
          stats.hlod_merges += 1;
        }
      }
      if (decision.merged) {
        stats.hlod_members += 1;
        continue;
      }
    }
    Draw& draw = draws_.emplace_back(Draw{v.slot, k, 0, false, &v, v.distance_m, k->order_key});
    if (!options.section.empty()) {
      DAabb bounds;
      for (int a = 0; a < 3; ++a) {
        bounds.min[a] = frame_view.spatial_origin_m[a] + double(v.min[a]);
        bounds.max[a] = frame_view.spatial_origin_m[a] + double(v.max[a]);
      }
      draw.cut = !section_keeps_all(options.section, bounds);
    }
    choose_level(*k, options, v.distance_m, v.px_per_m, v.extent_m(), draw.level, draw.centreline);
  }
}

}  // namespace detail

}  // namespace plantview
