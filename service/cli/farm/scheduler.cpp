#include "cli/farm/scheduler.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"

extern char** environ;

namespace plantview::cli::farm {

namespace fs = std::filesystem;

namespace {

std::string shell_quote(const std::string& word) {
  std::string out = "'";
  for (const char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Starts argv[0] (looked up on the PATH) with stdout and stderr sent to files; returns its pid,
// or -1 with the reason in `error`.
pid_t spawn_with_output(const std::vector<std::string>& argv, const fs::path& stdout_path,
                        const fs::path& stderr_path, std::string& error) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (stderr_path == stdout_path)
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
  else
    posix_spawn_file_actions_addopen(&actions, 2, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = ::posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    error = "cannot run " + argv[0] + ": " + std::strerror(rc);
    return -1;
  }
  return pid;
}

// Waits for `pid`; its exit status, or 128 + the signal that ended it.
int wait_for(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string trimmed(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text;
}

}  // namespace

std::vector<std::string> shard_command(const FarmJob& job, const std::string& shard) {
  if (job.clash) {
    std::vector<std::string> argv = {job.program, "clash",      "--store",         job.store.string(),
                                     "--shard",   shard,        "--farm-dir",      job.out.string()};
    argv.insert(argv.end(), job.clash_args.begin(), job.clash_args.end());
    return argv;
  }
  std::vector<std::string> argv = {job.program,           "render", "--store", job.store.string(),
                                   "--views",             (job.out / kViewsCopyName).string(),
                                   "--out",               job.out.string(),
                                   "--shard",             shard};
  argv.insert(argv.end(), job.render_args.begin(), job.render_args.end());
  return argv;
}

std::string sbatch_script(const FarmJob& job) {
  const std::string n = std::to_string(job.tasks);
  std::string s = "#!/bin/bash\n";
  if (job.clash)
    s += "# plantview farm clash job: " + n + " shards of the clash pass of " + job.store.string() +
         ",\n# merged by the last into " + (job.out / "clashes.json").string() + ";\n";
  else
    s += "# plantview farm job: " + n + " shards of " + (job.out / kViewsCopyName).string() + ",\n";
  s += "# one array task each. Written by `plantview farm submit`. Submitting it again (all of it,\n";
  s += "# or some tasks: sbatch --array=2 THIS) completes what failed or was cancelled: views\n";
  s += "# already done with the same settings are skipped. The shard count is written out, not\n";
  s += "# taken from SLURM_ARRAY_TASK_COUNT, so that a partial resubmission keeps the shards.\n";
  s += job.clash ? "#SBATCH --job-name=plantview-clash\n" : "#SBATCH --job-name=plantview-farm\n";
  s += "#SBATCH --array=0-" + std::to_string(job.tasks - 1) + "\n";
  s += "#SBATCH --ntasks=1\n";
  s += "#SBATCH --cpus-per-task=" + std::to_string(job.cpus_per_task) + "\n";
  s += "#SBATCH --output=" + (job.out / "logs" / "slurm-%A_%a.log").string() + "\n";
  if (!job.partition.empty()) s += "#SBATCH --partition=" + job.partition + "\n";
  if (!job.time_limit.empty()) s += "#SBATCH --time=" + job.time_limit + "\n";
  s += "set -eu\n";
  s += "# A software renderer (llvmpipe) uses as many threads as the task has CPUs.\n";
  s += "export LP_NUM_THREADS=\"${LP_NUM_THREADS:-${SLURM_CPUS_PER_TASK:-1}}\"\n";
  s += "exec";
  for (const std::string& word : shard_command(job, "@SHARD@")) {
    s += " ";
    s += word == "@SHARD@" ? "\"${SLURM_ARRAY_TASK_ID}/" + n + "\"" : shell_quote(word);
  }
  return s + "\n";
}

bool submit_to_slurm(const fs::path& script, std::string& job_id, std::string& error) {
  const char* configured = std::getenv("PLANTVIEW_SBATCH");
  const std::string sbatch = configured && *configured ? configured : "sbatch";
  const fs::path dir = script.parent_path();
  const fs::path out_path = dir / (".tmp-" + std::to_string(::getpid()) + "-sbatch.out"),
                 err_path = dir / (".tmp-" + std::to_string(::getpid()) + "-sbatch.err");
  const pid_t pid = spawn_with_output({sbatch, "--parsable", script.string()}, out_path, err_path, error);
  if (pid < 0) return false;
  const int status = wait_for(pid);
  std::string out, err, ignored;
  read_file(out_path, out, ignored);
  read_file(err_path, err, ignored);
  std::error_code ec;
  fs::remove(out_path, ec);
  fs::remove(err_path, ec);
  out = trimmed(out);
  if (status != 0 || out.empty()) {
    error = sbatch + " refused the job (exit status " + std::to_string(status) + "): " +
            (trimmed(err).empty() ? "no message" : trimmed(err));
    return false;
  }
  // --parsable prints "jobid" or "jobid;cluster".
  job_id = out.substr(0, out.find(';'));
  return true;
}

bool run_local_shards(const FarmJob& job, std::string& error) {
  std::vector<pid_t> pids;
  std::vector<fs::path> logs;
  for (uint32_t i = 0; i < job.tasks; ++i) {
    logs.push_back(job.out / "logs" / ("local-" + std::to_string(i) + ".log"));
    const pid_t pid = spawn_with_output(
        shard_command(job, std::to_string(i) + "/" + std::to_string(job.tasks)), logs.back(),
        logs.back(), error);
    if (pid < 0) break;
    pids.push_back(pid);
  }
  // Every shard that started is waited for, even when a later one could not start.
  std::string failures;
  for (size_t i = 0; i < pids.size(); ++i) {
    const int status = wait_for(pids[i]);
    if (status != 0)
      failures += (failures.empty() ? "" : "; ") + std::string("shard ") + std::to_string(i) + "/" +
                  std::to_string(job.tasks) + " exited with " + std::to_string(status) + " (log " +
                  logs[i].string() + ")";
  }
  if (pids.size() < job.tasks) return false;
  if (!failures.empty()) {
    error = failures;
    return false;
  }
  return true;
}

}  // namespace plantview::cli::farm
