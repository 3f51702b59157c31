#include "columns.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <mutex>
#include <thread>

#include <pthread.h>

#include "lmdb_guard.h"
#include "plantview/store.h"

namespace plantview::detail {

namespace {

std::atomic<unsigned> g_compression_threads{0};

// The threads that compress blocks for every ColumnWriter of the process: started on first use,
// grown to the largest count asked for. Each thread has its own compression context.
// Lifetime: created once per process and never destroyed (its threads end with the process; no
// job outlives its writer, which waits for its blocks). A child made by fork() has none of its
// parent's threads and may have copied the pool's mutex locked: it forgets the parent's pool
// (left allocated, untouched) and makes its own on first use.
class CompressionPool {
 public:
  using Job = std::function<void(ZSTD_CCtx*)>;
  static CompressionPool& shared() {
    static const int registered = pthread_atfork(nullptr, nullptr, [] {
      g_pool.store(nullptr);
      g_pool_mutex = new std::mutex;  // the parent's may have been held by another thread
    });
    (void)registered;
    if (CompressionPool* p = g_pool.load(std::memory_order_acquire)) return *p;
    const std::lock_guard lock(*g_pool_mutex);
    CompressionPool* p = g_pool.load(std::memory_order_acquire);
    if (!p) {
      p = new CompressionPool;
      g_pool.store(p, std::memory_order_release);
    }
    return *p;
  }
  void ensure(unsigned threads) {
    const std::lock_guard lock(mutex_);
    while (threads_.size() < threads) threads_.emplace_back([this] { work(); }).detach();
  }
  void submit(Job job) {
    {
      const std::lock_guard lock(mutex_);
      jobs_.push_back(std::move(job));
    }
    wake_.notify_one();
  }

 private:
  static inline std::atomic<CompressionPool*> g_pool{nullptr};
  static inline std::mutex* g_pool_mutex = new std::mutex;
  void work() {
    const ZstdCCtx cctx = make_compressor();
    for (;;) {
      Job job;
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [&] { return !jobs_.empty(); });
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job(cctx.get());
    }
  }
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> jobs_;
  std::vector<std::thread> threads_;  // detached: they wait for jobs until the process ends
};

}  // namespace

void set_compression_threads(unsigned threads) { g_compression_threads = threads; }

