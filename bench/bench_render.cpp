// Rendering: the LOD policies side by side along a walkthrough, the out-of-core run under a
// small vertex budget, and the time to the first image.
//
// Usage: bench_render [--quick] [--preset P] [--scale K] [--frames N] [--size WxH]
//                     [--vertex-budget MB] [--store DIR] [--out-of-core] [--samples S]
//                     [--interior N] [--pixel-error PX] [--extra-pixel-error PX]...
//                     [--occlusion-test automatic|coarse|exact] [--no-images]
//   default        preset c, 1280x720, 4 samples (antialiased stills), a 100-view walkthrough
//                  then 12 views from inside the plant; policies none, distance and
//                  screen-space (--pixel-error, 1 px), each with occlusion off and on (and
//                  screen-space at each --extra-pixel-error with it on), render every view in
//                  turn, each with its own renderer (and arena) in this one process. Per run:
//                  triangles (walkthrough, interior), mean and 95th-percentile frame and CPU
//                  time, occlusion culling time, vertex data uploaded per frame, PSNR against
//                  none without occlusion, and occlusion's id-buffer check
//                  against the same policy without it. --occlusion-test: how the runs with
//                  occlusion test what its first phase did not draw (render.h; default
//                  automatic: coarse on llvmpipe, exact on a GPU).
//   --out-of-core  a --store DIR (or a generated --scale K plant, default 100), as `plantview
//                  render` would show it: the time from Store::open to the overview's PNG
//                  written (open + first read, then renderer and overview frame), the
//                  overview's triangles and node boxes; then one renderer (screen-space) with
//                  --vertex-budget (default 256) along a --frames walkthrough (default 10),
//                  every image written: peak resident memory of the process (walkthrough +
//                  overview, images written), arena bytes, uploads and evictions per frame,
//                  frame times, the renderer's per-object memory (blocks held, objects known).
//   --quick        preset a, 320x180, 6 + 2 views, 1 sample (the CTest smoke run).
//   --no-images    no image files written and no PSNR (both need the image module, which a
//                  machine may lack: a GPU machine lent for a timing run, scripts/device_check.sh);
//                  every frame is still rendered and read back, ids included.
// The store is generated (in a child process, so that its memory does not count) into a
// temporary directory unless --store names one. Prints tables, then "json: " lines.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

uint64_t peak_rss_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return uint64_t(usage.ru_maxrss) * 1024;
}

// Generates a plant into `dir` in a child process. Returns the seconds it took, or < 0.
double generate_store(const fs::path& dir, char preset, uint32_t scale) {
  const auto start = Clock::now();
  const pid_t child = fork();
  if (child == 0) {
    std::string error;
    auto store = Store::open(dir.string(), Store::Mode::read_write, error);
    if (!store) {
      std::fprintf(stderr, "bench_render: %s\n", error.c_str());
      _exit(1);
    }
    GenerateOptions options;
    options.preset = preset;
    options.scale = scale;
    const IngestResult result = ingest_generated(*store, options);
    if (!result) std::fprintf(stderr, "bench_render: %s\n", result.error().message.c_str());
    _exit(result ? 0 : 1);
  }
  int status = 0;
  waitpid(child, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "bench_render: generating the store failed (status %d)\n", status);
    return -1;
  }
  return seconds_since(start);
}

// The walkthrough of a store. Computed in a child process (it reads every object), so that its
// memory does not count in the out-of-core run's peak.
std::vector<Camera> walkthrough_in_child(const fs::path& store_dir, int frames);

std::vector<Camera> walkthrough(const Store& store, int frames) {
  std::vector<Camera> cameras;
  std::string error;
  if (!make_camera_path(PathKind::walkthrough, frames, store, cameras, error))
    std::fprintf(stderr, "bench_render: %s\n", error.c_str());
  return cameras;
}

