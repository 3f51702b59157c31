// Rules: render_worker.h.
#include "server/render_worker.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "server/object_words.h"
#include "plantview/measure.h"
#include "server/objects_json.h"

namespace plantview::service {

namespace {

// ',"point_m":[x,y,z],"normal":[x,y,z]': where the pixel's ray meets the picked object's
// surface (its finest tessellation; a section's cut face where it shows the cut), or "" when
// the id is no object with primitives (a merged pipeline run) or the ray misses them (a
// silhouette pixel of a coarser level drawn).
std::string pick_point_json(const ReadView& view, uint64_t id, const RenderJob& job, uint32_t width,
                            uint32_t height, const Section& section) {
  std::optional<uint32_t> slot;
  std::string error;
  Object object;
  if (!view.slot_of(id, slot, error) || !slot || !view.object(*slot, object, false, error)) return "";
  const auto hit = cast_ray(object, pixel_ray(job.camera, width, height, job.x, job.y), &section);
  if (!hit) return "";
  char buf[256];
  std::snprintf(buf, sizeof buf, ",\"point_m\":[%.6f,%.6f,%.6f],\"normal\":[%.6f,%.6f,%.6f]", hit->point_m.x,
                hit->point_m.y, hit->point_m.z, hit->normal.x, hit->normal.y, hit->normal.z);
  return buf;
}

// llvmpipe's most rasteriser threads per context (Mesa's LP_MAX_THREADS).
constexpr uint32_t kMaxRasteriserThreads = 16;

// A GpuContext description names a software renderer: an EGL software device, Mesa's
// surfaceless platform (llvmpipe), or llvmpipe/softpipe through any other path.
bool is_software(std::string_view description) {
  return description.find("(software)") != std::string_view::npos ||
         description.rfind("Mesa surfaceless", 0) == 0 ||
         description.find("llvmpipe") != std::string_view::npos ||
         description.find("softpipe") != std::string_view::npos;
}

// The EGL device index in "EGL device 3 (...)", or -1.
int device_index_of(std::string_view description) {
  constexpr std::string_view prefix = "EGL device ";
  if (description.rfind(prefix, 0) != 0) return -1;
  int index = 0;
  size_t i = prefix.size();
  if (i >= description.size() || description[i] < '0' || description[i] > '9') return -1;
  for (; i < description.size() && description[i] >= '0' && description[i] <= '9'; ++i)
    index = index * 10 + (description[i] - '0');
  return index;
}

std::string format_ms(double ms) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", ms);
  return text;
}

std::string format_number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

}  // namespace

bool is_change_range_error(std::string_view message) {
  return message.substr(0, 8) == "changes ";
}

bool is_view_filter_error(std::string_view message) {
  static constexpr std::string_view kPrefixes[] = {"colour_by", "colour by", "--colour-by", "hide",
                                                   "only", "style", "section", "clip", "box",
                                                   "caps", "--clip", "--box", "--hide", "--only"};
  for (const std::string_view prefix : kPrefixes)
    if (message.substr(0, prefix.size()) == prefix) return true;
  return false;
}

uint32_t default_software_renderers(uint32_t cores) {
  // Measured with bench_service on a 2-core machine (llvmpipe, preset c, 1280x720, 12 s a run,
  // other builds running): 16 interactive clients got 11.3 frames/s from one renderer with
  // LP_NUM_THREADS=2, 13.9 from two with 2 each, 21.5 from two with 1 each; but with one
  // rasteriser thread a still took twice as long, and stills among 16 clients came 19x the
  // single-client still time (goal: 10x) against 4.7x and 5.8x with two threads. Two renderers
  // whose rasterisers each may use every core let one draw while the other culls, streams
  // and hands its pixels to the encoder, and a lone client still gets every core. Mesa runs at
  // most 16 rasteriser threads a context, so larger machines get a renderer per 16 cores.
  if (cores < 2) return 1;
  return std::max(2u, cores / kMaxRasteriserThreads);
}

Degradation choose_degradation(const RenderJob& job, size_t demand, size_t renderers) {
  Degradation d;
  if (job.kind != RenderJob::Kind::frame || job.mode != FrameMode::interactive) return d;
  renderers = std::max<size_t>(renderers, 1);
  if (demand <= renderers) return d;       // pressure <= 1
  d.pixel_error_factor = 4;
  if (demand <= 3 * renderers) return d;   // pressure <= 3
  d.size_divisor = demand <= 6 * renderers ? 2 : 4;
  return d;
}

uint8_t degradation_rung(const Degradation& d) {
  if (d.size_divisor >= 4) return 4;
  if (d.size_divisor >= 2) return 3;
  if (d.pixel_error_factor >= 4) return 2;
  return d.pixel_error_factor > 1 ? 1 : 0;
}

