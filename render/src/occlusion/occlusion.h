// Occlusion culling: the frame plan's stage between cull and choose. What is hidden is dropped:
// it is neither decoded, tessellated, uploaded nor drawn, and its visibility counter ages like
// a culled object's. Two forms, one buffer of tests (occlusion_buffer.h):
//
//   - Two phases on the GPU (frames drawn: Renderer::render), three where the second is
//     large. Phase 1 draws for real a set that will mostly be visible: the objects drawn in
//     the previous frame that are still in the frustum (temporal coherence; less those its own
//     first phase's depth hid), and the nearer half of this frame's largest on screen (of up
//     to kMaxOccluders spanning kOccluderMinPixels; for a first frame that is all there is;
//     none with the eye within its bounds, nor, with the exact test, reaching the eye's
//     plane); less what the largest, rasterised on the CPU as
//     below, hide; and only objects drawn as opaque triangles: see-through objects and
//     centrelines blend, and are drawn after the opaque surfaces behind them, as in a frame
//     drawn at once (so the image equals the one without occlusion). The GL backend reduces
//     the depth drawn to a coarse grid (each cell's farthest depth), read back into the
//     buffer; every other object, leaf and node box the cull found is tested against it
//     (coarse: a box's screen rectangle against the cells, on the CPU), and what passes is
//     tested exactly (GlBackend::test_boxes: its boxes drawn against the depth itself,
//     sample by sample; an object of several primitives by the bounds of up to kMaxTestBoxes
//     groups of them, Known::test_boxes). Phase 2 draws what is left into the same
//     framebuffer, without clearing. Where that is kThirdPhaseObjects or more (a view cut
//     to), phase 2 draws only those largest on screen for their distance, and the rest is
//     tested again (coarse, and exact where the exact test is on) against the depth of both
//     and drawn in phase 3. Correct by construction: what a
//     phase drew is in the image, so whatever it hides is hidden at every sample; an object
//     seen for the first time is drawn in the frame it appears (a later phase draws it).
//   - Occluders rasterised on the CPU (frames not drawn: Renderer::statistics). Of the objects
//     in the frustum, the largest on screen that can occlude (occlusion_occluders.h) are
//     rasterised at their farthest depth (up to kMaxOccluders objects spanning at least
//     kOccluderMinPixels, decoded here if new; not pipes drawn as centrelines, members of
//     merged runs, see-through objects). A hidden occluder may still hide others: whatever it
//     covers, what hides it covers too.
//
// Rules
//   - Never drops what is visible: the buffer is conservative either way.
//   - Memory follows the frame, not the plant: leaves are tested as the cull visited them (a
//     leaf's visible objects are consecutive), through the frame's blocks; nothing is kept per
//     node or per object between frames but what DecodedObjects keeps (Known::last_seen).
// Units: metres, pixels. Ownership: owns its buffer and scratch (reused).
// Threads: the renderer's thread; the per-object tests (read-only: the buffer, the decoded
//   objects' directory and Knowns) run on its worker pool, each part writing only its flags.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "occlusion/occlusion_buffer.h"
#include "plantview/render.h"

namespace plantview {
class ReadView;
}

namespace plantview::detail {

class DecodedObjects;
class FrameBlocks;
struct Known;
struct FrameView;
struct NodeBox;
struct VisibleObject;

class WorkerPool;

// One part's boxes for the exact test (OcclusionCulling::box_test_inputs): two corners a box,
// the index in `rest` of each box's object, and the objects left for the calling thread.
struct TestBoxes {
  std::vector<glm::vec4> boxes;
  std::vector<uint32_t> tested;
  std::vector<uint32_t> waiting;
};

inline constexpr size_t kMaxOccluders = 384;
inline constexpr size_t kObjectsPerPart = 2048;  // objects tested per part on the pool
inline constexpr double kOccluderMinPixels = 24;
inline constexpr size_t kOccludersPerPart = 32;  // occluders rasterised per part on the pool
// The first phase's largest: the nearer kFirstPhaseNearShare of the kMaxOccluders largest.
inline constexpr double kFirstPhaseNearShare = 0.5;
// A third phase is taken when the second holds at least kThirdPhaseObjects objects (a view
// cut to, with little drawn the frame before): the second then draws the
// kThirdPhaseLargestShare of them largest on screen for their distance, and the rest is
// tested against both. Measured on preset c's interior views (README, occlusion culling).
inline constexpr size_t kThirdPhaseObjects = 256;
// Triangles the exact test draws a box with (the faces the eye sees, GlBackend::test_boxes):
// an object is tested only where it draws more than its boxes would.
inline constexpr size_t kBoxTestTriangles = 6;
inline constexpr double kBoxTestDecodePixels = 8;
inline constexpr double kThirdPhaseLargestShare = 0.3;

// Where a box (relative to the spatial origin) lies on screen: its eight corners projected, the
// bounds grown by what rounding may move them, so that they hold the box's projection. (Not
// its bounds in view space, which a box turned to the view grows: up to 1.4x in width and
// depth for a plant's axis-aligned bounds seen at 45 degrees.) A box reaching the eye's plane
// gets the whole plane and a nearest distance of 0.
ProjectedBounds project_box(const FrameView& frame_view, const float min[3], const float max[3]);

class OcclusionCulling {
 public:
  // The per-object tests of split() and the drops run on `pool` (null: on the calling thread).
  explicit OcclusionCulling(WorkerPool* pool = nullptr);
  ~OcclusionCulling();

