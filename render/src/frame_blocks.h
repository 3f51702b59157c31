// Frame blocks: the blocks of the store's paged spatial index (store.h) that the frame plan's
// cull and occlusion walk, held for the frame.
//
// Rules
//   - While cull runs (its passes, begin_cull() to end_cull()), the blocks it walks are held,
//     so that a pass with larger node boxes does not read them again, up to
//     kMaxFrameBlocksHeld; beyond that a block is dropped after its walk unless the pass took
//     visible objects from it.
//   - end_cull() keeps only the blocks the last pass took visible objects from (occlusion tests
//     their leaves), until the next begin_cull(): what is held after cull follows the frame's
//     visible objects, never the plant (a block is about 48 KB: 2048 entries of 16 bytes and
//     its nodes).
//   - Across frames the store's own cache of decoded blocks (kSpatialCacheBytes, shared by the
//     views of a state) spares reading them again; this only keeps the frame's alive.
// Ownership: at() references stay valid until the next begin_cull().
// Threads: the renderer's thread.
#pragma once

#include <cassert>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "plantview/store.h"

namespace plantview::detail {

// Blocks held during a frame's cull besides those with visible objects, at most (~48 MB).
inline constexpr size_t kMaxFrameBlocksHeld = 1024;

class FrameBlocks {
 public:
  // Starts a frame's cull: the last frame's blocks are dropped (the store's cache may keep
  // them).
  void begin_cull() {
    blocks_.clear();
    needed_.clear();
    walked_ = 0;
  }
  // Starts a pass of the cull: no block is needed yet.
  void begin_pass() { needed_.clear(); }
  // Block `block` of `view`, held at least until walked() says otherwise. Null with a message
  // on a read error.
  const SpatialBlock* get(const ReadView& view, uint32_t block, std::string& error) {
    ++walked_;
    if (const auto it = blocks_.find(block); it != blocks_.end()) return it->second.get();
    std::shared_ptr<const SpatialBlock> b = view.spatial_block(block, error);
    if (!b) return nullptr;
    return blocks_.emplace(block, std::move(b)).first->second.get();
  }
  // After a pass walked `block`: whether it took visible objects from it.
  void walked(uint32_t block, bool needed) {
    if (needed) needed_.insert(block);
    else if (blocks_.size() > kMaxFrameBlocksHeld) blocks_.erase(block);
  }
  // Ends the cull: only the blocks the last pass needed stay.
  void end_cull() {
    std::erase_if(blocks_, [&](const auto& b) { return needed_.count(b.first) == 0; });
  }
  // Drops every block (a new snapshot of the store).
  void reset() { begin_cull(); }
  // A block the last pass needed.
  const SpatialBlock& at(uint32_t block) const {
    const auto it = blocks_.find(block);
    assert(it != blocks_.end());
    return *it->second;
  }
  // Block walks this frame's cull made (a block walked again in another pass counts again),
  // and blocks held now.
  size_t walked() const { return walked_; }
  size_t held() const { return blocks_.size(); }

 private:
  std::unordered_map<uint32_t, std::shared_ptr<const SpatialBlock>> blocks_;
  std::unordered_set<uint32_t> needed_;
  size_t walked_ = 0;
};

}  // namespace plantview::detail
