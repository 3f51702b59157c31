// Residency: which objects hold space in the vertex arena, and which to evict (Zhou et al.
// section 4). Pure bookkeeping, no GL: offsets and sizes are in arena units (vertices).
//
// Rules
//   - Every resident object has a visibility counter: 0 in a frame it is visible, one more
//     at the end of each frame it is not.
//   - admit() finds room for a newly visible object. When the arena is full it evicts resident
//     objects that are not visible this frame, largest counter first (ties: larger first, so
//     fewer evictions make the room), until a large enough free range exists. It never evicts
//     an object visible this frame; if room cannot be made, it admits nothing.
//   - The arena never hands out more than its capacity.
// Threads: one owner thread.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <unordered_map>
#include <vector>

namespace plantview::detail {

// Best-fit allocator over [0, capacity) with coalescing of freed ranges.
class RangeAllocator {
 public:
  explicit RangeAllocator(uint64_t capacity);
  std::optional<uint64_t> allocate(uint64_t size);
  void release(uint64_t offset, uint64_t size);
  uint64_t capacity() const { return capacity_; }
  uint64_t used() const { return used_; }
  uint64_t largest_free() const;

 private:
  void insert_free(uint64_t offset, uint64_t size);
  void erase_free(std::map<uint64_t, uint64_t>::iterator it);
  uint64_t capacity_, used_ = 0;
  std::map<uint64_t, uint64_t> by_offset_;         // offset -> size
  std::multimap<uint64_t, uint64_t> by_size_;      // size -> offset
};

// Values by residency key in flat arrays: a 4-byte index per slot (keys below 2^31) and per
// merged run (keys 2^31 + r, r below 2^24) into a dense array; other keys (the proxy cube) in a
// small map. Lookups are two array reads, not a hash. Pointers stay valid until the next insert.
template <class T>
class FlatKeyMap {
 public:
  T* find(uint32_t key) {
    const uint32_t i = index_of(key);
    return i == kAbsent ? nullptr : &dense_[i].second;
  }
  const T* find(uint32_t key) const { return const_cast<FlatKeyMap*>(this)->find(key); }
  // `key` must not be present.
  void insert(uint32_t key, const T& value) {
    uint32_t i;
    if (!free_.empty()) {
      i = free_.back();
      free_.pop_back();
      dense_[i] = {key, value};
    } else {
      i = uint32_t(dense_.size());
      dense_.emplace_back(key, value);
      alive_.push_back(0);
    }
    alive_[i] = 1;
    set_index(key, i);
    ++size_;
  }
  void erase(uint32_t key) {
    const uint32_t i = index_of(key);
    if (i == kAbsent) return;
    alive_[i] = 0;
    free_.push_back(i);
    set_index(key, kAbsent);
    --size_;
  }
  size_t size() const { return size_; }
  // f(key, value) for every present key, in no particular order.
  template <class F>
  void for_each(F f) const {
    for (size_t i = 0; i < dense_.size(); ++i)
      if (alive_[i]) f(dense_[i].first, dense_[i].second);
  }

 private:
  static constexpr uint32_t kAbsent = UINT32_MAX, kHighBit = 0x80000000u, kRuns = 1u << 24;
  uint32_t index_of(uint32_t key) const {
    if (!(key & kHighBit)) return key < slots_.size() ? slots_[key] : kAbsent;
    const uint32_t r = key & ~kHighBit;
    if (r < kRuns) return r < runs_.size() ? runs_[r] : kAbsent;
    const auto it = others_.find(key);
    return it == others_.end() ? kAbsent : it->second;
  }
  void set_index(uint32_t key, uint32_t i) {
    std::vector<uint32_t>* table = nullptr;
    uint32_t at = key;
    if (!(key & kHighBit)) {
      table = &slots_;
    } else if ((key & ~kHighBit) < kRuns) {
      table = &runs_;
      at = key & ~kHighBit;
    }
    if (!table) {
      if (i == kAbsent) others_.erase(key);
      else others_[key] = i;
      return;
    }
    if (at >= table->size()) {
      if (i == kAbsent) return;
      table->resize(std::max<size_t>(at + 1, table->size() * 2), kAbsent);
    }
    (*table)[at] = i;
  }
  std::vector<uint32_t> slots_, runs_;
  std::unordered_map<uint32_t, uint32_t> others_;
  std::vector<std::pair<uint32_t, T>> dense_;
  std::vector<uint8_t> alive_;
  std::vector<uint32_t> free_;
  size_t size_ = 0;
};

class Residency {
 public:
  explicit Residency(uint64_t capacity_units) : allocator_(capacity_units) {}

  void begin_frame() { ++frame_; candidates_built_ = false; }
  // Marks a resident object visible in this frame (resets its counter at end_frame).
  void mark_visible(uint32_t key);
  bool resident(uint32_t key) const { return entries_.find(key) != nullptr; }
  std::optional<uint64_t> offset(uint32_t key) const;
  uint32_t counter(uint32_t key) const;

  // Room for `units` for `key` (not yet resident), visible this frame. Evicted keys are appended
  // to `evicted` with their sizes; the caller frees what it kept for them.
  std::optional<uint64_t> admit(uint32_t key, uint64_t units,
                                std::vector<std::pair<uint32_t, uint64_t>>& evicted);
  // Drops a resident object (e.g. when its data could not be written).
  void drop(uint32_t key);
  // Ages every object not visible this frame. (No work per object: a counter is the number of
  // ended frames since the object was last visible.)
  void end_frame() { ended_ = frame_; }

  uint64_t used_units() const { return allocator_.used(); }
  uint64_t capacity_units() const { return allocator_.capacity(); }
  size_t resident_count() const { return entries_.size(); }

 private:
  struct Entry {
    uint64_t offset = 0, units = 0;
    uint64_t visible_frame = 0;
  };
  RangeAllocator allocator_;
  FlatKeyMap<Entry> entries_;
  uint64_t frame_ = 0, ended_ = 0;
  // This frame's eviction candidates, best last (popped from the back).
  std::vector<uint32_t> candidates_;
  bool candidates_built_ = false;
};

}  // namespace plantview::detail
