// Revisions: what recording them costs and how fast `changes` answers. Generates preset c (or
// the --preset given) into a scratch store (revision 1), generates it again unchanged (2: no
// changes; its commit time and the data file's growth are the cost of revisions on a re-import),
// then commits a revision that moves 1% of the equipment by 0.5 m and adds 20 pipes (copies of
// existing ones, renamed and raised 1 m) (3). Then times `plantview changes --from 2 --json` (the
// program, start to exit) and ReadView::changes(2, 3), and checks that they list exactly those
// objects.
//
// Usage: bench_revisions [--preset P]
// Prints lines of text, then one JSON object on stdout prefixed "json: ". Exit 1 when the
// changes listed are not exactly those made.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/store.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;

double since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

uint64_t file_bytes(const fs::path& dir) {
  std::error_code ec;
  const auto size = fs::file_size(dir / "data.mdb", ec);
  return ec ? 0 : size;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "bench_revisions: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  char preset = 'c';
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--preset") == 0 && i + 1 < argc) preset = argv[++i][0];
  }
  const fs::path dir =
      fs::temp_directory_path() / ("plantview-bench-revisions-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup{dir};
  std::string error;
  auto store = Store::open(dir.string(), Store::Mode::read_write, error);
  if (!store) return fail(error);
  nlohmann::json out;
  out["preset"] = std::string(1, preset);

  GenerateOptions options;
  options.preset = preset;
  for (int pass = 1; pass <= 2; ++pass) {
    const auto start = Clock::now();
    const IngestResult r = ingest_generated(*store, options);
    if (!r) return fail(r.error().message);
    const double seconds = since(start);
    const std::string key = pass == 1 ? "first" : "unchanged_reimport";
    out[key] = {{"seconds", seconds}, {"store_bytes", file_bytes(dir)}};
    std::printf("%-20s %7.2f s, data file %.1f MB\n", key.c_str(), seconds,
                double(file_bytes(dir)) / 1e6);
  }

  // Revision 3: 1% of the equipment moved, 20 pipes added.
  std::set<uint64_t> modified, added;
  {
    auto view = store->read(error);
    if (!view) return fail(error);
    std::vector<Object> moved, pipes;
    uint64_t equipment = 0;
    if (!view->for_each_object_of_class(
            ObjectClass::equipment,
            [&](uint32_t, Object&& o) {
              if (equipment++ % 100 == 0) moved.push_back(std::move(o));
              return true;
            },
            true, error) ||
        !view->for_each_object_of_class(
            ObjectClass::pipe,
            [&](uint32_t, Object&& o) {
              pipes.push_back(std::move(o));
              return pipes.size() < 20;
            },
            true, error)) {
      return fail(error);
    }
    view.reset();
    auto import = store->begin_import(error);
    if (!import) return fail(error);
    for (Object& o : moved) {
      o.origin_m.x += 0.5;
      modified.insert(o.id);
      if (!import->put(o, error)) return fail(error);
    }
    for (Object& o : pipes) {
      o.name += "-NEW";
      o.id = object_id(o.source, o.name);
      o.origin_m.z += 1.0;
      added.insert(o.id);
      if (!import->put(o, error)) return fail(error);
    }
    import->set_note("1% of the equipment moved, 20 pipes added");
    const auto start = Clock::now();
    if (!import->commit(error)) return fail(error);
    out["revision_3"] = {{"equipment", equipment},
                         {"moved", moved.size()},
                         {"added", pipes.size()},
                         {"commit_seconds", since(start)}};
    std::printf("revision 3: %zu of %llu equipment moved, %zu pipes added, commit %.3f s\n",
                moved.size(), (unsigned long long)equipment, pipes.size(), since(start));
  }
  store.reset();

  // The program, start to exit.
  const fs::path json_path = dir.string() + ".changes.json";
  const std::string command = std::string(PLANTVIEW_BIN) + " changes --store " + dir.string() +
                              " --from 2 --json >" + json_path.string();
  auto start = Clock::now();
  const int status = std::system(command.c_str());
  const double cli_seconds = since(start);
  if (status != 0) return fail("'" + command + "' failed");
  nlohmann::json listed;
  {
    std::ifstream in(json_path);
    listed = nlohmann::json::parse(in, nullptr, false);
  }
  fs::remove(json_path);
  std::set<uint64_t> listed_modified, listed_added, listed_other;
  for (const auto& c : listed["changes"]) {
    const uint64_t id = std::stoull(c["id"].get<std::string>());
    (c["kind"] == "modified" ? listed_modified : c["kind"] == "added" ? listed_added : listed_other)
        .insert(id);
  }
  const bool exact = listed_modified == modified && listed_added == added && listed_other.empty();

  // In process.
  store = Store::open(dir.string(), Store::Mode::read_only, error);
  auto view = store ? store->read(error) : nullptr;
  if (!view) return fail(error);
  std::vector<ObjectChange> changes;
  start = Clock::now();
  if (!view->changes(2, 3, changes, error)) return fail(error);
  const double library_seconds = since(start);
  out["changes"] = {{"cli_seconds", cli_seconds},
                    {"library_seconds", library_seconds},
                    {"listed", listed["changes"].size()},
                    {"exact", exact}};
  std::printf("plantview changes --from 2: %.3f s (%zu objects listed, %s); ReadView::changes %.4f s\n",
              cli_seconds, listed["changes"].size(), exact ? "exactly those changed" : "NOT those changed",
              library_seconds);
  std::printf("json: %s\n", out.dump().c_str());
  return exact ? 0 : 1;
}
