// Measuring (plantview/measure.h): milliseconds for two objects of about 5,000 primitives each,
// made from preset c's primitives (every kind of the generator, in plant proportions): A the
// first 5,000 non-line primitives of the plant as one object, B a copy of A moved
//   - beside it: past A's bounds along x by 0.5 m (the nearest parts: A's far end, B's near one);
//   - above it: past A's top by 0.05 m (every part of A's top near one of B's bottom);
//   - into it: by 0.3 m along x (overlapping: the first overlapping pair answers).
// "cold" is what `plantview measure` and /api/measure pay: building both objects' shapes (the
// meshes of tessellated kinds on first use) and the query; "warm" queries prebuilt shapes again.
// Median of N runs (wall clock, on whatever else the machine runs).
//
// Usage: bench_measure [--quick] [--runs N] [--primitives P]
//   --quick  3 runs (the CTest smoke run)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "plantview/generate.h"
#include "plantview/measure.h"

namespace {

using namespace plantview;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

Object first_primitives(size_t count) {
  const PlantModel model = generate_model({'c', 1, 1});
  Object a;
  a.name = "A";
  for (const Object& o : model.objects) {
    for (const Primitive& p : o.primitives) {
      if (a.primitives.size() == count) return a;
      if (p.kind() == PrimitiveKind::line) continue;
      if (a.primitives.empty()) a.origin_m = o.origin_m + glm::dvec3(p.placement.translation_m);
      Primitive q = p;
      q.placement.translation_m = glm::vec3(glm::dvec3(p.placement.translation_m) + o.origin_m - a.origin_m);
      a.primitives.push_back(std::move(q));
    }
  }
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 21;
  size_t primitives = 5000;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) runs = 3;
    else if (!std::strcmp(argv[i], "--runs") && i + 1 < argc) runs = std::max(1, std::atoi(argv[++i]));
    else if (!std::strcmp(argv[i], "--primitives") && i + 1 < argc) primitives = size_t(std::atoll(argv[++i]));
    else {
      std::fprintf(stderr, "usage: bench_measure [--quick] [--runs N] [--primitives P]\n");
      return 2;
    }
  }
  const Object a = first_primitives(primitives);
  const DAabb box = object_bounds(a);
  size_t meshed = 0;
  {
    const MeasureShapes shapes(a.primitives, a.origin_m, a.origin_m);
    meshed = shapes.size();
  }
  std::printf("A: %zu primitives (%zu with a surface), %.0f x %.0f x %.0f m; %d runs, median ms\n",
              a.primitives.size(), meshed, box.max.x - box.min.x, box.max.y - box.min.y,
              box.max.z - box.min.z, runs);
  std::printf("%-8s %10s %10s %12s %10s %s\n", "case", "cold", "warm", "distance m", "error mm", "method");
  struct Case {
    const char* name;
    glm::dvec3 shift;
  };
  const Case cases[] = {{"beside", {box.max.x - box.min.x + 0.5, 0, 0}},
                        {"above", {0, 0, box.max.z - box.min.z + 0.05}},
                        {"into", {0.3, 0, 0}}};
  bool ok = true;
  for (const Case& c : cases) {
    Object b = a;
    b.name = "B";
    b.origin_m += c.shift;
    std::vector<double> cold, warm;
    Clearance result;
    for (int r = 0; r < runs; ++r) {
      std::string error;
      const auto start = Clock::now();
      ok &= measure_objects(a, b, result, error);
      cold.push_back(ms_since(start));
    }
    const MeasureShapes sa(a.primitives, a.origin_m, a.origin_m), sb(b.primitives, b.origin_m, a.origin_m);
    for (int r = 0; r < runs; ++r) {
      const auto start = Clock::now();
      result = measure_clearance(sa, sb);
      warm.push_back(ms_since(start));
    }
    std::printf("%-8s %10.2f %10.2f %12.4f %10.3f %s\n", c.name, median(cold), median(warm), result.distance_m,
                result.error_m * 1000, result.analytic ? "analytic" : "tessellated");
  }
  return ok ? 0 : 1;
}
