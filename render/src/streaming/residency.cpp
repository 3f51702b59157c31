#include "streaming/residency.h"

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

size_t Residency::bookkeeping_bytes() const {
  // A map node: the bucket and about four pointers of the tree.
  size_t bytes = entries_.bytes() + buckets_.size() * (sizeof(Bucket) + 48);
  for (const auto& [frame, b] : buckets_)
    bytes += b.keys.capacity() * sizeof(uint32_t) + b.sorted.capacity() * sizeof(Candidate);
  return bytes;
}

void Residency::add_record(uint64_t frame, uint32_t key) {
  buckets_[frame].keys.push_back(key);
  if (++records_ > 2 * entries_.size() + 1024) compact();
}

void Residency::compact() {
  buckets_.clear();
  entries_.for_each([&](uint32_t key, const Entry& e) { buckets_[e.visible_frame].keys.push_back(key); });
  records_ = entries_.size();
}

std::optional<uint32_t> Residency::next_victim() {
  while (!buckets_.empty() && buckets_.begin()->first != frame_) {
    const auto it = buckets_.begin();
    const uint64_t frame = it->first;
    Bucket& b = it->second;
    // The entry of a record current in this bucket; else null, the record gone: to the bucket
    // of the frame its object was seen in since (a newer one: visible_frame only grows), or
    // dropped with its object.
    const auto current = [&](uint32_t key) -> const Entry* {
      const Entry* e = entries_.find(key);
      if (e && e->visible_frame == frame) return e;
      if (e) buckets_[e->visible_frame].keys.push_back(key);
      else --records_;
      return nullptr;
    };
    if (!b.is_sorted) {
      for (const uint32_t k : b.keys)
        if (const Entry* e = current(k)) b.sorted.push_back({e->units, k});
      // Best last: the largest (fewer evictions make the room), then the lowest key.
      std::sort(b.sorted.begin(), b.sorted.end(), [](const Candidate& x, const Candidate& y) {
        if (x.units != y.units) return x.units < y.units;
        return x.key > y.key;
      });
      // An object dropped and admitted again has two records.
      const auto end = std::unique(b.sorted.begin(), b.sorted.end(),
                                   [](const Candidate& x, const Candidate& y) { return x.key == y.key; });
      records_ -= size_t(b.sorted.end() - end);
      b.sorted.erase(end, b.sorted.end());
      b.keys = {};
      b.is_sorted = true;
    }
    while (!b.sorted.empty()) {
      const uint32_t key = b.sorted.back().key;
      b.sorted.pop_back();
      if (current(key)) {
        --records_;
        return key;
      }
    }
    buckets_.erase(it);
  }
  return std::nullopt;
}

std::optional<uint64_t> Residency::admit(uint32_t key, uint64_t units,
                                         std::vector<std::pair<uint32_t, uint64_t>>& evicted) {
  assert(!resident(key));
  if (units == 0 || units > allocator_.capacity()) return std::nullopt;
  auto place = allocator_.allocate(units);
  while (!place) {
    const std::optional<uint32_t> victim = next_victim();
    if (!victim) return std::nullopt;
    const Entry e = *entries_.find(*victim);
    allocator_.release(e.offset, e.units);
    entries_.erase(*victim);
    evicted.emplace_back(*victim, e.units);
    place = allocator_.allocate(units);
  }
  entries_.insert(key, Entry{*place, units, frame_});
  add_record(frame_, key);
  return place;
}

void Residency::drop(uint32_t key) {
  const Entry* e = entries_.find(key);
  if (!e) return;
  allocator_.release(e->offset, e->units);
  entries_.erase(key);
}

}  // namespace plantview::detail
