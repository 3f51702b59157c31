// `plantview clash --store S [--tolerance MM] [--clearance MM] [--between A --and B]
// [--include-connected] [--since FILE] [--out FILE] [--json] [--shard I/N] [--threads N]` and
// `plantview clash merge A.json B.json ... --out FILE`: clash detection (plantview/clash.h).
// Exit 2 for bad arguments (a tolerance or clearance out of range, a set that matches nothing,
// --between without --and, a bad --shard, a store without piping topology unless
// --include-connected), 1 for a store that cannot be read, a --since file
// that is truncated, damaged, from another store or other settings, or an output that cannot be
// written. --out is written through a temporary file and a rename: never half a file.
#include <unistd.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "cli/progress.h"
#include "plantview/clash.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

int fail(const std::string& message) {
  std::cerr << "plantview clash: " << message << "\n";
  return 1;
}

struct ClashArgs {
  std::string store, between, with, since, out, shard = "0/1";
  double tolerance_mm = kClashDefaultToleranceM * 1000, clearance_mm = 0;
  bool include_connected = false, json = false;
  unsigned threads = 0;
  std::vector<std::string> merge_inputs;
  std::string merge_out;
  std::string farm_dir;  // a farm task (farm submit --clash): its shard file and the merge there
};

bool parse_shard(const std::string& text, ClashShard& shard) {
  const size_t slash = text.find('/');
  if (slash == std::string::npos) return false;
  const auto whole = [](std::string_view s, uint32_t& v) {
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return !s.empty() && ec == std::errc() && end == s.data() + s.size();
  };
  return whole(std::string_view(text).substr(0, slash), shard.index) &&
         whole(std::string_view(text).substr(slash + 1), shard.count) && shard.count > 0 &&
         shard.index < shard.count;
}

bool read_report(const std::string& path, ClashReport& report, std::string& error) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    error = "cannot read " + path;
    return false;
  }
  if (!read_clash_report(file, report, error)) {
    error = path + ": " + error;
    return false;
  }
  return true;
}

void print_summary(const ClashReport& r) {
  uint64_t by_status[3] = {}, hard = 0;
  for (const Clash& c : r.clashes) {
    ++by_status[int(c.status)];
    hard += c.kind == ClashKind::hard && c.status != ClashStatus::resolved;
  }
  const uint64_t found = by_status[0] + by_status[1];
  std::printf("%llu clashes (%llu hard, %llu clearance): %llu new, %llu active, %llu resolved\n",
              static_cast<unsigned long long>(found), static_cast<unsigned long long>(hard),
              static_cast<unsigned long long>(found - hard), static_cast<unsigned long long>(by_status[0]),
              static_cast<unsigned long long>(by_status[1]), static_cast<unsigned long long>(by_status[2]));
  for (const Clash& c : r.clashes) {
    const glm::dvec3& p = c.points_m.front();
    std::printf("  %016llx %-8s %-9s %s %.1f mm  %s  <>  %s  at %.3f, %.3f, %.3f\n",
                static_cast<unsigned long long>(c.id), std::string(clash_status_name(c.status)).c_str(),
                c.kind == ClashKind::hard ? "hard" : "clearance", c.kind == ClashKind::hard ? "depth" : "distance",
                1000.0 * (c.kind == ClashKind::hard ? c.depth_m : c.distance_m), c.a.tag.c_str(), c.b.tag.c_str(),
                p.x, p.y, p.z);
    if (c.changed_id) std::printf("      changed since the previous run: %s\n", c.changed_tag().c_str());
  }
}

// clashes.json written clash by clash (never held whole), atomically.
bool write_report_atomically(const std::string& path, const ClashReport& report, std::string& error) {
  const std::string temporary = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream file(temporary, std::ios::binary | std::ios::trunc);
    if (!file) {
      error = "cannot write " + path + " (creating " + temporary + " failed)";
      return false;
    }
    const bool written = write_clash_report(report, [&file](std::string_view text) {
      file.write(text.data(), std::streamsize(text.size()));
      return bool(file);
    });
    if (!written || !file.flush()) {
      error = "writing " + temporary + " failed";
      std::filesystem::remove(temporary);
      return false;
    }
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) {
    error = "cannot write " + path + ": " + ec.message();
    std::filesystem::remove(temporary, ec);
    return false;
  }
  return true;
}

