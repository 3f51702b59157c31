// Handing a farm job's shards to a scheduler: Slurm (a job array, one task per shard) or local
// processes.
//
// The shard contract (what every scheduler runs): task I of N runs
//   plantview render --store STORE --views OUT/views.json --out OUT --shard I/N [render options]
// which opens the store once and renders views I, I+N, I+2N... of the views file, skipping views
// already done with the same settings (manifest.h). Any scheduler that starts N such processes
// with distinct I (a Slurm array, a Kubernetes Indexed Job's JOB_COMPLETION_INDEX) runs the job;
// running a task again, or the whole job, completes what is missing and renders nothing twice.
// A clash job (farm submit --clash) runs instead, in task I of N,
//   plantview clash --store STORE --shard I/N --farm-dir OUT [clash options]
//                   [--since OUT/clash-since.json]
// which checks the I-th region's block pairs into OUT/clash-shard-I-of-N.json; the task that
// finds all N there merges them into OUT/clashes.json (clash.h: merge_reports; docs/clash.md),
// and with --since (the previous result, copied there by farm submit) sets the statuses.
// Errors: false with a message naming the program and what it said (sbatch's own message).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace plantview::cli::farm {

struct FarmJob {
  std::string program;                    // absolute path of the plantview program
  std::filesystem::path store, out;       // absolute
  uint32_t tasks = 1;                     // shards, one task each
  uint32_t cpus_per_task = 1;             // Slurm: CPUs a task asks for (software renderer threads)
  std::vector<std::string> render_args;   // further render options, e.g. {"--size", "1280x720"}
  std::string partition, time_limit;      // Slurm; empty: the cluster's defaults
  bool clash = false;                     // a clash job: clash_args, not render_args
  std::vector<std::string> clash_args;    // further clash options, e.g. {"--tolerance", "5"}
};

// The render (or clash) command line of one shard; `shard` is "I/N" or a shell expression for it.
std::vector<std::string> shard_command(const FarmJob& job, const std::string& shard);

// The sbatch script of the job's array (shell-quoted; logs to OUT/logs/slurm-<job>_<task>.log).
std::string sbatch_script(const FarmJob& job);

// Runs `sbatch --parsable SCRIPT` ($PLANTVIEW_SBATCH, else sbatch on the PATH) and returns the
// job id it prints. Fails with sbatch's message when it refuses the job.
bool submit_to_slurm(const std::filesystem::path& script, std::string& job_id, std::string& error);

// Runs the N shards as processes on this machine, all at once, each logging to
// OUT/logs/local-<I>.log, and waits for them. False naming each shard that failed and its log.
bool run_local_shards(const FarmJob& job, std::string& error);

}  // namespace plantview::cli::farm
