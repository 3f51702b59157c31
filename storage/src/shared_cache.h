// Internal: decoded values shared by the views of one committed state (spatial blocks,
// decompressed chunks), found by number.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>

namespace plantview::detail {

// Keeps at most `bound_bytes` of values (the byte counts the inserter gives), least recently
// used going first. With `skip_held`, values somebody else holds are passed over (dropping
// them would free nothing: they stay until let go, and go at a later call once they are);
// without, they go from the cache and live on with their holders. A value inserted is kept
// whatever its size unless the bound drops it at once.
// Threads: any, at once (one mutex, held for a lookup or an insert).
template <class T>
class SharedCache {
 public:
  SharedCache(size_t bound_bytes, bool skip_held) : bound_(bound_bytes), skip_held_(skip_held) {}
  SharedCache(const SharedCache&) = delete;
  SharedCache& operator=(const SharedCache&) = delete;

  std::shared_ptr<const T> find(uint32_t key) {
    std::lock_guard lock(mutex_);
    const auto it = entries_.find(key);
    if (it == entries_.end()) return nullptr;
    lru_.splice(lru_.begin(), lru_, it->second.position);
    auto found = it->second.value;
    if (skip_held_) evict_locked();  // values let go since the last call may now go
    return found;
  }
  // A value another thread inserted meanwhile under the same key wins (they are the same).
  void insert(uint32_t key, const std::shared_ptr<const T>& value, size_t bytes) {
    std::lock_guard lock(mutex_);
    if (entries_.count(key)) return;
    lru_.push_front(key);
    entries_.emplace(key, Entry{value, bytes, lru_.begin()});
    bytes_ += bytes;
    evict_locked();
  }
  size_t bytes() const {
    std::lock_guard lock(mutex_);
    return bytes_;
  }

 private:
  void evict_locked() {
    for (auto it = lru_.end(); bytes_ > bound_ && it != lru_.begin();) {
      --it;
      auto e = entries_.find(*it);
      if (skip_held_ && e->second.value.use_count() > 1) continue;  // the cache's and theirs
      bytes_ -= e->second.bytes;
      entries_.erase(e);
      it = lru_.erase(it);
    }
  }
  struct Entry {
    std::shared_ptr<const T> value;
    size_t bytes;
    std::list<uint32_t>::iterator position;
  };
  mutable std::mutex mutex_;
  size_t bound_;
  bool skip_held_;
  size_t bytes_ = 0;
  std::list<uint32_t> lru_;  // most recently used first
  std::unordered_map<uint32_t, Entry> entries_;
};

}  // namespace plantview::detail
