// Ingest: time from nothing to a committed store (through plantview/ingest.h, as the program
// imports), and the store's size, for the generated presets a, b, c and c at scale 10, and for the
// Huldra RVM sample with its attributes (parse, classify, store). Then, as a
// renderer would read it: the time for a new view to fetch every object (without attributes) in
// the order of the spatial hierarchy's entries.
//
// Usage: bench_ingest [--quick] [--shared DIR]
//   --quick    presets a and c only, one run each (the CTest smoke run)
// Prints a table, then one JSON object per line on stdout prefixed "json: ".
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "plantview/ingest.h"
#include "plantview/store.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;

struct Row {
  std::string name;
  double seconds = 0;
  double read_seconds = 0;
  uint64_t objects = 0, primitives = 0, triangles = 0, store_bytes = 0;
};

fs::path scratch_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("plantview-bench-ingest-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(dir);
  return dir;
}

bool finish(Store& store, Row& row) {
  std::string error;
  const auto start = Clock::now();
  auto view = store.read(error);
  if (!view) {
    std::fprintf(stderr, "bench_ingest: %s\n", error.c_str());
    return false;
  }
  Object object;
  bool ok = true;
  const bool walked = view->for_each_spatial_entry(
      [&](const SpatialNode&, const SpatialEntry& e) {
        ok = view->object(e.slot, object, false, error);
        return ok;
      },
      error);
  if (!walked || !ok) {
    std::fprintf(stderr, "bench_ingest: %s\n", error.c_str());
    return false;
  }
  row.read_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  const StoreInfo info = view->info();
  row.objects = info.objects;
  row.primitives = info.statistics.primitives;
  row.triangles = info.statistics.triangles;
  row.store_bytes = info.store_bytes;
  return true;
}

// Times one ingest into a new store, from opening it to the commit, then reads it back.
bool timed_ingest(Row& row, const std::function<IngestResult(Store&)>& ingest) {
  const fs::path dir = scratch_dir(row.name);
  const auto start = Clock::now();
  std::string error;
  auto store = Store::open(dir.string(), Store::Mode::read_write, error);
  if (!store) {
    std::fprintf(stderr, "bench_ingest: %s\n", error.c_str());
    return false;
  }
  const IngestResult result = ingest(*store);
  row.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  if (!result) std::fprintf(stderr, "bench_ingest: %s\n", result.error().message.c_str());
  const bool ok = result && finish(*store, row);
  store.reset();
  fs::remove_all(dir);
  return ok;
}

bool ingest_preset(char preset, uint32_t scale, Row& row) {
  GenerateOptions options;
  options.preset = preset;
  options.scale = scale;
  return timed_ingest(row, [&](Store& store) { return ingest_generated(store, options); });
}

bool ingest_huldra(const fs::path& shared, Row& row) {
  const fs::path rvm = shared / "data" / "huldra" / "WD1-PSUP.RVM";
  const fs::path txt = shared / "data" / "huldra" / "WD1-PSUP.txt";
  if (!fs::exists(rvm)) return false;
  const ImportPlan plan{{{rvm, false, txt}}};
  return timed_ingest(row, [&](Store& store) { return ingest_files(store, plan); });
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  fs::path shared = PLANTVIEW_SHARED_DIR;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--quick") == 0) quick = true;
    else if (std::strcmp(argv[i], "--shared") == 0 && i + 1 < argc) shared = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_ingest [--quick] [--shared DIR]\n");
      return 2;
    }
  }
  std::vector<Row> rows;
  struct Job { const char* name; char preset; uint32_t scale; };
  std::vector<Job> jobs = {{"preset a", 'a', 1}, {"preset b", 'b', 1}, {"preset c", 'c', 1}, {"preset c x10", 'c', 10}};
  if (quick) jobs = {{"preset a", 'a', 1}, {"preset c", 'c', 1}};
  for (const Job& job : jobs) {
    Row row{job.name};
    if (!ingest_preset(job.preset, job.scale, row)) return 1;
    rows.push_back(row);
  }
  Row huldra{"huldra rvm+txt"};
  if (ingest_huldra(shared, huldra)) rows.push_back(huldra);

  std::printf("%-16s %10s %10s %12s %14s %12s %10s %10s\n", "input", "seconds", "objects", "primitives",
              "triangles", "store MB", "B/prim", "read s");
  for (const Row& r : rows) {
    std::printf("%-16s %10.3f %10llu %12llu %14llu %12.2f %10.1f %10.3f\n", r.name.c_str(), r.seconds,
                (unsigned long long)r.objects, (unsigned long long)r.primitives,
                (unsigned long long)r.triangles, double(r.store_bytes) / 1e6,
                r.primitives ? double(r.store_bytes) / double(r.primitives) : 0.0, r.read_seconds);
  }
  for (const Row& r : rows) {
    nlohmann::json j = {{"input", r.name}, {"seconds", r.seconds}, {"objects", r.objects},
                        {"primitives", r.primitives}, {"triangles", r.triangles}, {"store_bytes", r.store_bytes},
                        {"read_seconds", r.read_seconds}};
    std::printf("json: %s\n", j.dump().c_str());
  }
  return 0;
}