Degradation step_degradation(const Degradation& chosen, uint8_t& last_rung) {
  const uint8_t wanted = degradation_rung(chosen);
  if (wanted + 1 >= last_rung) {
    last_rung = wanted;
    return chosen;
  }
  last_rung = uint8_t(last_rung - 1);
  static constexpr Degradation kRungs[] = {{1, 1}, {2, 1}, {4, 1}, {4, 2}, {4, 4}};
  return kRungs[last_rung];
}

struct RenderWorker::Thread {
  std::thread thread;
  int device = -1;
  // Written by the thread before it says ready (under the worker's mutex), then constant.
  bool ready = false, ok = false;
  std::string description, error;
};

RenderWorker::RenderWorker() = default;
RenderWorker::~RenderWorker() { stop(); }

bool RenderWorker::start_thread(const Store& store, int device, std::string& description,
                                std::string& error) {
  auto t = std::make_unique<Thread>();
  t->device = device;
  Thread* raw = t.get();
  raw->thread = std::thread(&RenderWorker::run, this, raw, &store);
  std::unique_lock lock(mutex_);
  started_.wait(lock, [&] { return raw->ready; });
  const bool ok = raw->ok;
  description = raw->description;
  error = raw->error;
  lock.unlock();
  if (!ok) {
    raw->thread.join();
    return false;
  }
  threads_.push_back(std::move(t));
  return true;
}

bool RenderWorker::start(const Store& store, const RenderWorkerOptions& options,
                         std::function<void()> notify, std::string& error) {
  max_queue_ = options.max_queue;
  budget_ = options.vertex_budget_bytes;
  notify_ = std::move(notify);
  const uint32_t cores = std::max(1u, std::thread::hardware_concurrency());
  // Before the first context: llvmpipe reads it when its screen is made. Unused on hardware.
  if (!std::getenv("LP_NUM_THREADS"))
    setenv("LP_NUM_THREADS", std::to_string(std::min(cores, kMaxRasteriserThreads)).c_str(), 1);

  std::string first;
  if (!start_thread(store, options.device, first, error)) return false;
  std::vector<std::string> descriptions = {first};
  const bool software = is_software(first);
  if (options.renderers > 0) {
    // As many as asked for, all on the first one's device.
    const int device = options.device >= 0 ? options.device : device_index_of(first);
    for (uint32_t i = 1; i < options.renderers; ++i) {
      std::string description;
      if (!start_thread(store, device, description, error)) {
        error = "renderer " + std::to_string(i + 1) + " of " + std::to_string(options.renderers) + ": " + error;
        stop();
        return false;
      }
      descriptions.push_back(description);
    }
  } else if (software) {
    const uint32_t n = default_software_renderers(cores);
    const int device = options.device >= 0 ? options.device : device_index_of(first);
    for (uint32_t i = 1; i < n; ++i) {
      std::string description, why;
      if (!start_thread(store, device, description, why)) break;  // fewer, then
      descriptions.push_back(description);
    }
  } else if (options.device < 0) {
    // One per hardware device: those after the first that opened, until one does not open
    // (the end of EGL's list) or is a software one.
    for (int device = device_index_of(first) + 1; device > 0; ++device) {
      std::string description, why;
      if (!start_thread(store, device, description, why)) break;
      if (is_software(description)) {
        Thread& extra = *threads_.back();
        {
          std::lock_guard lock(mutex_);
          extra.ok = false;  // leaves its loop at once (it has no job yet)
        }
        wake_.notify_all();
        extra.thread.join();
        threads_.pop_back();
        break;
      }
      descriptions.push_back(description);
    }
  }
  {
    std::lock_guard lock(mutex_);
    serving_ = threads_.size();
  }
  const bool same = std::all_of(descriptions.begin(), descriptions.end(),
                                [&](const std::string& d) { return d == first; });
  device_ = std::to_string(threads_.size()) + (threads_.size() == 1 ? " renderer" : " renderers");
  if (same) {
    device_ += " on " + first;
  } else {
    for (size_t i = 0; i < descriptions.size(); ++i) device_ += (i ? "; " : ": ") + descriptions[i];
  }
  if (software) device_ += std::string(", LP_NUM_THREADS=") + std::getenv("LP_NUM_THREADS");
  return true;
}

