// Frame blocks: the blocks of the store's paged spatial index (store.h) that the frame plan's
// cull and occlusion walk, held for the frame.
//
// Rules
//   - Only blocks that hold a visible object's leaf are kept (occlusion tests those leaves);
//     cull drops the others after walking them (release()). A block kept in frame f is held
//     through frame f + 1 (so that a camera that moves a little reads no block again) and
//     dropped at begin_frame() of frame f + 2 unless used again: what is held follows the
//     visible objects of two frames, never the plant (a block is about 48 KB: 2048 entries of
//     16 bytes and its nodes).
//   - The store keeps its own cache of decoded blocks; this only keeps the frame's alive.
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
  // Starts a frame: the blocks not used in the last frame are dropped.
  void begin_frame() {
    previous_.swap(current_);
    current_.clear();
    released_ = 0;
  }
  // Drops every block (a new snapshot of the store).
  void reset() {
    previous_.clear();
    current_.clear();
  }
  // Block `block` of `view`, held for this frame. Null with a message on a read error.
  const SpatialBlock* get(const ReadView& view, uint32_t block, std::string& error) {
    if (const auto it = current_.find(block); it != current_.end()) return it->second.get();
    std::shared_ptr<const SpatialBlock> b;
    if (const auto it = previous_.find(block); it != previous_.end()) {
      b = std::move(it->second);
      previous_.erase(it);
    } else {
      b = view.spatial_block(block, error);
      if (!b) return nullptr;
    }
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
  // Blocks walked this frame (read or found held; a block walked again in another pass counts
  // again), and held now (this frame's and the last frame's).
  size_t walked() const { return current_.size() + released_; }
  size_t held() const { return current_.size() + previous_.size(); }

 private:
  std::unordered_map<uint32_t, std::shared_ptr<const SpatialBlock>> current_, previous_;
  size_t released_ = 0;
};

}  // namespace plantview::detail
