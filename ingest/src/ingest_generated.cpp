// Generated plants and objects in memory into a store: remove what their sources brought, put
// the objects as they come, commit.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <set>

#include "plantview/ingest.h"
#include "transaction.h"

namespace plantview {

using ingest_detail::Abandon;
using ingest_detail::Transaction;

IngestResult ingest_generated(Store& store, const GenerateOptions& options, const IngestControl& control) {
  assert(preset_info(options.preset) && "unknown preset: check it with parse_preset()");
  assert(options.scale >= 1 && options.scale <= kMaxGenerateScale && "scale out of range");
  Transaction t(store, control);
  const std::string source = "gen:" + std::string(1, options.preset);
  if (!t.begin() || !t.remove_source(source)) return t.failure();

  const uint64_t total = 1000 * uint64_t(options.scale);
  uint64_t reported = 0;
  t.report(IngestStage::generating, 0, total);
  try {
    t.summary().generated = generate_plant(
        options,
        [&](Object&& object) {
          object.source = source;
          if (!t.put(object)) throw Abandon{};
        },
        [&](double fraction) {
          // Thousandths of a unit, never backwards, and a report only when the figure moves.
          const auto done = std::min(total, uint64_t(std::floor(fraction * double(total))));
          if (done > reported) t.report(IngestStage::generating, reported = done, total);
          if (!t.check_stop()) throw Abandon{};
        });
  } catch (const Abandon&) {
    return t.failure();
  }
  return t.commit();
}

IngestResult ingest_objects(Store& store, std::span<const Object> objects, const IngestControl& control) {
  Transaction t(store, control);
  if (!t.begin()) return t.failure();
  std::set<std::string_view> sources;
  for (const Object& o : objects) sources.insert(o.source);
  for (std::string_view s : sources) {
    if (!t.remove_source(s)) return t.failure();
  }
  t.report(IngestStage::storing, 0, objects.size());
  for (size_t k = 0; k < objects.size(); ++k) {
    if (!t.put(objects[k])) return t.failure();
    t.report(IngestStage::storing, k + 1, objects.size());
  }
  return t.commit();
}

}  // namespace plantview
