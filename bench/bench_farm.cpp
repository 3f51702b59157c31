// The render farm: seconds per review view for one process, and views per minute for two local
// shards, with each view's cost split (store open, first frame, streaming, draw, encode).
//
// Usage: bench_farm [--quick] [--preset P] [--views N] [--size WxH] [--store DIR]
//   default  preset c, 1280x720, the per-equipment views (`plantview views --per equipment`
//            when the program has that command, else one view of each equipment item from
//            above a corner), the first N = 48 of them; LP_NUM_THREADS=1 for every process (one
//            core per shard on a software renderer). Runs `render --views` in one process, then
//            `farm submit --scheduler local --tasks 2`, each into a fresh directory.
//   --quick  preset a, 320x180, 8 views (the CTest smoke run).
//   --revision  the incremental farm (issue 42): the views of a store imported from the plant's
//            XML rendered, a revision imported (1% of the equipment moved, 20 pipes added), then
//            an incremental run and a full run of the revision: views rendered again, time
//            against the full run, images byte-identical (--views 1000 for all 232 of preset c).
// Goals (issue 11): <= 1 s per view amortised in one process; 2 shards >= 1.6x the views per
// minute of one. Prints a table, then a "json: " line.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Runs a command line (through the shell); its exit status. Output goes to `log`.
int shell(const std::string& command, const fs::path& log) {
  const int raw = std::system((command + " >>" + log.string() + " 2>&1").c_str());
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

// Views of the first `count` equipment items from the store's XML export (the fallback when
// the program has no `views` command): each from above one corner, 14 m off.
bool views_from_export(const std::string& program, const fs::path& store, const fs::path& dir,
                       size_t count, const fs::path& out, const fs::path& log) {
  const fs::path xml = dir / "plant.xml";
  if (shell(program + " export --store " + store.string() + " --xml " + xml.string(), log) != 0) return false;
  const std::string text = slurp(xml);
  const std::regex equipment(
      R"re(<object id="([0-9a-f]+)" name="/?([A-Za-z0-9._-]+)" class="equipment"[^>]*origin_m="([-0-9.e]+) ([-0-9.e]+) ([-0-9.e]+)")re");
  json views = json::array();
  for (auto it = std::sregex_iterator(text.begin(), text.end(), equipment);
       it != std::sregex_iterator() && views.size() < count; ++it) {
    const auto& m = *it;
    const double x = std::stod(m[3]), y = std::stod(m[4]), z = std::stod(m[5]) + 2;
    views.push_back({{"name", m[2]}, {"title", m[2]}, {"kind", "equipment"},
                     {"camera", {{"eye", {x + 10, y - 10, z + 8}}, {"target", {x, y, z}}, {"up", {0, 0, 1}}, {"fov_deg", 50}}},
                     {"aspect", 16.0 / 9.0}, {"subject", {std::stoull(m[1].str(), nullptr, 16)}},
                     {"attributes", {{"tag", m[2]}}}});
  }
  std::ofstream(out) << json{{"version", 1}, {"per", "equipment"}, {"views", views}}.dump();
  return !views.empty();
}

// The views to render: `plantview views --per equipment` cut to `count`, else views_from_export.
bool make_views(const std::string& program, const fs::path& store, const fs::path& dir, size_t count,
                const fs::path& out, const fs::path& log, std::string& source) {
  const fs::path all = dir / "all_views.json";
  if (shell(program + " views --store " + store.string() + " --per equipment --out " + all.string(), log) == 0) {
    json file = json::parse(slurp(all), nullptr, false);
    if (file.is_object() && file.contains("views") && !file["views"].empty()) {
      if (file["views"].size() > count) file["views"].erase(file["views"].begin() + long(count), file["views"].end());
      std::ofstream(out) << file.dump();
      source = "plantview views --per equipment";
      return true;
    }
  }
  source = "equipment from export --xml, corner cameras";
  return views_from_export(program, store, dir, count, out, log);
}

// CPU seconds (user + system) of every child process waited for so far.
double children_cpu_s() {
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  return double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

struct Run {
  double wall_s = 0, cpu_s = 0;  // cpu_s: of the run's processes, all together
  size_t views = 0;
  double store_open_ms = 0, context_ms = 0, first_frame_ms = 0, frame_ms = 0, stream_ms = 0,
         draw_ms = 0, encode_ms = 0, view_ms = 0;
};

// The cost split from a finished run's manifest: per-process costs averaged over processes,
// per-view costs averaged over views (first frames apart).
void read_costs(const fs::path& out, Run& run) {
  const json manifest = json::parse(slurp(out / "manifest.json"), nullptr, false);
  size_t firsts = 0, views = 0;
  for (const json& v : manifest.value("views", json::array())) {
    if (v.value("status", "") != "done") continue;
    const json& ms = v["ms"];
    const json& stats = v["stats"]["ms"];
    if (ms.value("first_in_process", false)) {
      ++firsts;
      run.store_open_ms += ms.value("store_open", 0.0);
      run.context_ms += ms.value("context", 0.0);
      run.first_frame_ms += ms.value("frame", 0.0);
      continue;
    }
    ++views;
    run.frame_ms += ms.value("frame", 0.0);
    run.stream_ms += stats.value("stream", 0.0);
    run.draw_ms += stats.value("draw", 0.0) + stats.value("read_back", 0.0);
    run.encode_ms += ms.value("encode", 0.0);
    run.view_ms += ms.value("total", 0.0);
  }
  if (firsts) {
    run.store_open_ms /= double(firsts);
    run.context_ms /= double(firsts);
    run.first_frame_ms /= double(firsts);
  }
  if (views) {
    for (double* x : {&run.frame_ms, &run.stream_ms, &run.draw_ms, &run.encode_ms, &run.view_ms}) *x /= double(views);
  }
}

json run_json(const Run& r) {
  return {{"wall_s", r.wall_s},         {"cpu_s", r.cpu_s},  {"views", r.views},
          {"s_per_view", r.wall_s / double(r.views)},
          {"views_per_min", 60.0 * double(r.views) / r.wall_s},
          {"store_open_ms", r.store_open_ms}, {"context_ms", r.context_ms},
          {"first_frame_ms", r.first_frame_ms}, {"frame_ms", r.frame_ms},
          {"stream_ms", r.stream_ms},   {"draw_ms", r.draw_ms},
          {"encode_ms", r.encode_ms},   {"view_ms", r.view_ms}};
}

std::string id_hex(uint64_t id) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(id));
  return hex;
}