unsigned compression_threads() {
  const unsigned set = g_compression_threads;
  return set != 0 ? set : std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace plantview::detail

namespace plantview {
// store.h's names for the same setting.
void set_import_threads(unsigned threads) { detail::set_compression_threads(threads); }
unsigned import_threads() { return detail::compression_threads(); }
}  // namespace plantview

namespace plantview::detail {

// A span on its way to LMDB: its records, flat, until a pool thread cuts and compresses them
// into chunks.
struct ColumnWriter::Pending {
  uint32_t number = 0;
  bool stored = false;  // the database held chunks of the span when it was handed over
  uint32_t first_slot = 0;
  std::vector<uint32_t> sizes;
  std::vector<uint8_t> bytes;
  size_t frame_budget = 0;
  int level = 3;
  std::vector<ChunkValue> chunks;  // once done
  std::string error;               // compression's reason, when it failed
  std::mutex mutex;
  std::condition_variable finished;
  bool done = false;

  void compress(ZSTD_CCtx* cctx) {
    std::string why;
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
    cut_chunks(cctx, first_slot, sizes, bytes, frame_budget, chunks, why);
    sizes = {};
    bytes = {};
    const std::lock_guard lock(mutex);
    error = std::move(why);
    done = true;
    finished.notify_all();
  }
  void wait() {
    std::unique_lock lock(mutex);
    finished.wait(lock, [&] { return done; });
  }
};

ColumnWriter::ColumnWriter(std::string directory, std::string name, MDB_dbi dbi, ColumnShape shape)
    : directory_(std::move(directory)),
      name_(std::move(name)),
      dbi_(dbi),
      shape_(shape),
      threads_(compression_threads()) {
  if (threads_ > 1) CompressionPool::shared().ensure(threads_);
}

ColumnWriter::~ColumnWriter() {
  // The pool's jobs hold their spans; waiting keeps a writer's work from outliving its import.
  for (const auto& p : in_flight_) p->wait();
}

std::string ColumnWriter::fail(std::string_view what, int rc) const {
  return lmdb_message(directory_, what, rc);
}

std::string ColumnWriter::slots_named(uint32_t number) const {
  return name_ + " slots " + std::to_string(uint64_t(number) * shape_.span_slots) + "-" +
         std::to_string(uint64_t(number + 1) * shape_.span_slots - 1);
}

bool ColumnWriter::begin(MDB_txn* txn, std::string& error) {
  MDB_stat stat;
  int rc = mdb_env_stat(mdb_txn_env(txn), &stat);
  if (rc != MDB_SUCCESS) {
    error = fail("reading the page size", rc);
    return false;
  }
  frame_budget_ = chunk_frame_budget(stat.ms_psize, shape_.value_pages);
  LmdbCursor cursor;
  rc = cursor.open(txn, dbi_);
  MDB_val k, v;
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_LAST);
  if (rc == MDB_SUCCESS && k.mv_size == 4) {
    last_stored_ = read_be32(k.mv_data);
  } else if (rc != MDB_NOTFOUND) {
    error = fail("reading the " + name_ + " records", rc);
    return false;
  }
  return true;
}

bool ColumnWriter::open_span(MDB_txn* txn, uint32_t number, Span*& span, std::string& error) {
  if (auto it = spans_.find(number); it != spans_.end()) {
    span = &it->second;
    return true;
  }
  // A span on its way to LMDB is read back from there once it has arrived.
  const bool travelling = std::any_of(in_flight_.begin(), in_flight_.end(),
                                      [&](const auto& p) { return p->number == number; });
  if (travelling && !store_compressed(txn, true, error)) return false;
  // Bounded memory for imports that touch many spans (replacing a large source).
  if (spans_.size() >= kMaxOpenSpans && !flush(txn, error)) return false;
  Span fresh;
  // The chunks keyed within the span (chunks never cross a span's end).
  const uint64_t first = uint64_t(number) * shape_.span_slots;
  const uint64_t end = first + shape_.span_slots;
  const Key32 key{uint32_t(first)};
  MDB_val k = key.val(), v;
  LmdbCursor cursor;
  int rc = cursor.open(txn, dbi_);
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_RANGE);
  for (; rc == MDB_SUCCESS; rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT)) {
    const uint64_t at = k.mv_size == 4 ? read_be32(k.mv_data) : UINT64_MAX;
    if (at >= end) break;
    if (!fresh.decoded) {
      fresh.records.assign(shape_.span_slots, {});
      fresh.decoded = fresh.stored = true;
    }
    uint32_t count = 0;
    std::span<const uint8_t> frame;
    std::string why;
    if (!split_chunk_value(static_cast<const uint8_t*>(v.mv_data), v.mv_size, count, frame,
                           why) ||
        !inflate_frame(dctx_.get(), frame, inflated_, why) ||
        !check_chunk(inflated_, count, ends_, why)) {
      error = "store " + directory_ + ": " + name_ + " chunk at slot " + std::to_string(at) +
              ": " + why;
      return false;
    }
    if (at + count > end) {
      error = "store " + directory_ + ": " + name_ + " chunk at slot " + std::to_string(at) +
              ": its " + std::to_string(count) + " slots run past " + slots_named(number);
      return false;
    }
    for (uint32_t i = 0; i < count; ++i) {
      const auto r = chunk_record(inflated_, ends_, i);
      fresh.records[at - first + i].assign(r.begin(), r.end());
    }
  }
  if (rc != MDB_SUCCESS && rc != MDB_NOTFOUND) {
    error = fail("reading " + slots_named(number), rc);
    return false;
  }
  span = &spans_.emplace(number, std::move(fresh)).first->second;
  return true;
}