  // CPU form. Drops the hidden objects of `visible` (in cull's tree order: a leaf's objects consecutive;
  // order kept) and the hidden `node_boxes`; counts objects_occluded and nodes_occluded
  // (leaves whose visible objects were all hidden at once, and node boxes). `blocks` holds the
  // blocks of the visible objects' leaves. False if an occluder cannot be decoded.
  bool apply(const ReadView& view, const FrameBlocks& blocks, DecodedObjects& objects,
             const FrameView& frame_view, const RenderOptions& options,
             std::vector<VisibleObject>& visible, std::vector<NodeBox>& node_boxes,
             FrameStats& stats, std::string& error);

  // Two phases, 1: moves out of `visible` (cull's, tree order) into `rest` (order kept) every
  // object that is neither drawn in the previous frame (`frame` - 1, Known::last_seen) nor
  // among this frame's largest on screen (with `exact`, the nearer kFirstPhaseNearShare of
  // them: the exact test drops what the nearer hide of the farther; none with the eye within
  // its bounds), or that the largest, rasterised on the CPU, hide (the CPU form's occluders
  // choose the first phase); counts the others in stats.occluders. Sizes the buffer for the
  // view (buffer().width() x height() cells). False if an occluder cannot be decoded.
  bool split(DecodedObjects& objects, const FrameView& frame_view, const RenderOptions& options,
             uint64_t frame, bool exact, std::vector<VisibleObject>& visible,
             std::vector<VisibleObject>& rest, FrameStats& stats, std::string& error);
  // Two phases, 2: loads the depth phase 1 drew (`reversed_depth`: GlBackend::reduce_depth's
  // grid of buffer().width() x height() cells) and drops the hidden of `rest` and `node_boxes`
  // (objects_occluded, nodes_occluded counted). `blocks` holds the blocks of rest's leaves.
  // `first`: the first phase's objects; those the buffer hides are remembered (a frame's
  // worth of slots) and not drawn first next frame.
  void test_rest(const FrameBlocks& blocks, const FrameView& frame_view, uint64_t frame,
                 std::span<const VisibleObject> first, std::span<const float> reversed_depth,
                 std::vector<VisibleObject>& rest, std::vector<NodeBox>& node_boxes,
                 FrameStats& stats);

  // A third phase, where the second is large: when `rest` (tested, tree order) holds at least
  // kThirdPhaseObjects objects, moves out of it into `later` (order kept) every object that is
  // not among the kThirdPhaseLargestShare of rest largest on screen for their distance (the
  // pixels it spans over its distance, under a metre counted as one: the large and near,
  // which hide the most and are the least hidden) or is not drawn as opaque triangles of its
  // own (`deferred` true); else changes nothing (`later` empty). Those chosen are decoded
  // here to know that (they are drawn next anyway). Once rest is drawn,
  // test_later() drops what of `later` and the node boxes the depth drawn by then hides.
  // False with an error if an object cannot be decoded.
  bool defer_smaller(DecodedObjects& objects, const FrameView& frame_view,
                 const RenderOptions& options, std::vector<VisibleObject>& rest,
                 std::vector<VisibleObject>& later, bool& deferred, std::string& error);
  // Loads the depth drawn so far (as test_rest) and drops the hidden of `later` and
  // `node_boxes` (objects_occluded, nodes_occluded counted).
  void test_later(const FrameBlocks& blocks, const FrameView& frame_view,
                  std::span<const float> reversed_depth, std::vector<VisibleObject>& later,
                  std::vector<NodeBox>& node_boxes, FrameStats& stats);

