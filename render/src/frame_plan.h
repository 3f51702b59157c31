// Frame plan: the renderer's frontend, no GL. From a camera the frame's view; from the store's
// spatial tree what is visible (cull); from the decoded objects a level per visible object and
// the pipeline runs drawn merged (choose); and the rule for which level an object is made
// resident from. Occlusion culling (occlusion.h) is a stage here, between cull and choose: on
// the CPU (occlude), or in two phases around drawing (first_phase, second_phase).
//
// Rules
//   - One derivation of the view: the focal length comes from lod.h (focal_length), rounded to
//     float as the projection matrix holds it, and every pixels-per-metre figure (culling,
//     level choice, node boxes) is focal_px / distance, the distance to the nearest point of
//     the bounds and no nearer than the near plane. What is chosen is what is drawn.
//   - cull walks the store's paged spatial index (store.h): the resident top, then the blocks
//     under the top nodes it enters, read on demand and held for the frame (frame_blocks.h).
//     Nodes and objects outside the frustum are dropped (no far plane). Screen-space policy
//     with subpixel culling: an object whose extent spans under the pixel error is left out,
//     and a node spanning under kNodeProxyPixels x the pixel error is drawn whole: a top node
//     as its far-field proxy (up to kProxyBoxes boxes in its objects' colours, stored with the
//     top, so a far node reads no block), a node inside a block as one grey box.
//   - The frame's work is bounded: nodes are opened largest on screen first (a node spans no
//     fewer pixels than its children), and when opening the next one would make more than
//     kMaxDrawnItems objects and boxes (kMaxCompleteItems where the frustum's top leaves hold
//     no more objects than that, so that such a view is opened whole), or need more than
//     kMaxFrameBlocksHeld blocks, it and every node not yet opened are drawn whole. That is the one node size above which all is
//     opened (node_proxy_pixels), found in one walk that reads no block it does not open: the
//     overview of a huge plant reads none. Nodes of kMaxNodeProxyPixels and more are always
//     opened. The other policies draw no node whole but stop at kMaxObjectsAnyPolicy objects.
//     The visible objects are then ordered largest on screen first, so that the arena's
//     budget goes where it shows most.
//   - Memory: nothing here is sized by the plant. What cull keeps follows the frame: its
//     visible objects and node boxes (kMaxDrawnItems), and the blocks it read.
//   - Sections (RenderOptions::section): a node, object or proxy box the section removes
//     wholly (section_removes_all on its bounds) is left out like one outside the frustum,
//     before any block under it is read or any object decoded (objects_clipped). What it cuts
//     is kept: the GPU clips it (gl/backend.h).
//   - choose: LodPolicy; merged runs replace their visible members (one draw per run).
//   - resident_base: one level of slack (see there).
// Units: metres and pixels; bounds relative to the store's spatial origin, matrices relative to
//   the eye (so that plants kilometres from the origin keep float precision).
// Ownership: a FramePlan owns its lists and reuses them frame after frame (no allocation once
//   warm); visible() and node_boxes() are valid until the next cull() (or first_phase(),
//   second_phase()), draws() until the next
//   choose(). The blocks of visible objects are held until the next cull (frame_blocks.h). A Draw points to its Known in DecodedObjects and to its VisibleObject here.
// Threads: the renderer's thread.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "frame_blocks.h"
#include "occlusion/occlusion.h"
#include "radix_sort.h"
#include "plantview/render.h"

namespace plantview {
class ReadView;
}

