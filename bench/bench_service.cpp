// The service under load, thin clients as the viewer is one: each client walks its own stretch
// of a walkthrough and asks for 1280x720 JPEG frames (screen-space LOD) one after another, over
// its own connection, against one `plantview serve`. Five runs, a fresh server each:
//   interactive x1    one client, mode=interactive: the single-client frame time
//   interactive x16   16 clients, mode=interactive: degraded under load, never starved
//   still x1          one client, mode=still: the single-client still time
//   mixed x16         16 clients, each 7 interactive frames then a still (the viewer at rest),
//                     the clients out of step (client c rests first after c frames)
//   leaving x16       16 interactive clients arrive together and leave one by one (client c
//                     stops after (c + 1) / 16 of the run): degradation lifts step by step, and
//                     the frames in which it lifts (a lighter rung than the client's frame
//                     before: X-Plantview-Pixel-Error, X-Plantview-Render-Size) are reported
//                     apart, with the renderer's own time for them (X-Frame-Ms)
// Per run: frames/s in all and per client (min and mean), p50 and p99 latency per kind
// (interactive, still), errors, and the server's peak resident memory (VmHWM); then the issue's
// goals: p99 interactive at 16 clients <= 4x the single-client p50, no client below half the mean
// rate, stills at 16 clients (p99) within 10x the single-client still p50, and p99 of the
// leaving run <= 4x the single-client p50 (issue 43: quality steps back up without a hitch).
//
// Usage: bench_service [--quick] [--store DIR] [--seconds S] [--size WxH] [--clients N]
//                      [--renderers N] [--bin PLANTVIEW] [--no-mode]
//   --quick      preset a, 320x180, 4 clients, 1 s a run (the CTest smoke run)
//   --renderers  passed to serve (default: serve's own choice)
//   --bin        the plantview program to serve with (e.g. an older build, for a before/after)
//   --no-mode    never send mode= (servers from before it: every frame is what they render)
//   --only NAME  run the single-client interactive run and the run NAME ("interactive",
//                "still", "mixed", "leaving") alone
// The store is generated into a temporary directory (preset c) unless --store names one.
// Prints a table, then "json: " lines.
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "plantview/render.h"
#include "plantview/store.h"
#include "support/http_client.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;

pid_t start_server(const std::string& bin, const std::string& store, int renderers, int& port) {
  int out[2];
  if (pipe(out) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], 1);
    close(out[0]);
    const std::string n = std::to_string(renderers);
    if (renderers > 0)
      execl(bin.c_str(), bin.c_str(), "serve", "--store", store.c_str(), "--listen", "127.0.0.1:0",
            "--max-queue", "64", "--renderers", n.c_str(), static_cast<char*>(nullptr));
    else
      execl(bin.c_str(), bin.c_str(), "serve", "--store", store.c_str(), "--listen", "127.0.0.1:0",
            "--max-queue", "64", static_cast<char*>(nullptr));
    _exit(127);
  }
  close(out[1]);
  std::string line;
  char c;
  pollfd pfd{out[0], POLLIN, 0};
  while (line.find('\n') == std::string::npos && poll(&pfd, 1, 60000) > 0 && read(out[0], &c, 1) == 1) line += c;
  close(out[0]);
  const size_t colon = line.rfind(':');
  port = colon == std::string::npos ? 0 : std::atoi(line.c_str() + colon + 1);
  return port > 0 ? pid : -1;
}

uint64_t peak_rss_of(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  return 0;
}

std::string camera_query(const Camera& c) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "eye=%.4f,%.4f,%.4f&target=%.4f,%.4f,%.4f&up=%.3f,%.3f,%.3f&fov=%.2f",
                c.eye_m.x, c.eye_m.y, c.eye_m.z, c.target_m.x, c.target_m.y, c.target_m.z, c.up.x,
                c.up.y, c.up.z, c.fov_deg);
  return buf;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(std::ceil(p * double(v.size()))) - 1)];
}

struct Run {
  std::string name;
  int clients = 1;
  int still_every = 0;  // 0: interactive only; 1: stills only; k: every k-th frame a still
  bool leaving = false;  // client c stops after (c + 1) / clients of the run
};

