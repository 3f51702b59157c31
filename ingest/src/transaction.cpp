#include "transaction.h"

#include <cassert>

namespace plantview::ingest_detail {

Transaction::Transaction(Store& store, const IngestControl& control) : store_(store), control_(control) {}

bool Transaction::begin() {
  if (!check_stop()) return false;
  import_ = store_.begin_import(store_error_);
  if (!import_) fail_store();
  if (import_) {
    import_->set_note(control_.note);
    import_->set_keep_revisions(control_.keep_revisions);
  }
  return import_ != nullptr;
}

bool Transaction::check_stop() {
  if (!control_.stop.stop_requested()) return true;
  if (!error_) error_ = IngestError{IngestError::Kind::cancelled, "cancelled", {}};
  return false;
}

bool Transaction::remove_source(std::string_view source) {
  if (!check_stop()) return false;
  if (import_->remove_source(source, store_error_)) return true;
  fail_store();
  return false;
}

bool Transaction::put(const Object& object) {
  if (!check_stop()) return false;
  if (!import_->put(object, store_error_)) {
    fail_store();
    return false;
  }
  return true;
}

IngestResult Transaction::commit() {
  if (!check_stop()) return failure();
  file_index_ = file_count_;
  report(IngestStage::committing, 0, 1);
  const ModelStatistics& put = import_->put_statistics();
  summary_.added.add_counts(put);
  if (!put.bounds.empty()) {
    summary_.added.bounds.extend(put.bounds.min);
    summary_.added.bounds.extend(put.bounds.max);
  }
  if (!import_->commit(store_error_)) {
    fail_store();
    return failure();
  }
  report(IngestStage::committing, 1, 1);
  summary_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  return std::move(summary_);
}

void Transaction::report(IngestStage stage, uint64_t done, uint64_t total, std::string_view path) {
  if (!control_.progress) return;
  IngestProgress p;
  p.stage = stage;
  p.path = path;
  p.file_index = file_index_;
  p.file_count = file_count_;
  // An empty stage (no bytes, no objects) is reported as complete: 1 of 1.
  p.total = total == 0 ? 1 : total;
  p.done = total == 0 ? 1 : (done < total ? done : total);
  control_.progress(p);
}

void Transaction::fail_input(std::string message, std::string path) {
  if (!error_) error_ = IngestError{IngestError::Kind::input, std::move(message), std::move(path)};
}

void Transaction::fail_store() {
  if (!error_) error_ = IngestError{IngestError::Kind::store, store_error_, {}};
}

IngestResult Transaction::failure() {
  assert(error_ && "failure() without an error");
  import_.reset();  // abandoned: the store stays as it was
  return std::move(*error_);
}

}  // namespace plantview::ingest_detail
