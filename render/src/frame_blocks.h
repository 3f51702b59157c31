// Frame blocks: the blocks of the store's paged spatial index (store.h) that the frame plan's
// cull and occlusion walk, held for the frame.
//
// Rules
//   - Only blocks that hold a visible object's leaf are kept (occlusion tests those leaves);
//     cull drops the others after walking them (release()), and begin_frame() drops the last
//     frame's: what is held follows one frame's visible objects, never the plant (a block is
//     about 48 KB: 2048 entries of 16 bytes and its nodes).
//   - Across frames the store's own cache of decoded blocks (kSpatialCacheBytes, shared by
//     the views of a state) spares reading them again; this only keeps the frame's alive.
// Ownership: at() references stay valid until the next begin_frame().
// Threads: the renderer's thread.
#pragma once

#include <cassert>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>

#include "plantview/store.h"

namespace plantview::detail {

class FrameBlocks {
 public:
  // Starts a frame: the last frame's blocks are dropped (the store's cache may keep them).
  void begin_frame() {
    current_.clear();
    released_ = 0;
  }
  // Drops every block (a new snapshot of the store).
  void reset() { begin_frame(); }
  // Block `block` of `view`, held for this frame. Null with a message on a read error.
  const SpatialBlock* get(const ReadView& view, uint32_t block, std::string& error) {
    if (const auto it = current_.find(block); it != current_.end()) return it->second.get();
    std::shared_ptr<const SpatialBlock> b = view.spatial_block(block, error);
    if (!b) return nullptr;
    return current_.emplace(block, std::move(b)).first->second.get();
  }
  // Drops a block got this frame that no visible object needs (the store's cache may keep it).
  void release(uint32_t block) {
    if (current_.erase(block) > 0) ++released_;
  }
  // A block got this frame.
  const SpatialBlock& at(uint32_t block) const {
    const auto it = current_.find(block);
    assert(it != current_.end());
    return *it->second;
  }
  // Blocks walked this frame (a block walked again in another pass counts again), and held.
  size_t walked() const { return current_.size() + released_; }
  size_t held() const { return current_.size(); }

 private:
  std::unordered_map<uint32_t, std::shared_ptr<const SpatialBlock>> current_;
  size_t released_ = 0;
};

}  // namespace plantview::detail
