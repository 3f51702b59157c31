// `plantview farm submit` and `farm status`: a views file rendered as N shards by a scheduler
// (Slurm job array, or local processes), and the account of what is done. The shard contract
// and the files in the output directory are stated in farm/scheduler.h and farm/manifest.h.
#include <sys/stat.h>

#include <charconv>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <tuple>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/farm/incremental.h"
#include "cli/farm/job_inputs.h"
#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"
#include "cli/farm/scheduler.h"
#include "plantview/clash.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

namespace fs = std::filesystem;

int fail(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 1;
}

struct SubmitArgs {
  std::string scheduler = "slurm", views, store, out, partition, time_limit;
  uint32_t tasks = 1, cpus_per_task = 1;
  bool dry_run = false;
  std::vector<std::pair<CLI::Option*, std::string>> render_values;  // given only
  std::vector<CLI::Option*> render_flags;
  std::vector<std::string> render_storage = std::vector<std::string>(24);
  std::vector<std::string> clip;  // --clip, repeatable
  bool clash = false;             // --clash: a clash job (clash options below), not a render
  std::vector<std::pair<CLI::Option*, std::string>> clash_values;  // given only
  std::vector<std::string> clash_storage = std::vector<std::string>(8);
  CLI::Option* include_connected = nullptr;
  std::string since;  // --since: a previous clashes.json (clash jobs only)
};

// The render options given to `farm submit`, as the shards' command line passes them on.
std::vector<std::string> passed_render_args(const SubmitArgs& a) {
  std::vector<std::string> args;
  for (const auto& [option, value] : a.render_values)
    if (option->count() > 0) args.insert(args.end(), {option->get_name(), value});
  for (CLI::Option* flag : a.render_flags)
    if (flag->count() > 0) args.push_back(flag->get_name());
  // One word each, so that a plane whose point starts with a minus stays a value.
  for (const std::string& plane : a.clip) args.push_back("--clip=" + plane);
  return args;
}

// The done views of DIR that the store's current state makes stale, and why
// (farm/incremental.h); writes DIR's objects file of that state if missing. Settings are not
// compared (the render options are not known here): `farm submit` re-renders views whose
// settings changed as well.
struct StaleViews {
  uint32_t revision = 0;  // the store's
  size_t done = 0;
  std::map<std::string, size_t> by_reason;
  std::vector<std::tuple<std::string, std::string, std::string>> views;  // name, reason, detail
};
bool stale_views(const fs::path& dir, const ReadView& read, StaleViews& out, std::string& error) {
  out = StaleViews{};
  out.revision = read.info().revision;
  const std::string identity = farm::store_identity(read);
  if (!farm::ensure_objects_file(dir, identity, read, error)) return false;
  std::map<std::string, nlohmann::json> newest;
  if (!farm::read_newest_records(dir, newest, error)) return false;
  const DAabb bounds = read.info().statistics.bounds;
  farm::StalenessJudge judge(dir, identity);
  std::error_code ec;
  for (const auto& [name, record] : newest) {
    if (record.value("status", "") != "done" || !fs::is_regular_file(dir / record.value("file", ""), ec))
      continue;
    ++out.done;
    farm::Staleness staleness;
    const std::string global = farm::global_inputs_hash(bounds, record.value("global_uses_bounds", true));
    if (!judge.judge(record, "", global, staleness, error)) return false;
    if (staleness.reason == farm::Staleness::Reason::fresh) continue;
    ++out.by_reason[farm::staleness_name(staleness.reason)];
    out.views.emplace_back(name, farm::staleness_name(staleness.reason), staleness.detail);
  }
  return true;
}

nlohmann::json stale_json(const StaleViews& stale) {
  nlohmann::json views = nlohmann::json::array();
  for (const auto& [name, reason, detail] : stale.views)
    views.push_back({{"name", name}, {"reason", reason}, {"detail", detail}});
  return {{"revision", stale.revision}, {"done", stale.done}, {"stale", stale.views.size()}, {"by_reason", stale.by_reason}, {"views", views}};
}

