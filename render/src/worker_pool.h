// Worker pool: the renderer's threads for the parallel parts of a frame (tessellating newly
// resident objects, writing the index lists). Started once with the renderer, so that a frame
// pays no thread start; idle workers sleep on a condition variable.
//
// Rules
//   - run(parts, f) calls f(part, worker) once for every part in [0, parts), spread over the
//     workers and the calling thread, and returns when every call has returned. `worker` is in
//     [0, size()): the caller is worker 0, so per-worker scratch indexed by it is never shared.
//   - f must not throw, and must not call run() on the same pool.
//   - A pool of size 1 has no thread: run() calls f on the caller, in order.
// Threads: run() from one thread at a time (the renderer's); f runs on any worker.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace plantview::detail {

class WorkerPool {
 public:
  // `threads` in all, the caller included (at least 1).
  explicit WorkerPool(unsigned threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  unsigned size() const { return unsigned(threads_.size()) + 1; }
  void run(size_t parts, const std::function<void(size_t part, unsigned worker)>& f);

  // The pool size for this machine: its cores, at most kMaxWorkers.
  static unsigned default_size();
  static constexpr unsigned kMaxWorkers = 16;

 private:
  void work(unsigned worker);
  // Runs parts of the current job until none is left.
  void take_parts(const std::function<void(size_t, unsigned)>& f, size_t parts, unsigned worker);

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  // The current job (guarded by mutex_; a worker copies it when it wakes). Every worker takes
  // part in every job, if only to find no part left, and run() waits for all of them: so no
  // worker is still in a job when the next one starts.
  const std::function<void(size_t, unsigned)>* job_ = nullptr;
  size_t parts_ = 0;
  std::atomic<size_t> next_{0};  // the next part to take
  unsigned running_ = 0;         // workers not yet done with the current job
  unsigned long generation_ = 0;
  bool stopping_ = false;
};

}  // namespace plantview::detail
