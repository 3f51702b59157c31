// The service following imports (issue 42): clients ask for frames while revisions of the plant
// are imported into the served store by another process, and the data file's size.
//
//   load     `plantview serve` on a store of a generated plant (preset a unless --preset),
//            imported from one XML file; N clients (16) ask for interactive 320x180 frames of the
//            default view one after another, and every fourth request is /api/model; meanwhile
//            the file is rewritten and imported again --imports times (20), alternating two
//            revisions: the plant, and the plant with 1% of its objects moved up 0.5 m (every
//            import changes 1% of the objects). Measured: failed requests (any answer but 200),
//            the delay from each commit (seen by polling Store::last_commit every millisecond)
//            to the first answer that carries its revision (X-Plantview-Revision), max and
//            median, and the data file's size after all imports against a fresh import.
//   growth   no clients: --growth re-imports (50) of the same two revisions into a served store,
//            once with the service following and once with one more read view held open for
//            the whole run (what a reader that never moves does: the service before it followed
//            imports): the data file's size every 10 imports.
//
// Usage: bench_follow [--quick] [--preset a|b|c] [--clients N] [--imports N] [--growth N]
//                     [--bin PLANTVIEW]
//   --quick   4 clients, 4 imports, growth over 6 (the CTest smoke run)
// Prints a table, then "json: " lines.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "plantview/store.h"
#include "plantview/xml.h"
#include "support/http_client.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;

pid_t start_server(const std::string& bin, const std::string& store, int& port) {
  int out[2];
  if (pipe(out) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], 1);
    close(out[0]);
    const int null = ::open("/dev/null", O_WRONLY);
    dup2(null, 2);
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

void stop_server(pid_t pid) {
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
}