std::string stale_summary(const StaleViews& stale) {
  std::string text = std::to_string(stale.views.size()) + " of " + std::to_string(stale.done) +
                     " done views stale at the store's revision " + std::to_string(stale.revision);
  std::string reasons;
  for (const auto& [reason, count] : stale.by_reason)
    reasons += (reasons.empty() ? "" : ", ") + reason + ": " + std::to_string(count);
  return reasons.empty() ? text : text + " (" + reasons + ")";
}

// A clash job's marker in its output directory (farm status reads it): {"clash": true,
// "tasks": N, "store": ...}, and with --since "since": the copy's name in DIR (kClashSinceName)
// and "since_from": the file given (absolute).
constexpr const char* kClashJobName = "clash-job.json";
// The --since file as submit copied it into DIR, where every task can read it (the merging
// task applies it).
constexpr const char* kClashSinceName = "clash-since.json";

// A clash job's state: the shard files done of its `tasks` shards in `dir`, and once merged the
// merged file's clashes found (new and active; -1: not merged yet) and its entries by status.
struct ClashProgress {
  uint32_t done = 0;
  int64_t clashes = -1;
  std::map<std::string, int64_t> by_status;  // "new", "active", "resolved"
};
// Counts the clashes of a clashes.json by status from parser events (clash.h's format: each
// clash an object in the top-level "clashes" list), never holding the file or its tree.
struct StatusCounter final : nlohmann::json_sax<nlohmann::json> {
  int64_t counts[3] = {};  // new, active, resolved
  int depth = 0;
  bool status_key = false;
  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t& v) override {
    if (status_key) {
      if (v == "new") ++counts[0];
      else if (v == "active") ++counts[1];
      else if (v == "resolved") ++counts[2];
    }
    return value();
  }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override { return open(); }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(); }
  bool end_array() override { return close(); }
  bool key(string_t& k) override {
    status_key = depth == 3 && k == "status";  // {"clashes": [{"status": ...}]}
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override { return false; }

 private:
  bool value() {
    status_key = false;
    return true;
  }
  bool open() {
    ++depth;
    return value();
  }
  bool close() {
    --depth;
    return true;
  }
};

ClashProgress clash_progress(const fs::path& dir, uint32_t tasks) {
  ClashProgress p;
  std::error_code ec;
  for (uint32_t i = 0; i < tasks; ++i)
    p.done += fs::exists(dir / ("clash-shard-" + std::to_string(i) + "-of-" + std::to_string(tasks) + ".json"), ec);
  std::ifstream file(dir / "clashes.json", std::ios::binary);
  StatusCounter counter;
  if (file && nlohmann::json::sax_parse(file, &counter)) {
    p.by_status = {{"new", counter.counts[0]}, {"active", counter.counts[1]}, {"resolved", counter.counts[2]}};
    p.clashes = counter.counts[0] + counter.counts[1];
  }
  return p;
}

// The job's state as `farm status --json` prints it; with --since (`since`: the file given)
// the merged file's new, active and resolved counts.
nlohmann::json clash_status_json(const fs::path& dir, uint32_t tasks, const std::string& since) {
  const ClashProgress p = clash_progress(dir, tasks);
  nlohmann::json out = {{"clash", true}, {"tasks", tasks}, {"shards_done", p.done}, {"complete", p.clashes >= 0}};
  if (p.clashes >= 0) out["clashes"] = p.clashes;
  if (!since.empty()) {
    out["since"] = since;
    if (p.clashes >= 0)
      for (const char* status : {"new", "active", "resolved"}) out[status] = p.by_status.at(status);
  }
  return out;
}

