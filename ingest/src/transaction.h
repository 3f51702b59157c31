// One ingest call's store transaction, with the rules every entry point shares: the stop token
// is checked before each object, progress goes to the caller's callback, the counts of what was
// put are kept, and the first error is kept as the call's result. The Import it holds aborts
// unless committed, so returning early (or unwinding) leaves the store as it was.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "plantview/ingest.h"

namespace plantview::ingest_detail {

// Thrown out of a generator or XML-reader sink to unwind it once the transaction has failed or
// been cancelled; the entry points catch it and return the error the Transaction holds.
struct Abandon {};

class Transaction {
 public:
  Transaction(Store& store, const IngestControl& control);
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

  // Starts the store transaction. False (error() set) if cancelled already or the store refuses.
  bool begin();
  // False with the error "cancelled" set when a stop was requested.
  bool check_stop();
  bool remove_source(std::string_view source);
  // Checks the stop token, then puts the object (the store counts its statistics: see commit()).
  bool put(const Object& object);
  // Reports the committing stage and commits; the result is the summary or the error, whose
  // `added` adds the statistics of the objects put (Import::put_statistics()) to what the caller
  // counted there itself.
  IngestResult commit();

  void report(IngestStage stage, uint64_t done, uint64_t total, std::string_view path = {});
  // Which model file the next reports are about.
  void set_file(uint32_t index, uint32_t count) { file_index_ = index, file_count_ = count; }

  void fail_input(std::string message, std::string path);
  // The error that stopped the call (asserts there is one).
  IngestResult failure();
  IngestSummary& summary() { return summary_; }

 private:
  void fail_store();

  Store& store_;
  const IngestControl& control_;
  std::unique_ptr<Import> import_;
  std::string store_error_;
  std::optional<IngestError> error_;
  IngestSummary summary_;
  uint32_t file_index_ = 0, file_count_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace plantview::ingest_detail