struct Figures {
  std::vector<double> interactive_ms, still_ms;
  // Interactive frames in which degradation lifted (a lighter rung than the client's frame
  // before): the client's latency and the renderer's time (X-Frame-Ms).
  std::vector<double> lift_ms, lift_render_ms;
  std::vector<double> render_ms;  // every interactive frame's X-Frame-Ms
  std::vector<int> frames;  // per client
  int errors = 0;
  double seconds = 0;
  uint64_t peak_bytes = 0;
  double fps() const { return double(interactive_ms.size() + still_ms.size()) / seconds; }
  double client_fps_min() const { return *std::min_element(frames.begin(), frames.end()) / seconds; }
  double client_fps_mean() const { return fps() / double(frames.size()); }
};

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, send_mode = true;
  std::string store_dir, size = "1280x720", bin = PLANTVIEW_BIN, only;
  double seconds = 30;
  int many = 16, renderers = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") quick = true;
    else if (a == "--store") store_dir = next();
    else if (a == "--seconds") seconds = std::stod(next());
    else if (a == "--size") size = next();
    else if (a == "--clients") many = std::stoi(next());
    else if (a == "--renderers") renderers = std::stoi(next());
    else if (a == "--bin") bin = next();
    else if (a == "--no-mode") send_mode = false;
    else if (a == "--only") only = next();
    else {
      std::fprintf(stderr, "bench_service: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  char preset = 'c';
  if (quick) {
    preset = 'a';
    size = "320x180";
    seconds = 1;
    many = 4;
  }
  uint32_t w = 0, h = 0;
  if (std::sscanf(size.c_str(), "%ux%u", &w, &h) != 2 || many < 1) return 2;

  bool remove_after = false;
  if (store_dir.empty()) {
    store_dir = (fs::temp_directory_path() / ("plantview-bench-service-" + std::to_string(::getpid()))).string();
    fs::remove_all(store_dir);
    const std::string command = bin + " gen --preset " + preset + " --store " + store_dir + " >/dev/null";
    if (std::system(command.c_str()) != 0) return 1;
    remove_after = true;
  }
  // Every client walks the walkthrough from its own starting view.
  std::vector<Camera> path;
  {
    std::string error;
    auto store = Store::open(store_dir, Store::Mode::read_only, error);
    if (!store || !make_camera_path(PathKind::walkthrough, 400, *store, path, error)) {
      std::fprintf(stderr, "bench_service: %s\n", error.c_str());
      return 1;
    }
  }

  const std::string m = std::to_string(many);
  std::vector<Run> runs = {{"interactive x1", 1, 0}, {"interactive x" + m, many, 0}, {"still x1", 1, 1},
                           {"mixed x" + m, many, 8}, {"leaving x" + m, many, 0, true}};
  if (!only.empty()) {
    // The single-client interactive run (the goals' measure), then the one asked for.
    std::erase_if(runs, [&](const Run& r) { return r.name != "interactive x1" && r.name.rfind(only + " ", 0) != 0; });
    if (runs.size() < 2) {
      std::fprintf(stderr, "bench_service: --only %s: no such run\n", only.c_str());
      return 2;
    }
  }
  std::printf("%-16s %9s %9s %9s %9s %9s %9s %9s %7s %9s\n", "run", "frames/s", "client", "client",
              "inter.", "inter.", "still", "still", "errors", "server");
  std::printf("%-16s %9s %9s %9s %9s %9s %9s %9s %7s %9s\n", "", "all", "min f/s", "mean f/s", "p50 ms",
              "p99 ms", "p50 ms", "p99 ms", "", "peak MB");
  std::vector<Figures> results;
  std::vector<Run> result_runs;
  for (const Run& run : runs) {
    int port = 0;
    const pid_t server = start_server(bin, store_dir, renderers, port);
    if (server < 0) {
      std::fprintf(stderr, "bench_service: the server did not start\n");
      return 1;
    }
    std::mutex mutex;
    Figures f;
    f.frames.assign(size_t(run.clients), 0);
    std::atomic<int> errors{0}, warm{0};
    // Timed once every client has had one frame (the renderers' arenas filled, as a server
    // that has been running has them).
    Clock::time_point deadline = Clock::time_point::max();
    std::condition_variable all_warm;
    std::vector<std::thread> threads;
    for (int c = 0; c < run.clients; ++c) {
      threads.emplace_back([&, c] {
        test_support::HttpClient connection(port, 0);  // no receive timeout: frames may be slow
        size_t step = size_t(c) * path.size() / size_t(run.clients);
        std::vector<double> interactive, still, lift, lift_render, rendered;
        // The rung of the client's frame before: pixel error x (w / rendered width).
        double last_rung = 0;
        const Clock::duration leave_after = std::chrono::duration_cast<Clock::duration>(
            std::chrono::duration<double>(seconds * double(c + 1) / double(run.clients)));
        const std::string first = "/api/frame?" + camera_query(path[step]) + "&w=" + std::to_string(w) +
                                  "&h=" + std::to_string(h);
        connection.request(first);
        {
          std::unique_lock lock(mutex);
          if (++warm == run.clients) {
            deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
            all_warm.notify_all();
          }
          all_warm.wait(lock, [&] { return warm == run.clients; });
        }
        const Clock::time_point start = deadline - std::chrono::duration_cast<Clock::duration>(
                                                        std::chrono::duration<double>(seconds));
        const Clock::time_point leave = run.leaving ? start + leave_after : deadline;
        for (int n = 1; Clock::now() < leave; ++n) {
          // Clients rest at different times (client c after c frames, then every still_every).
          const bool is_still = run.still_every > 0 && (n + c) % run.still_every == 0;
          const Camera& camera = path[step % path.size()];
          if (!is_still || run.still_every == 1) ++step;  // a still: the view the walk rests at
          std::string target = "/api/frame?" + camera_query(camera) + "&w=" + std::to_string(w) +
                               "&h=" + std::to_string(h) + "&format=jpeg&quality=85";
          if (send_mode) target += is_still ? "&mode=still" : "&mode=interactive";
          const auto t = Clock::now();
          const test_support::HttpResponse response = connection.request(target);
          if (response.status != 200 || response.body.empty()) {
            errors += 1;
            if (response.status == 0) break;
            continue;
          }
          const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
          (is_still ? still : interactive).push_back(ms);
          if (!is_still) {
            const auto header = [&](const char* name) {
              const auto it = response.headers.find(name);
              return it == response.headers.end() ? std::string() : it->second;
            };
            const double pixel_error = std::atof(header("x-plantview-pixel-error").c_str());
            const double rendered_w = std::atof(header("x-plantview-render-size").c_str());
            const double rung = pixel_error * (rendered_w > 0 ? double(w) / rendered_w : 1.0);
            rendered.push_back(std::atof(header("x-frame-ms").c_str()));
            if (last_rung > 0 && rung < last_rung) {
              lift.push_back(ms);
              lift_render.push_back(std::atof(header("x-frame-ms").c_str()));
            }
            last_rung = rung;
          }
          f.frames[size_t(c)] += 1;
        }
        std::lock_guard lock(mutex);
        f.interactive_ms.insert(f.interactive_ms.end(), interactive.begin(), interactive.end());
        f.still_ms.insert(f.still_ms.end(), still.begin(), still.end());
        f.lift_ms.insert(f.lift_ms.end(), lift.begin(), lift.end());
        f.lift_render_ms.insert(f.lift_render_ms.end(), lift_render.begin(), lift_render.end());
        f.render_ms.insert(f.render_ms.end(), rendered.begin(), rendered.end());
      });
    }
    for (auto& t : threads) t.join();
    f.seconds = seconds;
    f.errors = errors.load();
    f.peak_bytes = peak_rss_of(server);
    kill(server, SIGTERM);
    waitpid(server, nullptr, 0);
    const double ip50 = percentile(f.interactive_ms, 0.5), ip99 = percentile(f.interactive_ms, 0.99);
    const double sp50 = percentile(f.still_ms, 0.5), sp99 = percentile(f.still_ms, 0.99);
    const double lift_max = f.lift_ms.empty() ? 0 : *std::max_element(f.lift_ms.begin(), f.lift_ms.end());
    const double lift_render_max =
        f.lift_render_ms.empty() ? 0 : *std::max_element(f.lift_render_ms.begin(), f.lift_render_ms.end());
    std::printf("%-16s %9.2f %9.2f %9.2f %9.0f %9.0f %9.0f %9.0f %7d %9.0f\n", run.name.c_str(), f.fps(),
                f.client_fps_min(), f.client_fps_mean(), ip50, ip99, sp50, sp99, f.errors, f.peak_bytes / 1048576.0);
    nlohmann::json j = {{"bench", "service"}, {"run", run.name}, {"clients", run.clients},
                        {"frames_per_second", f.fps()}, {"client_fps_min", f.client_fps_min()},
                        {"client_fps_mean", f.client_fps_mean()}, {"interactive_p50_ms", ip50},
                        {"interactive_p99_ms", ip99}, {"still_p50_ms", sp50}, {"still_p99_ms", sp99},
                        {"errors", f.errors}, {"server_peak_rss_bytes", f.peak_bytes},
                        {"width", w}, {"height", h}, {"seconds", seconds}, {"renderers", renderers}};
    if (run.leaving) {
      std::printf("%-16s frames where degradation lifted: %zu, latency p50 %.0f max %.0f ms, rendered p50 %.0f "
                  "max %.0f ms; interactive max %.0f ms; every frame rendered p50 %.0f p99 %.0f ms\n", "",
                  f.lift_ms.size(), percentile(f.lift_ms, 0.5), lift_max, percentile(f.lift_render_ms, 0.5),
                  lift_render_max,
                  f.interactive_ms.empty() ? 0.0 : *std::max_element(f.interactive_ms.begin(), f.interactive_ms.end()),
                  percentile(f.render_ms, 0.5), percentile(f.render_ms, 0.99));
      j["lift_frames"] = f.lift_ms.size();
      j["lift_p50_ms"] = percentile(f.lift_ms, 0.5);
      j["lift_max_ms"] = lift_max;
      j["lift_render_p50_ms"] = percentile(f.lift_render_ms, 0.5);
      j["lift_render_max_ms"] = lift_render_max;
      j["render_p50_ms"] = percentile(f.render_ms, 0.5);
      j["render_p99_ms"] = percentile(f.render_ms, 0.99);
    }
    std::printf("json: %s\n", j.dump().c_str());
    std::fflush(stdout);
    results.push_back(std::move(f));
    result_runs.push_back(run);
  }
  // The goals, from the runs above (those that ran).
  const auto find = [&](const std::string& prefix) -> const Figures* {
    for (size_t i = 0; i < result_runs.size(); ++i)
      if (result_runs[i].name.rfind(prefix, 0) == 0) return &results[i];
    return nullptr;
  };
  const Figures* lone = find("interactive x1");
  const Figures* loaded = find("interactive x" + m);
  const Figures* lone_still = find("still x1");
  const Figures* mixed = find("mixed x" + m);
  const Figures* leaving = find("leaving x" + m);
  const double single = lone ? percentile(lone->interactive_ms, 0.5) : 0;
  nlohmann::json goals = {{"bench", "service_goals"}};
  if (loaded) {
    const double loaded_p99 = percentile(loaded->interactive_ms, 0.99);
    const double fairness = loaded->client_fps_min() / loaded->client_fps_mean();
    std::printf("goal: interactive p99 at %d clients / single-client p50 = %.0f / %.0f = %.2f (<= 4)\n", many,
                loaded_p99, single, single > 0 ? loaded_p99 / single : 0.0);
    std::printf("goal: slowest client / mean frame rate at %d clients = %.2f (>= 0.5)\n", many, fairness);
    goals["interactive_p99_over_single"] = single > 0 ? loaded_p99 / single : 0.0;
    goals["slowest_over_mean_rate"] = fairness;
  }
  if (lone_still && mixed) {
    const double single_still = percentile(lone_still->still_ms, 0.5);
    const double loaded_still = percentile(mixed->still_ms, 0.99);
    std::printf("goal: still p99 at %d clients / single-client still p50 = %.0f / %.0f = %.2f (<= 10)\n", many,
                loaded_still, single_still, single_still > 0 ? loaded_still / single_still : 0.0);
    goals["still_p99_over_single"] = single_still > 0 ? loaded_still / single_still : 0.0;
  }
  if (leaving) {
    const double p99 = percentile(leaving->interactive_ms, 0.99);
    std::printf("goal: interactive p99 of %d clients leaving one by one / single-client p50 = %.0f / %.0f = %.2f "
                "(<= 4)\n", many, p99, single, single > 0 ? p99 / single : 0.0);
    goals["leaving_p99_over_single"] = single > 0 ? p99 / single : 0.0;
  }
  std::printf("json: %s\n", goals.dump().c_str());
  if (remove_after) fs::remove_all(store_dir);
  return 0;
}