void ColumnWriter::decode(Span& span) {
  span.records.assign(shape_.span_slots, {});
  size_t at = 0;
  for (size_t i = 0; i < span.sizes.size(); ++i) {
    span.records[i].assign(span.bytes.begin() + at, span.bytes.begin() + at + span.sizes[i]);
    at += span.sizes[i];
  }
  span.sizes = {};
  span.bytes = {};
  span.decoded = true;
}

bool ColumnWriter::open_record(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>*& record,
                               std::string& error) {
  Span* span;
  if (!open_span(txn, shape_.span_of(slot), span, error)) return false;
  if (!span->decoded) decode(*span);
  record = &span->records[slot % shape_.span_slots];
  return true;
}

bool ColumnWriter::put(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>&& record,
                       std::string& error) {
  const uint32_t number = shape_.span_of(slot);
  Span* span;
  if (!open_span(txn, number, span, error)) return false;
  const uint32_t index = slot % shape_.span_slots;
  if (!span->decoded && index >= span->sizes.size()) {
    // Appending: the record goes straight into the span's flat buffer.
    if (span->bytes.capacity() == 0) {
      // Room for as much as the last span held: one allocation a span, mostly.
      span->bytes.reserve(std::max(span_bytes_, record.size()));
      span->sizes.reserve(shape_.span_slots);
    }
    span->sizes.resize(index, 0);
    span->sizes.push_back(uint32_t(record.size()));
    span->bytes.insert(span->bytes.end(), record.begin(), record.end());
  } else {
    std::vector<uint8_t>* at;
    if (!open_record(txn, slot, at, error)) return false;
    at->assign(record.begin(), record.end());
    span = &spans_.at(number);
  }
  span->changed = true;
  // Imports fill slots in order: a span whose last slot is put is complete.
  if (index == shape_.span_slots - 1) {
    if (!write_span(txn, number, *span, error)) return false;
    spans_.erase(number);
  }
  return true;
}

bool ColumnWriter::erase(MDB_txn* txn, uint32_t slot, std::string& error) {
  std::vector<uint8_t>* at;
  if (!open_record(txn, slot, at, error)) return false;
  at->clear();
  at->shrink_to_fit();
  spans_.at(shape_.span_of(slot)).changed = true;
  return true;
}

bool ColumnWriter::get(MDB_txn* txn, uint32_t slot, std::span<const uint8_t>& record,
                       std::string& error) {
  std::vector<uint8_t>* at;
  if (!open_record(txn, slot, at, error)) return false;
  record = *at;
  return true;
}

// Hands the span over for cutting and compression; its contents move out (the caller drops it).
bool ColumnWriter::write_span(MDB_txn* txn, uint32_t number, Span& span, std::string& error) {
  if (!span.changed) return true;
  auto p = std::make_shared<Pending>();
  p->number = number;
  p->stored = span.stored;
  p->first_slot = number * shape_.span_slots;
  p->frame_budget = frame_budget_;
  p->level = shape_.zstd_level;
  if (span.decoded) {
    size_t used = 0, total = 0;  // the slots up to the last record, and its bytes
    for (size_t i = 0; i < span.records.size(); ++i) {
      if (!span.records[i].empty()) used = i + 1;
      total += span.records[i].size();
    }
    p->sizes.resize(used);
    p->bytes.reserve(total);
    for (size_t i = 0; i < used; ++i) {
      p->sizes[i] = uint32_t(span.records[i].size());
      p->bytes.insert(p->bytes.end(), span.records[i].begin(), span.records[i].end());
    }
  } else {
    span_bytes_ = span.bytes.size();
    p->sizes = std::move(span.sizes);
    p->bytes = std::move(span.bytes);
  }
  span.changed = false;
  in_flight_.push_back(p);
  if (threads_ > 1) {
    CompressionPool::shared().submit([p](ZSTD_CCtx* cctx) { p->compress(cctx); });
  } else {
    p->compress(cctx_.get());
  }
  return store_compressed(txn, false, error);
}

