// Frame plan: view, cull and choose (rules in frame_plan.h).
#include "frame_plan.h"

#include <algorithm>
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

bool FrameView::outside(const float mn[3], const float mx[3]) const {
  for (const glm::vec4& pl : planes) {
    const glm::vec3 p(pl.x > 0 ? mx[0] : mn[0], pl.y > 0 ? mx[1] : mn[1], pl.z > 0 ? mx[2] : mn[2]);
    if (pl.x * (p.x + shift_m.x) + pl.y * (p.y + shift_m.y) + pl.z * (p.z + shift_m.z) + pl.w < 0)
      return true;
  }
  return false;
}

double FrameView::nearest_distance_m(const float mn[3], const float mx[3]) const {
  glm::dvec3 nearest;
  for (int a = 0; a < 3; ++a)
    nearest[a] = std::clamp(0.0, double(mn[a]) + shift_m[a], double(mx[a]) + shift_m[a]);
  return glm::length(nearest);
}

void FramePlan::cull(const ReadView& view, const FrameView& frame_view,
                     const RenderOptions& options, FrameStats& stats) {
  find_visible(view, frame_view, options, stats);
  order();
}

void FramePlan::find_visible(const ReadView& view, const FrameView& frame_view,
                             const RenderOptions& options, FrameStats& stats) {
  const bool subpixel_culling = options.subpixel_culling && options.lod_policy == LodPolicy::screen_space;
  // The frame's work is bounded: when more objects than kMaxVisibleObjects are in view, nodes
  // are boxed at ever larger sizes until they fit (huge plants seen whole).
  double node_proxy_px = kNodeProxyPixels * options.pixel_error;
  while (!cull_pass(view, frame_view, options, node_proxy_px, stats)) node_proxy_px *= 2;
  stats.node_proxy_pixels = subpixel_culling ? node_proxy_px : 0;
  stats.objects_visible = visible_.size();
  stats.objects_culled = view.spatial_entries().size() - visible_.size() - stats.objects_subpixel -
                         stats.objects_in_node_proxies;
  stats.node_proxies = node_boxes_.size();
}

bool FramePlan::occlude(const ReadView& view, DecodedObjects& objects, const FrameView& frame_view,
                        const RenderOptions& options, FrameStats& stats, std::string& error) {
  // With a highlight, whatever hides the subject is drawn see-through: nothing may be left out.
  if (!options.occlusion || !options.highlight_ids.empty()) return true;
  if (!occlusion_.apply(view, objects, frame_view, options, visible_, node_boxes_, stats, error))
    return false;
  stats.objects_visible = visible_.size();
  stats.node_proxies = node_boxes_.size();
  return true;
}

void FramePlan::order() {
  std::sort(visible_.begin(), visible_.end(), [](const VisibleObject& a, const VisibleObject& b) {
    return a.px_per_m * a.extent_m() > b.px_per_m * b.extent_m();
  });
}

// One walk of the tree with nodes under node_proxy_px boxed. Returns false, unfinished, once
// more than kMaxVisibleObjects are found and boxing larger nodes can still make them fewer.
bool FramePlan::cull_pass(const ReadView& view, const FrameView& frame_view,
                          const RenderOptions& options, double node_proxy_px, FrameStats& stats) {
  const auto nodes = view.spatial_nodes();
  const auto entries = view.spatial_entries();
  const bool subpixel_culling = options.subpixel_culling && options.lod_policy == LodPolicy::screen_space;
  const bool bounded = subpixel_culling && node_proxy_px < kMaxNodeProxyPixels;
  stats.objects_subpixel = stats.objects_in_node_proxies = 0;
  visible_.clear();
  node_boxes_.clear();
  stack_.clear();
  if (!nodes.empty()) stack_.push_back(0);
  while (!stack_.empty()) {
    const SpatialNode& node = nodes[stack_.back()];
    stack_.pop_back();
    if (frame_view.outside(node.min, node.max)) continue;
    // Tree-level HLOD: a whole node that spans only a few pixels is drawn as one box instead of
    // its objects (which are then not even decoded), so that the cost of a far view of a huge
    // plant is bounded by the image, not by the plant.
    if (subpixel_culling && (node.count == 0 || node.count > 1)) {
      const double extent_m = std::max({node.max[0] - node.min[0], node.max[1] - node.min[1], node.max[2] - node.min[2]});
      const double px = extent_m * frame_view.focal_px /
                        std::max(frame_view.nearest_distance_m(node.min, node.max), kNearPlaneM);
      if (px < node_proxy_px) {
        node_boxes_.push_back({node.min[0], node.min[1], node.min[2], node.max[0], node.max[1], node.max[2]});
        // Count the objects it stands for.
        count_stack_.assign(1, uint32_t(&node - nodes.data()));
        while (!count_stack_.empty()) {
          const SpatialNode& n = nodes[count_stack_.back()];
          count_stack_.pop_back();
          if (n.count) stats.objects_in_node_proxies += n.count;
          else count_stack_.insert(count_stack_.end(), {n.first, n.first + 1});
        }
        continue;
      }
    }
    if (node.count == 0) {
      stack_.push_back(node.first);
      stack_.push_back(node.first + 1);
      continue;
    }
    for (uint32_t e = node.first; e < node.first + node.count; ++e) {
      VisibleObject v{entries[e].slot, {}, {}, 0.0, 0.0, uint32_t(&node - nodes.data())};
      entry_bounds(node, entries[e], v.min, v.max);
      if (frame_view.outside(v.min, v.max)) continue;
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
    if (bounded && visible_.size() > kMaxVisibleObjects) return false;
  }
  return true;
}

bool drawn_as_centreline(const Known& k, const RenderOptions& options, double distance_m,
                         double px_per_m) {
  if (!options.centrelines || k.centreline.empty()) return false;
  switch (options.lod_policy) {
    case LodPolicy::none: return false;
    case LodPolicy::screen_space: return k.pipe_diameter_m * px_per_m < 1.0;
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

namespace {

// The level for one object or run by the policy, and whether it is drawn as its centreline.
void choose_level(const Known& k, const RenderOptions& options, double distance_m,
                  double px_per_m, double size_m, uint8_t& level, bool& centreline) {
  level = 0;
  centreline = drawn_as_centreline(k, options, distance_m, px_per_m);
  switch (options.lod_policy) {
    case LodPolicy::none: break;
    case LodPolicy::screen_space:
      level = uint8_t(choose_level_screen_space(k.error_m.data(), k.level_count, px_per_m,
                                                options.pixel_error));
      break;
    case LodPolicy::distance:
      level = uint8_t(choose_level_distance(k.level_count, distance_m, size_m));
      break;
  }
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
    k->last_seen = frame;
    if (k->vertex_count == 0) continue;
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
          Draw& draw = draws_.emplace_back(Draw{kRunKeyBit | r, &rk, 0, false, nullptr, d, rk.order_key});
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
    choose_level(*k, options, v.distance_m, v.px_per_m, v.extent_m(), draw.level, draw.centreline);
  }
}

}  // namespace detail

}  // namespace plantview