// "12 clashes" once merged, with --since "12 clashes (since F: 1 new, 11 active, 2 resolved)".
std::string clash_status_text(const nlohmann::json& status) {
  if (!status["complete"].get<bool>()) return "not merged yet";
  std::string text = "clashes.json: " + status["clashes"].dump() + " clashes";
  if (status.contains("new"))
    text += " (since " + status["since"].get<std::string>() + ": " + status["new"].dump() + " new, " +
            status["active"].dump() + " active, " + status["resolved"].dump() + " resolved)";
  return text;
}

// A clash option's value in millimetres, read as `clash` reads it: false when it is not a number.
bool millimetres(const std::string& text, double& mm) {
  char* end = nullptr;
  mm = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size();
}

// --dry-run: what the job would run, the Slurm script or each local shard's command line.
void print_dry_run(const farm::FarmJob& job, const std::string& scheduler) {
  if (scheduler == "slurm") {
    std::cout << farm::sbatch_script(job);
    return;
  }
  for (uint32_t i = 0; i < job.tasks; ++i) {
    for (const std::string& word : farm::shard_command(job, std::to_string(i) + "/" + std::to_string(job.tasks)))
      std::cout << word << " ";
    std::cout << "\n";
  }
}

// farm submit --clash: the clash pass as N shards (scheduler.h states the task's command).
int run_submit_clash(const SubmitArgs& a) {
  if (!a.views.empty())
    return usage_error("farm submit --clash: no --views (a clash job checks the store, then `views --per clash` "
                       "and a render job make its images)");
  for (const auto& [option, value] : a.render_values)
    if (option->count() > 0)
      return usage_error("farm submit --clash: " + option->get_name() +
                         " is a render option (a clash job takes --tolerance, --clearance, --between, --and, "
                         "--include-connected, --threads, --since)");
  std::string error;
  // What every task (or the merge) would refuse is refused here, before anything is queued or
  // an earlier job's output removed: the checks of `clash` itself (check_clash_options).
  ClashOptions options;
  for (const auto& [option, value] : a.clash_values) {
    if (option->count() == 0) continue;
    const std::string& name = option->get_name();
    if (name == "--tolerance" || name == "--clearance") {
      double& mm = name == "--tolerance" ? options.tolerance_mm : options.clearance_mm;
      if (!millimetres(value, mm))
        return usage_error("farm submit --clash: " + name + ": expected millimetres, got '" + value + "'");
    }
    unsigned threads = 0;
    if (name == "--threads" && (std::from_chars(value.data(), value.data() + value.size(), threads).ptr !=
                                    value.data() + value.size() ||
                                value.empty()))
      return usage_error("farm submit --clash: --threads: expected a whole number, got '" + value + "'");
    if (name == "--between") options.between = value;
    if (name == "--and") options.with = value;
  }
  options.include_connected = a.include_connected->count() > 0;
  options.since = a.since;
  {
    std::unique_ptr<ReadView> view;
    PreviousClashes previous;
    if (const int status = check_clash_options("farm submit --clash", options, a.store, view, previous); status != 0)
      return status;
  }
  farm::FarmJob job;
  job.clash = true;
  job.tasks = a.tasks;
  job.cpus_per_task = a.cpus_per_task;
  job.partition = a.partition;
  job.time_limit = a.time_limit;
  bool threads_given = false;
  for (const auto& [option, value] : a.clash_values)
    if (option->count() > 0) {
      job.clash_args.insert(job.clash_args.end(), {option->get_name(), value});
      threads_given = threads_given || option->get_name() == "--threads";
    }
  if (a.include_connected->count() > 0) job.clash_args.push_back("--include-connected");
  // A task uses the CPUs it asked for (Slurm's), not every core of its node.
  if (!threads_given) job.clash_args.insert(job.clash_args.end(), {"--threads", std::to_string(a.cpus_per_task)});
  std::error_code ec;
  job.program = fs::read_symlink("/proc/self/exe", ec).string();
  if (ec) return fail("cannot find this program's path (/proc/self/exe): " + ec.message());
  job.store = fs::absolute(a.store);
  job.out = fs::absolute(a.out);
  // The merging task reads the previous result from DIR (a path every node reaches).
  if (!a.since.empty()) job.clash_args.insert(job.clash_args.end(), {"--since", (job.out / kClashSinceName).string()});
  if (a.dry_run) {
    print_dry_run(job, a.scheduler);
    return 0;
  }
  if (!farm::prepare_output_dir(job.out, error) || !farm::prepare_output_dir(job.out / "logs", error))
    return fail(error);
  // The previous result copied first: --since may name DIR/clashes.json, removed next.
  if (!a.since.empty() && !farm::copy_file_atomically(a.since, job.out / kClashSinceName, error))
    return fail(error);
  // A new job: what an earlier one left (its shards, its merge, its --since copy) would read as
  // this one's.
  fs::remove(job.out / "clashes.json", ec);
  if (a.since.empty()) fs::remove(job.out / kClashSinceName, ec);
  for (uint32_t i = 0; i < job.tasks; ++i)
    fs::remove(job.out / ("clash-shard-" + std::to_string(i) + "-of-" + std::to_string(job.tasks) + ".json"), ec);
  nlohmann::json marker = {{"clash", true}, {"tasks", job.tasks}, {"store", job.store.string()}};
  if (!a.since.empty()) {
    marker["since"] = kClashSinceName;
    marker["since_from"] = fs::absolute(a.since).string();
  }
  if (!farm::write_file_atomically(job.out / kClashJobName, marker.dump() + "\n", error)) return fail(error);
  if (a.scheduler == "slurm") {
    const fs::path script = job.out / "farm.sbatch";
    if (!farm::write_file_atomically(script, farm::sbatch_script(job), error)) return fail(error);
    ::chmod(script.c_str(), 0755);
    std::string job_id;
    if (!farm::submit_to_slurm(script, job_id, error)) {
      fs::remove(script, ec);
      fs::remove(job.out / kClashJobName, ec);
      return fail(error);
    }
    std::cerr << "plantview: submitted clash job " << job_id << " (" << job.tasks << " tasks; script "
              << script.string() << "); `plantview farm status " << job.out.string()
              << "` tells how far it got\n";
    std::cout << job_id << "\n";
    return 0;
  }
  const bool shards_ok = farm::run_local_shards(job, error);
  std::cout << clash_status_json(job.out, job.tasks, a.since.empty() ? "" : fs::absolute(a.since).string()).dump()
            << "\n";
  if (!shards_ok) return fail(error);
  return 0;
}