int run(const std::string& command) {
  const int status = std::system((command + " >/dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

uint64_t data_file_bytes(const fs::path& store) {
  std::error_code ec;
  const auto size = fs::file_size(store / "data.mdb", ec);
  return ec ? 0 : size;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Two revisions of one plant as XML text: as generated, and with every 100th object moved up.
bool make_revisions(const std::string& bin, char preset, const fs::path& dir, std::string& a,
                    std::string& b) {
  const fs::path generated = dir / "generated.xml";
  if (run(bin + " gen --preset " + std::string(1, preset) + " --xml " + generated.string()) != 0) return false;
  std::vector<Object> objects;
  XmlError error;
  if (!read_xml_file(generated, [&](Object&& o) { objects.push_back(std::move(o)); }, error)) {
    std::fprintf(stderr, "bench_follow: %s\n", error.message.c_str());
    return false;
  }
  if (!write_xml(objects, a, error)) return false;
  for (size_t i = 0; i < objects.size(); i += 100) objects[i].origin_m.z += 0.5;
  return write_xml(objects, b, error);
}

// Imports `text` as the store's one source file (the same path every time, so that an import
// replaces the previous one's objects).
bool import_text(const std::string& bin, const fs::path& file, const std::string& text, const fs::path& store) {
  std::ofstream(file, std::ios::binary | std::ios::trunc) << text;
  return run(bin + " import " + file.string() + " --store " + store.string()) == 0;
}

struct Answer {
  Clock::time_point at;
  int status = 0;
  int revision = -1;
  double ms = 0;       // from the request to the answer
  bool frame = false;  // a frame (else /api/model)
};

}  // namespace

int main(int argc, char** argv) {
  std::string bin = PLANTVIEW_BIN;
  char preset = 'a';
  int clients = 16, imports = 20, growth = 50;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (a == "--quick") {
      clients = 4;
      imports = 4;
      growth = 6;
    } else if (a == "--preset") {
      preset = next()[0];
    } else if (a == "--clients") {
      clients = std::stoi(next());
    } else if (a == "--imports") {
      imports = std::stoi(next());
    } else if (a == "--growth") {
      growth = std::stoi(next());
    } else if (a == "--bin") {
      bin = next();
    } else {
      std::fprintf(stderr, "bench_follow: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  const fs::path dir = fs::temp_directory_path() / ("bench-follow-" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::string revision_a, revision_b;
  if (!make_revisions(bin, preset, dir, revision_a, revision_b)) {
    std::fprintf(stderr, "bench_follow: cannot make the revisions\n");
    return 1;
  }
  const fs::path source = dir / "plant.xml";

  // A fresh import of each revision: what the served store is compared with.
  uint64_t fresh_bytes[2] = {0, 0};
  for (int r = 0; r < 2; ++r) {
    const fs::path fresh = dir / ("fresh" + std::to_string(r));
    if (!import_text(bin, source, r ? revision_b : revision_a, fresh)) return 1;
    fresh_bytes[r] = data_file_bytes(fresh);
    fs::remove_all(fresh);
  }

  // --- load -------------------------------------------------------------------------------------
  const fs::path store_dir = dir / "served";
  if (!import_text(bin, source, revision_a, store_dir)) return 1;
  int port = 0;
  const pid_t server = start_server(bin, store_dir.string(), port);
  if (server < 0) {
    std::fprintf(stderr, "bench_follow: the server did not start\n");
    return 1;
  }
  std::string error;
  auto store = Store::open(store_dir.string(), Store::Mode::read_only, error);
  if (!store) {
    std::fprintf(stderr, "bench_follow: %s\n", error.c_str());
    return 1;
  }
  std::atomic<bool> done{false};
  std::mutex mutex;
  std::map<int, Clock::time_point> committed;  // revision -> when its commit was seen
  std::thread watcher([&] {
    uint64_t seen = store->last_commit();
    Clock::time_point changed_at{};
    while (!done) {
      const uint64_t now = store->last_commit();
      if (now != seen) {
        if (changed_at == Clock::time_point{}) changed_at = Clock::now();
        // LMDB writes the meta page a moment before readers may begin at it: read until they do.
        std::string why;
        const auto view = store->read(why);
        if (view && view->commit() == now) {
          seen = now;
          std::lock_guard lock(mutex);
          committed.emplace(int(view->info().revision), changed_at);
          changed_at = {};
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  std::vector<std::vector<Answer>> answers(static_cast<size_t>(clients));
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      auto client = std::make_unique<test_support::HttpClient>(port);
      for (uint64_t n = 0; !done; ++n) {
        const std::string target = n % 4 == 3 ? "/api/model"
                                              : "/api/frame?w=320&h=180&mode=interactive&px=3&quality=60";
        const auto asked = Clock::now();
        const test_support::HttpResponse r = client->request(target);
        Answer a{Clock::now(), r.status, -1, 0, n % 4 != 3};
        a.ms = std::chrono::duration<double, std::milli>(a.at - asked).count();
        const auto it = r.headers.find("x-plantview-revision");
        if (it != r.headers.end()) a.revision = std::atoi(it->second.c_str());
        answers[size_t(c)].push_back(a);
        if (r.status == 0) client = std::make_unique<test_support::HttpClient>(port);  // closed: again
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));
  int import_failures = 0;
  for (int i = 1; i <= imports; ++i) {
    if (!import_text(bin, source, i % 2 ? revision_b : revision_a, store_dir)) ++import_failures;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  done = true;
  for (auto& t : threads) t.join();
  watcher.join();
  const uint64_t served_bytes = data_file_bytes(store_dir);
  store.reset();
  stop_server(server);

  uint64_t total = 0, failed = 0;
  std::vector<Answer> all;
  for (const auto& list : answers) {
    total += list.size();
    for (const Answer& a : list) {
      if (a.status != 200) ++failed;
      all.push_back(a);
    }
  }
  std::sort(all.begin(), all.end(), [](const Answer& x, const Answer& y) { return x.at < y.at; });
  std::vector<double> delays_ms;
  int never = 0;
  for (const auto& [revision, at] : committed) {
    const auto first = std::find_if(all.begin(), all.end(),
                                    [&](const Answer& a) { return a.at >= at && a.revision >= revision; });
    if (first == all.end()) {
      ++never;
      continue;
    }
    delays_ms.push_back(std::chrono::duration<double, std::milli>(first->at - at).count());
  }
  // Frame latency within 250 ms of each commit (the renderers start afresh: refresh() forgets
  // what they decoded) against the rest.
  std::vector<double> after_commit_ms, other_ms;
  for (const Answer& a : all) {
    if (!a.frame || a.status != 200) continue;
    bool near = false;
    for (const auto& [revision, at] : committed)
      near = near || (a.at >= at && a.at - at < std::chrono::milliseconds(250));
    (near ? after_commit_ms : other_ms).push_back(a.ms);
  }
  const double max_delay = delays_ms.empty() ? 0 : *std::max_element(delays_ms.begin(), delays_ms.end());
  const uint64_t fresh_last = fresh_bytes[imports % 2];
  std::printf("load: preset %c, %d clients, %d imports (%d failed), %zu commits seen\n", preset, clients,
              imports, import_failures, committed.size());
  std::printf("  revisions seen committed:");
  for (const auto& [revision, at] : committed) std::printf(" %d", revision);
  std::printf("\n");
  std::printf("  requests %llu, failed %llu\n", static_cast<unsigned long long>(total),
              static_cast<unsigned long long>(failed));
  std::printf("  commit -> first answer carrying it: median %.0f ms, max %.0f ms, never %d\n",
              median(delays_ms), max_delay, never);
  std::printf("  frame ms, median: %.0f answered within 250 ms of a commit (%zu frames), %.0f otherwise (%zu)\n",
              median(after_commit_ms), after_commit_ms.size(), median(other_ms), other_ms.size());
  std::printf("  data file %.2f MB after, fresh import %.2f MB: %.2fx\n", served_bytes / 1e6, fresh_last / 1e6,
              double(served_bytes) / double(fresh_last));
  nlohmann::json load = {{"preset", std::string(1, preset)}, {"clients", clients}, {"imports", imports},
                         {"import_failures", import_failures}, {"requests", total}, {"failed", failed},
                         {"delay_ms_median", median(delays_ms)}, {"delay_ms_max", max_delay},
                         {"revisions_never_served", never},
                         {"frame_ms_median_after_commit", median(after_commit_ms)},
                         {"frame_ms_median_otherwise", median(other_ms)}, {"data_bytes", served_bytes},
                         {"fresh_bytes", fresh_last}};
  std::printf("json: %s\n", nlohmann::json({{"load", load}}).dump().c_str());

  // --- growth -----------------------------------------------------------------------------------
  nlohmann::json growth_json = nlohmann::json::object();
  for (const bool held : {false, true}) {
    const fs::path g = dir / (held ? "held" : "following");
    if (!import_text(bin, source, revision_a, g)) return 1;
    const pid_t s = start_server(bin, g.string(), port);
    if (s < 0) return 1;
    auto opened = Store::open(g.string(), Store::Mode::read_only, error);
    std::unique_ptr<ReadView> old_reader;
    if (held && opened) old_reader = opened->read(error);
    std::vector<uint64_t> sizes = {data_file_bytes(g)};
    for (int i = 1; i <= growth; ++i) {
      import_text(bin, source, i % 2 ? revision_b : revision_a, g);
      std::this_thread::sleep_for(std::chrono::milliseconds(150));  // the service moves on
      if (i % 10 == 0 || i == growth) sizes.push_back(data_file_bytes(g));
    }
    old_reader.reset();
    opened.reset();
    stop_server(s);
    std::printf("growth (%s): data file MB at 0, every 10 imports, and after %d:", held ? "one reader held open" : "following",
                growth);
    for (const uint64_t b : sizes) std::printf(" %.2f", b / 1e6);
    std::printf("\n");
    growth_json[held ? "held" : "following"] = sizes;
  }
  std::printf("json: %s\n", nlohmann::json({{"growth", growth_json}, {"fresh_bytes", fresh_bytes[0]}}).dump().c_str());
  fs::remove_all(dir);
  return failed == 0 && never == 0 && import_failures == 0 ? 0 : 1;
}
