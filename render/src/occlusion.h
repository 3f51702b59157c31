// Occlusion culling: the frame plan's stage between cull and choose. Of the objects in the
// frustum, the largest on screen that can occlude (occlusion_occluders.h) are rasterised into
// a small software depth buffer (occlusion_buffer.h); then every leaf of the spatial tree that
// holds visible objects, every visible object and every node box is tested against it, and what
// is hidden is dropped: it is neither decoded, tessellated, uploaded nor drawn, and its
// visibility counter ages like a culled object's.
//
// Rules
//   - Never drops what is visible: occluders are inside what is drawn of them, and the buffer is
//     conservative (occlusion_buffer.h). One phase suffices: the occluders are chosen from this
//     frame's frustum, so an object seen for the first time is tested against this frame's
//     occluders only.
//   - Occluders: up to kMaxOccluders objects spanning at least kOccluderMinPixels on screen,
//     largest first, decoded here if new. Objects that may be drawn otherwise than as their
//     solids are not occluders: pipes drawn as centrelines, members of merged runs, see-through
//     objects (occlusion_occluders.h).
//   - A hidden occluder may still hide others: whatever it covers, what hides it covers too.
//   - Memory follows the frame, not the plant: leaves are tested as the cull visited them (a
//     leaf's visible objects are consecutive), through the frame's blocks; nothing is kept per
//     node or per object between frames.
// Units: metres, pixels. Ownership: owns its buffer and scratch (reused).
// Threads: the renderer's thread.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "occlusion_buffer.h"
#include "plantview/render.h"

namespace plantview {
class ReadView;
}

namespace plantview::detail {

class DecodedObjects;
class FrameBlocks;
struct FrameView;
struct NodeBox;
struct VisibleObject;

inline constexpr size_t kMaxOccluders = 384;
inline constexpr double kOccluderMinPixels = 24;

class OcclusionCulling {
 public:
  // Drops the hidden objects of `visible` (in cull's tree order: a leaf's objects consecutive;
  // order kept) and the hidden `node_boxes`; counts objects_occluded and nodes_occluded
  // (leaves whose visible objects were all hidden at once, and node boxes). `blocks` holds the
  // blocks of the visible objects' leaves. False if an occluder cannot be decoded.
  bool apply(const ReadView& view, const FrameBlocks& blocks, DecodedObjects& objects,
             const FrameView& frame_view, const RenderOptions& options,
             std::vector<VisibleObject>& visible, std::vector<NodeBox>& node_boxes,
             FrameStats& stats, std::string& error);

  const OcclusionBuffer& buffer() const { return buffer_; }

 private:
  // Whether the box (relative to the spatial origin) is hidden.
  bool hidden(const FrameView& frame_view, const float min[3], const float max[3]) const;

  OcclusionBuffer buffer_;
  // Scratch, reused.
  std::vector<VisibleObject> candidates_;
  std::vector<glm::vec3> piece_;
};

}  // namespace plantview::detail
