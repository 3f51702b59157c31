// Rendering: the LOD policies side by side along a walkthrough, the out-of-core run under a
// small vertex budget, and the time to the first image.
//
// Usage: bench_render [--quick] [--preset P] [--scale K] [--frames N] [--size WxH]
//                     [--vertex-budget MB] [--store DIR] [--out-of-core]
//   default        preset c, 1280x720, a 120-view walkthrough; policies none, distance and
//                  screen-space (1 px, and 0.25 px) render every view in turn, each with its own renderer
//                  (and arena) in this one process. Per policy: mean and 95th-percentile frame
//                  time, triangles drawn, and the PSNR of each view against policy none's.
//   --out-of-core  one renderer (screen-space) with --vertex-budget (default 256) along the
//                  walkthrough of a --scale K plant (default 100): peak resident memory of the
//                  process, arena bytes, uploads and evictions per frame, frame times.
//   --quick        preset a, 320x180, 6 views (the CTest smoke run).
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
  const char* name;
  RenderOptions options;
  std::unique_ptr<Renderer> renderer;
  std::vector<double> frame_ms, triangles, psnr;
  Image image;
};

int policies(const Store& store, const std::vector<Camera>& cameras, uint32_t w, uint32_t h,
             uint64_t budget_bytes, uint64_t full_triangles) {
  // Screen-space error at 1 px (the default) and at 0.25 px, to show the PSNR it buys.
  std::vector<PolicyRun> runs(4);
  runs[0].name = "none";
  runs[0].options.lod_policy = LodPolicy::none;
  runs[1].name = "distance";
  runs[1].options.lod_policy = LodPolicy::distance;
  runs[2].name = "screen-space 1px";
  runs[2].options.lod_policy = LodPolicy::screen_space;
  runs[3].name = "screen-space 0.25px";
  runs[3].options.lod_policy = LodPolicy::screen_space;
  runs[3].options.pixel_error = 0.25;
  std::string error;
  for (auto& r : runs) {
    r.options.vertex_budget_bytes = budget_bytes;
    r.renderer = Renderer::create(store, r.options, error);
    if (!r.renderer) {
      std::fprintf(stderr, "bench_render: %s\n", error.c_str());
      return 1;
    }
  }
  const bool tty = isatty(2);
  for (size_t v = 0; v < cameras.size(); ++v) {
    for (auto& r : runs) {
      FrameStats stats;
      if (!r.renderer->render(cameras[v], w, h, false, r.image, stats, error)) {
        std::fprintf(stderr, "bench_render: view %zu, %s: %s\n", v, r.name, error.c_str());
        return 1;
      }
      r.frame_ms.push_back(stats.ms.total);
      r.triangles.push_back(double(stats.triangles));
      if (&r != &runs[0]) {
        ImageComparison c;
        if (!compare_images(runs[0].image, r.image, c, error)) return 1;
        r.psnr.push_back(std::isinf(c.psnr_db) ? 99.0 : c.psnr_db);
      }
    }
    if (tty) std::fprintf(stderr, "\rview %zu/%zu", v + 1, cameras.size());
  }
  if (tty) std::fputc('\n', stderr);

  std::printf("\nPolicies along a %zu-view walkthrough at %ux%u (full resolution: %.2f M triangles)\n",
              cameras.size(), w, h, double(full_triangles) / 1e6);
  std::printf("%-18s %10s %10s %10s %14s %9s %10s %10s %8s\n", "policy", "mean ms", "p95 ms",
              "first ms", "mean triangles", "% of full", "PSNR mean", "PSNR min", "speedup");
  // Frame times without the first view (which streams the whole start) and with it.
  const auto steady = [](const std::vector<double>& v) {
    return std::vector<double>(v.begin() + (v.size() > 1 ? 1 : 0), v.end());
  };
  const double none_mean = mean(steady(runs[0].frame_ms));
  for (auto& r : runs) {
    const auto ms = steady(r.frame_ms);
    const double tri = mean(r.triangles);
    const double psnr_mean = r.psnr.empty() ? INFINITY : mean(r.psnr);
    const double psnr_min = r.psnr.empty() ? INFINITY : *std::min_element(r.psnr.begin(), r.psnr.end());
    std::printf("%-18s %10.1f %10.1f %10.1f %14.0f %8.2f%% %10.1f %10.1f %7.1fx\n", r.name, mean(ms),
                percentile(ms, 0.95), r.frame_ms.front(), tri, 100.0 * tri / double(full_triangles),
                psnr_mean, psnr_min, none_mean / std::max(mean(ms), 1e-9));
    nlohmann::json j = {{"bench", "render_policies"}, {"policy", r.name}, {"views", cameras.size()},
                        {"width", w}, {"height", h}, {"mean_ms", mean(ms)},
                        {"p95_ms", percentile(ms, 0.95)}, {"first_ms", r.frame_ms.front()},
                        {"mean_triangles", tri}, {"full_triangles", full_triangles},
                        {"speedup_vs_none", none_mean / std::max(mean(ms), 1e-9)}};
    if (!r.psnr.empty()) {
      j["psnr_mean_db"] = psnr_mean;
      j["psnr_min_db"] = psnr_min;
    }
    std::printf("json: %s\n", j.dump().c_str());
  }
  std::printf("(PSNR of 99 dB stands for identical images; frame times exclude view 0.)\n");
  return 0;
}