std::vector<Camera> walkthrough_in_child(const fs::path& store_dir, int frames) {
  const fs::path file = fs::temp_directory_path() / ("plantview-bench-path-" + std::to_string(::getpid()) + ".json");
  const pid_t child = fork();
  if (child == 0) {
    std::string error;
    auto store = Store::open(store_dir.string(), Store::Mode::read_only, error);
    if (!store) _exit(1);
    const auto cameras = walkthrough(*store, frames);
    FILE* f = std::fopen(file.c_str(), "w");
    if (!f) _exit(1);
    const std::string json = camera_path_json(cameras);
    std::fwrite(json.data(), 1, json.size(), f);
    _exit(std::fclose(f) == 0 && !cameras.empty() ? 0 : 1);
  }
  int status = 0;
  waitpid(child, &status, 0);
  std::vector<Camera> cameras;
  std::ifstream in(file);
  const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string error;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || !parse_camera_path(json, cameras, error)) cameras.clear();
  fs::remove(file);
  return cameras;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, size_t(std::ceil(p * double(v.size()))) - 1);
  return v[i];
}

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / double(v.size());
}

struct PolicyRun {
  std::string name;
  RenderOptions options;
  size_t reference = 0;  // the run with occlusion off at the same policy (itself if off)
  std::unique_ptr<Renderer> renderer;
  std::vector<double> frame_ms, cpu_ms, ahead_ms, cpu_without_growth_ms, occlusion_ms, depth_ms, walk_triangles,
      interior_triangles, psnr, id_match, uploaded;
  FrameStats::Times cpu_parts_ms{};  // summed over the steady views (cull, occlusion, ...)
  uint64_t missing = 0, occluded = 0, occluders = 0;
  // Interior views: objects drawn, and objects seen (with a pixel in the same policy's id
  // buffer without occlusion): what exact visibility would draw.
  std::vector<double> interior_drawn, interior_seen;
  Image image;
};

// Random cameras inside the plant at eye height, looking level in random directions (seeded):
// the views where most objects are hidden behind others.
std::vector<Camera> interior_views(const DAabb& bounds, int count) {
  std::vector<Camera> cameras;
  uint64_t state = 2026;
  const auto u = [&]() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) / double(1ull << 53);
  };
  for (int i = 0; i < count; ++i) {
    Camera c;
    c.eye_m = {bounds.min.x + (0.1 + 0.8 * u()) * (bounds.max.x - bounds.min.x),
               bounds.min.y + (0.1 + 0.8 * u()) * (bounds.max.y - bounds.min.y), bounds.min.z + 1.7};
    const double a = u() * 2 * M_PI;
    c.target_m = c.eye_m + glm::dvec3(std::cos(a), std::sin(a), -0.05) * 10.0;
    cameras.push_back(c);
  }
  return cameras;
}