// Replaces the value of attribute `name` in the first tag of an XML element.
std::string with_attribute(std::string element, const std::string& name, const std::string& value) {
  const size_t at = element.find(" " + name + "=\"");
  if (at == std::string::npos) return element;
  const size_t first = at + name.size() + 3, last = element.find('"', first);
  return element.replace(first, last - first, value);
}

std::string moved(const std::string& element, double dx, double dy, double dz) {
  const size_t at = element.find(" origin_m=\"") + 11;
  std::istringstream in(element.substr(at, element.find('"', at) - at));
  double x = 0, y = 0, z = 0;
  in >> x >> y >> z;
  std::ostringstream out;
  out.precision(17);
  out << x + dx << " " << y + dy << " " << z + dz;
  return with_attribute(element, "origin_m", out.str());
}

// The revision of issue 42: 1% of the equipment moved 1 m along x, 20 pipes added (copies of
// pipes spread through the file, new ids, 0.5 m up). Returns false if the file has too few.
bool write_revision(const fs::path& xml_path, size_t& moved_count, size_t& added_count) {
  std::string xml = slurp(xml_path);
  std::vector<std::pair<size_t, size_t>> equipment, pipes;
  for (size_t at = xml.find("<object "); at != std::string::npos; at = xml.find("<object ", at + 1)) {
    const size_t tag_end = xml.find('>', at);
    const std::string tag = xml.substr(at, tag_end - at);
    const size_t end = xml.find("</object>", at) + 9;
    if (tag.find(" class=\"equipment\"") != std::string::npos) equipment.emplace_back(at, end);
    if (tag.find(" class=\"pipe\"") != std::string::npos) pipes.emplace_back(at, end);
  }
  moved_count = (equipment.size() + 99) / 100;
  added_count = 20;
  if (equipment.empty() || pipes.size() < added_count) return false;
  std::string added;
  for (size_t k = 0; k < added_count; ++k) {
    const auto [b, e] = pipes[k * pipes.size() / added_count];
    std::string copy = moved(xml.substr(b, e - b), 0, 0, 0.5);
    copy = with_attribute(with_attribute(copy, "id", id_hex(0x00fa000000000000ull + k)), "name",
                          "/BENCH-ADDED-PIPE-" + std::to_string(k));
    added += copy + "\n";
  }
  // Moved from the last to the first, so that earlier offsets stay valid.
  for (size_t k = moved_count; k-- > 0;) {
    const auto [b, e] = equipment[k * equipment.size() / moved_count];
    xml.replace(b, e - b, moved(xml.substr(b, e - b), 1, 0, 0));
  }
  xml.insert(xml.rfind("</plantview>"), added);
  std::ofstream(xml_path) << xml;
  return true;
}

