// glTF export (plantview/gltf.h): seconds, file size, triangles and peak memory of
//   - Huldra: import (RVM + attributes into a new store) and a full-resolution GLB export, side
//     by side with rvmparser's conversion of the same files when $RVMPARSER names its binary;
//   - preset c at 1, 5 and 20 mm tolerance (and at 5 mm without quantization: what it saves);
//   - preset c at full resolution with shared meshes and without (what sharing saves);
//   - with --large, preset c at --scale 100 at 5 mm (the streaming bound: peak memory).
// Each case runs in a child process of its own, so that its peak resident memory (wait4's
// ru_maxrss) is its own; times are wall-clock, on whatever else the machine runs.
//
// Usage: bench_export [--quick] [--large] [--shared DIR]
//   --quick    Huldra (if present) and preset a at 5 mm only (the CTest smoke run)
// Prints a table, then one JSON object per line on stdout prefixed "json: ".
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "plantview/generate.h"
#include "plantview/gltf.h"
#include "plantview/ingest.h"
#include "plantview/store.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;

struct Row {
  std::string name;
  double seconds = 0;
  uint64_t bytes = 0, triangles = 0, meshes = 0, objects = 0;
  uint64_t peak_kb = 0;
  bool ok = false;
};

double since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// Runs `work` in a child; it fills the row's figures (not peak_kb), which come back through a
// pipe as JSON; the child's peak resident memory is added here.
Row in_child(const std::string& name, const std::function<bool(Row&)>& work) {
  Row row;
  row.name = name;
  int fds[2];
  if (::pipe(fds) != 0) return row;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    Row r;
    const bool ok = work(r);
    const std::string j = nlohmann::json{{"ok", ok}, {"seconds", r.seconds}, {"bytes", r.bytes},
                                         {"triangles", r.triangles}, {"meshes", r.meshes}, {"objects", r.objects}}.dump();
    if (::write(fds[1], j.data(), j.size()) != ssize_t(j.size())) ::_exit(3);
    ::_exit(ok ? 0 : 1);
  }
  ::close(fds[1]);
  std::string text;
  char buffer[512];
  ssize_t n;
  while ((n = ::read(fds[0], buffer, sizeof buffer)) > 0) text.append(buffer, size_t(n));
  ::close(fds[0]);
  int status = 0;
  struct rusage usage {};
  ::wait4(pid, &status, 0, &usage);
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_object()) {
    row.ok = j["ok"];
    row.seconds = j["seconds"];
    row.bytes = j["bytes"];
    row.triangles = j["triangles"];
    row.meshes = j["meshes"];
    row.objects = j["objects"];
  }
  row.peak_kb = uint64_t(usage.ru_maxrss);
  return row;
}

// Runs a program (no shell) with its peak memory and wall time.
Row run_program(const std::string& name, const std::vector<std::string>& argv, const fs::path& output) {
  Row row;
  row.name = name;
  const auto start = Clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    if (!std::freopen("/dev/null", "w", stdout)) ::_exit(127);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  int status = 0;
  struct rusage usage {};
  ::wait4(pid, &status, 0, &usage);
  row.seconds = since(start);
  row.peak_kb = uint64_t(usage.ru_maxrss);
  row.ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  std::error_code ec;
  row.bytes = fs::file_size(output, ec);
  return row;
}

bool export_to(const Store& store, const fs::path& path, double tolerance_m, bool share, Row& r,
               bool quantize = true) {
  GltfExportOptions o;
  o.path = path.string();
  o.tolerance_m = tolerance_m;
  o.share_meshes = share;
  o.quantize = quantize;
  GltfExportSummary s;
  std::string error;
  if (export_gltf(store, o, s, error) != GltfExportStatus::ok) {
    std::fprintf(stderr, "bench_export: %s\n", error.c_str());
    return false;
  }
  r.bytes = s.bytes;
  r.triangles = s.triangles;
  r.meshes = s.meshes;
  r.objects = s.objects;
  return true;
}

bool generate(const fs::path& dir, char preset, uint32_t scale) {
  std::string error;
  auto store = Store::open(dir.string(), Store::Mode::read_write, error);
  GenerateOptions g;
  g.preset = preset;
  g.scale = scale;
  if (!store || !ingest_generated(*store, g)) {
    std::fprintf(stderr, "bench_export: cannot generate preset %c x%u: %s\n", preset, scale, error.c_str());
    return false;
  }
  return true;
}

