// The farm's manifests: what each task rendered, and the merged account of a whole job.
//
// Files in an output directory DIR (each written atomically, output_dir.h):
//   views.json                the views file the job renders (a copy; every shard reads it)
//   manifest.<I>-of-<N>.json  one per shard: {"version": 1, "shard": "I/N", "views": [record]},
//                             rewritten after every view, so that it lists what a killed task
//                             finished; a shard run again keeps the records of the views it
//                             skipped
//   manifest.json             the merge: {"version": 1, "summary": {...}, "views": [...]}, one
//                             entry per view of views.json in its order: the newest record of that
//                             view from any part, or {"name", "title", "kind", "status": "missing"}
//   stats.jsonl               the merge's LOD statistics, one line per rendered view
//   index.html                the contact sheet (contact_sheet.h)
// A record: name, title, kind, file (relative to DIR), camera, aspect, subject, status ("done" or
// "failed", with "error"), settings_hash (the view, size, format and render options), shard,
// finished_unix_ms, ms (the view's cost split: frame, caption, encode, write, total;
// store_open_ms once per process), stats (FrameStats); and what the incremental farm judges it
// by (incremental.h): store (the store state it holds for) and revision (its number), global and global_uses_bounds,
// size {width, height}, section, drawn {file, objects, regions, pipelines, digest}; where it
// was rendered again, rendered_because ("changed object: ..."); where a later state was found
// not to change it, checked_unix_ms.
// A view counts as done when its newest record (finished last; of equal ones, checked last)
// says done and its image file exists.
// Threads: plain functions; merges of one DIR are serialised across processes (DirLock).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace plantview::cli::farm {

inline constexpr const char* kViewsCopyName = "views.json";
inline constexpr const char* kManifestName = "manifest.json";
inline constexpr const char* kStatsName = "stats.jsonl";
inline constexpr const char* kContactSheetName = "index.html";

// 64-bit FNV-1a of `text` as 16 lower-case hex digits (settings hashes: stable across runs,
// machines and builds; not for security).
std::string hash_hex(std::string_view text);

// "manifest.<I>-of-<N>.json".
std::string manifest_part_name(uint32_t shard_index, uint32_t shard_count);

// Milliseconds since the Unix epoch, now.
int64_t unix_ms_now();

// Reads every manifest part of `dir` and keeps, per view name, the record finished last.
// A part that is not JSON of the form above fails with its path (a killed writer never leaves
// one: parts are written atomically).
bool read_newest_records(const std::filesystem::path& dir,
                         std::map<std::string, nlohmann::json>& newest, std::string& error);

bool write_manifest_part(const std::filesystem::path& dir, uint32_t shard_index,
                         uint32_t shard_count, const std::vector<nlohmann::json>& records,
                         std::string& error);

struct FarmSummary {
  size_t views = 0;
  std::vector<std::string> done, failed, missing;  // view names, in the views file's order
};
nlohmann::json summary_json(const FarmSummary& summary);

// Merges the parts of `dir` against its views.json into manifest.json, stats.jsonl and
// index.html (under DIR's lock). Errors: no or a bad views.json, a bad part, a failed write.
bool merge_manifests(const std::filesystem::path& dir, FarmSummary& summary, std::string& error);

}  // namespace plantview::cli::farm
