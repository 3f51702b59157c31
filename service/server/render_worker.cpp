// Rules: render_worker.h.
#include "server/render_worker.h"

#include <cstdio>

#include "server/objects_json.h"

namespace plantview::service {

RenderWorker::~RenderWorker() { stop(); }

bool RenderWorker::start(const Store& store, uint64_t vertex_budget_bytes, int device,
                         uint32_t max_queue, std::function<void()> notify, std::string& error) {
  max_queue_ = max_queue;
  budget_ = vertex_budget_bytes;
  notify_ = std::move(notify);
  bool ready = false;
  std::string thread_error;
  thread_ = std::thread(&RenderWorker::run, this, &store, device, &thread_error, &ready);
  std::unique_lock lock(mutex_);
  started_.wait(lock, [&] { return ready; });
  if (!thread_error.empty()) {
    lock.unlock();
    thread_.join();
    error = thread_error;
    return false;
  }
  return true;
}

RenderWorker::Submitted RenderWorker::submit(RenderJob job, uint64_t& dropped) {
  std::lock_guard lock(mutex_);
  for (auto it = queue_.begin(); it != queue_.end(); ++it) {
    if (it->client == job.client) {
      dropped = it->ticket;
      *it = std::move(job);  // the newest takes the older one's place in line
      wake_.notify_one();
      return Submitted::replaced;
    }
  }
  if (queue_.size() >= max_queue_) return Submitted::busy;
  queue_.push_back(std::move(job));
  wake_.notify_one();
  return Submitted::queued;
}

std::vector<RenderResult> RenderWorker::take_results() {
  std::vector<RenderResult> results;
  std::lock_guard lock(mutex_);
  results.swap(done_);
  return results;
}

size_t RenderWorker::queue_depth() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

bool RenderWorker::idle() const {
  std::lock_guard lock(mutex_);
  return queue_.empty() && !running_job_ && done_.empty();
}

void RenderWorker::stop() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void RenderWorker::run(const Store* store, int device, std::string* error, bool* ready) {
  std::string why;
  auto context = GpuContext::create(device, why);
  std::unique_ptr<Renderer> renderer;
  if (context) {
    RenderOptions options;
    options.vertex_budget_bytes = budget_;
    renderer = Renderer::create(*store, options, why);
  }
  {
    std::lock_guard lock(mutex_);
    if (!renderer) *error = why;
    else device_ = context->description();
    *ready = true;
  }
  started_.notify_all();
  if (!renderer) return;

  for (;;) {
    RenderJob job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) break;  // stopping, and every queued job has been answered
      job = std::move(queue_.front());
      queue_.pop_front();
      running_job_ = true;
    }
    RenderResult result = execute_job(job, *renderer);
    {
      std::lock_guard lock(mutex_);
      done_.push_back(std::move(result));
      running_job_ = false;
    }
    notify_();
  }
  renderer.reset();
  context.reset();
}

RenderResult execute_job(const RenderJob& job, Renderer& renderer) {
  RenderResult r;
  r.ticket = job.ticket;
  RenderOptions options = renderer.options();
  options.lod_policy = job.policy;
  options.pixel_error = job.pixel_error;
  renderer.set_options(options);
  std::string error;
  Image image;
  const bool ok = job.kind == RenderJob::Kind::stats
                      ? renderer.statistics(job.camera, job.width, job.height, r.stats, error)
                      : renderer.render(job.camera, job.width, job.height,
                                        job.kind == RenderJob::Kind::pick, image, r.stats, error);
  if (!ok) {
    r.status = 500;
    r.content_type = "application/json";
    r.body = error_body(error);
    return r;
  }
  r.rendered = true;
  switch (job.kind) {
    case RenderJob::Kind::stats:
      r.content_type = "application/json";
      r.body = r.stats.to_json() + "\n";
      break;
    case RenderJob::Kind::pick: {
      const uint64_t id = image.object_ids[size_t(job.y) * job.width + job.x];
      r.content_type = "application/json";
      if (id == 0) {
        r.body = "{\"object\":null}\n";
        break;
      }
      std::string json;
      if (!object_json(renderer.read_view(), id, json, error)) {
        // Picked, but not an object of the store (a merged pipeline run has its pipeline's id,
        // which is one): report the id alone.
        json = "{\"id\":\"" + std::to_string(id) + "\"}";
      }
      r.body = "{\"object\":" + json + "}\n";
      break;
    }
    case RenderJob::Kind::frame:
      r.needs_encoding = true;
      r.image = std::move(image);
      r.format = job.format;
      r.quality = job.quality;
      r.content_type = job.format == ImageFormat::png ? "image/png" : "image/jpeg";
      break;
  }
  char ms[32];
  std::snprintf(ms, sizeof ms, "%.1f", r.stats.ms.total);
  r.headers = {{"X-Triangles", std::to_string(r.stats.triangles)},
               {"X-Objects-Visible", std::to_string(r.stats.objects_visible)},
               {"X-Arena-Bytes", std::to_string(r.stats.arena_bytes_resident)},
               {"X-Arena-Budget-Bytes", std::to_string(r.stats.arena_bytes_budget)},
               {"X-Hlod-Merges", std::to_string(r.stats.hlod_merges)},
               {"X-Frame-Ms", ms}};
  return r;
}

}  // namespace plantview::service
