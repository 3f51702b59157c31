// The render threads of the service: N renderers, each on a thread of its own with its own EGL
// context, Renderer and vertex arena, taking frame, statistics and pick jobs from one queue.
//
// Renderers
//   - Each render thread makes its GpuContext and Renderer and uses them alone (a GL context is
//     current on one thread; render.h). They share the Store, but each Renderer reads it through
//     a read view of its own: a view is an LMDB read transaction, which belongs to the thread
//     that began it, so N threads cannot share one. The views are snapshots of the same commit
//     unless an import commits between two renderers' start.
//   - Memory: every renderer has its own vertex arena of vertex_budget_bytes and its own cache of
//     decoded objects, so N renderers hold up to N times one renderer's memory (on a software
//     renderer the "GPU" arena is system memory).
//   - How many (renderers = 0, automatic): on hardware, one per EGL device (the first device
//     that works, then each later device that opens as hardware); on a software renderer
//     (llvmpipe) default_software_renderers(cores): 2, and one per 16 cores on larger machines.
//     llvmpipe rasterises each context with LP_NUM_THREADS threads; unless the environment
//     sets it, start() sets it to the number of cores (at most 16, Mesa's limit) before the
//     first context, so that a lone client's frame uses every core and two renderers overlap
//     one's serial work (cull, choose, stream) with the other's rasterising. Measured on 2
//     cores: render_worker.cpp, default_software_renderers.
//
// Scheduling (one queue for all renderers)
//   - Round-robin across clients: each client (job.client) has a line of waiting jobs; the next
//     job is the first of the first line, and a client whose job is taken goes to the back. A
//     client with one request waiting is served after at most one job of every other client.
//   - Latest wins: a job whose client and kind match a waiting one replaces it in its place (the
//     older one's ticket is returned, to be answered 409). A running job is never replaced.
//   - At most max_queue jobs wait; beyond that submit() refuses (busy).
//   - Degradation: when a renderer takes a job, the requests that want a renderer (those
//     waiting, those running on the other renderers, and this one) are compared with the number
//     of renderers, and choose_degradation() says how much cheaper an interactive frame is
//     rendered. Stills, statistics and picks are never degraded. The frame's X-Plantview-*
//     headers say what was used.
//
// Threads
//   - start(), submit(), take_results(), queue_depth(), idle() and stop() are called by one
//     owning thread (the server's loop thread; a test's thread). They lock a mutex, briefly:
//     never while a job renders.
//   - `notify` (given to start) is called on a render thread each time a result is ready; it
//     must not block for long and must be safe from any thread (the server passes
//     uv_async_send).
// Picks read their object from the snapshot of the renderer that drew them: the commit the
// frame was drawn from.
// Following imports: each renderer moves to the store's newest commit between jobs, never within
// one: before every job it compares Store::last_commit() with its view's commit (no read, no
// lock), and an idle one looks every kFollowIntervalMs, so that no renderer holds an old read
// transaction (LMDB keeps every page a reader's snapshot uses: the file would grow with each
// import). On a change it refresh()es: a new snapshot, and what it decoded and made resident
// forgotten (slots of re-imported objects change). A refresh that fails (the new commit cannot
// be read) keeps the old snapshot, says so on stderr, and is tried again at the next commit.
// Every result carries X-Plantview-Revision: the revision (StoreInfo::revision) of the snapshot
// the job read.
// View filters: each job sets its renderer's section, style and highlight ids (RenderOptions)
// from the job's own, so nothing of one job's view carries over to the next. Highlight words
// are resolved through the renderer's read view (object_words.h), the snapshot it draws.
// Errors: start() fails with a message when the first GPU context or renderer cannot be made,
// or one of an explicit number of renderers cannot. A job fails with the renderer's message:
// 404 when a highlight word names no object; 400 when the renderer refuses the job's view
// filters (is_view_filter_error: its message starts with the filter's name, e.g. "colour_by
// 'Foo': ... keys: ..."); 422 when the store cannot draw a change range (is_change_range_error:
// a revision pruned, never made, or not the snapshot's); 500 otherwise.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>
#include <vector>

#include "plantview/render.h"
#include "plantview/store.h"
#include "server/render_job.h"

