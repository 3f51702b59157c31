// Worker pool (rules in worker_pool.h).
#include "worker_pool.h"

#include <algorithm>

namespace plantview::detail {

WorkerPool::WorkerPool(unsigned threads) {
  for (unsigned w = 1; w < std::max(threads, 1u); ++w) threads_.emplace_back([this, w] { work(w); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
}

unsigned WorkerPool::default_size() {
  return std::clamp(std::thread::hardware_concurrency(), 1u, kMaxWorkers);
}

void WorkerPool::run(size_t parts, const std::function<void(size_t, unsigned)>& f) {
  if (parts == 0) return;
  if (threads_.empty() || parts == 1) {
    for (size_t p = 0; p < parts; ++p) f(p, 0);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    job_ = &f;
    parts_ = parts;
    next_.store(0, std::memory_order_relaxed);
    running_ = unsigned(threads_.size());
    ++generation_;
  }
  wake_.notify_all();
  take_parts(f, parts, 0);
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return running_ == 0; });
  job_ = nullptr;
}

void WorkerPool::take_parts(const std::function<void(size_t, unsigned)>& f, size_t parts,
                            unsigned worker) {
  for (size_t p = next_.fetch_add(1, std::memory_order_relaxed); p < parts;
       p = next_.fetch_add(1, std::memory_order_relaxed))
    f(p, worker);
}

void WorkerPool::work(unsigned worker) {
  unsigned long seen = 0;
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stopping_ || generation_ != seen; });
    if (stopping_) return;
    seen = generation_;
    const auto* f = job_;
    const size_t parts = parts_;
    lock.unlock();
    take_parts(*f, parts, worker);
    lock.lock();
    if (--running_ == 0) done_.notify_one();
  }
}

}  // namespace plantview::detail