// name -> finished_unix_ms of the done views of a farm directory.
std::map<std::string, int64_t> done_times(const fs::path& dir) {
  std::map<std::string, int64_t> times;
  const json manifest = json::parse(slurp(dir / "manifest.json"), nullptr, false);
  for (const json& v : manifest.value("views", json::array()))
    if (v.value("status", "") == "done") times[v["name"]] = v["finished_unix_ms"].get<int64_t>();
  return times;
}

// --revision: a full farm run of the equipment views of a store imported from the plant's XML,
// the revision above imported, then the incremental run and a full run of the revision (2 local
// shards each); views rendered again and time against the full run, and every image of the
// incremental run compared with the full run's.
int bench_revision(const std::string& program, const std::string& preset, const std::string& size,
                   size_t count, const fs::path& dir) {
  const fs::path log = dir / "log.txt", gen = dir / "gen", store = dir / "store", xml = dir / "plant.xml";
  const fs::path views = dir / "views.json";
  std::string source;
  if (shell(program + " gen --preset " + preset + " --store " + gen.string(), log) != 0 ||
      shell(program + " export --store " + gen.string() + " --xml " + xml.string(), log) != 0 ||
      shell(program + " import --store " + store.string() + " " + xml.string(), log) != 0 ||
      !make_views(program, store, dir, count, views, log, source)) {
    std::fprintf(stderr, "bench_farm: preparing the store failed:\n%s\n", slurp(log).c_str());
    return 1;
  }
  const size_t n = json::parse(slurp(views))["views"].size();
  const std::string submit = program + " farm submit --scheduler local --tasks 2 --store " + store.string() +
                             " --views " + views.string() + " --size " + size + " --out ";
  // Wall seconds, and CPU seconds of the run's processes (what a busy machine distorts least).
  std::map<std::string, double> cpu;
  const auto timed = [&](const fs::path& out, double& seconds) {
    const auto t = Clock::now();
    const double cpu_before = children_cpu_s();
    const int rc = shell(submit + out.string(), log);
    seconds = std::chrono::duration<double>(Clock::now() - t).count();
    cpu[out.filename().string() + (cpu.count(out.filename().string()) ? "_again" : "")] = children_cpu_s() - cpu_before;
    return rc == 0;
  };
  double first_s = 0, incremental_s = 0, full_s = 0;
  size_t moved_count = 0, added_count = 0;
  const fs::path incremental = dir / "incremental", full = dir / "full";
  if (!timed(incremental, first_s) || !write_revision(xml, moved_count, added_count) ||
      shell(program + " import --store " + store.string() + " " + xml.string(), log) != 0) {
    std::fprintf(stderr, "bench_farm: the first run or the revision failed:\n%s\n", slurp(log).c_str());
    return 1;
  }
  const auto t_status = Clock::now();
  shell(program + " farm status --json " + incremental.string() + " --store " + store.string() + " > " +
            (dir / "status.json").string(), log);
  const double status_s = std::chrono::duration<double>(Clock::now() - t_status).count();
  const auto before = done_times(incremental);
  if (!timed(incremental, incremental_s) || !timed(full, full_s)) {
    std::fprintf(stderr, "bench_farm: a run after the revision failed:\n%s\n", slurp(log).c_str());
    return 1;
  }
  const auto after = done_times(incremental);
  size_t rendered = 0, identical = 0, images = 0;
  std::map<std::string, size_t> reasons;
  // The full run's view time (ms.total) of the views rendered again, over all of it: the share
  // of the work the incremental run had to do (wide views, which draw more, are stale more often).
  std::map<std::string, double> full_view_ms;
  double all_view_ms = 0, stale_view_ms = 0;
  for (const json& v : json::parse(slurp(full / "manifest.json"), nullptr, false).value("views", json::array()))
    all_view_ms += full_view_ms[v.value("name", "")] = v.value("ms", json::object()).value("total", 0.0);
  const json manifest = json::parse(slurp(incremental / "manifest.json"), nullptr, false);
  for (const json& v : manifest.value("views", json::array())) {
    const std::string name = v.value("name", "");
    if (!before.count(name) || !after.count(name) || before.at(name) != after.at(name)) {
      ++rendered;
      stale_view_ms += full_view_ms[name];
      const std::string why = v.value("rendered_because", "?");
      ++reasons[why.substr(0, why.find(':'))];
    }
    const std::string file = v.value("file", "");
    ++images;
    identical += !file.empty() && slurp(incremental / file) == slurp(full / file);
  }
  std::printf("bench_farm --revision: preset %s, %zu views (%s), %s, 2 local shards\n", preset.c_str(), n,
              source.c_str(), size.c_str());
  std::printf("revision: %zu equipment moved 1 m, %zu pipes added\n", moved_count, added_count);
  std::printf("first full run %.1f s; farm status --store %.2f s\n", first_s, status_s);
  std::printf("after the revision: incremental %.1f s rendering %zu of %zu views; full %.1f s (%.2fx)\n",
              incremental_s, rendered, n, full_s, full_s / incremental_s);
  for (const auto& [why, k] : reasons) std::printf("  rendered again, %s: %zu\n", why.c_str(), k);
  std::printf("their share of the full run's view time: %.0f%%\n", 100.0 * stale_view_ms / all_view_ms);
  std::printf("CPU s: first run %.1f, incremental %.1f, full %.1f (%.2fx)\n", cpu["incremental"],
              cpu["incremental_again"], cpu["full"], cpu["full"] / cpu["incremental_again"]);
  std::printf("images byte-identical to the full run: %zu of %zu\n", identical, images);
  std::printf("json: %s\n", json{{"preset", preset}, {"size", size}, {"views", n}, {"moved_equipment", moved_count},
                                  {"added_pipes", added_count}, {"first_s", first_s}, {"status_s", status_s},
                                  {"incremental_s", incremental_s}, {"rendered", rendered},
                                  {"full_s", full_s}, {"reasons", reasons}, {"cpu_s", cpu}, {"stale_view_time_share", stale_view_ms / all_view_ms}, {"identical", identical},
                                  {"images", images}}.dump().c_str());
  return identical == images && images == n ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  std::string preset = "c", size = "1280x720", store_arg;
  size_t count = 48;
  bool revision = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") {
      preset = "a";
      size = "320x180";
      count = 8;
    } else if (a == "--revision") {
      revision = true;
    } else if (a == "--preset") {
      preset = value();
    } else if (a == "--views") {
      count = std::strtoul(value().c_str(), nullptr, 10);
    } else if (a == "--size") {
      size = value();
    } else if (a == "--store") {
      store_arg = value();
    } else {
      std::fprintf(stderr, "usage: bench_farm [--quick] [--revision] [--preset P] [--views N] [--size WxH] [--store DIR]\n");
      return 2;
    }
  }
  const std::string program = PLANTVIEW_BIN;
  const fs::path dir = fs::temp_directory_path() / ("plantview-bench-farm-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  if (revision) {
    const int rc = bench_revision(program, preset, size, count, dir);
    std::error_code ignored;
    fs::remove_all(dir, ignored);
    return rc;
  }
  const fs::path log = dir / "log.txt";
  const fs::path store = store_arg.empty() ? dir / "store" : fs::path(store_arg);
  int status = 0;
  if (store_arg.empty() && shell(program + " gen --preset " + preset + " --store " + store.string(), log) != 0) {
    std::fprintf(stderr, "bench_farm: gen failed:\n%s\n", slurp(log).c_str());
    status = 1;
  }
  const fs::path views = dir / "views.json";
  std::string source;
  if (status == 0 && !make_views(program, store, dir, count, views, log, source)) {
    std::fprintf(stderr, "bench_farm: no views:\n%s\n", slurp(log).c_str());
    status = 1;
  }
  Run one, two;
  if (status == 0) {
    const size_t n = json::parse(slurp(views))["views"].size();
    // One core per process: a software renderer limited to one thread.
    const std::string env = "LP_NUM_THREADS=1 ";
    const std::string common = " --store " + store.string() + " --views " + views.string() + " --size " + size;
    auto t = Clock::now();
    double cpu = children_cpu_s();
    if (shell(env + program + " render" + common + " --out " + (dir / "one").string(), log) != 0) status = 1;
    one.wall_s = std::chrono::duration<double>(Clock::now() - t).count();
    one.views = n;
    one.cpu_s = children_cpu_s() - cpu;
    cpu = children_cpu_s();
    t = Clock::now();
    if (shell(env + program + " farm submit --scheduler local --tasks 2" + common + " --out " + (dir / "two").string(), log) != 0)
      status = 1;
    two.wall_s = std::chrono::duration<double>(Clock::now() - t).count();
    two.views = n;
    two.cpu_s = children_cpu_s() - cpu;
    if (status != 0) {
      std::fprintf(stderr, "bench_farm: a render failed:\n%s\n", slurp(log).c_str());
    } else {
      read_costs(dir / "one", one);
      read_costs(dir / "two", two);
      std::printf("bench_farm: preset %s, %zu views (%s), %s, LP_NUM_THREADS=1 per process\n",
                  preset.c_str(), n, source.c_str(), size.c_str());
      std::printf("%-10s %8s %9s %8s | per process: %9s %9s %11s | per view: %8s %8s %8s %8s %8s\n", "run",
                  "wall s", "s/view", "views/min", "store ms", "ctx ms", "1st frame", "frame", "stream",
                  "draw", "encode", "total");
      for (const auto& [label, r] : {std::pair<const char*, const Run&>{"1 process", one}, {"2 shards", two}})
        std::printf("%-10s %8.2f %9.3f %8.1f | %22.1f %9.1f %11.1f | %17.1f %8.1f %8.1f %8.1f %8.1f\n", label,
                    r.wall_s, r.wall_s / double(r.views), 60.0 * double(r.views) / r.wall_s, r.store_open_ms,
                    r.context_ms, r.first_frame_ms, r.frame_ms, r.stream_ms, r.draw_ms, r.encode_ms, r.view_ms);
      // On a busy machine the wall-clock ratio says more about the neighbours than about the
      // shards; CPU seconds per view that stay the same show that nothing is serial between them.
      std::printf("CPU s per view: 1 process %.3f, 2 shards %.3f\n", one.cpu_s / double(one.views),
                  two.cpu_s / double(two.views));
      const double speedup = one.wall_s / two.wall_s;
      std::printf("2 shards / 1 process views per minute: %.2fx (goal >= 1.6x); 1 process: %.3f s/view (goal <= 1 s)\n",
                  speedup, one.wall_s / double(one.views));
      std::printf("json: %s\n", json{{"preset", preset}, {"size", size}, {"views_source", source},
                                     {"one_process", run_json(one)}, {"two_shards", run_json(two)},
                                     {"speedup", speedup}}
                                     .dump()
                                     .c_str());
    }
  }
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  return status;
}
