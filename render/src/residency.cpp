#include "residency.h"

#include <algorithm>
#include <cassert>

namespace plantview::detail {

RangeAllocator::RangeAllocator(uint64_t capacity) : capacity_(capacity) {
  if (capacity > 0) insert_free(0, capacity);
}

void RangeAllocator::insert_free(uint64_t offset, uint64_t size) {
  by_offset_.emplace(offset, size);
  by_size_.emplace(size, offset);
}

void RangeAllocator::erase_free(std::map<uint64_t, uint64_t>::iterator it) {
  by_size_.erase({it->second, it->first});
  by_offset_.erase(it);
}

std::optional<uint64_t> RangeAllocator::allocate(uint64_t size) {
  if (size == 0) return std::nullopt;
  // The smallest range that fits, the lowest such first.
  const auto best = by_size_.lower_bound({size, 0});
  if (best == by_size_.end()) return std::nullopt;
  const uint64_t offset = best->second, free_size = best->first;
  erase_free(by_offset_.find(offset));
  if (free_size > size) insert_free(offset + size, free_size - size);
  used_ += size;
  return offset;
}

void RangeAllocator::release(uint64_t offset, uint64_t size) {
  assert(size > 0 && offset + size <= capacity_ && used_ >= size);
  used_ -= size;
  // Merge with the free neighbours on either side.
  auto next = by_offset_.lower_bound(offset);
  if (next != by_offset_.end() && next->first == offset + size) {
    size += next->second;
    erase_free(next);
  }
  auto prev = by_offset_.lower_bound(offset);
  if (prev != by_offset_.begin()) {
    --prev;
    if (prev->first + prev->second == offset) {
      offset = prev->first;
      size += prev->second;
      erase_free(prev);
    }
  }
  insert_free(offset, size);
}

uint64_t RangeAllocator::largest_free() const {
  return by_size_.empty() ? 0 : by_size_.rbegin()->first;
}

void Residency::mark_visible(uint32_t key) {
  if (Entry* e = entries_.find(key)) e->visible_frame = frame_;
}

std::optional<uint64_t> Residency::offset(uint32_t key) const {
  const Entry* e = entries_.find(key);
  if (!e) return std::nullopt;
  return e->offset;
}

uint32_t Residency::counter(uint32_t key) const {
  const Entry* e = entries_.find(key);
  if (!e || e->visible_frame >= ended_) return 0;
  return uint32_t(ended_ - e->visible_frame);
}

std::optional<uint64_t> Residency::admit(uint32_t key, uint64_t units,
                                         std::vector<std::pair<uint32_t, uint64_t>>& evicted) {
  assert(!resident(key));
  if (units == 0 || units > allocator_.capacity()) return std::nullopt;
  auto place = allocator_.allocate(units);
  while (!place) {
    if (!candidates_built_) {
      candidates_.clear();
      entries_.for_each([&](uint32_t k, const Entry& e) {
        if (e.visible_frame != frame_) candidates_.push_back({e.visible_frame, e.units, k});
      });
      // Best candidate last: largest counter (the longest unseen), then largest size, then key
      // for determinism.
      std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
        if (a.visible_frame != b.visible_frame) return a.visible_frame > b.visible_frame;
        if (a.units != b.units) return a.units < b.units;
        return a.key > b.key;
      });
      candidates_built_ = true;
    }
    // Candidates made visible or dropped since the list was built are skipped.
    while (!candidates_.empty()) {
      const Entry* e = entries_.find(candidates_.back().key);
      if (e && e->visible_frame != frame_) break;
      candidates_.pop_back();
    }
    if (candidates_.empty()) return std::nullopt;
    const uint32_t victim = candidates_.back().key;
    candidates_.pop_back();
    const Entry e = *entries_.find(victim);
    allocator_.release(e.offset, e.units);
    entries_.erase(victim);
    evicted.emplace_back(victim, e.units);
    place = allocator_.allocate(units);
  }
  entries_.insert(key, Entry{*place, units, frame_});
  return place;
}

void Residency::drop(uint32_t key) {
  const Entry* e = entries_.find(key);
  if (!e) return;
  allocator_.release(e->offset, e->units);
  entries_.erase(key);
}



}  // namespace plantview::detail