int run_submit(const SubmitArgs& a) {
  if (a.clash) return run_submit_clash(a);
  if (a.views.empty()) return usage_error("farm submit: --views is required (or --clash)");
  if (!a.since.empty())
    return usage_error("farm submit: --since is a clash job's option (--clash); a render job re-renders what "
                       "changed by itself");
  std::string error, text;
  farm::FarmJob job;
  job.tasks = a.tasks;
  job.cpus_per_task = a.cpus_per_task;
  job.partition = a.partition;
  job.time_limit = a.time_limit;
  job.render_args = passed_render_args(a);
  // The BCF file is written from the shards' working directory: named absolutely here.
  for (size_t k = 0; k + 1 < job.render_args.size(); ++k)
    if (job.render_args[k] == "--bcf") job.render_args[k + 1] = fs::absolute(job.render_args[k + 1]).string();
  // A render option every shard would refuse is refused here, before anything is written.
  if (const int status = check_render_options(job.render_args, a.views, a.out); status != 0)
    return status;
  std::error_code ec;
  job.program = fs::read_symlink("/proc/self/exe", ec).string();
  if (ec) return fail("cannot find this program's path (/proc/self/exe): " + ec.message());
  job.store = fs::absolute(a.store);
  job.out = fs::absolute(a.out);

  // Everything that can be refused is checked here, before a task starts.
  std::vector<ReviewView> views;
  if (!farm::read_views_file(a.views, views, text, error)) return fail(error);
  if (a.tasks > views.size())
    return usage_error("--tasks: " + std::to_string(a.tasks) + " shards for " +
                       std::to_string(views.size()) + " views would leave shards without work");
  {
    auto store = Store::open(job.store.string(), Store::Mode::read_only, error);
    if (!store) return fail(error);
    auto read = store->read(error);
    if (!read || !farm::check_subjects(views, *read, error)) return fail(a.views + ": " + error);
  }
  if (a.dry_run) {
    print_dry_run(job, a.scheduler);
    return 0;
  }
  // What this submit adds to the output directory, taken back if the scheduler refuses the job
  // (a refused submit leaves the directory as it was).
  const bool out_existed = fs::exists(job.out, ec);
  const bool logs_existed = fs::exists(job.out / "logs", ec);
  const bool views_copy_existed = fs::exists(job.out / farm::kViewsCopyName, ec);
  const bool objects_dir_existed = fs::exists(job.out / "objects", ec);
  fs::path objects_written;
  const auto take_back = [&](const fs::path& script) {
    std::error_code ignored;
    fs::remove(script, ignored);
    if (!out_existed) {
      fs::remove_all(job.out, ignored);
      return;
    }
    if (!views_copy_existed) fs::remove(job.out / farm::kViewsCopyName, ignored);
    if (!logs_existed) fs::remove(job.out / "logs", ignored);  // only if still empty
    if (!objects_written.empty()) fs::remove(objects_written, ignored);
    if (!objects_dir_existed) fs::remove(job.out / "objects", ignored);  // only if still empty
  };
  if (!farm::prepare_output_dir(job.out, error) || !farm::prepare_output_dir(job.out / "logs", error))
    return fail(error);
  {
    // The store's objects at this state, once for every shard; and what an earlier run left
    // that this state makes stale (the shards judge each view again, settings included).
    auto store = Store::open(job.store.string(), Store::Mode::read_only, error);
    if (!store) return fail(error);
    auto read = store->read(error);
    if (!read) return fail(error);
    const fs::path objects = farm::objects_file(job.out, farm::store_identity(*read));
    if (!fs::exists(objects, ec)) objects_written = objects;
    StaleViews stale;
    if (!stale_views(job.out, *read, stale, error)) return fail(error);
    if (stale.done > 0) std::cerr << "plantview: " << stale_summary(stale) << "\n";
  }
  if (!fs::equivalent(a.views, job.out / farm::kViewsCopyName, ec) &&
      !farm::write_file_atomically(job.out / farm::kViewsCopyName, text, error))
    return fail(error);

  if (a.scheduler == "slurm") {
    const fs::path script = job.out / "farm.sbatch";
    const bool script_existed = fs::exists(script, ec);
    if (!farm::write_file_atomically(script, farm::sbatch_script(job), error)) return fail(error);
    ::chmod(script.c_str(), 0755);
    std::string job_id;
    if (!farm::submit_to_slurm(script, job_id, error)) {
      take_back(script_existed ? fs::path() : script);
      return fail(error);
    }
    std::cerr << "plantview: submitted job " << job_id << " (" << job.tasks << " tasks, "
              << views.size() << " views; script " << script.string()
              << "); `plantview farm status " << job.out.string() << "` tells how far it got\n";
    std::cout << job_id << "\n";
    return 0;
  }
  const bool shards_ok = farm::run_local_shards(job, error);
  const std::string shard_error = error;
  farm::FarmSummary summary;
  if (!farm::merge_manifests(job.out, summary, error)) return fail(error);
  std::cout << farm::summary_json(summary).dump() << "\n";
  if (!shards_ok) return fail(shard_error);
  return 0;
}

