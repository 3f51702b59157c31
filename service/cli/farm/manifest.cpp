#include "cli/farm/manifest.h"

#include <chrono>
#include <cstdio>
#include <regex>

#include "cli/farm/contact_sheet.h"
#include "cli/farm/output_dir.h"

namespace plantview::cli::farm {

namespace fs = std::filesystem;
using nlohmann::json;

std::string hash_hex(std::string_view text) {
  uint64_t h = 14695981039346656037ull;
  for (const unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

std::string manifest_part_name(uint32_t shard_index, uint32_t shard_count) {
  return "manifest." + std::to_string(shard_index) + "-of-" + std::to_string(shard_count) + ".json";
}

int64_t unix_ms_now() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool read_newest_records(const fs::path& dir, std::map<std::string, json>& newest,
                         std::string& error) {
  static const std::regex part_pattern(R"(manifest\.[0-9]+-of-[0-9]+\.json)");
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string file = entry.path().filename().string();
    if (!std::regex_match(file, part_pattern)) continue;
    std::string text;
    if (!read_file(entry.path(), text, error)) return false;
    const json part = json::parse(text, nullptr, false);
    if (!part.is_object() || !part.contains("views") || !part["views"].is_array()) {
      error = entry.path().string() + ": not a manifest part (an object with a \"views\" list)";
      return false;
    }
    for (const json& record : part["views"]) {
      if (!record.is_object() || !record.contains("name") || !record["name"].is_string() ||
          !record.contains("finished_unix_ms") || !record["finished_unix_ms"].is_number_integer()) {
        error = entry.path().string() + ": a record without \"name\" or \"finished_unix_ms\"";
        return false;
      }
      json& kept = newest[record["name"].get<std::string>()];
      // The newest; of two records of one image, the one checked last against the store
      // (incremental.h: a kept view's record is rewritten with the store state it holds for).
      const auto newer = [](const json& r, const json& than) {
        const int64_t f = r["finished_unix_ms"].get<int64_t>(), g = than["finished_unix_ms"].get<int64_t>();
        return f != g ? f > g : r.value("checked_unix_ms", int64_t(0)) >= than.value("checked_unix_ms", int64_t(0));
      };
      if (kept.is_null() || newer(record, kept)) kept = record;
    }
  }
  if (ec) {
    error = "cannot list " + dir.string() + ": " + ec.message();
    return false;
  }
  return true;
}

bool write_manifest_part(const fs::path& dir, uint32_t shard_index, uint32_t shard_count,
                         const std::vector<json>& records, std::string& error) {
  const json part = {{"version", 1},
                     {"shard", std::to_string(shard_index) + "/" + std::to_string(shard_count)},
                     {"views", records}};
  return write_file_atomically(dir / manifest_part_name(shard_index, shard_count), part.dump(1) + "\n",
                               error);
}

json summary_json(const FarmSummary& summary) {
  return {{"views", summary.views},
          {"done", summary.done.size()},
          {"failed", summary.failed.size()},
          {"missing", summary.missing.size()},
          {"complete", summary.done.size() == summary.views},
          {"failed_views", summary.failed},
          {"missing_views", summary.missing}};
}

bool merge_manifests(const fs::path& dir, FarmSummary& summary, std::string& error) {
  // Merged one process at a time: the shards of a job finish together and each merges.
  DirLock lock(dir, error);
  if (!lock.locked()) return false;
  std::string text;
  if (!read_file(dir / kViewsCopyName, text, error)) return false;
  const json views = json::parse(text, nullptr, false);
  if (!views.is_object() || !views.contains("views") || !views["views"].is_array()) {
    error = (dir / kViewsCopyName).string() + ": not a views file (an object with a \"views\" list)";
    return false;
  }
  std::map<std::string, json> newest;
  if (!read_newest_records(dir, newest, error)) return false;

  summary = FarmSummary{};
  json entries = json::array();
  std::string stats_lines;
  for (const json& view : views["views"]) {
    const std::string name = view.value("name", "");
    ++summary.views;
    const auto found = newest.find(name);
    std::error_code ec;
    if (found != newest.end() && found->second.value("status", "") == "done" &&
        fs::is_regular_file(dir / found->second.value("file", ""), ec)) {
      summary.done.push_back(name);
      entries.push_back(found->second);
      json line = found->second.value("stats", json::object());
      line["view"] = name;
      line["file"] = found->second.value("file", "");
      stats_lines += line.dump() + "\n";
    } else if (found != newest.end() && found->second.value("status", "") == "failed") {
      summary.failed.push_back(name);
      entries.push_back(found->second);
    } else {
      summary.missing.push_back(name);
      entries.push_back({{"name", name},
                         {"title", view.value("title", "")},
                         {"kind", view.value("kind", "")},
                         {"status", "missing"}});
    }
  }
  const json manifest = {{"version", 1}, {"summary", summary_json(summary)}, {"views", entries}};
  return write_file_atomically(dir / kManifestName, manifest.dump(1) + "\n", error) &&
         write_file_atomically(dir / kStatsName, stats_lines, error) &&
         write_file_atomically(dir / kContactSheetName, contact_sheet_html(manifest), error);
}

}  // namespace plantview::cli::farm