namespace plantview::service {

struct RenderWorkerOptions {
  uint64_t vertex_budget_bytes = 512ull << 20;  // per renderer
  int device = -1;         // EGL device, as GpuContext::create takes it; < 0: automatic
  uint32_t renderers = 0;  // render threads; 0: automatic (see the rules above)
  uint32_t max_queue = 64; // jobs waiting at most
};

// Whether a renderer's error message is about the caller's view filters (a bad request, not a
// failure of the server): it starts with the name of one of them, as an option or a parameter:
// colour_by, "colour by", --colour-by, hide, only, style, section, clip, box, caps (or their --
// forms). The renderer's messages for a bad style or section must start so.
bool is_view_filter_error(std::string_view message);
// Whether a renderer's error message is a change range the store cannot draw: it starts with
// "changes " (render/src/change_set.h: ChangeSet::load).
bool is_change_range_error(std::string_view message);

// Renderers on a software renderer when the number is automatic, for `cores` cores (measured on
// llvmpipe with bench_service: see render_worker.cpp).
uint32_t default_software_renderers(uint32_t cores);

// How much cheaper an interactive frame is rendered when `demand` requests want one of
// `renderers` renderers (demand counts the job itself). The ladder, by pressure = demand /
// renderers:
//   <= 1: nothing                                          X-Plantview-Degraded: none
//   <= 3: pixel error x4                                                     pixel-error
//   <= 6: pixel error x4, half the width and height                          pixel-error,resolution
//   >  6: pixel error x4, a quarter of the width and height                  pixel-error,resolution
// Stills, statistics and picks: nothing, whatever the demand. The pixel error counts pixels of
// the image rendered, so a smaller image also draws coarser levels: on llvmpipe, where a frame
// costs by its triangles more than by its pixels, that is most of what the smaller size saves.
// The ladder was set by bench_service (README, "Serving under load").
Degradation choose_degradation(const RenderJob& job, size_t demand, size_t renderers);

// Degradation lifts a rung a frame (issue 43: the frame in which it lifted at once streamed
// every finer level in one go, up to 5.5x a loaded frame). The rungs, heaviest last:
//   0 nothing, 1 pixel error x2 (on the way back only), 2 pixel error x4, 3 and half the size,
//   4 and a quarter of the size.
// A client's interactive frame gets the rung choose_degradation() says, or where that is
// lighter than its frame before (`last_rung`), the rung below that one; `last_rung` is then
// the rung given. Heavier rungs are taken at once (load comes suddenly, and waits cost more).
uint8_t degradation_rung(const Degradation& d);
Degradation step_degradation(const Degradation& chosen, uint8_t& last_rung);

// The vertices an interactive frame streams into its renderer's arena, about at most
// (RenderOptions::stream_budget_vertices): the rest of what its levels need comes in the
// frames after (progressive refinement). Stills stream everything. Measured with bench_service
// (README, "Under load").
constexpr uint64_t kInteractiveStreamBudgetVertices = 1u << 17;

// The JPEG quality of a degraded interactive frame at most (as the remote-rendering views of
// vtk.js and trame use while the user interacts).
constexpr int kDegradedJpegQuality = 60;

// How often an idle renderer looks for a new commit (milliseconds): a revision is served within
// this of its commit, and an old snapshot let go.
constexpr int kFollowIntervalMs = 100;

class RenderWorker {
 public:
  RenderWorker();
  ~RenderWorker();  // stop()
  RenderWorker(const RenderWorker&) = delete;
  RenderWorker& operator=(const RenderWorker&) = delete;

  // Starts the render threads and waits until their contexts and renderers exist (or the first
  // failed: false, error). `store` must outlive the worker.
  bool start(const Store& store, const RenderWorkerOptions& options, std::function<void()> notify,
             std::string& error);

  enum class Submitted { queued, replaced, busy };
  // Queues a job (job.client not empty). replaced: a waiting job of the same client and kind
  // was dropped (its ticket in `dropped`); busy: the queue is full and nothing was queued.
  Submitted submit(RenderJob job, uint64_t& dropped);
  // The results ready so far, in the order they finished.
  std::vector<RenderResult> take_results();
  size_t queue_depth() const;  // jobs waiting (not running)
  bool idle() const;           // nothing queued, running or waiting to be taken
  // Lets queued jobs finish, then ends the threads. Results not yet taken stay to be taken.
  void stop();
  // Set by a successful start(), then constant.
  size_t renderers() const { return threads_.size(); }
  // One line: the renderers and the device(s) they render on.
  const std::string& device_description() const { return device_; }
  uint64_t vertex_budget_bytes() const { return budget_; }  // per renderer

 private:
  struct Thread;
  struct ClientLine {
    std::string client;
    std::deque<RenderJob> jobs;  // at most one of each kind
  };
  bool start_thread(const Store& store, int device, std::string& description, std::string& error);
  void run(Thread* thread, const Store* store);

  mutable std::mutex mutex_;
  std::condition_variable wake_, started_;
  std::deque<ClientLine> lines_;        // guarded by mutex_; round-robin order
  size_t waiting_ = 0;                  // guarded by mutex_; jobs in lines_
  size_t running_ = 0;                  // guarded by mutex_
  std::vector<RenderResult> done_;      // guarded by mutex_
  bool stopping_ = false;               // guarded by mutex_
  size_t serving_ = 0;                  // guarded by mutex_; renderers taking jobs
  // The rung of each client's last interactive frame while above 0 (step_degradation), and
  // the job count when it was given: clients gone for 4096 jobs are forgotten once more than
  // 1024 are remembered. Guarded by mutex_.
  struct Rung {
    uint8_t rung = 0;
    uint64_t taken = 0;
  };
  std::unordered_map<std::string, Rung> rungs_;
  uint64_t taken_ = 0;                  // guarded by mutex_; jobs taken
  uint32_t max_queue_ = 64;             // set before the threads start
  uint64_t budget_ = 0;                 // set before the threads start
  std::string device_;                  // set by start()
  std::function<void()> notify_;        // set before the threads start
  std::vector<std::unique_ptr<Thread>> threads_;  // the owning thread's
};

// Runs one job on a renderer (its render thread) as `degradation` says: the renderer's options
// take the job's LOD policy and pixel error. `waiting`: the jobs that waited when it was taken
// (X-Plantview-Queue). Frames come back with needs_encoding and the pixels.
RenderResult execute_job(const RenderJob& job, const Degradation& degradation, size_t waiting,
                         Renderer& renderer);

}  // namespace plantview::service