namespace plantview::detail {

struct Known;
struct PipelineRun;
class WorkerPool;
class DecodedObjects;

// Objects drawn one by one plus node boxes in a frame, at most, unless nodes of
// kMaxNodeProxyPixels would have to be boxes. Measured on preset c at 1280x720 and the still
// pixel error (0.5 px): one unit's overview and widest walkthrough views need 36,000-39,000
// (with this bound alone they boxed nodes under 6-10 px in grey), x1000's overview boxes nodes
// under 35 px (0.4 M triangles) and its walkthrough views under 35-90 px.
inline constexpr size_t kMaxDrawnItems = 32768;
// ... unless the top leaves the frustum meets hold at most kMaxCompleteItems objects: then
// every node above the proxy size is opened, so that a plant of one unit (preset c: 40,746
// objects) is never boxed for the bound. Views of more keep kMaxDrawnItems (their cost and
// memory are what the bound is for).
inline constexpr size_t kMaxCompleteItems = 2 * kMaxDrawnItems;
inline constexpr double kMaxNodeProxyPixels = 256;
// Objects drawn one by one in a frame by the policies that draw no node whole (none, distance,
// or no subpixel culling), at most (their decoded records take about 250 MB): beyond, the top
// nodes not walked yet, the smallest on screen, are drawn as their far-field proxies. Only
// plants of millions of objects seen whole reach it.
inline constexpr size_t kMaxObjectsAnyPolicy = size_t(1) << 17;
inline constexpr Colour kNodeBoxColour{150, 150, 150, 255};  // nodes inside blocks drawn whole

// A camera's view of the store for one frame.
struct FrameView {
  glm::dvec3 eye_m{0.0};
  glm::dvec3 spatial_origin_m{0.0};  // the store's: what cull's bounds are relative to
  glm::vec3 shift_m{0.0f};           // spatial_origin_m - eye_m: spatial bounds to the eye frame
  uint32_t width = 0, height = 0;    // pixels
  glm::mat4 rotation{1.0f};          // model axes to view axes (looking down -z)
  // Eye-relative model space to clip space: infinite far plane, reversed depth (near -> 1,
  // infinity -> 0).
  glm::mat4 view_projection{1.0f};
  float focal = 1.0f;                // 1 / tan(fov / 2)
  float aspect = 1.0f;               // width / height
  double focal_px = 1.0;             // pixels a metre spans at 1 m
  // Frustum planes (x, y, z, w), eye-relative: inside where dot(p, xyz) + w >= 0; no far plane.
  std::array<glm::vec4, 5> planes{};

