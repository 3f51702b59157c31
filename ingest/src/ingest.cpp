#include <cassert>

#include "plantview/ingest.h"

namespace plantview {

std::string_view stage_name(IngestStage stage) {
  switch (stage) {
    case IngestStage::parsing: return "parsing";
    case IngestStage::classifying: return "classifying";
    case IngestStage::storing: return "storing";
    case IngestStage::reading: return "reading";
    case IngestStage::generating: return "generating";
    case IngestStage::committing: return "committing";
  }
  return "unknown";
}

const IngestSummary& IngestResult::summary() const {
  assert(ok());
  return *std::get_if<0>(&state_);
}

const IngestError& IngestResult::error() const {
  assert(!ok());
  return *std::get_if<1>(&state_);
}

}  // namespace plantview