bool ColumnWriter::store_compressed(MDB_txn* txn, bool all, std::string& error) {
  // When a span reaches LMDB depends on the calls made, never on the threads' timing: so the
  // data file's pages come in the same order whatever the thread count.
  while (!in_flight_.empty() && (all || in_flight_.size() > kMaxSpansInFlight)) {
    const std::shared_ptr<Pending> p = in_flight_.front();
    p->wait();
    in_flight_.pop_front();
    if (!p->error.empty()) {
      error = "store " + directory_ + ": " + slots_named(p->number) + ": " + p->error;
      return false;
    }
    int rc = MDB_SUCCESS;
    if (p->stored) {
      // The span's chunks as stored go: the new cut need not share their keys.
      const uint64_t end = uint64_t(p->first_slot) + shape_.span_slots;
      std::vector<uint32_t> keys;
      LmdbCursor cursor;
      const Key32 first(p->first_slot);
      MDB_val k = first.val(), v;
      rc = cursor.open(txn, dbi_);
      if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_RANGE);
      for (; rc == MDB_SUCCESS && k.mv_size == 4 && read_be32(k.mv_data) < end;
           rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT)) {
        keys.push_back(read_be32(k.mv_data));
      }
      if (rc == MDB_NOTFOUND || rc == MDB_SUCCESS) rc = MDB_SUCCESS;
      for (size_t i = 0; i < keys.size() && rc == MDB_SUCCESS; ++i) {
        const Key32 key(keys[i]);
        MDB_val dk = key.val();
        rc = mdb_del(txn, dbi_, &dk, nullptr);
      }
    }
    for (size_t i = 0; i < p->chunks.size() && rc == MDB_SUCCESS; ++i) {
      const ChunkValue& c = p->chunks[i];
      const Key32 key(c.first_slot);
      MDB_val k = key.val(), v = as_val(c.value.data(), c.value.size());
      // Chunks past the last one stored append to full pages.
      const bool append = int64_t(c.first_slot) > last_stored_;
      rc = mdb_put(txn, dbi_, &k, &v, append ? MDB_APPEND : 0);
      last_stored_ = std::max<int64_t>(last_stored_, c.first_slot);
    }
    if (rc != MDB_SUCCESS) {
      error = fail("writing " + slots_named(p->number), rc);
      return false;
    }
  }
  return true;
}

bool ColumnWriter::flush(MDB_txn* txn, std::string& error) {
  for (auto& [number, span] : spans_) {
    if (!write_span(txn, number, span, error)) return false;
  }
  spans_.clear();
  return store_compressed(txn, true, error);
}

// ---------------------------------------------------------------------------------------------

ChunkCache::ChunkCache(MDB_dbi dbi, size_t capacity, size_t byte_budget, SharedChunks* shared)
    : dbi_(dbi), byte_budget_(byte_budget), shared_(shared), entries_(capacity) {}

ChunkCache::~ChunkCache() { release_touched(); }

void ChunkCache::touched(const uint8_t* begin, const uint8_t* end, const uint8_t* leaf) {
  touched_begin_ = touched_begin_ ? std::min(touched_begin_, begin) : begin;
  touched_end_ = std::max(touched_end_, end);
  leaves_begin_ = leaves_begin_ ? std::min(leaves_begin_, leaf) : leaf;
  leaves_end_ = std::max(leaves_end_, leaf + 1);
  if (++reads_since_release_ == kReadsPerRelease) release_touched();
}

void ChunkCache::release_touched() {
  if (!touched_begin_) return;
  release_map_pages(touched_begin_, size_t(touched_end_ - touched_begin_));
  release_map_pages(leaves_begin_, size_t(leaves_end_ - leaves_begin_));
  touched_begin_ = touched_end_ = leaves_begin_ = leaves_end_ = nullptr;
  reads_since_release_ = 0;
}

