// The render thread of the service: owns the EGL context and the renderer, runs frame,
// statistics and pick jobs one at a time, and hands results back to the libuv loop.
// Threads: submit(), queue_depth() and stop() are called on the loop thread; results are
// delivered on the loop thread (through a uv_async handle) to the callback given to start().
#pragma once

#include <uv.h>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "plantview/render.h"
#include "plantview/store.h"
#include "server/http.h"

namespace plantview::service {

struct RenderJob {
  enum class Kind { frame, stats, pick } kind = Kind::frame;
  Camera camera;
  uint32_t width = 0, height = 0;
  ImageFormat format = ImageFormat::jpeg;
  int quality = 85;
  LodPolicy policy = LodPolicy::screen_space;
  double pixel_error = 1.0;
  uint32_t x = 0, y = 0;    // pick
  std::string client;       // latest-wins key
  uint64_t ticket = 0;      // the response it answers
};

struct RenderResult {
  uint64_t ticket = 0;
  int status = 200;
  std::string content_type;
  std::string body;
  Fields headers;
  bool rendered = false;    // stats below are meaningful
  FrameStats stats;
  // Frames: the pixels, encoded off the render thread (on libuv's pool) so that the next
  // frame renders while this one encodes. body is empty until then.
  bool needs_encoding = false;
  Image image;
  ImageFormat format = ImageFormat::jpeg;
  int quality = 85;
};

class RenderWorker {
 public:
  RenderWorker() = default;
  ~RenderWorker();
  RenderWorker(const RenderWorker&) = delete;
  RenderWorker& operator=(const RenderWorker&) = delete;

  // Starts the thread and waits until its context and renderer exist (or failed: error).
  bool start(const Store& store, uint64_t vertex_budget_bytes, int device, uint32_t max_queue,
             uv_loop_t* loop, std::function<void(RenderResult&&)> on_done, std::string& error);

  enum class Submitted { queued, replaced, busy };
  // Queues a job. replaced: a waiting job of the same client was dropped (its ticket in
  // `dropped`); busy: the queue is full and nothing was queued.
  Submitted submit(RenderJob job, uint64_t& dropped);
  size_t queue_depth() const;
  bool idle() const;  // nothing queued or running
  // Lets queued jobs finish, then ends the thread and closes the async handle.
  void stop();
  const std::string& device_description() const { return device_; }
  uint64_t vertex_budget_bytes() const { return budget_; }

 private:
  void run(const Store* store, int device, std::string* error, bool* ready);
  RenderResult execute(const RenderJob& job, Renderer& renderer, const Store& store);

  mutable std::mutex mutex_;
  std::condition_variable wake_, started_;
  std::deque<RenderJob> queue_;
  std::vector<RenderResult> done_;
  bool running_job_ = false, stopping_ = false;
  uint32_t max_queue_ = 64;
  uint64_t budget_ = 0;
  std::string device_;
  std::thread thread_;
  uv_async_t* async_ = nullptr;
  std::function<void(RenderResult&&)> on_done_;
};

}  // namespace plantview::service