// Policies none, distance and screen-space, each with occlusion off and on (and screen-space
// at the extra pixel errors, occlusion on), along the walkthrough and then the interior views.
int policies(const Store& store, const std::vector<Camera>& walk, uint32_t w, uint32_t h,
             uint64_t budget_bytes, uint64_t full_triangles, uint32_t samples,
             double pixel_error, const std::vector<double>& extra_pixel_errors, int interior,
             OcclusionTest occlusion_test, bool images) {
  std::vector<PolicyRun> runs;
  for (const LodPolicy policy : {LodPolicy::none, LodPolicy::distance, LodPolicy::screen_space}) {
    for (const bool occlusion : {false, true}) {
      PolicyRun& r = runs.emplace_back();
      r.options.lod_policy = policy;
      r.options.pixel_error = pixel_error;
      r.options.occlusion = occlusion;
      r.options.occlusion_test = occlusion_test;
      char name[64];
      std::snprintf(name, sizeof name, "%s%s occl %s", std::string(lod_policy_name(policy)).c_str(),
                    policy == LodPolicy::screen_space ? (" " + std::to_string(pixel_error).substr(0, 4) + "px").c_str() : "",
                    occlusion ? "on" : "off");
      r.name = name;
      r.reference = occlusion ? runs.size() - 2 : runs.size() - 1;
    }
  }
  for (const double pe : extra_pixel_errors) {
    PolicyRun& r = runs.emplace_back();
    r.options.pixel_error = pe;
    r.options.occlusion_test = occlusion_test;
    r.name = "screen-space " + std::to_string(pe).substr(0, 4) + "px occl on";
    r.reference = runs.size() - 1;  // no id check: no run with occlusion off at this error
  }
  std::string error;
  std::vector<Camera> cameras = walk;
  Renderer* first = nullptr;
  for (auto& r : runs) {
    r.options.vertex_budget_bytes = budget_bytes;
    r.options.samples = samples;
    r.renderer = Renderer::create(store, r.options, error);
    if (!r.renderer) {
      std::fprintf(stderr, "bench_render: %s\n", error.c_str());
      return 1;
    }
    if (!first) first = r.renderer.get();
  }
  const auto inside = interior_views(first->model_bounds(), interior);
  cameras.insert(cameras.end(), inside.begin(), inside.end());
  const bool tty = isatty(2);
  for (size_t v = 0; v < cameras.size(); ++v) {
    const bool is_interior = v >= walk.size();
    for (size_t i = 0; i < runs.size(); ++i) {
      PolicyRun& r = runs[i];
      FrameStats stats;
      // The path is known: each view's start (cull, occlusion's first phase) is made while the
      // one before draws, as `plantview render --path` does.
      if (v + 1 < cameras.size()) r.renderer->expect(cameras[v + 1]);
      if (!r.renderer->render(cameras[v], w, h, true, r.image, stats, error)) {
        std::fprintf(stderr, "bench_render: view %zu, %s: %s\n", v, r.name.c_str(), error.c_str());
        return 1;
      }
      r.frame_ms.push_back(stats.ms.total);
      r.cpu_ms.push_back(stats.ms.cpu);
      r.ahead_ms.push_back(stats.ms.ahead);
      r.cpu_without_growth_ms.push_back(stats.ms.cpu - stats.ms.arena_growth);
      r.occlusion_ms.push_back(stats.ms.occlusion);
      r.depth_ms.push_back(stats.ms.depth_reduction);
      if (v > 0) {
        r.cpu_parts_ms.cull += stats.ms.cull;
        r.cpu_parts_ms.occlusion += stats.ms.occlusion;
        r.cpu_parts_ms.choose += stats.ms.choose;
        r.cpu_parts_ms.stream += stats.ms.stream;
      }
      r.occluders += stats.occluders;
      r.uploaded.push_back(double(stats.arena_bytes_uploaded));
      r.occluded += stats.objects_occluded;
      (is_interior ? r.interior_triangles : r.walk_triangles).push_back(double(stats.triangles));
      if (is_interior) r.interior_drawn.push_back(double(stats.objects_visible));
      if (i != 0 && images) {
        ImageComparison c;
        if (!compare_images(runs[0].image, r.image, c, error)) return 1;
        r.psnr.push_back(std::isinf(c.psnr_db) ? 99.0 : c.psnr_db);
      }
      if (r.reference != i) {
        // The id buffer against the same policy without occlusion, and the objects it shows
        // that this one does not.
        const auto& a = runs[r.reference].image.object_ids;
        const auto& b = r.image.object_ids;
        size_t same = 0;
        for (size_t p = 0; p < a.size(); ++p) same += a[p] == b[p];
        r.id_match.push_back(100.0 * double(same) / double(std::max<size_t>(a.size(), 1)));
        std::vector<uint64_t> ia(a.begin(), a.end()), ib(b.begin(), b.end());
        std::sort(ia.begin(), ia.end());
        ia.erase(std::unique(ia.begin(), ia.end()), ia.end());
        std::sort(ib.begin(), ib.end());
        ib.erase(std::unique(ib.begin(), ib.end()), ib.end());
        std::vector<uint64_t> lost;
        std::set_difference(ia.begin(), ia.end(), ib.begin(), ib.end(), std::back_inserter(lost));
        if (is_interior) r.interior_seen.push_back(double(ia.size() - (!ia.empty() && ia[0] == 0)));
        r.missing += lost.size();
        // Each one named, with what the frame with occlusion shows in its place (a twin whose
        // surface coincides with it wins a depth tie, and is not a dropped object).
        for (const uint64_t id : lost) {
          size_t pixels = 0;
          std::map<uint64_t, size_t> instead;
          for (size_t p = 0; p < a.size(); ++p) {
            if (a[p] != id) continue;
            ++pixels;
            ++instead[b[p]];
          }
          std::string there;
          for (const auto& [other, n] : instead)
            there += " " + std::to_string(other) + " (" + std::to_string(n) + " px)";
          std::fprintf(stderr, "bench_render: view %zu, %s: object %llu (%zu px) not shown; there:%s\n",
                       v, r.name.c_str(), (unsigned long long)id, pixels, there.c_str());
        }
      }
    }
    if (tty) std::fprintf(stderr, "\rview %zu/%zu", v + 1, cameras.size());
  }
  if (tty) std::fputc('\n', stderr);

  std::printf("\nPolicies along a %zu-view walkthrough and %d interior views at %ux%u, %u samples "
              "(full resolution: %.2f M triangles; occlusion test %s)\n",
              walk.size(), interior, w, h, samples, double(full_triangles) / 1e6,
              std::string(occlusion_test_name(occlusion_test)).c_str());
  std::printf("%-26s %9s %9s %7s %8s %8s %7s %7s %7s %7s %7s %7s %7s %8s %7s %7s\n", "policy",
              "walk tri", "inside tri", "in off/on", "frame ms", "p95 ms", "cpu ms", "cpu p95",
              "occl ms", "depth ms", "up MB/f", "PSNR", "PSNR min", "id match", "missing",
              "speedup");
  // Frame times without the first view (which streams the whole start).
  const auto steady = [](const std::vector<double>& v) {
    return std::vector<double>(v.begin() + (v.size() > 1 ? 1 : 0), v.end());
  };
  const double none_mean = mean(steady(runs[0].frame_ms));
  struct CpuSplit {
    std::string name;
    double walk_mean, walk_p95, interior_mean, interior_p95, ahead_mean, with_ahead_mean;
  };
  std::vector<CpuSplit> cpu_split;
  for (size_t i = 0; i < runs.size(); ++i) {
    PolicyRun& r = runs[i];
    const auto ms = steady(r.frame_ms), cpu = steady(r.cpu_ms),
               cpu_without_growth = steady(r.cpu_without_growth_ms), occlusion = steady(r.occlusion_ms),
               depth = steady(r.depth_ms);
    const double psnr_mean = r.psnr.empty() ? 99 : mean(r.psnr);
    const double psnr_min = r.psnr.empty() ? 99 : *std::min_element(r.psnr.begin(), r.psnr.end());
    const double id_min = r.id_match.empty() ? 100 : *std::min_element(r.id_match.begin(), r.id_match.end());
    const double inside_ratio = mean(runs[r.reference].interior_triangles) / std::max(mean(r.interior_triangles), 1.0);
    const double uploaded_mb = mean(steady(r.uploaded)) / 1048576.0;
    char psnr_text[32] = "      -       -";  // not measured (--no-images)
    if (images) std::snprintf(psnr_text, sizeof psnr_text, "%7.1f %7.1f", psnr_mean, psnr_min);
    std::printf("%-26s %9.0f %9.0f %6.2fx %8.1f %8.1f %7.2f %7.2f %7.2f %7.2f %7.2f %s %7.3f%% %7llu %6.1fx\n",
                r.name.c_str(), mean(r.walk_triangles), mean(r.interior_triangles), inside_ratio,
                mean(ms), percentile(ms, 0.95), mean(cpu), percentile(cpu, 0.95), mean(occlusion),
                mean(depth), uploaded_mb, psnr_text,
                id_min, (unsigned long long)r.missing, none_mean / std::max(mean(ms), 1e-9));
    nlohmann::json j = {{"bench", "render_policies"}, {"policy", lod_policy_name(r.options.lod_policy)},
                        {"occlusion_test", occlusion_test_name(r.options.occlusion_test)},
                        {"pixel_error", r.options.pixel_error}, {"occlusion", r.options.occlusion},
                        {"samples", samples}, {"walk_views", walk.size()}, {"interior_views", interior},
                        {"width", w}, {"height", h}, {"mean_ms", mean(ms)},
                        {"p95_ms", percentile(ms, 0.95)}, {"first_ms", r.frame_ms.front()},
                        {"cpu_mean_ms", mean(cpu)}, {"cpu_p95_ms", percentile(cpu, 0.95)},
                        {"cpu_without_arena_growth_mean_ms", mean(cpu_without_growth)},
                        {"cpu_without_arena_growth_p95_ms", percentile(cpu_without_growth, 0.95)},
                        {"uploaded_mean_bytes_per_frame", uploaded_mb * 1048576.0},
                        {"walk_mean_triangles", mean(r.walk_triangles)},
                        {"interior_mean_triangles", mean(r.interior_triangles)},
                        {"interior_triangles_off_over_on", inside_ratio},
                        {"full_triangles", full_triangles}, {"objects_occluded", r.occluded},
                        {"occluders", r.occluders}, {"occlusion_mean_ms", mean(occlusion)},
                        {"depth_reduction_mean_ms", mean(depth)},
                        {"cpu_parts_mean_ms",
                         {{"cull", r.cpu_parts_ms.cull / double(std::max<size_t>(cpu.size(), 1))},
                          {"occlusion", r.cpu_parts_ms.occlusion / double(std::max<size_t>(cpu.size(), 1))},
                          {"choose", r.cpu_parts_ms.choose / double(std::max<size_t>(cpu.size(), 1))},
                          {"stream", r.cpu_parts_ms.stream / double(std::max<size_t>(cpu.size(), 1))}}},
                        {"interior_mean_objects_drawn", mean(r.interior_drawn)},
                        {"id_match_min_percent", id_min}, {"objects_missing", r.missing},
                        {"speedup_vs_none", none_mean / std::max(mean(ms), 1e-9)}};
    // The CPU frame apart for the walkthrough's views (a camera moving by steps, the frames
    // before known) and the interior views (each a jump: thousands of objects new at once).
    const std::vector<double> walk_cpu(r.cpu_ms.begin() + (walk.size() > 1 ? 1 : 0),
                                       r.cpu_ms.begin() + ptrdiff_t(std::min(walk.size(), r.cpu_ms.size())));
    const std::vector<double> interior_cpu(r.cpu_ms.begin() + ptrdiff_t(std::min(walk.size(), r.cpu_ms.size())),
                                           r.cpu_ms.end());
    j["cpu_walk_mean_ms"] = mean(walk_cpu);
    j["cpu_walk_p95_ms"] = percentile(walk_cpu, 0.95);
    j["cpu_interior_mean_ms"] = mean(interior_cpu);
    j["cpu_interior_p95_ms"] = percentile(interior_cpu, 0.95);
    j["ahead_mean_ms"] = mean(steady(r.ahead_ms));
    // A frame's CPU work wherever it is done: what the look ahead moved off the frame's path
    // is still work, which a GPU that draws faster than it cannot hide.
    j["cpu_with_ahead_mean_ms"] = mean(cpu) + mean(steady(r.ahead_ms));
    cpu_split.push_back({r.name, mean(walk_cpu), percentile(walk_cpu, 0.95), mean(interior_cpu),
                         percentile(interior_cpu, 0.95), mean(steady(r.ahead_ms)),
                         mean(cpu) + mean(steady(r.ahead_ms))});
    if (!r.interior_seen.empty()) j["interior_mean_objects_seen"] = mean(r.interior_seen);
    if (!r.psnr.empty()) {
      j["psnr_mean_db"] = psnr_mean;
      j["psnr_min_db"] = psnr_min;
    }
    std::printf("json: %s\n", j.dump().c_str());
  }
  std::printf("(PSNR against none with occlusion off, 99 dB standing for identical images, - for not\n"
              " measured (--no-images); id match: the\n"
              " worst view's share of pixels whose object id equals the same policy's without occlusion;\n"
              " missing: objects shown without occlusion and not with it, summed over views; in off/on:\n"
              " interior views' triangles without occlusion over with it; occl ms: occlusion culling's\n"
              " CPU part (choosing phase 1, the tests; in cpu ms); depth ms: its GPU part (the depth\n"
              " reductions, the exact test's boxes, their read-backs; not in cpu ms); up MB/f: vertex data uploaded\n"
              " per frame; times and uploads exclude view 0.)\n");
  std::printf("\nCPU frame (ms.cpu), walkthrough views (after view 0) and interior views apart:\n");
  std::printf("%-26s %9s %9s %9s %9s %9s %9s\n", "policy", "walk ms", "walk p95", "inside ms", "inside p95",
              "ahead ms", "cpu+ahead");
  for (const CpuSplit& c : cpu_split)
    std::printf("%-26s %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f\n", c.name.c_str(), c.walk_mean, c.walk_p95,
                c.interior_mean, c.interior_p95, c.ahead_mean, c.with_ahead_mean);
  std::printf("(ahead ms: the next view's cull and occlusion's first phase, chosen and streamed, made\n"
              " while this one draws (Renderer::expect); in the frame's total, not in its cpu ms; that\n"
              " view's cull ms is then near 0, its choose and stream ms the second phase's alone.\n"
              " cpu+ahead: all views' mean ms.cpu plus ahead ms, the CPU work a frame costs wherever it\n"
              " is done: on a GPU that draws a frame in less, frames follow each other at about that.)\n");
  return 0;
}

