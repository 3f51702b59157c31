// `plantview clash --store S [--tolerance MM] [--clearance MM] [--between A --and B]
// [--include-connected] [--since FILE] [--out FILE] [--json] [--shard I/N] [--threads N]` and
// `plantview clash merge A.json B.json ... --out FILE`: clash detection (plantview/clash.h).
// Exit 2 for bad arguments (a tolerance or clearance out of range, a set that matches nothing,
// --between without --and, a bad --shard, a store without piping topology unless
// --include-connected), 1 for a store that cannot be read, a --since file
// that is truncated, damaged, from another store or other settings, or an output that cannot be
// written; checked before the pass (check_clash_options, which farm submit --clash shares).
// --out is written through a temporary file and a rename: never half a file.
#include <fcntl.h>
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
  std::string store, out, shard = "0/1";
  ClashOptions options;
  bool json = false;
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

// A clashes file read whole (read_clash_report) or as its keys (read_previous_clashes); the
// error names the file.
template <class Out>
bool read_clashes_file(const std::string& path, bool (*read)(std::istream&, Out&, std::string&), Out& out,
                       std::string& error) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    error = "cannot read " + path;
    return false;
  }
  if (!read(file, out, error)) {
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
    // (a run of millions of clashes writes gigabytes: the terminal sees how far it got)
    Progress progress("writing " + path);
    const double pieces = double(report.clashes.size()) + 3.0;  // the header, each clash, the end
    uint64_t written_pieces = 0;
    const bool written = write_clash_report(report, [&](std::string_view text) {
      file.write(text.data(), std::streamsize(text.size()));
      if ((++written_pieces & 4095) == 0) progress.update(double(written_pieces) / pieces);
      return bool(file);
    });
    progress.finish();
    file.close();
    // The data reaches the disk before the rename makes it the file (a crash then leaves the
    // previous clashes.json, never an empty one).
    const int fd = written && file ? ::open(temporary.c_str(), O_RDONLY | O_CLOEXEC) : -1;
    const bool synced = fd >= 0 && ::fsync(fd) == 0;
    if (fd >= 0) ::close(fd);
    if (!synced) {
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
// the merge wait for the task that rewrites them; that is said, not a failure. With --since
// (farm submit copies the file into DIR) only the merging task reads it, and applies it to the
// merged result as `clash --since` does to one process's.
std::string farm_shard_file(const std::string& dir, const ClashShard& shard) {
  return (std::filesystem::path(dir) / ("clash-shard-" + std::to_string(shard.index) + "-of-" +
                                        std::to_string(shard.count) + ".json"))
      .string();
}

// --since PATH, once the run's clashes are found (all shards merged): statuses against
// `previous` (that file's keys; the file is read again for the clashes now resolved, never held
// whole), then the new clashes' changed objects (a note on stderr when the store cannot name
// them). False with a message naming the file.
bool apply_since(ClashReport& report, const PreviousClashes& previous, const ReadView& view, const std::string& path,
                 std::string& error) {
  std::vector<bool> matched;
  std::ifstream file(path, std::ios::binary);
  if (!match_previous(report, previous, matched, error) || !file || !append_resolved(report, file, matched, error)) {
    error = "--since " + path + ": " + (error.empty() ? "cannot read it again" : error);
    return false;
  }
  std::string note;
  if (!name_changed_objects(report, view, previous.header.revision, note))
    std::cerr << "plantview clash: note: --since " << path << ": " << note << "\n";
  return true;
}

int finish_farm_task(const ClashReport& report, const std::string& dir, const ReadView& view,
                     const std::string& since) {
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
    if (!read_clashes_file(path, read_clash_report, shards[i], error)) return fail(error);
  }
  ClashReport merged;
  if (!merge_reports(std::move(shards), merged, error)) {
    std::cout << "shard " << report.shard.index << "/" << report.shard.count
              << ": not merged yet: " << error << "\n";
    return 0;
  }
  shards.clear();
  // The merged run against the previous one, as one process's `clash --since` compares (the
  // shards are of this task's snapshot: merge_reports checked it).
  if (!since.empty()) {
    PreviousClashes previous;
    if (!read_clashes_file(since, read_previous_clashes, previous, error)) return fail("--since " + error);
    if (!apply_since(merged, previous, view, since, error)) return fail(error);
  }
  const std::string out = (std::filesystem::path(dir) / "clashes.json").string();
  if (!write_report_atomically(out, merged, error)) return fail(error);
  std::cout << "shard " << report.shard.index << "/" << report.shard.count << " merged all "
            << report.shard.count << " into " << out << ": " << merged.clashes.size() << " clashes"
            << (since.empty() ? "" : " (statuses since " + since + ")") << "\n";
  return 0;
}

int run_clash(const ClashArgs& a) {
  if (a.store.empty()) return usage_error("clash: --store is required");
  ClashSettings settings;
  if (!parse_shard(a.shard, settings.shard))
    return usage_error("clash: --shard: expected I/N with 0 <= I < N, got '" + a.shard + "'");
  if (!a.farm_dir.empty() && (!a.out.empty() || a.json))
    return usage_error("clash: --farm-dir writes the shard's file and the merged clashes.json itself (no --out, --json)");
  if (!a.options.since.empty() && settings.shard.count > 1 && a.farm_dir.empty())
    return usage_error("clash: --since applies to a whole run: merge the shards, then compare");
  // A farm task leaves --since to the task that merges (farm submit checked the file).
  ClashOptions options = a.options;
  if (!a.farm_dir.empty()) options.since.clear();
  std::unique_ptr<ReadView> view;
  PreviousClashes previous;
  if (const int status = check_clash_options("clash", options, a.store, view, previous); status != 0)
    return status;
  settings.tolerance_m = a.options.tolerance_mm / 1000;
  settings.clearance_m = a.options.clearance_mm / 1000;
  settings.between.word = a.options.between;
  settings.with.word = a.options.with;
  settings.include_connected = a.options.include_connected;
  settings.threads = a.threads;

  std::string error;
  Progress progress("clash");
  settings.progress = [&progress](double fraction, uint64_t found) {
    progress.update(fraction, std::to_string(found) + " clashes");
  };
  ClashReport report;
  if (!find_clashes(*view, a.store, settings, report, error)) return fail(error);
  progress.finish();
  if (!a.farm_dir.empty()) return finish_farm_task(report, a.farm_dir, *view, a.options.since);
  if (!a.options.since.empty() && !apply_since(report, previous, *view, a.options.since, error)) return fail(error);
  return emit(report, a.out, a.json);
}

int run_merge(const ClashArgs& a) {
  if (a.merge_inputs.empty()) return usage_error("clash merge: name the shards' result files");
  std::vector<ClashReport> shards(a.merge_inputs.size());
  std::string error;
  for (size_t i = 0; i < shards.size(); ++i)
    if (!read_clashes_file(a.merge_inputs[i], read_clash_report, shards[i], error)) return fail(error);
  ClashReport merged;
  if (!merge_reports(std::move(shards), merged, error)) return fail(error);
  return emit(merged, a.merge_out, a.json);
}

}  // namespace