std::shared_ptr<const InflatedChunk> ChunkCache::find_or_inflate(MDB_txn* txn, ZSTD_DCtx* dctx,
                                                                 uint32_t slot, std::string& why) {
  // The chunk with the greatest first slot not above `slot`. Through a cursor, which returns the
  // key in place: in the leaf page that points to the value (a page of its own, for a value of
  // more than half a page), released with it.
  const Key32 key(slot);
  MDB_val k = key.val(), v;
  LmdbCursor cursor;
  int rc = cursor.open(txn, dbi_);
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_RANGE);
  if (rc == MDB_SUCCESS && (k.mv_size != 4 || read_be32(k.mv_data) != slot)) {
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_PREV);
  } else if (rc == MDB_NOTFOUND) {
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_LAST);
  }
  if (rc == MDB_NOTFOUND) return nullptr;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return nullptr;
  }
  if (k.mv_size != 4) {
    why = "a chunk key of " + std::to_string(k.mv_size) + " bytes";
    return nullptr;
  }
  const uint32_t first = read_be32(k.mv_data);
  uint32_t count = 0;
  std::span<const uint8_t> frame;
  if (!split_chunk_value(static_cast<const uint8_t*>(v.mv_data), v.mv_size, count, frame, why)) {
    return nullptr;
  }
  if (first > slot || uint64_t(slot) - first >= count) return nullptr;  // in no chunk
  if (shared_) {
    if (auto found = shared_->find(first)) return found;
  }
  auto chunk = std::make_shared<InflatedChunk>();
  chunk->first = first;
  chunk->slot_count = count;
  ++inflated_;
  const bool inflated = inflate_frame(dctx, frame, chunk->bytes, why);
  // After inflating, so that the pages it brought in count.
  touched(static_cast<const uint8_t*>(v.mv_data), frame.data() + frame.size(),
          static_cast<const uint8_t*>(k.mv_data));
  if (!inflated || !check_chunk(chunk->bytes, count, chunk->ends, why)) return nullptr;
  if (shared_) shared_->insert(first, chunk);
  return chunk;
}

bool ChunkCache::record(MDB_txn* txn, ZSTD_DCtx* dctx, uint32_t slot, std::span<const uint8_t>& out,
                        std::string& why) {
  Entry* entry = nullptr;
  for (Entry& e : entries_) {
    if (e.inflated && slot >= e.inflated->first && slot - e.inflated->first < e.inflated->slot_count)
      entry = &e;
  }
  if (!entry) {
    why.clear();
    std::shared_ptr<const InflatedChunk> found = find_or_inflate(txn, dctx, slot, why);
    if (!found) {
      out = {};
      return why.empty();  // no chunk holds the slot: no record
    }
    entry = &*std::min_element(entries_.begin(), entries_.end(),
                               [](const Entry& a, const Entry& b) { return a.used < b.used; });
    if (entry->inflated) held_bytes_ -= entry->inflated->memory_bytes();
    entry->inflated = std::move(found);
    held_bytes_ += entry->inflated->memory_bytes();
    // Chunks of big meshes can be megabytes: keep the entries within the byte budget, least
    // recently used first, the chunk just read always.
    while (held_bytes_ > byte_budget_) {
      Entry* oldest = nullptr;
      for (Entry& e : entries_) {
        if (&e != entry && e.inflated && (!oldest || e.used < oldest->used)) oldest = &e;
      }
      if (!oldest) break;
      held_bytes_ -= oldest->inflated->memory_bytes();
      oldest->inflated.reset();
    }
  }
  entry->used = ++clock_;
  const InflatedChunk& c = *entry->inflated;
  out = chunk_record(c.bytes, c.ends, slot - c.first);
  return true;
}

}  // namespace plantview::detail
