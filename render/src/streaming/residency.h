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
#include <bit>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

namespace plantview::detail {

// Best-fit allocator over [0, capacity) with coalescing of freed ranges: the smallest free range
// that fits, the lowest of equal ones. O(log n) per call.
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
  // (size, offset): best fit is the first not smaller; a range is erased by its exact key
  // (free ranges of one size are many when objects share a template).
  std::set<std::pair<uint64_t, uint64_t>> by_size_;
};

// Values by residency key (any uint32_t) in a dense array, found through an open-addressing
// hash table (linear probing, at most half full, backward-shift deletion: no tombstones). Memory follows the keys present at most at once (the
// working set: what is resident), never the slot numbers: 8 bytes a table cell (2 to 4 per key)
// plus the dense entry. Lookups are a multiply, a probe or two and an array read. Pointers stay
// valid until the next insert.
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
    if ((size_ + 1) * 2 > cells_.size()) grow();
    place(key, i);
    ++size_;
  }
  void erase(uint32_t key) {
    if (cells_.empty()) return;
    size_t at = home(key);
    while (cells_[at].index != kAbsent && cells_[at].key != key) at = (at + 1) & mask();
    if (cells_[at].index == kAbsent) return;
    alive_[cells_[at].index] = 0;
    free_.push_back(cells_[at].index);
    --size_;
    // Backward shift: pull later cells of the run into the hole where their home allows.
    size_t hole = at;
    for (size_t next = (hole + 1) & mask(); cells_[next].index != kAbsent; next = (next + 1) & mask()) {
      const size_t h = home(cells_[next].key);
      // `next` may move to `hole` if its home is not in (hole, next] (cyclically).
      const bool stays = hole < next ? (h > hole && h <= next) : (h > hole || h <= next);
      if (stays) continue;
      cells_[hole] = cells_[next];
      hole = next;
    }
    cells_[hole].index = kAbsent;
  }
  size_t size() const { return size_; }
  // Bytes held by the map itself (table, dense entries, free list): for memory bounds.
  size_t bytes() const {
    return cells_.capacity() * sizeof(Cell) + dense_.capacity() * sizeof(dense_[0]) +
           alive_.capacity() + free_.capacity() * sizeof(uint32_t);
  }
  // f(key, value) for every present key, in no particular order.
  template <class F>
  void for_each(F f) const {
    for (size_t i = 0; i < dense_.size(); ++i)
      if (alive_[i]) f(dense_[i].first, dense_[i].second);
  }

 private:
  static constexpr uint32_t kAbsent = UINT32_MAX;
  struct Cell {
    uint32_t key = 0, index = kAbsent;  // index into dense_; kAbsent: empty cell
  };
  size_t mask() const { return cells_.size() - 1; }
  size_t home(uint32_t key) const { return size_t((uint64_t(key) * 0x9E3779B97F4A7C15ull) >> shift_); }
  uint32_t index_of(uint32_t key) const {
    if (cells_.empty()) return kAbsent;
    for (size_t at = home(key);; at = (at + 1) & mask()) {
      const Cell& c = cells_[at];
      if (c.index == kAbsent || c.key == key) return c.index;
    }
  }
  void place(uint32_t key, uint32_t index) {
    size_t at = home(key);
    while (cells_[at].index != kAbsent) at = (at + 1) & mask();
    cells_[at] = {key, index};
  }
  void grow() {
    std::vector<Cell> old = std::move(cells_);
    const size_t n = std::max<size_t>(16, old.size() * 2);
    cells_.assign(n, Cell{});
    shift_ = 64 - uint32_t(std::countr_zero(n));
    for (const Cell& c : old)
      if (c.index != kAbsent) place(c.key, c.index);
  }
  std::vector<Cell> cells_;  // a power of two in size
  uint32_t shift_ = 64;
  std::vector<std::pair<uint32_t, T>> dense_;
  std::vector<uint8_t> alive_;
  std::vector<uint32_t> free_;
  size_t size_ = 0;
};

class Residency {
 public:
  explicit Residency(uint64_t capacity_units) : allocator_(capacity_units) {}

  void begin_frame() { ++frame_; }
  // Marks a resident object visible in this frame (resets its counter at end_frame).
  void mark_visible(uint32_t key);
  bool resident(uint32_t key) const { return entries_.find(key) != nullptr; }
  std::optional<uint64_t> offset(uint32_t key) const;
  uint32_t counter(uint32_t key) const;

  // Room for `units` for `key` (not yet resident), visible this frame. Evicted keys are appended
  // to `evicted` with their sizes; the caller frees what it kept for them. Cost: the evictions
  // it makes, and a sort of the objects last seen in one frame the first time it evicts from
  // them; never a walk of every resident object.
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
  // Bytes of the per-object bookkeeping (follows the resident count, not the plant).
  size_t bookkeeping_bytes() const;

 private:
  struct Entry {
    uint64_t offset = 0, units = 0;
    uint64_t visible_frame = 0;
  };
  struct Candidate {
    uint64_t units;
    uint32_t key;
  };
  // Eviction order without a walk of every resident object: each entry has a record (its key)
  // in the bucket of the frame it was admitted in, or of its visible_frame as last seen by
  // next_victim(), which takes the oldest bucket, moves its records whose object was seen
  // since to the bucket of that frame (at most once per pass of eviction over them), and sorts
  // the rest (all the objects last seen in that frame), best last. mark_visible() only sets
  // visible_frame. Records of dropped objects are found stale and skipped.
  struct Bucket {
    std::vector<uint32_t> keys;
    std::vector<Candidate> sorted;
    bool is_sorted = false;
  };
  // The next object to evict (the longest unseen, then the largest, then the lowest key),
  // its record removed; none when only objects visible this frame are left.
  std::optional<uint32_t> next_victim();
  void add_record(uint64_t frame, uint32_t key);
  // Files every resident object's record again, dropping the stale: when stale records
  // (dropped objects') outnumber the resident ones.
  void compact();

  RangeAllocator allocator_;
  FlatKeyMap<Entry> entries_;
  uint64_t frame_ = 0, ended_ = 0;
  std::map<uint64_t, Bucket> buckets_;  // by frame
  size_t records_ = 0;                  // keys and sorted candidates in all buckets
};

}  // namespace plantview::detail