int out_of_core(const Store& store, const std::vector<Camera>& cameras, uint32_t w, uint32_t h,
                uint64_t budget_bytes, uint64_t full_triangles) {
  RenderOptions options;
  options.vertex_budget_bytes = budget_bytes;
  std::string error;
  auto renderer = Renderer::create(store, options, error);
  if (!renderer) {
    std::fprintf(stderr, "bench_render: %s\n", error.c_str());
    return 1;
  }
  Image image;
  std::vector<double> ms, uploaded, evicted_objects, resident;
  uint64_t max_resident = 0, proxies = 0, coarsened = 0, triangles = 0;
  const bool tty = isatty(2);
  for (size_t v = 0; v < cameras.size(); ++v) {
    FrameStats stats;
    if (!renderer->render(cameras[v], w, h, false, image, stats, error)) {
      std::fprintf(stderr, "bench_render: view %zu: %s\n", v, error.c_str());
      return 1;
    }
    ms.push_back(stats.ms.total);
    uploaded.push_back(double(stats.arena_bytes_uploaded));
    evicted_objects.push_back(double(stats.objects_evicted));
    resident.push_back(double(stats.arena_bytes_resident));
    max_resident = std::max(max_resident, stats.arena_bytes_resident);
    proxies += stats.budget_proxies;
    coarsened += stats.budget_coarsened;
    triangles += stats.triangles;
    if (stats.arena_bytes_resident > budget_bytes) {
      std::fprintf(stderr, "bench_render: view %zu: arena %llu bytes over its budget\n", v,
                   (unsigned long long)stats.arena_bytes_resident);
      return 1;
    }
    if (tty)
      std::fprintf(stderr, "\rview %zu/%zu  %.0f ms  arena %.0f MB  peak %.0f MB   ", v + 1,
                   cameras.size(), stats.ms.total, stats.arena_bytes_resident / 1048576.0,
                   peak_rss_bytes() / 1048576.0);
  }
  if (tty) std::fputc('\n', stderr);
  const double peak = double(peak_rss_bytes());
  std::printf("\nOut of core: %zu views at %ux%u, %.0f M triangles at full resolution, budget %llu MB\n",
              cameras.size(), w, h, double(full_triangles) / 1e6,
              (unsigned long long)(budget_bytes >> 20));
  std::printf("  peak resident memory of the process  %.0f MB\n", peak / 1048576.0);
  std::printf("  arena resident: mean %.0f MB, max %.0f MB (never over budget)\n",
              mean(resident) / 1048576.0, double(max_resident) / 1048576.0);
  std::printf("  uploaded per frame: mean %.1f MB, p95 %.1f MB; evictions per frame: mean %.0f, max %.0f\n",
              mean(uploaded) / 1048576.0, percentile(uploaded, 0.95) / 1048576.0,
              mean(evicted_objects), percentile(evicted_objects, 1.0));
  std::printf("  frame ms: mean %.1f, p95 %.1f, first %.1f; triangles per frame %.0f; "
              "proxies %llu, coarsened %llu\n",
              mean(ms), percentile(ms, 0.95), ms.front(), double(triangles) / double(ms.size()),
              (unsigned long long)proxies, (unsigned long long)coarsened);
  nlohmann::json j = {{"bench", "render_out_of_core"}, {"views", cameras.size()},
                      {"budget_bytes", budget_bytes}, {"peak_rss_bytes", peak},
                      {"arena_max_bytes", max_resident}, {"arena_mean_bytes", mean(resident)},
                      {"uploaded_mean_bytes", mean(uploaded)}, {"evictions_mean", mean(evicted_objects)},
                      {"mean_ms", mean(ms)}, {"p95_ms", percentile(ms, 0.95)},
                      {"full_triangles", full_triangles}};
  std::printf("json: %s\n", j.dump().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const auto process_start = Clock::now();
  bool quick = false, ooc = false;
  char preset = 'c';
  uint32_t scale = 0, w = 1280, h = 720;
  int frames = 120;
  uint64_t budget_mb = 0;
  std::string store_dir;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") quick = true;
    else if (a == "--out-of-core") ooc = true;
    else if (a == "--preset") preset = next().c_str()[0];
    else if (a == "--scale") scale = uint32_t(std::stoul(next()));
    else if (a == "--frames") frames = std::stoi(next());
    else if (a == "--vertex-budget") budget_mb = std::stoull(next());
    else if (a == "--store") store_dir = next();
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
  }
  if (scale == 0) scale = ooc ? 100 : 1;
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
    // As `plantview render` does, once the context exists; not out of core, which writes no
    // image (OpenImageIO's libraries would count in its peak).
    if (!ooc) preload_image_io();
    if (!ooc) {
      RenderOptions options;
      options.vertex_budget_bytes = uint64_t(budget_mb) << 20;
      auto renderer = Renderer::create(*store, options, error);
      Image image;
      FrameStats stats;
      const fs::path png = fs::temp_directory_path() / ("plantview-bench-first-" + std::to_string(::getpid()) + ".png");
      if (!renderer ||
          !renderer->render(default_camera(renderer->model_bounds(), double(w) / h), w, h, false, image, stats, error) ||
          !write_image(png.string(), image, 90, error)) {
        std::fprintf(stderr, "bench_render: %s\n", error.c_str());
        return 1;
      }
      fs::remove(png);
      std::printf("first image (default view, %ux%u, PNG written): %.2f s from opening the store "
                  "(%.2f s from process start; render %.0f ms, %llu triangles)\n",
                  w, h, seconds_since(start), seconds_since(process_start), stats.ms.total,
                  (unsigned long long)stats.triangles);
      std::printf("json: {\"bench\":\"render_first_image\",\"seconds\":%.3f}\n", seconds_since(start));
    }
    const auto cameras = ooc ? walkthrough_in_child(dir, frames) : walkthrough(*store, frames);
    if (cameras.empty()) return 1;
    const int status = ooc ? out_of_core(*store, cameras, w, h, uint64_t(budget_mb) << 20, full_triangles)
                           : policies(*store, cameras, w, h, uint64_t(budget_mb) << 20, full_triangles);
    if (status != 0) return status;
  }
  store.reset();
  if (remove_after) fs::remove_all(dir);
  return 0;
}