int emit(const ClashReport& report, const std::string& out, bool json) {
  if (!out.empty()) {
    std::string error;
    if (!write_report_atomically(out, report, error)) return fail(error);
  }
  if (json)
    write_clash_report(report, [](std::string_view text) { return bool(std::cout.write(text.data(), std::streamsize(text.size()))); });
  else
    print_summary(report);
  return 0;
}

// A farm clash job's directory (farm submit --clash): task I of N writes
// DIR/clash-shard-I-of-N.json; the task that finds all N there (of one snapshot and settings)
// merges them into DIR/clashes.json (atomically: two tasks finishing together write the same
// bytes). Shard files of another job (another snapshot: the store changed between tasks) make
// the merge wait for the task that rewrites them; that is said, not a failure.
std::string farm_shard_file(const std::string& dir, const ClashShard& shard) {
  return (std::filesystem::path(dir) / ("clash-shard-" + std::to_string(shard.index) + "-of-" +
                                        std::to_string(shard.count) + ".json"))
      .string();
}

int finish_farm_task(const ClashReport& report, const std::string& dir) {
  std::string error;
  if (!write_report_atomically(farm_shard_file(dir, report.shard), report, error)) return fail(error);
  std::vector<ClashReport> shards(report.shard.count);
  for (uint32_t i = 0; i < report.shard.count; ++i) {
    ClashShard s;
    s.index = i;
    s.count = report.shard.count;
    const std::string path = farm_shard_file(dir, s);
    if (!std::filesystem::exists(path)) {
      std::cout << "shard " << report.shard.index << "/" << report.shard.count << ": " << report.clashes.size()
                << " clashes; waiting for the others (" << path << " is missing)\n";
      return 0;
    }
    if (!read_report(path, shards[i], error)) return fail(error);
  }
  ClashReport merged;
  if (!merge_reports(std::move(shards), merged, error)) {
    std::cout << "shard " << report.shard.index << "/" << report.shard.count
              << ": not merged yet: " << error << "\n";
    return 0;
  }
  const std::string out = (std::filesystem::path(dir) / "clashes.json").string();
  if (!write_report_atomically(out, merged, error)) return fail(error);
  std::cout << "shard " << report.shard.index << "/" << report.shard.count << " merged all "
            << report.shard.count << " into " << out << ": " << merged.clashes.size() << " clashes\n";
  return 0;
}

int run_clash(const ClashArgs& a) {
  if (a.store.empty()) return usage_error("clash: --store is required");
  if (!std::isfinite(a.tolerance_mm) || a.tolerance_mm < 0 || a.tolerance_mm > kClashMaxDistanceM * 1000)
    return usage_error("clash: --tolerance must be from 0 to " + std::to_string(int(kClashMaxDistanceM * 1000)) +
                       " mm, got " + std::to_string(a.tolerance_mm));
  if (!std::isfinite(a.clearance_mm) || a.clearance_mm < 0 || a.clearance_mm > kClashMaxDistanceM * 1000)
    return usage_error("clash: --clearance must be from 0 (off) to " +
                       std::to_string(int(kClashMaxDistanceM * 1000)) + " mm, got " + std::to_string(a.clearance_mm));
  if (a.between.empty() != a.with.empty()) return usage_error("clash: --between and --and go together");
  ClashSettings settings;
  if (!parse_shard(a.shard, settings.shard))
    return usage_error("clash: --shard: expected I/N with 0 <= I < N, got '" + a.shard + "'");
  if (!a.farm_dir.empty() && (!a.out.empty() || a.json))
    return usage_error("clash: --farm-dir writes the shard's file and the merged clashes.json itself (no --out, --json)");
  if (!a.since.empty() && settings.shard.count > 1)
    return usage_error("clash: --since applies to a whole run: merge the shards, then compare");
  settings.tolerance_m = a.tolerance_mm / 1000;
  settings.clearance_m = a.clearance_mm / 1000;
  settings.between.word = a.between;
  settings.with.word = a.with;
  settings.include_connected = a.include_connected;
  settings.threads = a.threads;

  std::string error;
  const auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  const auto view = store->read(error);
  if (!view) return fail(error);
  if (!settings.include_connected && view->info().objects > 0 &&
      view->info().statistics.objects_by_class[int(ObjectClass::pipeline)] == 0)
    return usage_error("clash: the store " + a.store +
                       " has no piping topology (no pipeline objects: an RVM file without its attributes?), so "
                       "the rules that exempt a line's own parts, connected ends, supports and nozzles cannot "
                       "apply: run with --include-connected to report every contact");
  for (const auto& [option, set] : {std::pair{"--between", &settings.between}, std::pair{"--and", &settings.with}}) {
    bool matches = false;
    if (!clash_set_matches(*view, *set, matches, error)) return fail(error);
    if (!matches)
      return usage_error(std::string("clash: ") + option + " '" + set->word +
                         "' matches no object of the store (a class: equipment, pipeline, pipe, component, "
                         "structure, other; or a glob on the tag)");
  }
  ClashReport previous;
  if (!a.since.empty() && !read_report(a.since, previous, error)) return fail("--since " + error);

  Progress progress("clash");
  settings.progress = [&progress](double fraction, uint64_t found) {
    progress.update(fraction, std::to_string(found) + " clashes");
  };
  ClashReport report;
  if (!find_clashes(*view, a.store, settings, report, error)) return fail(error);
  progress.finish();
  if (!a.farm_dir.empty()) return finish_farm_task(report, a.farm_dir);
  if (!a.since.empty() && !apply_previous(report, previous, error))
    return fail("--since " + a.since + ": " + error);
  std::string note;
  if (!a.since.empty() && !name_changed_objects(report, *view, previous.revision, note))
    std::cerr << "plantview clash: note: --since " << a.since << ": " << note << "\n";
  return emit(report, a.out, a.json);
}

