// Clash detection (plantview/clash.h): seconds for every object of a store against every other,
// with the counts the broad phase saw and the process's peak memory.
//
// Usage: bench_clash [--store DIR] [--preset c] [--scale N] [--threads N] [--clearance MM]
//   --store DIR  the store to check (generated there first from --preset/--scale when it holds
//                no store yet; kept for the next run)
//   default: preset c at scale 1 in a temporary directory, removed afterwards
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include "plantview/clash.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/store.h"

int main(int argc, char** argv) {
  using namespace plantview;
  std::string directory;
  GenerateOptions generate;
  ClashSettings settings;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool value = i + 1 < argc;
    if (a == "--store" && value) directory = argv[++i];
    else if (a == "--preset" && value) generate.preset = argv[++i][0];
    else if (a == "--scale" && value) generate.scale = uint32_t(std::atoi(argv[++i]));
    else if (a == "--threads" && value) settings.threads = unsigned(std::atoi(argv[++i]));
    else if (a == "--clearance" && value) settings.clearance_m = std::atof(argv[++i]) / 1000;
    else if (a == "--mesh-error" && value) settings.mesh_error_m = std::atof(argv[++i]) / 1000;
    else {
      std::fprintf(stderr, "usage: bench_clash [--store DIR] [--preset c] [--scale N] [--threads N] [--clearance MM] [--mesh-error MM]\n");
      return 2;
    }
  }
  const bool temporary = directory.empty();
  if (temporary)
    directory = (std::filesystem::temp_directory_path() / ("bench_clash-" + std::to_string(::getpid()))).string();
  std::string error;
  const bool fresh = !std::filesystem::exists(std::filesystem::path(directory) / "data.mdb");
  auto store = Store::open(directory, fresh ? Store::Mode::read_write : Store::Mode::read_only, error);
  if (!store) {
    std::fprintf(stderr, "bench_clash: %s\n", error.c_str());
    return 1;
  }
  if (fresh) {
    const auto start = std::chrono::steady_clock::now();
    const IngestResult result = ingest_generated(*store, generate);
    if (!result) {
      std::fprintf(stderr, "bench_clash: %s\n", result.error().message.c_str());
      return 1;
    }
    std::printf("generated preset %c x%u in %.1f s\n", generate.preset, generate.scale,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  auto view = store->read(error);
  if (!view) {
    std::fprintf(stderr, "bench_clash: %s\n", error.c_str());
    return 1;
  }
  ClashReport report;
  const auto start = std::chrono::steady_clock::now();
  const bool ok = find_clashes(*view, directory, settings, report, error);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!ok) {
    std::fprintf(stderr, "bench_clash: %s\n", error.c_str());
    return 1;
  }
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  size_t hard = 0;
  for (const Clash& c : report.clashes) hard += c.kind == ClashKind::hard;
  std::printf("objects %llu: %.2f s, %zu clashes (%zu hard), block pairs %llu, candidate pairs %llu, narrow %llu, "
              "skipped same_pipeline %llu connected %llu support %llu nozzle %llu, peak RSS %.0f MB\n",
              static_cast<unsigned long long>(report.objects), seconds, report.clashes.size(), hard,
              static_cast<unsigned long long>(report.counts.block_pairs),
              static_cast<unsigned long long>(report.counts.candidate_pairs),
              static_cast<unsigned long long>(report.counts.narrow_pairs),
              static_cast<unsigned long long>(report.counts.skipped_by_rule[0]),
              static_cast<unsigned long long>(report.counts.skipped_by_rule[1]),
              static_cast<unsigned long long>(report.counts.skipped_by_rule[2]),
              static_cast<unsigned long long>(report.counts.skipped_by_rule[3]), usage.ru_maxrss / 1024.0);
  view.reset();
  store.reset();
  if (temporary) std::filesystem::remove_all(directory);
  return 0;
}
