// The render thread of the service: owns the EGL context and the renderer, and runs frame,
// statistics and pick jobs one at a time, in the order they wait.
//
// Threads
//   - start(), submit(), take_results(), queue_depth(), idle() and stop() are called by one
//     owning thread (the server's loop thread; a test's thread). They lock a mutex, briefly:
//     never while a job renders.
//   - `notify` (given to start) is called on the render thread each time a result is ready; it
//     must not block and must be safe from any thread (the server passes uv_async_send).
//   - The EGL context and renderer are made, used and destroyed on the render thread only.
// Queueing: a job whose client key matches a waiting one replaces it in its place in line (the
// older one's ticket is returned, to be answered 409); at most max_queue jobs wait, beyond that
// submit() refuses (busy). A running job is never replaced.
// Picks read their object from the renderer's snapshot of the store: the commit the frame was
// drawn from.
// Errors: start() fails with a message when the GPU context or renderer cannot be made; a job
// that fails gives a 500 result with the renderer's message.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "plantview/render.h"
#include "plantview/store.h"
#include "server/render_job.h"

namespace plantview::service {

class RenderWorker {
 public:
  RenderWorker() = default;
  ~RenderWorker();  // stop()
  RenderWorker(const RenderWorker&) = delete;
  RenderWorker& operator=(const RenderWorker&) = delete;

  // Starts the thread and waits until its context and renderer exist (or failed: false, error).
  // `store` must outlive the worker.
  bool start(const Store& store, uint64_t vertex_budget_bytes, int device, uint32_t max_queue,
             std::function<void()> notify, std::string& error);

  enum class Submitted { queued, replaced, busy };
  // Queues a job. replaced: a waiting job of the same client was dropped (its ticket in
  // `dropped`); busy: the queue is full and nothing was queued.
  Submitted submit(RenderJob job, uint64_t& dropped);
  // The results ready so far, in the order their jobs ran.
  std::vector<RenderResult> take_results();
  size_t queue_depth() const;
  bool idle() const;  // nothing queued, running or waiting to be taken
  // Lets queued jobs finish, then ends the thread. Results not yet taken stay to be taken.
  void stop();
  // Set by a successful start(), then constant.
  const std::string& device_description() const { return device_; }
  uint64_t vertex_budget_bytes() const { return budget_; }

 private:
  void run(const Store* store, int device, std::string* error, bool* ready);

  mutable std::mutex mutex_;
  std::condition_variable wake_, started_;
  std::deque<RenderJob> queue_;         // guarded by mutex_
  std::vector<RenderResult> done_;      // guarded by mutex_
  bool running_job_ = false;            // guarded by mutex_
  bool stopping_ = false;               // guarded by mutex_
  uint32_t max_queue_ = 64;             // set before the thread starts
  uint64_t budget_ = 0;                 // set before the thread starts
  std::string device_;                  // written by the thread before start() returns
  std::function<void()> notify_;        // set before the thread starts
  std::thread thread_;
};

// Runs one job on the renderer (the render thread): the renderer's options take the job's LOD
// policy and pixel error. Frames come back with needs_encoding and the pixels.
RenderResult execute_job(const RenderJob& job, Renderer& renderer);

}  // namespace plantview::service