int run_merge(const ClashArgs& a) {
  if (a.merge_inputs.empty()) return usage_error("clash merge: name the shards' result files");
  std::vector<ClashReport> shards(a.merge_inputs.size());
  std::string error;
  for (size_t i = 0; i < shards.size(); ++i)
    if (!read_report(a.merge_inputs[i], shards[i], error)) return fail(error);
  ClashReport merged;
  if (!merge_reports(std::move(shards), merged, error)) return fail(error);
  return emit(merged, a.merge_out, a.json);
}

}  // namespace

Action add_clash_command(CLI::App& app) {
  auto args = std::make_shared<ClashArgs>();
  auto* clash = app.add_subcommand("clash", "Clash detection: objects that interpenetrate or come too close");
  clash->add_option("--store", args->store, "Store directory");
  clash->add_option("--tolerance", args->tolerance_mm, "Hard clash: penetration deeper than this (mm, default 1)");
  clash->add_option("--clearance", args->clearance_mm, "Clearance clash: closer than this (mm; default 0, off)");
  clash->add_option("--between", args->between, "Only pairs with one object in this set (a class or a glob on the tag)");
  clash->add_option("--and", args->with, "... and the other in this one");
  clash->add_flag("--include-connected", args->include_connected,
                  "Report what the rules exempt too (a pipeline's own parts, connected ends, supports)");
  clash->add_option("--since", args->since, "A previous clashes.json of this store: mark clashes new, active, resolved");
  clash->add_option("--out", args->out, "Write clashes.json here");
  clash->add_flag("--json", args->json, "Print clashes.json on stdout instead of the summary");
  clash->add_option("--shard", args->shard, "Check shard I of N of the block pairs (a spatial region)");
  clash->add_option("--threads", args->threads, "Worker threads (default: all cores)");
  clash->add_option("--farm-dir", args->farm_dir,
                    "A farm task (farm submit --clash): write DIR/clash-shard-I-of-N.json; the last shard "
                    "merges all into DIR/clashes.json");
  auto* merge = clash->add_subcommand("merge", "Merge the shards' clashes.json files into one");
  merge->add_option("files", args->merge_inputs, "The shards' result files")->required();
  merge->add_option("--out", args->merge_out, "Write the merged clashes.json here");
  merge->add_flag("--json", args->json, "Print it on stdout instead of the summary");
  return [=]() -> int {
    if (merge->parsed()) return run_merge(*args);
    return clash->parsed() ? run_clash(*args) : -1;
  };
}

}  // namespace plantview::cli
