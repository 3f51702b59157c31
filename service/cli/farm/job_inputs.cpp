#include "cli/farm/job_inputs.h"

#include <optional>

#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"
#include "plantview/store.h"

namespace plantview::cli::farm {

bool read_views_file(const std::string& path, std::vector<ReviewView>& views, std::string& text,
                     std::string& error) {
  if (!read_file(path, text, error)) return false;
  if (parse_review_views(text, views, error)) return true;
  error = path + ": " + error;
  return false;
}

bool check_subjects(const std::vector<ReviewView>& views, const ReadView& read, std::string& error) {
  std::string unknown;
  size_t count = 0;
  for (const ReviewView& view : views) {
    for (const uint64_t id : view.subject) {
      std::optional<uint32_t> slot;
      if (!read.slot_of(id, slot, error)) return false;
      if (slot) continue;
      if (++count <= 5)
        unknown += (unknown.empty() ? "" : ", ") + ("view '" + view.name + "': id " + std::to_string(id));
    }
  }
  if (count == 0) return true;
  error = std::to_string(count) + " subject id(s) are not objects of the store: " + unknown +
          (count > 5 ? ", ..." : "");
  return false;
}

std::string store_identity(const ReadView& read) {
  const StoreInfo info = read.info();
  // The commit id changes with every import, whatever the statistics say; the statistics
  // still tell apart stores of other origins whose imports happen to digest alike.
  return hash_hex(std::to_string(info.commit_id) + "\n" + statistics_json(info.statistics) + "\n" +
                  std::to_string(info.objects));
}

}  // namespace plantview::cli::farm