  // The exact test, after a coarse one (test_rest, test_later), for GlBackend::test_boxes:
  // `boxes` gets, eye-relative and grown by a hair, boxes for the objects of `rest`: for one
  // drawn as solids of its own, the bounds of groups of its primitives (Known::test_boxes,
  // else its own bounds), where it draws more than kBoxTestTriangles a box (else it is kept);
  // for one not decoded, drawn as a centreline, with lines or merged into a run, its own
  // bounds grown by kSpillPixels (what is drawn of it may reach past them). New objects are
  // decoded for it only where they span kBoxTestDecodePixels (few, and drawn most likely:
  // decoding what turns out hidden costs, and out of core it is decoded again frame after
  // frame). Not one of which a box holds the eye (kept). Node boxes are not tested (a
  // box costs what testing it would). In parts on the pool, joined in order: the same boxes
  // in the same order whatever the core count. False on a decode error.
  bool box_test_inputs(DecodedObjects& objects, const FrameView& frame_view,
                       const RenderOptions& options, std::span<const VisibleObject> rest,
                       std::vector<glm::vec4>& boxes, std::string& error);
  // Drops the objects of `rest` (as given to box_test_inputs()) none of whose boxes `seen`
  // says a sample of is visible (objects_occluded counted).
  void drop_unseen(std::span<const uint32_t> seen, std::vector<VisibleObject>& rest,
                   FrameStats& stats);

  const OcclusionBuffer& buffer() const { return buffer_; }

 private:
  // Steps 1 and 2 of the CPU form: the largest of `visible` decoded and rasterised into a
  // cleared buffer (any: something covered); stats.occluders counted.
  bool rasterise_occluders(DecodedObjects& objects, const FrameView& frame_view,
                           const RenderOptions& options, std::span<const VisibleObject> visible,
                           bool& any, FrameStats& stats, std::string& error);
  // Drops the objects of `visible` (tree order) and the `node_boxes` the buffer hides.
  void drop_hidden(const FrameBlocks& blocks, const FrameView& frame_view,
                   std::vector<VisibleObject>& visible, std::vector<NodeBox>& node_boxes,
                   FrameStats& stats) const;
  // Whether the box (relative to the spatial origin) is hidden.
  bool hidden(const FrameView& frame_view, const float min[3], const float max[3]) const;

  // box_test_inputs() for one object of `rest` (its index), into `out` (`rotation`: the
  // view's): false on a read error. Without `may_read`, one whose groups would be built from
  // primitives read again from the store is left in out.waiting instead (the workers share no
  // read buffer).
  static bool object_boxes(DecodedObjects& objects, const FrameView& frame_view,
                           const glm::mat3& rotation, const RenderOptions& options,
                           const VisibleObject& v, uint32_t index, bool may_read,
                           TestBoxes& out, std::string& error);

  // Runs f(first, end) over [0, n) in runs of kObjectsPerPart, on the pool if there is one.
  template <class F>
  void for_parts(size_t n, const F& f) const;

  WorkerPool* pool_;
  OcclusionBuffer buffer_;
  // Scratch, reused.
  mutable std::vector<uint8_t> flags_;  // per object: kept (split) or hidden (drops)
  std::vector<VisibleObject> candidates_;
  std::vector<double> distances_;  // split() and defer_smaller(): sort keys
  std::vector<uint32_t> tested_;   // box_test_inputs(): per box, its index in `rest`
  std::vector<TestBoxes> part_boxes_;  // box_test_inputs(): per part
  double smallest_candidate_px_ = 0;  // of the last rasterise_occluders()
  // Slots of the first phase's objects found hidden in frame hidden_drawn_frame_ (sorted).
  std::vector<uint32_t> hidden_drawn_;
  uint64_t hidden_drawn_frame_ = 0;
  // rasterise_occluders(): the occluders, and per worker a buffer (worker 0: buffer_) and
  // scratch.
  std::vector<const Known*> occluding_;
  struct WorkerBuffer {
    OcclusionBuffer buffer;
    std::vector<glm::vec3> piece;
    bool any = false;   // covered a cell
    bool used = false;  // begun this frame (worker 0 draws into buffer_)
  };
  std::vector<WorkerBuffer> worker_buffers_;
};

}  // namespace plantview::detail
