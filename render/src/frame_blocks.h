// Frame blocks: the blocks of the store's paged spatial index (store.h) that the frame plan's
// cull and occlusion walk, held for the frame.
//
// Rules
//   - While cull runs (begin_cull() to end_cull()) the blocks it reads are held: cull refines
//     the nodes inside a block in the order of their size on screen, so a block stays needed
//     until the cull ends. Cull reads at most kMaxFrameBlocksHeld blocks a frame (~48 MB; it
//     boxes the rest of the view instead), and drops a block at once (release()) where it walks
//     the whole block in one go and takes nothing from it.
//   - end_cull() keeps only the blocks cull took visible objects from (occlusion tests their
//     leaves), until the next begin_cull(): what is held after cull follows the frame's visible
//     objects, never the plant (a block is about 48 KB: 2048 entries of 16 bytes and its nodes).
//   - Across frames the store's own cache of decoded blocks (kSpatialCacheBytes, shared by the
//     views of a state) spares reading them again; this only keeps the frame's alive.
// Ownership: get() and at() references stay valid until the next begin_cull(), or release() of
//   that block.
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

// Blocks a frame's cull reads, at most (~48 MB).
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
  // Block `block` of `view`, held until release() or the end of the cull (longer if needed()).
  // Null with a message on a read error.
  const SpatialBlock* get(const ReadView& view, uint32_t block, std::string& error) {
    ++walked_;
    if (const auto it = blocks_.find(block); it != blocks_.end()) return it->second.get();
    std::shared_ptr<const SpatialBlock> b = view.spatial_block(block, error);
    if (!b) return nullptr;
    return blocks_.emplace(block, std::move(b)).first->second.get();
  }
  // Cull took visible objects from `block`: it stays held after the cull.
  void needed(uint32_t block) { needed_.insert(block); }
  // Cull is done with `block` and took nothing from it.
  void release(uint32_t block) {
    if (needed_.count(block) == 0) blocks_.erase(block);
  }
  // Ends the cull: only the blocks cull needed stay.
  void end_cull() {
    std::erase_if(blocks_, [&](const auto& b) { return needed_.count(b.first) == 0; });
    culled_ = true;
  }
  // Drops every block (a new snapshot of the store).
  void reset() {
    begin_cull();
    culled_ = false;
  }
  // Whether no cull has run since the last reset() (the renderer's first frame of a snapshot).
  bool first_cull() const { return !culled_; }
  // A block held now.
  const SpatialBlock& at(uint32_t block) const {
    const auto it = blocks_.find(block);
    assert(it != blocks_.end());
    return *it->second;
  }
  // Blocks this frame's cull read (get() calls), and blocks held now.
  size_t walked() const { return walked_; }
  size_t held() const { return blocks_.size(); }

 private:
  std::unordered_map<uint32_t, std::shared_ptr<const SpatialBlock>> blocks_;
  std::unordered_set<uint32_t> needed_;
  size_t walked_ = 0;
  bool culled_ = false;
};

}  // namespace plantview::detail