RenderWorker::Submitted RenderWorker::submit(RenderJob job, uint64_t& dropped) {
  std::lock_guard lock(mutex_);
  ClientLine* line = nullptr;
  for (ClientLine& l : lines_) {
    if (l.client != job.client) continue;
    line = &l;
    for (RenderJob& waiting : l.jobs) {
      if (waiting.kind != job.kind) continue;
      dropped = waiting.ticket;
      waiting = std::move(job);  // the newest takes the older one's place in line
      return Submitted::replaced;
    }
    break;
  }
  if (waiting_ >= max_queue_) return Submitted::busy;
  if (!line) line = &lines_.emplace_back(ClientLine{job.client, {}});
  line->jobs.push_back(std::move(job));
  ++waiting_;
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
  return waiting_;
}

bool RenderWorker::idle() const {
  std::lock_guard lock(mutex_);
  return waiting_ == 0 && running_ == 0 && done_.empty();
}

void RenderWorker::stop() {
  if (threads_.empty()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (auto& t : threads_) t->thread.join();
  threads_.clear();
}

void RenderWorker::run(Thread* self, const Store* store) {
  std::string why;
  auto context = GpuContext::create(self->device, why);
  std::unique_ptr<Renderer> renderer;
  if (context) {
    RenderOptions options;
    options.vertex_budget_bytes = budget_;
    renderer = Renderer::create(*store, options, why);
  }
  {
    std::lock_guard lock(mutex_);
    self->ok = renderer != nullptr;
    if (renderer) self->description = context->description();
    else self->error = why;
    self->ready = true;
  }
  started_.notify_all();
  if (!renderer) return;

  // Following imports (render_worker.h): the commit last looked at, and the revision drawn.
  uint64_t seen_commit = renderer->read_view().commit();
  uint32_t revision = renderer->read_view().info().revision;
  const auto follow = [&] {
    const uint64_t newest = store->last_commit();
    if (newest == seen_commit) return;
    std::string refresh_error;
    if (renderer->refresh(refresh_error)) {
      seen_commit = renderer->read_view().commit();  // a commit since makes the next look move again
      revision = renderer->read_view().info().revision;
    } else {
      seen_commit = newest;  // not tried again until the next commit
      std::fprintf(stderr, "plantview serve: a renderer keeps revision %u: %s\n", revision,
                   refresh_error.c_str());
    }
  };

  for (;;) {
    RenderJob job;
    Degradation degradation;
    size_t waiting = 0;
    {
      std::unique_lock lock(mutex_);
      if (!wake_.wait_for(lock, kFollowIntervalMs * std::chrono::milliseconds(1),
                          [&] { return stopping_ || !self->ok || waiting_ > 0; })) {
        lock.unlock();
        follow();  // idle: let go of an old snapshot promptly
        continue;
      }
      if (!self->ok || waiting_ == 0) break;  // dismissed, or stopping with every queued job answered
      // Round-robin: the first client's first job; the client goes to the back of the line.
      ClientLine line = std::move(lines_.front());
      lines_.pop_front();
      job = std::move(line.jobs.front());
      line.jobs.pop_front();
      if (!line.jobs.empty()) lines_.push_back(std::move(line));
      --waiting_;
      waiting = waiting_;
      degradation = choose_degradation(job, waiting_ + running_ + 1, std::max<size_t>(serving_, 1));
      ++taken_;
      if (job.kind == RenderJob::Kind::frame) {
        if (job.mode == FrameMode::still) {
          rungs_.erase(job.client);  // drawn whole: the next frame starts from there
        } else if (const auto it = rungs_.find(job.client); it != rungs_.end() || degradation.any()) {
          Rung& r = it != rungs_.end() ? it->second : rungs_[job.client];
          degradation = step_degradation(degradation, r.rung);
          r.taken = taken_;
          if (r.rung == 0) rungs_.erase(job.client);
          if (rungs_.size() > 1024)
            std::erase_if(rungs_, [&](const auto& entry) { return entry.second.taken + 4096 < taken_; });
        }
      }
      ++running_;
    }
    follow();  // between frames, never within one
    RenderResult result = execute_job(job, degradation, waiting, *renderer);
    result.headers.emplace_back("X-Plantview-Revision", std::to_string(revision));
    {
      std::lock_guard lock(mutex_);
      done_.push_back(std::move(result));
      --running_;
    }
    notify_();
  }
  renderer.reset();
  context.reset();
}

RenderResult execute_job(const RenderJob& job, const Degradation& degradation, size_t waiting,
                         Renderer& renderer) {
  RenderResult r;
  r.ticket = job.ticket;
  const uint32_t width = std::max(1u, job.width / degradation.size_divisor);
  const uint32_t height = std::max(1u, job.height / degradation.size_divisor);
  const double pixel_error = job.pixel_error * degradation.pixel_error_factor;
  RenderOptions options = renderer.options();
  options.lod_policy = job.policy;
  options.pixel_error = pixel_error;
  // Interactive frames refine progressively (a bounded streaming budget); stills, statistics
  // and picks stream all their levels.
  options.stream_budget_vertices = job.kind == RenderJob::Kind::frame && job.mode == FrameMode::interactive
                                       ? kInteractiveStreamBudgetVertices
                                       : 0;
  // Stills look like review images (antialiased, ambient occlusion); interactive frames, and the
  // stats and pick renders that show no image, skip both: they cost 1.5 x and 1.2 x on llvmpipe.
  const bool still = job.kind == RenderJob::Kind::frame && job.mode == FrameMode::still;
  options.antialias = still;
  options.ambient_occlusion = still;
  options.section = job.section;
  options.style = job.style;
  options.highlight_ids.clear();
  options.changes = job.changes;
  std::string error;
  r.headers.emplace_back("X-Plantview-Client", job.client_id);
  bool unknown = false;
  if (!ids_of_words(renderer.read_view(), job.highlight, "'highlight'", options.highlight_ids, error, unknown)) {
    r.status = unknown ? 404 : 500;
    r.content_type = "application/json";
    r.body = error_body(error);
    return r;
  }
  renderer.set_options(options);
  Image image;
  const bool ok = job.kind == RenderJob::Kind::stats
                      ? renderer.statistics(job.camera, width, height, r.stats, error)
                      : renderer.render(job.camera, width, height, job.kind == RenderJob::Kind::pick,
                                        image, r.stats, error);
  if (!ok) {
    // A change range the store cannot draw (pruned, never made, not its revision): 422.
    r.status = is_view_filter_error(error) ? 400 : is_change_range_error(error) ? 422 : 500;
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
      const uint64_t id = image.object_ids[size_t(job.y) * width + job.x];
      r.content_type = "application/json";
      if (id == 0) {
        r.body = "{\"object\":null}\n";
        break;
      }
      std::string json;
      if (!object_json(renderer.read_view(), id, json, error) &&
          !(options.changes && object_at_json(renderer.read_view(), options.changes->from, id, json, error))) {
        // Picked, but not an object of the store (a merged pipeline run has its pipeline's id,
        // which is one; a change image's removed object is answered as it was): the id alone.
        json = "{\"id\":\"" + std::to_string(id) + "\"}";
      }
      r.body = "{\"object\":" + json +
               pick_point_json(renderer.read_view(), id, job, width, height, options.section) + "}\n";
      break;
    }
    case RenderJob::Kind::frame: {
      r.needs_encoding = true;
      r.image = std::move(image);
      r.format = job.format;
      r.quality = degradation.any() ? std::min(job.quality, kDegradedJpegQuality) : job.quality;
      r.content_type = job.format == ImageFormat::png ? "image/png" : "image/jpeg";
      const char* degraded = degradation.size_divisor != 1 ? "pixel-error,resolution"
                             : degradation.pixel_error_factor != 1 ? "pixel-error"
                                                                    : "none";
      r.headers.insert(r.headers.end(),
                       {{"X-Plantview-Mode", job.mode == FrameMode::still ? "still" : "interactive"},
                        {"X-Plantview-Degraded", degraded},
                        {"X-Plantview-Pixel-Error", format_number(pixel_error)},
                        {"X-Plantview-Render-Size", std::to_string(width) + "x" + std::to_string(height)},
                        {"X-Plantview-Jpeg-Quality", std::to_string(r.quality)},
                        {"X-Plantview-Queue", std::to_string(waiting)},
                        {"X-Plantview-Render-Ms", format_ms(r.stats.ms.total)}});
      // Coloured by an attribute: the frame's legend (FrameLegend::to_json, one line).
      if (!r.stats.legend.key.empty())
        r.headers.emplace_back("X-Plantview-Legend", r.stats.legend.to_json());
      // A change image: its caption (the range and its counts).
      if (r.stats.changes.shown)
        r.headers.emplace_back("X-Plantview-Changes", change_caption(r.stats.changes));
      break;
    }
  }
  r.headers.insert(r.headers.end(),
                   {{"X-Triangles", std::to_string(r.stats.triangles)},
                    {"X-Objects-Visible", std::to_string(r.stats.objects_visible)},
                    {"X-Arena-Bytes", std::to_string(r.stats.arena_bytes_resident)},
                    {"X-Arena-Budget-Bytes", std::to_string(r.stats.arena_bytes_budget)},
                    {"X-Hlod-Merges", std::to_string(r.stats.hlod_merges)},
                    {"X-Frame-Ms", format_ms(r.stats.ms.total)}});
  return r;
}

}  // namespace plantview::service