int check_clash_options(const std::string& command, const ClashOptions& o, const std::string& store_dir,
                        std::unique_ptr<ReadView>& view, PreviousClashes& previous) {
  const auto runtime_failure = [&command](const std::string& message) {
    std::cerr << "plantview " << command << ": " << message << "\n";
    return 1;
  };
  const std::string max_mm = std::to_string(int(kClashMaxDistanceM * 1000));
  if (!std::isfinite(o.tolerance_mm) || o.tolerance_mm < 0 || o.tolerance_mm > kClashMaxDistanceM * 1000)
    return usage_error(command + ": --tolerance must be from 0 to " + max_mm + " mm, got " +
                       std::to_string(o.tolerance_mm));
  if (!std::isfinite(o.clearance_mm) || o.clearance_mm < 0 || o.clearance_mm > kClashMaxDistanceM * 1000)
    return usage_error(command + ": --clearance must be from 0 (off) to " + max_mm + " mm, got " +
                       std::to_string(o.clearance_mm));
  if (o.between.empty() != o.with.empty()) return usage_error(command + ": --between and --and go together");

  std::string error;
  const auto store = Store::open(store_dir, Store::Mode::read_only, error);
  if (!store) return runtime_failure(error);
  view = store->read(error);
  if (!view) return runtime_failure(error);
  if (!o.include_connected && view->info().objects > 0 &&
      view->info().statistics.objects_by_class[int(ObjectClass::pipeline)] == 0)
    return usage_error(command + ": the store " + store_dir +
                       " has no piping topology (no pipeline objects: an RVM file without its attributes?), so "
                       "the rules that exempt a line's own parts, connected ends, supports and nozzles cannot "
                       "apply: run with --include-connected to report every contact");
  for (const auto& [option, word] : {std::pair{"--between", &o.between}, std::pair{"--and", &o.with}}) {
    ClashSet set;
    set.word = *word;
    bool matches = false;
    if (!clash_set_matches(*view, set, matches, error)) return runtime_failure(error);
    if (!matches)
      return usage_error(command + ": " + option + " '" + set.word +
                         "' matches no object of the store (a class: equipment, pipeline, pipe, component, "
                         "structure, other; or a glob on the tag)");
  }
  if (o.since.empty()) return 0;
  if (!read_clashes_file(o.since, read_previous_clashes, previous, error)) return runtime_failure("--since " + error);
  // The store and settings a run would record (find_clashes), compared as match_previous does.
  if (!view->spatial_ready(error)) return runtime_failure(error);
  ClashReport run;
  std::error_code ec;
  const auto canonical = std::filesystem::weakly_canonical(store_dir, ec);
  run.store_directory = ec ? store_dir : canonical.string();
  run.spatial_origin_m = view->spatial_origin();
  run.tolerance_m = o.tolerance_mm / 1000;
  run.clearance_m = o.clearance_mm / 1000;
  run.between = o.between;
  run.with = o.with;
  run.include_connected = o.include_connected;
  std::vector<bool> matched;
  if (!match_previous(run, previous, matched, error)) return runtime_failure("--since " + o.since + ": " + error);
  return 0;
}

Action add_clash_command(CLI::App& app) {
  auto args = std::make_shared<ClashArgs>();
  auto* clash = app.add_subcommand("clash", "Clash detection: objects that interpenetrate or come too close");
  clash->add_option("--store", args->store, "Store directory");
  clash->add_option("--tolerance", args->options.tolerance_mm, "Hard clash: penetration deeper than this (mm, default 1)");
  clash->add_option("--clearance", args->options.clearance_mm, "Clearance clash: closer than this (mm; default 0, off)");
  clash->add_option("--between", args->options.between, "Only pairs with one object in this set (a class or a glob on the tag)");
  clash->add_option("--and", args->options.with, "... and the other in this one");
  clash->add_flag("--include-connected", args->options.include_connected,
                  "Report what the rules exempt too (a pipeline's own parts, connected ends, supports)");
  clash->add_option("--since", args->options.since, "A previous clashes.json of this store: mark clashes new, active, resolved");
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