  // Whether a box (relative to the spatial origin) lies wholly outside one plane; wholly inside
  // every plane.
  bool outside(const float min[3], const float max[3]) const;
  bool inside(const float min[3], const float max[3]) const;
  // From the eye to the nearest point of a box (relative to the spatial origin); 0 inside it.
  double nearest_distance_m(const float min[3], const float max[3]) const;
};

// `camera` must be valid (validate_camera); width, height >= 1.
FrameView make_frame_view(const Camera& camera, uint32_t width, uint32_t height,
                          const glm::dvec3& spatial_origin_m);

// An object in the frustum (and not under the pixel error).
struct VisibleObject {
  uint32_t slot;
  float min[3], max[3];  // metres, relative to the spatial origin
  double distance_m;     // to the nearest point of its bounds
  double px_per_m;       // pixels a metre spans there
  // The leaf that holds it: block `block` of the spatial index, its node `node` (block-local).
  uint32_t block = 0, node = 0;
  float extent_m() const { return std::max({max[0] - min[0], max[1] - min[1], max[2] - min[2]}); }
};

// A spatial node drawn whole as a box (node proxies, far-field proxies): not pickable.
struct NodeBox {
  float min[3], max[3];  // metres, relative to the spatial origin
  Colour colour;
};

// One object, or one merged run, to draw: its level chosen here, its place in the arena filled
// in by streaming.
struct Draw {
  uint32_t key;                    // residency key: slot, or kRunKeyBit | run
  Known* known;
  uint8_t level;                   // chosen; streaming may coarsen it to the resident base
  bool centreline;                 // drawn as its centreline
  const VisibleObject* visible;    // null for merged runs
  double distance_m = 0;           // from the eye to the nearest point of its bounds
  uint32_t order_key = 0;          // Known::order_key: breaks draw-order ties
  bool drawn = false;              // resident this frame (else a proxy box or nothing)
  bool cut = false;                // the section cuts its bounds (its closed solids capped)
  uint32_t arena_first = 0;        // the object's first vertex in the arena, once drawn
  // Filled by streaming for drawn ones: its index ranges, [segment_first, + segment_count) of
  // the frame's segment list (arena_streaming.h), so that writing the indices reads no Known.
  uint32_t segment_first = 0, segment_count = 0;
};

// The level an object is made resident from when `level` is chosen: one level of slack below
// it, so that coming nearer only swaps the index range drawn, while the arena is roomy (under
// half full); once it is not, every vertex counts and the chosen level is used. Policy none
// draws level 0 only.
inline bool arena_roomy(uint64_t used_units, uint64_t capacity_units) {
  return used_units * 2 < capacity_units;
}
inline uint8_t resident_base(uint32_t level, LodPolicy policy, bool roomy) {
  if (policy == LodPolicy::none) return 0;
  return uint8_t(level > 0 && roomy ? level - 1 : level);
}

// Whether a pipeline run is drawn merged this frame, and its nearest distance and pixels per
// metre there (the same decision choose() makes; occlusion uses it to know what is drawn).
struct RunDecisionInputs {
  bool merged = false;
  double distance_m = 0, px_per_m = 0;
};
RunDecisionInputs decide_run(const PipelineRun& run, const FrameView& frame_view,
                             const RenderOptions& options);
// The level choose() draws an object at (`size_m`: its largest extent), by the policy.
uint32_t chosen_level(const Known& k, const RenderOptions& options, double distance_m,
                      double px_per_m, double size_m);

// Whether a pipe (k.centreline not empty) is drawn as its centreline at that distance:
// screen-space, where its diameter projects under a pixel and under the pixel error.
bool drawn_as_centreline(const Known& k, const RenderOptions& options, double distance_m,
                         double px_per_m);

class FramePlan {
 public:
  // Occlusion's per-object tests run on `pool` (null: on the calling thread); it must outlive
  // the plan.
  explicit FramePlan(WorkerPool* pool = nullptr) : occlusion_(pool) {}

