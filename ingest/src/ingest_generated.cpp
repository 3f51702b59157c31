// Generated plants and objects in memory into a store: remove what their sources brought, put
// the objects as they come, commit.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <set>
#include <thread>

#include "plantview/ingest.h"
#include "transaction.h"

namespace plantview {

using ingest_detail::Abandon;
using ingest_detail::Transaction;

namespace {

// Objects from the generator thread to the calling thread, in batches, at most kMaxBatches
// waiting (and one being filled): what is generated ahead of the store is a few thousand
// objects whatever the scale.
class BatchQueue {
 public:
  // Big enough that handing a batch over (a wake-up on each side) is rare.
  static constexpr size_t kBatchObjects = 1024, kMaxBatches = 4;
  struct Batch {
    std::vector<Object> objects;
    uint64_t done = 0;  // generating progress after these objects, thousandths of a unit
  };
  // Generator side. False once the consumer has given up (the batch is dropped).
  bool push(Batch&& batch) {
    std::unique_lock lock(mutex_);
    space_.wait(lock, [&] { return abandoned_ || batches_.size() < kMaxBatches; });
    if (abandoned_) return false;
    batches_.push_back(std::move(batch));
    ready_.notify_one();
    return true;
  }
  // Generator side, last: no more batches.
  void close() {
    const std::lock_guard lock(mutex_);
    closed_ = true;
    ready_.notify_one();
  }
  bool abandoned() {
    const std::lock_guard lock(mutex_);
    return abandoned_;
  }
  // Calling thread. False when the generator has closed the queue and everything was taken.
  bool pop(Batch& batch) {
    std::unique_lock lock(mutex_);
    ready_.wait(lock, [&] { return closed_ || !batches_.empty(); });
    if (batches_.empty()) return false;
    batch = std::move(batches_.front());
    batches_.pop_front();
    space_.notify_one();
    return true;
  }
  // Calling thread: the generator stops at its next object or progress step.
  void abandon() {
    const std::lock_guard lock(mutex_);
    abandoned_ = true;
    batches_.clear();
    space_.notify_one();
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_, space_;
  std::deque<Batch> batches_;
  bool closed_ = false, abandoned_ = false;
};

// Thousandths of a unit done, from the generator's fraction (never above `total`).
uint64_t thousandths(double fraction, uint64_t total) {
  return std::min(total, uint64_t(std::floor(fraction * double(total))));
}

// The generator on the calling thread, each object put as it comes.
bool generate_inline(Transaction& t, const GenerateOptions& options, const std::string& source) {
  const uint64_t total = 1000 * uint64_t(options.scale);
  uint64_t reported = 0;
  try {
    t.summary().generated = generate_plant(
        options,
        [&](Object&& object) {
          object.source = source;
          if (!t.put(object)) throw Abandon{};
        },
        [&](double fraction) {
          // Thousandths of a unit, never backwards, and a report only when the figure moves.
          const uint64_t done = thousandths(fraction, total);
          if (done > reported) t.report(IngestStage::generating, reported = done, total);
          if (!t.check_stop()) throw Abandon{};
        });
  } catch (const Abandon&) {
    return false;
  }
  return true;
}

// The generator on a thread of its own, one batch of objects ahead of the calling thread, which
// puts them (the store's transaction belongs to it) and reports progress. The objects are put in
// the order generated, so the store is the same as generate_inline's.
bool generate_pipelined(Transaction& t, const GenerateOptions& options, const std::string& source,
                        const std::stop_token& stop) {
  const uint64_t total = 1000 * uint64_t(options.scale);
  BatchQueue queue;
  GenerateSummary generated;
  std::exception_ptr failure;  // an exception other than Abandon, rethrown on the calling thread
  std::thread generator([&] {
    BatchQueue::Batch batch;
    try {
      generated = generate_plant(
          options,
          [&](Object&& object) {
            object.source = source;
            batch.objects.push_back(std::move(object));
            if (batch.objects.size() == BatchQueue::kBatchObjects) {
              if (!queue.push(std::move(batch))) throw Abandon{};
              batch = {};
              batch.objects.reserve(BatchQueue::kBatchObjects);
            }
          },
          [&](double fraction) {
            batch.done = std::max(batch.done, thousandths(fraction, total));
            // A stop ends generating here; the calling thread finds it before it commits.
            if (queue.abandoned() || stop.stop_requested()) throw Abandon{};
          });
      if (!batch.objects.empty() || batch.done > 0) queue.push(std::move(batch));
    } catch (const Abandon&) {
    } catch (...) {
      failure = std::current_exception();
    }
    queue.close();
  });
  // However the calling thread leaves (an error, a progress callback that throws), the
  // generator stops and is joined first.
  struct Joiner {
    BatchQueue& queue;
    std::thread& thread;
    ~Joiner() {
      queue.abandon();
      thread.join();
    }
  };
  bool ok = true;
  {
    const Joiner joiner{queue, generator};
    // Put, report, check the stop token between objects (Transaction::put).
    uint64_t reported = 0;
    BatchQueue::Batch batch;
    while (ok && queue.pop(batch)) {
      for (const Object& object : batch.objects) {
        if (!t.put(object)) {
          ok = false;
          break;
        }
      }
      if (ok && batch.done > reported) t.report(IngestStage::generating, reported = batch.done, total);
    }
  }
  if (failure) std::rethrow_exception(failure);
  if (!ok || !t.check_stop()) return false;
  t.summary().generated = generated;
  return true;
}

}  // namespace

IngestResult ingest_generated(Store& store, const GenerateOptions& options, const IngestControl& control) {
  assert(preset_info(options.preset) && "unknown preset: check it with parse_preset()");
  assert(options.scale >= 1 && options.scale <= kMaxGenerateScale && "scale out of range");
  Transaction t(store, control);
  const std::string source = "gen:" + std::string(1, options.preset);
  if (!t.begin() || !t.remove_source(source)) return t.failure();
  t.report(IngestStage::generating, 0, 1000 * uint64_t(options.scale));
  const bool ok = import_threads() > 1 ? generate_pipelined(t, options, source, control.stop)
                                       : generate_inline(t, options, source);
  if (!ok) return t.failure();
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