// Exports the store at `dir` in a child: open, export, timed from the open.
Row export_case(const std::string& name, const fs::path& dir, const fs::path& out, double tolerance_m, bool share,
                bool quantize = true) {
  return in_child(name, [&](Row& r) {
    const auto start = Clock::now();
    std::string error;
    auto store = Store::open(dir.string(), Store::Mode::read_only, error);
    if (!store) {
      std::fprintf(stderr, "bench_export: %s\n", error.c_str());
      return false;
    }
    const bool ok = export_to(*store, out, tolerance_m, share, r, quantize);
    r.seconds = since(start);
    return ok;
  });
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, large = false;
  fs::path shared = fs::path(PLANTVIEW_SHARED_DIR);
  if (const char* env = std::getenv("PLANTVIEW_SHARED_DIR")) shared = env;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--large")) large = true;
    else if (!std::strcmp(argv[i], "--shared") && i + 1 < argc) shared = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_export [--quick] [--large] [--shared DIR]\n");
      return 2;
    }
  }
  const fs::path scratch = fs::temp_directory_path() / ("plantview-bench-export-" + std::to_string(::getpid()));
  fs::remove_all(scratch);
  fs::create_directories(scratch);
  std::vector<Row> rows;

  // Huldra: import + export at full resolution, against rvmparser's conversion.
  const fs::path rvm = shared / "data/huldra/WD1-PSUP.RVM", txt = shared / "data/huldra/WD1-PSUP.txt";
  if (fs::exists(rvm)) {
    rows.push_back(in_child("huldra import + glb (full)", [&](Row& r) {
      const auto start = Clock::now();
      std::string error;
      const std::vector<std::string> files{rvm.string()};
      const auto plan = plan_import(files, error);
      auto store = plan ? Store::open((scratch / "huldra").string(), Store::Mode::read_write, error) : nullptr;
      if (!store || !ingest_files(*store, *plan)) {
        std::fprintf(stderr, "bench_export: Huldra import failed: %s\n", error.c_str());
        return false;
      }
      const bool ok = export_to(*store, scratch / "huldra.glb", 0, true, r);
      r.seconds = since(start);
      return ok;
    }));
    if (const char* rvmparser = std::getenv("RVMPARSER")) {
      const fs::path out = scratch / "huldra-rvmparser.glb";
      rows.push_back(run_program("huldra rvmparser --output-gltf",
                                 {rvmparser, "--output-gltf=" + out.string(), rvm.string(), txt.string()}, out));
    }
  } else {
    std::fprintf(stderr, "bench_export: no Huldra at %s; skipped\n", rvm.c_str());
  }

  if (quick) {
    if (generate(scratch / "a", 'a', 1)) rows.push_back(export_case("preset a 5 mm", scratch / "a", scratch / "a5.glb", 0.005, true));
  } else {
    const bool have_c = in_child("generate c", [&](Row&) { return generate(scratch / "c", 'c', 1); }).ok;
    if (have_c) {
      for (const double mm : {1.0, 5.0, 20.0}) {
        const std::string name = "preset c " + std::to_string(int(mm)) + " mm";
        rows.push_back(export_case(name, scratch / "c", scratch / ("c" + std::to_string(int(mm)) + ".glb"), mm / 1000, true));
      }
      rows.push_back(export_case("preset c 5 mm, float32 vertices", scratch / "c", scratch / "c5-float.glb", 0.005,
                                 true, false));
      rows.push_back(export_case("preset c full, shared meshes", scratch / "c", scratch / "c-shared.glb", 0, true));
      rows.push_back(export_case("preset c full, a mesh per object", scratch / "c", scratch / "c-own.glb", 0, false));
    }
    if (large && in_child("generate c x100", [&](Row&) { return generate(scratch / "c100", 'c', 100); }).ok)
      rows.push_back(export_case("preset c x100 5 mm", scratch / "c100", scratch / "c100.glb", 0.005, true));
  }

  std::printf("%-36s %9s %10s %12s %8s %9s %10s\n", "case", "seconds", "MB", "triangles", "meshes", "objects", "peak MB");
  for (const Row& r : rows) {
    std::printf("%-36s %9.3f %10.2f %12llu %8llu %9llu %10.1f%s\n", r.name.c_str(), r.seconds, double(r.bytes) / 1e6,
                (unsigned long long)r.triangles, (unsigned long long)r.meshes, (unsigned long long)r.objects,
                double(r.peak_kb) / 1024.0, r.ok ? "" : "  FAILED");
  }
  for (const Row& r : rows) {
    std::printf("json: %s\n", nlohmann::json{{"case", r.name}, {"ok", r.ok}, {"seconds", r.seconds}, {"bytes", r.bytes},
                                             {"triangles", r.triangles}, {"meshes", r.meshes}, {"objects", r.objects},
                                             {"peak_kb", r.peak_kb}}.dump().c_str());
  }
  fs::remove_all(scratch);
  for (const Row& r : rows)
    if (!r.ok) return 1;
  return 0;
}