  // 1. Cull: fills visible() and node_boxes(), largest on screen first, and the statistics
  //    objects_visible, objects_culled, objects_subpixel, node_proxies, node_proxy_pixels and
  //    objects_in_node_proxies. `view` must be the same snapshot frame after frame (else
  //    reset_view()). Equivalent to find_visible() then order(), with no occlusion culling.
  //    False with a message if a block of the index cannot be read.
  bool cull(const ReadView& view, const FrameView& frame_view, const RenderOptions& options,
            FrameStats& stats, std::string& error);
  // 1a'. In the first frame of a snapshot (reset_view()), which reads up to
  //      kMaxFrameBlocksHeld index blocks at once, those that find_visible() will most likely
  //      read: the top's leaves in the frustum that are not drawn whole for their size, the
  //      largest on screen first, at most kMaxFrameBlocksHeld; else none. Read ahead in
  //      parallel (DecodedObjects::read_blocks), they are found decoded when the cull asks.
  void blocks_ahead(const ReadView& view, const FrameView& frame_view, const RenderOptions& options,
                    std::vector<uint32_t>& blocks);
  // 1a. The frustum and subpixel part of cull, in tree order (not ordered yet): a leaf's
  //     objects are consecutive in visible().
  bool find_visible(const ReadView& view, const FrameView& frame_view,
                    const RenderOptions& options, FrameStats& stats, std::string& error);
  // 1b. Occlusion culling (occlusion.h), when options.occlusion: drops the hidden objects and
  //     node boxes (objects_occluded, nodes_occluded, occluders; objects_visible and
  //     node_proxies updated). Occluders are decoded into `objects`. False on a read error.
  bool occlude(const ReadView& view, DecodedObjects& objects, const FrameView& frame_view,
               const RenderOptions& options, FrameStats& stats, std::string& error);
  // 1b, in two phases (occlusion.h), for a drawn frame when two_phase(options):
  //   first_phase(): visible() keeps the first phase's objects (those drawn in frame - 1 and
  //     the largest on screen, but what the largest hide on the CPU; stats.occluders; `exact`:
  //     the exact test follows, OcclusionCulling::split),
  //     node_boxes() none; the rest is set aside. False if an occluder cannot be decoded.
  //   second_phase(): once the first phase is drawn, with its depth reduced to
  //     occlusion_cells() cells (GlBackend::reduce_depth): visible() and node_boxes() become
  //     what was set aside and is not hidden (objects_occluded, nodes_occluded; objects_visible
  //     and node_proxies count both phases).
  static bool two_phase(const RenderOptions& options) {
    return options.occlusion && options.highlight_ids.empty();
  }
  bool first_phase(DecodedObjects& objects, const FrameView& frame_view,
                   const RenderOptions& options, uint64_t frame, bool exact, FrameStats& stats,
                   std::string& error);
  std::pair<uint32_t, uint32_t> occlusion_cells() const {
    return {occlusion_.buffer().width(), occlusion_.buffer().height()};
  }
  void second_phase(const FrameView& frame_view, uint64_t frame,
                    std::span<const float> reversed_depth, FrameStats& stats);
  //   defer_smaller(): after second_phase(), where the second phase is large (occlusion.h:
  //     defer_smaller): visible() keeps its largest opaque part, and the rest and the node boxes
  //     are set aside for a third phase (`third` true). False on a decode error.
  //   third_phase(): once the second phase is drawn too, its depth reduced likewise:
  //     visible() and node_boxes() become what was set aside and is not hidden.
  bool defer_smaller(DecodedObjects& objects, const FrameView& frame_view,
                 const RenderOptions& options, bool& third, std::string& error);
  void third_phase(const FrameView& frame_view, std::span<const float> reversed_depth,
                   FrameStats& stats);
  //   box_test_inputs() / drop_unseen(): after second_phase() or third_phase(), the exact
  //     test of what the coarse one left (occlusion.h). False on a decode error.
  bool box_test_inputs(DecodedObjects& objects, const FrameView& frame_view,
                       const RenderOptions& options, std::vector<glm::vec4>& boxes,
                       std::string& error);
  void drop_unseen(std::span<const uint32_t> seen, FrameStats& stats);
  // 1c. Largest on screen first, so that the arena's budget goes where it shows most.
  void order();
  // 2. Choose: a Draw per visible object with geometry that its style does not hide
  //    (objects_hidden counted), or per merged run (hlod_merges and hlod_members counted). visible() must be what `objects` decoded last (its Knowns are
  //    read from objects.decoded(), no lookup per object); those seen get last_seen = frame.
  //    Merged runs are decoded (made) here.
  void choose(DecodedObjects& objects, const FrameView& frame_view, const RenderOptions& options,
              uint64_t frame, FrameStats& stats);

  // Forgets the blocks held (a new snapshot of the store).
  void reset_view() { blocks_.reset(); }

  std::span<const VisibleObject> visible() const { return visible_; }
  // Boxes of nodes drawn whole.
  std::span<const NodeBox> node_boxes() const { return node_boxes_; }
  // The blocks this frame's cull walked (those of visible()'s leaves among them).
  const FrameBlocks& blocks() const { return blocks_; }
  std::span<Draw> draws() { return draws_; }
  std::span<const Draw> draws() const { return draws_; }

