// The service under load: 1, 4 and 16 clients, each walking its own camera path and asking
// for 1280x720 JPEG frames (screen-space LOD) one after another, against one `plantview serve`.
// Per client count: frames per second served, p50 and p99 latency, the fewest frames any client
// got (starvation), and the server's peak resident memory (VmHWM).
//
// Usage: bench_service [--quick] [--store DIR] [--seconds S] [--size WxH] [--clients 1,4,16]
//   --quick   preset a, 320x180, 1 and 4 clients for 3 s each (the CTest smoke run)
// The store is generated into a temporary directory (preset c) unless --store names one.
// Prints a table, then "json: " lines.
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
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

pid_t start_server(const std::string& store, int& port) {
  int out[2];
  if (pipe(out) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], 1);
    close(out[0]);
    execl(PLANTVIEW_BIN, PLANTVIEW_BIN, "serve", "--store", store.c_str(), "--listen", "127.0.0.1:0",
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

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string store_dir, size = "1280x720";
  double seconds = 30;
  std::vector<int> client_counts = {1, 4, 16};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") quick = true;
    else if (a == "--store") store_dir = next();
    else if (a == "--seconds") seconds = std::stod(next());
    else if (a == "--size") size = next();
    else if (a == "--clients") {
      client_counts.clear();
      std::stringstream list(next());
      for (std::string n; std::getline(list, n, ',');) client_counts.push_back(std::stoi(n));
    } else {
      std::fprintf(stderr, "bench_service: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  char preset = 'c';
  if (quick) {
    preset = 'a';
    size = "320x180";
    seconds = 3;
    client_counts = {1, 4};
  }
  uint32_t w = 0, h = 0;
  if (std::sscanf(size.c_str(), "%ux%u", &w, &h) != 2) return 2;

  bool remove_after = false;
  if (store_dir.empty()) {
    store_dir = (fs::temp_directory_path() / ("plantview-bench-service-" + std::to_string(::getpid()))).string();
    fs::remove_all(store_dir);
    const std::string command = std::string(PLANTVIEW_BIN) + " gen --preset " + preset + " --store " + store_dir + " >/dev/null";
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

  std::printf("%-8s %10s %10s %10s %10s %12s %14s\n", "clients", "frames/s", "p50 ms", "p99 ms",
              "min frames", "errors", "server peak MB");
  double single_p50 = 0;
  for (const int clients : client_counts) {
    int port = 0;
    const pid_t server = start_server(store_dir, port);
    if (server < 0) {
      std::fprintf(stderr, "bench_service: the server did not start\n");
      return 1;
    }
    std::mutex mutex;
    std::vector<double> latencies;
    std::vector<int> frames(size_t(clients), 0);
    std::atomic<int> errors{0};
    const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
    std::vector<std::thread> threads;
    for (int c = 0; c < clients; ++c) {
      threads.emplace_back([&, c] {
        test_support::HttpClient connection(port, 0);  // no receive timeout: frames may be slow
        size_t step = size_t(c) * path.size() / size_t(clients);
        std::vector<double> mine;
        while (Clock::now() < deadline) {
          const Camera& camera = path[step++ % path.size()];
          const std::string target = "/api/frame?" + camera_query(camera) + "&w=" + std::to_string(w) +
                                     "&h=" + std::to_string(h) + "&format=jpeg&quality=85&client=c" + std::to_string(c);
          const auto t = Clock::now();
          const test_support::HttpResponse response = connection.request(target);
          const int status = response.status;
          if (status != 200 || response.body.empty()) {
            errors += 1;
            if (status == 0) break;
            continue;
          }
          mine.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
          frames[size_t(c)] += 1;
        }
        std::lock_guard lock(mutex);
        latencies.insert(latencies.end(), mine.begin(), mine.end());
      });
    }
    for (auto& t : threads) t.join();
    const uint64_t peak = peak_rss_of(server);
    kill(server, SIGTERM);
    waitpid(server, nullptr, 0);
    const int total = int(latencies.size());
    const double fps = total / seconds;
    const double p50 = percentile(latencies, 0.5), p99 = percentile(latencies, 0.99);
    if (clients == client_counts.front()) single_p50 = p50;
    const int fewest = *std::min_element(frames.begin(), frames.end());
    std::printf("%-8d %10.2f %10.0f %10.0f %10d %12d %14.0f\n", clients, fps, p50, p99, fewest,
                errors.load(), peak / 1048576.0);
    nlohmann::json j = {{"bench", "service"}, {"clients", clients}, {"frames_per_second", fps},
                        {"p50_ms", p50}, {"p99_ms", p99}, {"min_frames_per_client", fewest},
                        {"errors", errors.load()}, {"server_peak_rss_bytes", peak},
                        {"p99_over_single_p50", single_p50 > 0 ? p99 / single_p50 : 0.0},
                        {"width", w}, {"height", h}, {"seconds", seconds}};
    std::printf("json: %s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  if (remove_after) fs::remove_all(store_dir);
  return 0;
}