int run_status(const std::string& dir, const std::string& store_dir, bool json) {
  std::string error, text;
  std::error_code ec;
  if (!fs::is_regular_file(fs::path(dir) / farm::kViewsCopyName, ec) &&
      farm::read_file(fs::path(dir) / kClashJobName, text, error)) {
    // A clash job: its shards done and its merge.
    const nlohmann::json marker = nlohmann::json::parse(text, nullptr, false);
    if (marker.is_discarded() || !marker.contains("tasks") || !marker["tasks"].is_number_unsigned())
      return fail((fs::path(dir) / kClashJobName).string() + ": not a clash job's marker");
    const std::string since = marker.contains("since_from") && marker["since_from"].is_string()
                                  ? marker["since_from"].get<std::string>()
                                  : std::string();
    const nlohmann::json out = clash_status_json(dir, marker["tasks"].get<uint32_t>(), since);
    if (json)
      std::cout << out.dump() << "\n";
    else
      std::cout << "clash job: " << out["shards_done"] << " of " << out["tasks"] << " shards done; "
                << clash_status_text(out) << "\n";
    return 0;
  }
  if (!fs::is_regular_file(fs::path(dir) / farm::kViewsCopyName, ec))
    return fail(dir + ": not a farm output directory (no " + farm::kViewsCopyName + ")");
  farm::FarmSummary summary;
  if (!farm::merge_manifests(dir, summary, error)) return fail(error);
  StaleViews stale;
  if (!store_dir.empty()) {
    auto store = Store::open(store_dir, Store::Mode::read_only, error);
    if (!store) return fail(error);
    auto read = store->read(error);
    if (!read || !stale_views(dir, *read, stale, error)) return fail(error);
  }
  if (json) {
    nlohmann::json out = farm::summary_json(summary);
    if (!store_dir.empty()) out["stale"] = stale_json(stale);
    std::cout << out.dump() << "\n";
    return 0;
  }
  std::cout << summary.views << " views: " << summary.done.size() << " done, " << summary.failed.size()
            << " failed, " << summary.missing.size() << " missing\n";
  const auto list = [](const char* label, const std::vector<std::string>& names) {
    if (names.empty()) return;
    std::cout << label << ":";
    for (const std::string& name : names) std::cout << " " << name;
    std::cout << "\n";
  };
  list("failed", summary.failed);
  list("missing", summary.missing);
  if (!store_dir.empty()) {
    std::cout << stale_summary(stale) << "\n";
    for (const auto& [name, reason, detail] : stale.views)
      std::cout << "stale: " << name << ": " << reason << " (" << detail << ")\n";
  }
  return 0;
}

}  // namespace

