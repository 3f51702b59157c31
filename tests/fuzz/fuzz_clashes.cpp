// Fuzz harness for clashes files (plantview/clash.h: parse_clash_report, read_previous_clashes,
// append_resolved). For any input:
//   - a failure leaves the output alone and says what is wrong;
//   - whatever is accepted has a point for every clash and a valid shard, its keys (the reading
//     --since makes) agree with its clashes, and written back it reads back to the same text.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/clash.h"

namespace {

void check(bool condition) {
  if (!condition) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace plantview;
  const std::string text(reinterpret_cast<const char*>(data), size);
  ClashReport report;
  report.revision = 77;
  std::string error;
  if (!parse_clash_report(text, report, error)) {
    check(!error.empty());
    check(report.revision == 77 && report.clashes.empty());
    std::istringstream stream(text);
    PreviousClashes previous;
    check(!read_previous_clashes(stream, previous, error) && previous.keys.empty());
    return 0;
  }
  check(report.shard.count >= 1 && report.shard.index < report.shard.count);
  for (const Clash& c : report.clashes) check(!c.points_m.empty());
  std::istringstream stream(text);
  PreviousClashes previous;
  check(read_previous_clashes(stream, previous, error));
  check(previous.keys.size() == report.clashes.size());
  check(previous.header.revision == report.revision && previous.header.commit_id == report.commit_id);
  for (size_t i = 0; i < report.clashes.size(); ++i) {
    const Clash& c = report.clashes[i];
    const ClashKey& k = previous.keys[i];
    check(k.id == c.id && k.a == c.a.id && k.b == c.b.id && k.first_point_m == c.points_m.front());
    check(k.resolved == (c.status == ClashStatus::resolved));
  }
  const std::string written = clash_report_json(report);
  ClashReport again;
  check(parse_clash_report(written, again, error));
  check(again.clashes.size() == report.clashes.size());
  check(clash_report_json(again) == written);
  // Nothing matched: every clash not resolved already comes back resolved, read from the file.
  ClashReport empty = again;
  empty.clashes.clear();
  std::vector<bool> matched(previous.keys.size(), false);
  std::istringstream file(text);
  check(append_resolved(empty, file, matched, error));
  size_t open = 0;
  for (const ClashKey& k : previous.keys) open += !k.resolved;
  check(empty.clashes.size() == open);
  return 0;
}
