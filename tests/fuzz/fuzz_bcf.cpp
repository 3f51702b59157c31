// Fuzz harness for BCF files (plantview/bcf.h: read_bcf), the zip archive and the XML in it,
// read without a store. For any input:
//   - a failure leaves the output alone and says what is wrong (a message that is not empty);
//   - whatever is accepted gives views that hold the views file's rules: written as a views file
//     (review_views_json) they read back (parse_review_views) as many as they were.
// The bytes reach read_bcf as a file: an anonymous in-memory file (memfd) named through /proc.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "plantview/bcf.h"
#include "plantview/review.h"

namespace {

void check(bool condition) {
  if (!condition) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const int fd = memfd_create("bcf", 0);
  check(fd >= 0);
  size_t written = 0;
  while (written < size) {
    const ssize_t n = write(fd, data + written, size - written);
    check(n > 0);
    written += size_t(n);
  }
  std::vector<plantview::ReviewView> views(1);
  views[0].name = "untouched";
  plantview::BcfReadOptions options;
  options.max_entry_bytes = 4u << 20;  // keep each run small
  options.max_total_bytes = 16u << 20;
  plantview::BcfReadReport report;
  std::string error;
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  if (!plantview::read_bcf(path, nullptr, options, views, report, error)) {
    check(!error.empty());
    check(views.size() == 1 && views[0].name == "untouched");
  } else {
    check(report.imported == views.size());
    if (!views.empty()) {
      std::vector<plantview::ReviewView> again;
      check(plantview::parse_review_views(plantview::review_views_json(views, "area"), again, error));
      check(again.size() == views.size());
    }
  }
  close(fd);
  return 0;
}