 private:
  // A node not opened yet: a top node (block == kTopNode) or a node of a held block, the pixels
  // its largest side spans, and the objects and boxes it makes if drawn as it stands
  // (`items`: its proxy boxes in the frustum, or one box, or one object).
  static constexpr uint32_t kTopNode = UINT32_MAX;
  struct Candidate {
    double px;
    uint32_t block, node, items;
    bool boxable;  // drawn whole when not opened (else it is one object, always opened)
    bool operator<(const Candidate& o) const { return px < o.px; }
  };
  // Adds a node to fresh_ unless it is outside the frustum; push_fresh() makes fresh_
  // candidates.
  void consider_top(const ReadView& view, uint32_t node, const FrameView& frame_view,
                    bool subpixel_culling);
  void consider_block_node(const SpatialBlock& block, uint32_t block_index, uint32_t node,
                           const FrameView& frame_view, bool subpixel_culling);
  void push_fresh();
  // Opens a candidate: its children become candidates, or a leaf's objects visible. With
  // `bounded`, leaves `fits` false and changes nothing when that would make more than
  // kMaxDrawnItems items or read a block beyond kMaxFrameBlocksHeld. False on a read error.
  bool open(const ReadView& view, const Candidate& c, const FrameView& frame_view,
            const RenderOptions& options, bool subpixel_culling, bool bounded, bool& fits,
            FrameStats& stats, std::string& error);
  // Draws a candidate whole (its proxy boxes or its box), or, for one object, opens it.
  void draw_whole(const ReadView& view, const Candidate& c, const FrameView& frame_view,
                  FrameStats& stats);
  // Walks a whole block with nothing drawn whole (no subpixel culling); false on a read error.
  bool walk_block(const ReadView& view, uint32_t block, const FrameView& frame_view,
                  const RenderOptions& options, FrameStats& stats, std::string& error);
  // Appends the visible objects of leaf `node` of `block`; returns how many were added.
  size_t take_leaf(const SpatialBlock& block, uint32_t block_index, uint32_t node,
                   const FrameView& frame_view, const RenderOptions& options,
                   bool subpixel_culling, FrameStats& stats);
  size_t items() const { return visible_.size() + node_boxes_.size() + pending_items_; }
  // Whether the section (RenderOptions::section, set by find_visible) removes every point of a
  // box relative to the spatial origin: such nodes, objects and proxy boxes are left out.
  bool clipped(const float min[3], const float max[3]) const;
  const Section* section_ = nullptr;  // this cull's, null when empty
  glm::dvec3 section_origin_m_{0.0};  // the spatial origin the boxes are relative to
  uint64_t clipped_ = 0;              // objects left out so this cull (objects_clipped)
  // Whether the top leaves in the frustum hold at most `limit` objects (counted from the
  // resident top; stops as soon as they do not).
  bool frustum_objects_at_most(const ReadView& view, const FrameView& frame_view, uint64_t limit);
  size_t item_bound_ = kMaxDrawnItems;  // this frame's
  std::vector<VisibleObject> visible_;
  std::vector<NodeBox> node_boxes_;
  std::vector<VisibleObject> second_visible_;  // set aside for the second phase (tree order)
  std::vector<NodeBox> second_boxes_;
  size_t drawn_before_ = 0;  // objects drawn in the phases before the one in visible_
  // What was set aside and passed its test becomes visible() and node_boxes(); `drawn`
  // objects were drawn in the phases before.
  void take_set_aside(size_t drawn, FrameStats& stats);
  FrameBlocks blocks_;
  std::vector<Draw> draws_;
  std::vector<Candidate> candidates_;  // a max-heap on px
  std::vector<Candidate> fresh_;       // an opened node's children, before they fit
  size_t pending_items_ = 0;           // items of candidates_
  std::vector<uint32_t> stack_, count_stack_;
  struct Ahead {
    double px;
    uint32_t block;
  };
  std::vector<Ahead> ahead_;  // blocks_ahead()'s top leaves
  std::vector<SortPair> order_keys_, order_scratch_;  // order(): (key, index in visible_)
  std::vector<VisibleObject> ordered_;
  OcclusionCulling occlusion_;
};

}  // namespace plantview::detail