// The out-of-core run (see the usage above). The walkthrough is computed first, in a child.
int out_of_core(const fs::path& dir, int frames, uint32_t w, uint32_t h, uint64_t budget_bytes,
                bool images) {
  const auto cameras = walkthrough_in_child(dir, frames);
  if (cameras.empty()) return 1;
  const fs::path out = fs::temp_directory_path() / ("plantview-bench-ooc-" + std::to_string(::getpid()));
  fs::create_directories(out);
  std::string error;
  const auto fail = [&](const std::string& what) {
    std::fprintf(stderr, "bench_render: %s\n", what.c_str());
    fs::remove_all(out);
    return 1;
  };
  // As `plantview render` does: the context and the image libraries first.
  const auto context_start = Clock::now();
  auto context = GpuContext::create(-1, error);
  if (!context) return fail(error);
  if (images) preload_image_io();
  const double context_s = seconds_since(context_start);
  std::printf("device: %s\n", context->description().c_str());

  // Opening the store and writing its overview image.
  const auto open_start = Clock::now();
  auto store = Store::open(dir.string(), Store::Mode::read_only, error);
  if (!store) return fail(error);
  uint64_t objects = 0, full_triangles = 0;
  {
    auto view = store->read(error);
    if (!view) return fail(error);
    const StoreInfo info = view->info();
    objects = info.objects;
    full_triangles = info.statistics.triangles;
  }
  const double open_s = seconds_since(open_start);
  RenderOptions options;
  options.vertex_budget_bytes = budget_bytes;
  auto renderer = Renderer::create(*store, options, error);
  if (!renderer) return fail(error);
  const Camera overview =
      default_camera(overview_boxes(renderer->read_view()), double(w) / double(h));
  Image image;
  FrameStats overview_stats;
  if (!renderer->render(overview, w, h, false, image, overview_stats, error) ||
      (images && !write_image((out / "overview.png").string(), image, 90, error)))
    return fail(error);
  const double overview_s = seconds_since(open_start);

  std::vector<double> ms, uploaded, evicted_objects, resident;
  uint64_t max_resident = 0, proxies = 0, coarsened = 0, triangles = 0;
  uint64_t max_blocks_held = 0, max_known = 0, max_residency_bytes = 0;
  const bool tty = isatty(2);
  for (size_t v = 0; v < cameras.size(); ++v) {
    FrameStats stats;
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.png", v);
    if (v + 1 < cameras.size()) renderer->expect(cameras[v + 1]);
    if (!renderer->render(cameras[v], w, h, false, image, stats, error) ||
        (images && !write_image((out / name).string(), image, 90, error)))
      return fail("view " + std::to_string(v) + ": " + error);
    ms.push_back(stats.ms.total);
    uploaded.push_back(double(stats.arena_bytes_uploaded));
    evicted_objects.push_back(double(stats.objects_evicted));
    resident.push_back(double(stats.arena_bytes_resident));
    max_resident = std::max(max_resident, stats.arena_bytes_resident);
    max_blocks_held = std::max(max_blocks_held, stats.spatial_blocks_held);
    max_known = std::max(max_known, stats.objects_known);
    max_residency_bytes = std::max(max_residency_bytes, stats.residency_bytes);
    proxies += stats.budget_proxies;
    coarsened += stats.budget_coarsened;
    triangles += stats.triangles;
    if (stats.arena_bytes_resident > budget_bytes)
      return fail("view " + std::to_string(v) + ": arena " +
                  std::to_string(stats.arena_bytes_resident) + " bytes over its budget");
    if (tty)
      std::fprintf(stderr, "\rview %zu/%zu  %.0f ms  arena %.0f MB  peak %.0f MB   ", v + 1,
                   cameras.size(), stats.ms.total, stats.arena_bytes_resident / 1048576.0,
                   peak_rss_bytes() / 1048576.0);
  }
  if (tty) std::fputc('\n', stderr);
  fs::remove_all(out);
  const double peak = double(peak_rss_bytes());
  std::printf("\nOut of core: %s, %llu objects, %.0f M triangles at full resolution\n",
              dir.c_str(), (unsigned long long)objects, double(full_triangles) / 1e6);
  std::printf("  GPU context and image libraries             %.2f s\n", context_s);
  std::printf("  Store::open + first read + info             %.3f s\n", open_s);
  std::printf("  ... + overview rendered%s %.2f s  (frame %.0f ms, cull %.0f ms)\n",
              images ? " and written (PNG)  " : " (not written)     ", overview_s,
              overview_stats.ms.total, overview_stats.ms.cull);
  std::printf("  overview at %ux%u: %.2f M triangles, %llu objects, %llu node boxes (nodes under "
              "%.0f px, %llu objects)\n",
              w, h, double(overview_stats.triangles) / 1e6,
              (unsigned long long)overview_stats.objects_visible,
              (unsigned long long)overview_stats.node_proxies, overview_stats.node_proxy_pixels,
              (unsigned long long)overview_stats.objects_in_node_proxies);
  std::printf("  walkthrough: %zu views at %ux%u, budget %llu MB, images %s\n", cameras.size(),
              w, h, (unsigned long long)(budget_bytes >> 20), images ? "written" : "not written");
  std::printf("  peak resident memory of the process  %.0f MB (overview + walkthrough)\n",
              peak / 1048576.0);
  std::printf("  arena resident: mean %.0f MB, max %.0f MB (never over budget)\n",
              mean(resident) / 1048576.0, double(max_resident) / 1048576.0);
  std::printf("  uploaded per frame: mean %.1f MB, p95 %.1f MB; evictions per frame: mean %.0f, max %.0f\n",
              mean(uploaded) / 1048576.0, percentile(uploaded, 0.95) / 1048576.0,
              mean(evicted_objects), percentile(evicted_objects, 1.0));
  std::printf("  frame ms: mean %.1f, p95 %.1f, first %.1f; triangles per frame %.0f; "
              "proxies %llu, coarsened %llu\n",
              mean(ms), percentile(ms, 0.95), ms.front(), double(triangles) / double(ms.size()),
              (unsigned long long)proxies, (unsigned long long)coarsened);
  std::printf("  per-object memory, most at once: %llu index blocks held, %llu objects decoded, "
              "residency table %.1f MB\n",
              (unsigned long long)max_blocks_held, (unsigned long long)max_known,
              max_residency_bytes / 1048576.0);
  nlohmann::json j = {{"bench", "render_out_of_core"}, {"store", dir.string()},
                      {"objects", objects}, {"views", cameras.size()},
                      {"budget_bytes", budget_bytes}, {"peak_rss_bytes", peak},
                      {"open_seconds", open_s}, {"overview_seconds", overview_s},
                      {"overview_triangles", overview_stats.triangles},
                      {"overview_node_boxes", overview_stats.node_proxies},
                      {"arena_max_bytes", max_resident}, {"arena_mean_bytes", mean(resident)},
                      {"uploaded_mean_bytes", mean(uploaded)}, {"evictions_mean", mean(evicted_objects)},
                      {"mean_ms", mean(ms)}, {"p95_ms", percentile(ms, 0.95)},
                      {"blocks_held_max", max_blocks_held}, {"objects_known_max", max_known},
                      {"residency_bytes_max", max_residency_bytes},
                      {"full_triangles", full_triangles}, {"images_written", images}};
  std::printf("json: %s\n", j.dump().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const auto process_start = Clock::now();
  bool quick = false, ooc = false, frames_given = false, images = true;
  char preset = 'c';
  uint32_t scale = 0, w = 1280, h = 720;
  int frames = 100, interior = 12;
  uint32_t samples = 4;
  double pixel_error = 1.0;
  std::vector<double> extra_pixel_errors;
  uint64_t budget_mb = 0;
  std::string store_dir;
  OcclusionTest occlusion_test = OcclusionTest::automatic;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") quick = true;
    else if (a == "--out-of-core") ooc = true;
    else if (a == "--no-images") images = false;
    else if (a == "--preset") preset = next().c_str()[0];
    else if (a == "--scale") scale = uint32_t(std::stoul(next()));
    else if (a == "--frames") frames = std::stoi(next()), frames_given = true;
    else if (a == "--vertex-budget") budget_mb = std::stoull(next());
    else if (a == "--store") store_dir = next();
    else if (a == "--samples") samples = uint32_t(std::stoul(next()));
    else if (a == "--interior") interior = std::stoi(next());
    else if (a == "--pixel-error") pixel_error = std::stod(next());
    else if (a == "--extra-pixel-error") extra_pixel_errors.push_back(std::stod(next()));
    else if (a == "--occlusion-test") {
      const std::string t = next();
      if (t == "automatic") occlusion_test = OcclusionTest::automatic;
      else if (t == "coarse") occlusion_test = OcclusionTest::coarse;
      else if (t == "exact") occlusion_test = OcclusionTest::exact;
      else {
        std::fprintf(stderr, "bench_render: --occlusion-test is automatic, coarse or exact, not '%s'\n", t.c_str());
        return 2;
      }
    }
    else if (a == "--size") {
      const std::string s = next();
      if (std::sscanf(s.c_str(), "%ux%u", &w, &h) != 2) return 2;
    } else {
      std::fprintf(stderr, "bench_render: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  if (quick) {
    preset = 'a';
    w = 320;
    h = 180;
    frames = 6;
    interior = 2;
    samples = 1;
  }
  if (scale == 0) scale = ooc ? 100 : 1;
  if (ooc && !frames_given) frames = 10;
  if (budget_mb == 0) budget_mb = ooc ? 256 : 1024;

  fs::path dir = store_dir;
  bool remove_after = false;
  if (dir.empty()) {
    dir = fs::temp_directory_path() / ("plantview-bench-render-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    std::fprintf(stderr, "bench_render: generating preset %c at scale %u...\n", preset, scale);
    const double s = generate_store(dir, preset, scale);
    if (s < 0) return 1;
    std::printf("generated preset %c x%u in %.1f s\n", preset, scale, s);
    remove_after = true;
  }
  if (ooc) {
    const int status = out_of_core(dir, frames, w, h, uint64_t(budget_mb) << 20, images);
    if (remove_after) fs::remove_all(dir);
    return status;
  }
  std::string error;
  auto store = Store::open(dir.string(), Store::Mode::read_only, error);
  if (!store) {
    std::fprintf(stderr, "bench_render: %s\n", error.c_str());
    return 1;
  }
  uint64_t full_triangles = 0;
  {
    auto view = store->read(error);
    if (!view) return 1;
    full_triangles = view->info().statistics.triangles;
  }

  // Time to the first image: context, renderer, the default view rendered and written as PNG.
  {
    const auto start = Clock::now();
    auto context = GpuContext::create(-1, error);
    if (!context) {
      std::fprintf(stderr, "bench_render: %s\n", error.c_str());
      return 1;
    }
    std::printf("device: %s\n", context->description().c_str());
    // As `plantview render` does, once the context exists.
    if (images) preload_image_io();
    {
      RenderOptions options;
      options.vertex_budget_bytes = uint64_t(budget_mb) << 20;
      auto renderer = Renderer::create(*store, options, error);
      Image image;
      FrameStats stats;
      const fs::path png = fs::temp_directory_path() / ("plantview-bench-first-" + std::to_string(::getpid()) + ".png");
      if (!renderer ||
          !renderer->render(default_camera(renderer->model_bounds(), double(w) / h), w, h, false, image, stats, error) ||
          (images && !write_image(png.string(), image, 90, error))) {
        std::fprintf(stderr, "bench_render: %s\n", error.c_str());
        return 1;
      }
      fs::remove(png);
      std::printf("first image (default view, %ux%u, %s): %.2f s from opening the store "
                  "(%.2f s from process start; render %.0f ms, %llu triangles)\n",
                  w, h, images ? "PNG written" : "not written", seconds_since(start),
                  seconds_since(process_start), stats.ms.total, (unsigned long long)stats.triangles);
      std::printf("json: {\"bench\":\"render_first_image\",\"seconds\":%.3f}\n", seconds_since(start));
    }
    const auto cameras = walkthrough(*store, frames);
    if (cameras.empty()) return 1;
    const int status = policies(*store, cameras, w, h, uint64_t(budget_mb) << 20, full_triangles,
                                samples, pixel_error, extra_pixel_errors, interior, occlusion_test, images);
    if (status != 0) return status;
  }
  store.reset();
  if (remove_after) fs::remove_all(dir);
  return 0;
}
