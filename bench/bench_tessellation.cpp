// Tessellation throughput on one core for the primitive mix of Zhou et al. Table 1, against a
// memcpy of the same number of bytes into a destination of the same size, in the same run.
//
// "Tessellate" is what streaming an object into the vertex arena costs: plan the mesh (template
// lookup), write its level-0 vertices (16 bytes each), and write every level's indices offset to
// the object's base vertex (so a level switch is only an index range), for every primitive of the
// mix in every iteration. All output goes to one large caller-owned buffer, as it would to a
// staging buffer; nothing is allocated per primitive.
//
// Both sides run on warm buffers: the output buffers and memcpy's source and destination are
// written once before timing (a renderer's arena is persistent), so neither side pays first-touch
// page faults, and each iteration rewrites the same bytes.
//
// Prints, after Google Benchmark's table: vertices/s, output bytes/s, memcpy bytes/s, and the
// ratio tessellate/memcpy (goal: at least 0.25).
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "plantview/primitives.h"
#include "primitive_mix.h"

namespace {

using namespace plantview;

struct Workload {
  std::vector<Primitive> primitives;
  size_t vertices = 0, indices = 0, triangles_full = 0;
  std::vector<PackedVertex> vertex_out;
  std::vector<uint32_t> index_out;

  Workload() : primitives(bench::zhou_table1_mix(20120316, 1.0)) {
    for (const Primitive& p : primitives) {
      const MeshPlan plan = plan_mesh(p);
      vertices += plan.vertex_count;
      for (uint32_t l = 0; l < plan.level_count; ++l) indices += plan.index_count(l);
      triangles_full += element_count(plan, 0);
    }
    // resize() zero-fills: every page is touched here, before timing.
    vertex_out.resize(vertices);
    index_out.resize(indices);
  }
  size_t bytes() const { return vertices * sizeof(PackedVertex) + indices * sizeof(uint32_t); }
};

Workload& workload() {
  static Workload w;
  return w;
}

void BM_TessellateTable1Mix(benchmark::State& state) {
  Workload& w = workload();
  for (auto _ : state) {
    size_t v = 0, i = 0;
    for (const Primitive& p : w.primitives) {
      const MeshPlan plan = plan_mesh(p);
      // Fitted to level 0, as the renderer writes an object it draws at full detail.
      write_vertices(p, plan, glm::dvec3(0.0), std::span(w.vertex_out).subspan(v), 0);
      for (uint32_t l = 0; l < plan.level_count; ++l) {
        i += write_indices(plan, l, uint32_t(v), std::span(w.index_out).subspan(i));
      }
      v += plan.vertex_count;
    }
    benchmark::DoNotOptimize(w.vertex_out.data());
    benchmark::DoNotOptimize(w.index_out.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(w.bytes()));
  state.counters["vertices_per_s"] =
      benchmark::Counter(double(w.vertices), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["primitives"] = double(w.primitives.size());
  state.counters["triangles_L0"] = double(w.triangles_full);
}

void BM_WriteVerticesOnly(benchmark::State& state) {
  Workload& w = workload();
  std::vector<MeshPlan> plans;
  for (const Primitive& p : w.primitives) plans.push_back(plan_mesh(p));
  for (auto _ : state) {
    size_t v = 0;
    for (size_t k = 0; k < w.primitives.size(); ++k) {
      write_vertices(w.primitives[k], plans[k], glm::dvec3(0.0), std::span(w.vertex_out).subspan(v),
                     0);
      v += plans[k].vertex_count;
    }
    benchmark::DoNotOptimize(w.vertex_out.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(w.vertices * sizeof(PackedVertex)));
  state.counters["vertices_per_s"] =
      benchmark::Counter(double(w.vertices), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_WriteIndicesOnly(benchmark::State& state) {
  Workload& w = workload();
  std::vector<MeshPlan> plans;
  for (const Primitive& p : w.primitives) plans.push_back(plan_mesh(p));
  for (auto _ : state) {
    size_t v = 0, i = 0;
    for (const MeshPlan& plan : plans) {
      for (uint32_t l = 0; l < plan.level_count; ++l) {
        i += write_indices(plan, l, uint32_t(v), std::span(w.index_out).subspan(i));
      }
      v += plan.vertex_count;
    }
    benchmark::DoNotOptimize(w.index_out.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(w.indices * sizeof(uint32_t)));
}

void BM_MemcpySameBytes(benchmark::State& state) {
  const size_t bytes = workload().bytes();
  std::vector<char> src(bytes, 1), dst(bytes, 0);  // both touched before timing
  for (auto _ : state) {
    std::memcpy(dst.data(), src.data(), bytes);
    benchmark::DoNotOptimize(dst.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(bytes));
}

BENCHMARK(BM_TessellateTable1Mix)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteVerticesOnly)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteIndicesOnly)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MemcpySameBytes)->Unit(benchmark::kMillisecond)->UseRealTime();

// Keeps each benchmark's rates so the ratio can be printed after the table.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  // Colours only on a terminal.
  RatioReporter() : ConsoleReporter(::isatty(1) ? OO_Defaults : OO_Tabular) {}
  std::map<std::string, double> bytes_per_s, vertices_per_s;
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.run_type != Run::RT_Iteration || r.iterations == 0) continue;
      const std::string name = r.benchmark_name();
      auto bytes = r.counters.find("bytes_per_second");
      if (bytes != r.counters.end()) bytes_per_s[name] = bytes->second.value;
      auto verts = r.counters.find("vertices_per_s");
      if (verts != r.counters.end()) vertices_per_s[name] = verts->second.value;
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  const Workload& w = workload();
  std::printf("Zhou Table 1 mix: %zu primitives, %zu level-0 triangles, %zu vertices, %.1f MB out\n",
              w.primitives.size(), w.triangles_full, w.vertices, double(w.bytes()) / 1e6);
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();

  const auto tess = reporter.bytes_per_s.find("BM_TessellateTable1Mix/real_time");
  const auto copy = reporter.bytes_per_s.find("BM_MemcpySameBytes/real_time");
  if (tess == reporter.bytes_per_s.end() || copy == reporter.bytes_per_s.end()) return 0;
  std::printf("\ntessellate: %.1f M vertices/s, %.2f GB/s out; memcpy %.2f GB/s; ratio %.2f (goal >= 0.25)\n",
              reporter.vertices_per_s["BM_TessellateTable1Mix/real_time"] / 1e6, tess->second / 1e9,
              copy->second / 1e9, tess->second / copy->second);
  return 0;
}