Action add_farm_command(CLI::App& app) {
  auto* farm = app.add_subcommand("farm", "Render a views file on a scheduler (Slurm or local shards)");
  farm->require_subcommand(1);

  auto a = std::make_shared<SubmitArgs>();
  auto* submit = farm->add_subcommand(
      "submit", "Render a views file as N shards: a Slurm job array, or N local processes");
  submit->add_option("--scheduler", a->scheduler, "slurm or local")
      ->check(CLI::IsMember({"slurm", "local"}))
      ->capture_default_str();
  submit->add_option("--views", a->views, "Views file (from `plantview views`); not with --clash");
  submit->add_option("--store", a->store, "Store directory (every task opens it read-only)")->required();
  submit->add_option("--out", a->out, "Output directory (shared by every task)")->required();
  submit->add_option("--tasks", a->tasks, "Shards, one task each")->required()->check(CLI::Range(1u, 10000u));
  submit->add_option("--partition", a->partition, "Slurm partition (default: the cluster's)");
  submit->add_option("--time", a->time_limit, "Slurm time limit per task, e.g. 30:00");
  submit->add_option("--cpus-per-task", a->cpus_per_task, "Slurm CPUs per task (software renderer threads)")
      ->check(CLI::Range(1u, 1024u))
      ->capture_default_str();
  submit->add_flag("--dry-run", a->dry_run, "Print the sbatch script (or the local command lines); submit nothing");
  // Render options, passed on to every shard as given (see `plantview render --help`).
  const std::pair<const char*, const char*> values[] = {
      {"--size", "Image size WxH"},
      {"--format", "png or jpeg"},
      {"--quality", "JPEG quality 1..100"},
      {"--lod-policy", "screen-space, distance or none"},
      {"--pixel-error", "Allowed screen-space error (pixels)"},
      {"--vertex-budget", "GPU vertex arena (MB)"},
      {"--samples", "Multisampling per pixel"},
      {"--antialias", "automatic, multisampling, supersampling, edge-filter or off"},
      {"--occlusion", "on or off"},
      {"--occlusion-test", "automatic, coarse or exact"},
      {"--device", "EGL device index"},
      {"--bcf", "BCF file of the views, written by the shard that finds the job complete"},
      {"--section-box", "Section box MINX,MINY,MINZ,MAXX,MAXY,MAXZ (each view's own wins)"},
      {"--colour-by", "KEY: colour objects by this attribute (replaces the views' own)"},
      {"--hide", "CLASS|GLOB,...: leave these out (replaces the views' own)"},
      {"--only", "CLASS|GLOB,...: show only these (replaces the views' own)"}};
  size_t i = 0;
  for (const auto& [name, help] : values) {
    CLI::Option* option = submit->add_option(name, a->render_storage[i], help);
    a->render_values.emplace_back(option, std::string());
    ++i;
  }
  for (const char* name : {"--force", "--no-centrelines", "--no-hlod", "--no-subpixel-culling",
                           "--no-ground", "--no-ambient-occlusion", "--no-caps"})
    a->render_flags.push_back(submit->add_flag(name)->description("Passed on to render"));
  submit->add_option("--clip", a->clip,
                     "Clip plane PX,PY,PZ,NX,NY,NZ, repeatable (each view's own section wins)");
  // A clash job instead of a render: `clash --shard I/N` per task, merged by the last one.
  submit->add_flag("--clash", a->clash,
                   "Run the clash pass as N shards (clash options below) into OUT/clashes.json");
  const std::pair<const char*, const char*> clash_values[] = {
      {"--tolerance", "clash: hard clash deeper than this (mm)"},
      {"--clearance", "clash: clearance clash closer than this (mm)"},
      {"--between", "clash: one object in this set (class or glob)"},
      {"--and", "clash: the other in this one"},
      {"--threads", "clash: worker threads a task (default: --cpus-per-task)"}};
  size_t j = 0;
  for (const auto& [name, help] : clash_values) {
    CLI::Option* option = submit->add_option(name, a->clash_storage[j], help);
    a->clash_values.emplace_back(option, std::string());
    ++j;
  }
  a->include_connected = submit->add_flag("--include-connected")->description("clash: report what the rules exempt");
  submit->add_option("--since", a->since,
                     "clash: a previous clashes.json of this store and settings; the merge marks clashes new, "
                     "active, resolved (copied into OUT at submit)");

  auto status_dir = std::make_shared<std::string>();
  auto status_json = std::make_shared<bool>(false);
  auto status_store = std::make_shared<std::string>();
  auto* status = farm->add_subcommand(
      "status", "Done, failed and missing views of an output directory; merges the shards' manifests");
  status->add_option("DIR", *status_dir, "Output directory of a farm job")->required();
  status->add_flag("--json", *status_json, "One JSON object on stdout");
  status->add_option("--store", *status_store,
                     "Also say which done views the store's current state makes stale, and why");

  return [=]() -> int {
    if (submit->parsed()) {
      for (size_t k = 0; k < a->render_values.size(); ++k) a->render_values[k].second = a->render_storage[k];
      for (size_t k = 0; k < a->clash_values.size(); ++k) a->clash_values[k].second = a->clash_storage[k];
      return run_submit(*a);
    }
    if (status->parsed()) return run_status(*status_dir, *status_store, *status_json);
    return -1;
  };
}

}  // namespace plantview::cli
