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

// A block on its way to LMDB: its chunks' frames (stored ones as they were, the others as their
// layout until a pool thread compresses them in place).
struct ColumnWriter::Pending {
  uint32_t number = 0;
  bool stored = false;                      // the database held a version when it was handed over
  std::vector<std::vector<uint8_t>> frames;  // one per chunk; empty: nothing in the chunk
  std::vector<uint8_t> to_compress;         // per chunk: 1 while frames[i] is a layout
  std::string error;                        // compression's reason, when it failed
  std::mutex mutex;
  std::condition_variable finished;
  bool done = false;

  int level = 3;
  void compress(ZSTD_CCtx* cctx) {
    std::vector<uint8_t> out;
    std::string why;
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
    for (size_t i = 0; i < frames.size() && why.empty(); ++i) {
      if (!to_compress[i]) continue;
      if (compress_frame(cctx, frames[i], out, why)) frames[i].swap(out);
    }
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
  // The pool's jobs hold their blocks; waiting keeps a writer's work from outliving its import.
  for (const auto& p : in_flight_) p->wait();
}

std::string ColumnWriter::fail(std::string_view what, int rc) const {
  return lmdb_message(directory_, what, rc);
}

bool ColumnWriter::begin(MDB_txn* txn, std::string& error) {
  LmdbCursor cursor;
  int rc = cursor.open(txn, dbi_);
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

bool ColumnWriter::open_block(MDB_txn* txn, uint32_t number, Block*& block, std::string& error) {
  if (auto it = blocks_.find(number); it != blocks_.end()) {
    block = &it->second;
    return true;
  }
  // A block on its way to LMDB is read back from there once it has arrived.
  const bool travelling = std::any_of(in_flight_.begin(), in_flight_.end(),
                                      [&](const auto& p) { return p->number == number; });
  if (travelling && !store_compressed(txn, true, error)) return false;
  // Bounded memory for imports that touch many blocks (replacing a large source).
  if (blocks_.size() >= kMaxOpenBlocks && !flush(txn, error)) return false;
  Block fresh;
  fresh.chunks.resize(shape_.chunks_per_block());
  const Key32 key(number);
  MDB_val k = key.val(), v;
  const int rc = mdb_get(txn, dbi_, &k, &v);
  if (rc == MDB_SUCCESS) {
    std::vector<std::span<const uint8_t>> frames;
    std::string why;
    if (!split_block(static_cast<const uint8_t*>(v.mv_data), v.mv_size, shape_.chunks_per_block(),
                     frames, why)) {
      error = "store " + directory_ + ": " + name_ + " slots " +
              std::to_string(uint64_t(number) * shape_.block_slots) + "-" +
              std::to_string(uint64_t(number + 1) * shape_.block_slots - 1) + ": " + why;
      return false;
    }
    for (size_t i = 0; i < frames.size(); ++i) {
      fresh.chunks[i].frame.assign(frames[i].begin(), frames[i].end());
    }
    fresh.stored = true;
  } else if (rc != MDB_NOTFOUND) {
    error = fail("reading " + name_ + " records", rc);
    return false;
  }
  block = &blocks_.emplace(number, std::move(fresh)).first->second;
  return true;
}

void ColumnWriter::decode(Chunk& chunk) {
  chunk.records.assign(shape_.chunk_slots, {});
  if (!chunk.packed.empty()) {
    // Laid out by put(): well formed by construction.
    std::string why;
    [[maybe_unused]] const bool ok = check_chunk(chunk.packed, shape_.chunk_slots, ends_, why);
    assert(ok && "a chunk laid out by put() is malformed");
    for (uint32_t i = 0; i < shape_.chunk_slots; ++i) {
      const auto r = chunk_record(chunk.packed, ends_, i);
      chunk.records[i].assign(r.begin(), r.end());
    }
  }
  chunk.packed = {};
  chunk.decoded = true;
}

bool ColumnWriter::open_record(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>*& record,
                               std::string& error) {
  Block* block;
  if (!open_block(txn, shape_.block_of(slot), block, error)) return false;
  Chunk& chunk = block->chunks[shape_.chunk_in_block(slot)];
  if (!chunk.decoded) {
    if (!chunk.frame.empty()) {
      std::string why;
      if (!inflate_frame(dctx_.get(), chunk.frame, chunk.packed, why) ||
          !check_chunk(chunk.packed, shape_.chunk_slots, ends_, why)) {
        chunk.packed = {};
        error = "store " + directory_ + ": " + name_ + " slot " + std::to_string(slot) + ": " + why;
        return false;
      }
      chunk.frame = {};
    }
    decode(chunk);
  }
  record = &chunk.records[slot % shape_.chunk_slots];
  return true;
}

bool ColumnWriter::put(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>&& record,
                       std::string& error) {
  const uint32_t number = shape_.block_of(slot);
  Block* block;
  if (!open_block(txn, number, block, error)) return false;
  Chunk& chunk = block->chunks[shape_.chunk_in_block(slot)];
  const uint32_t index = slot % shape_.chunk_slots;
  if (!chunk.decoded && chunk.frame.empty() && index >= chunk.next) {
    // Appending: the record goes straight into the chunk's layout.
    const size_t header = size_t(shape_.chunk_slots) * 4;
    if (chunk.packed.empty()) {
      // Room for as much as the last chunk laid out held: one allocation a chunk, mostly.
      chunk.packed.reserve(std::max(packed_bytes_, header + record.size()));
      chunk.packed.assign(header, 0);
    }
    const auto size = uint32_t(record.size());
    std::memcpy(chunk.packed.data() + 4 * size_t(index), &size, 4);
    chunk.packed.insert(chunk.packed.end(), record.begin(), record.end());
    chunk.next = index + 1;
  } else {
    std::vector<uint8_t>* at;
    if (!open_record(txn, slot, at, error)) return false;
    at->assign(record.begin(), record.end());
    block = &blocks_.at(number);
  }
  block->changed = true;
  // Imports fill slots in order: a block whose last slot is put is complete.
  if (slot % shape_.block_slots == shape_.block_slots - 1) {
    if (!write_block(txn, number, *block, error)) return false;
    blocks_.erase(number);
  }
  return true;
}

bool ColumnWriter::erase(MDB_txn* txn, uint32_t slot, std::string& error) {
  std::vector<uint8_t>* at;
  if (!open_record(txn, slot, at, error)) return false;
  at->clear();
  at->shrink_to_fit();
  blocks_.at(shape_.block_of(slot)).changed = true;
  return true;
}

bool ColumnWriter::get(MDB_txn* txn, uint32_t slot, std::span<const uint8_t>& record,
                       std::string& error) {
  std::vector<uint8_t>* at;
  if (!open_record(txn, slot, at, error)) return false;
  record = *at;
  return true;
}

// Hands the block over for compression; the block's contents move out (the caller drops it).
bool ColumnWriter::write_block(MDB_txn* txn, uint32_t number, Block& block, std::string& error) {
  if (!block.changed) return true;
  auto p = std::make_shared<Pending>();
  p->number = number;
  p->stored = block.stored;
  p->level = shape_.zstd_level;
  p->frames.resize(block.chunks.size());
  p->to_compress.assign(block.chunks.size(), 0);
  for (size_t i = 0; i < block.chunks.size(); ++i) {
    Chunk& chunk = block.chunks[i];
    if (chunk.decoded) {
      const bool empty = std::all_of(chunk.records.begin(), chunk.records.end(),
                                     [](const std::vector<uint8_t>& r) { return r.empty(); });
      if (!empty) {
        pack_chunk(chunk.records, p->frames[i]);
        p->to_compress[i] = 1;
      }
    } else if (!chunk.frame.empty()) {
      p->frames[i] = std::move(chunk.frame);
    } else if (!chunk.packed.empty()) {
      packed_bytes_ = chunk.packed.size();
      p->frames[i] = std::move(chunk.packed);
      p->to_compress[i] = 1;
    }
  }
  block.changed = false;
  in_flight_.push_back(p);
  if (threads_ > 1) {
    CompressionPool::shared().submit([p](ZSTD_CCtx* cctx) { p->compress(cctx); });
  } else {
    p->compress(cctx_.get());
  }
  return store_compressed(txn, false, error);
}

bool ColumnWriter::store_compressed(MDB_txn* txn, bool all, std::string& error) {
  // When a block reaches LMDB depends on the calls made, never on the threads' timing: so the
  // data file's pages come in the same order whatever the thread count.
  while (!in_flight_.empty() && (all || in_flight_.size() > kMaxBlocksInFlight)) {
    const std::shared_ptr<Pending> p = in_flight_.front();
    p->wait();
    in_flight_.pop_front();
    if (!p->error.empty()) {
      error = "store " + directory_ + ": " + name_ + " block " + std::to_string(p->number) + ": " +
              p->error;
      return false;
    }
    const bool any = std::any_of(p->frames.begin(), p->frames.end(),
                                 [](const std::vector<uint8_t>& f) { return !f.empty(); });
    const Key32 key(p->number);
    MDB_val k = key.val();
    int rc = MDB_SUCCESS;
    if (!any) {
      if (p->stored) rc = mdb_del(txn, dbi_, &k, nullptr);
      if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;
    } else {
      join_block(p->frames, value_);
      MDB_val v = as_val(value_.data(), value_.size());
      // Blocks past the last one stored append to full pages.
      rc = mdb_put(txn, dbi_, &k, &v, int64_t(p->number) > last_stored_ ? MDB_APPEND : 0);
      last_stored_ = std::max<int64_t>(last_stored_, p->number);
    }
    if (rc != MDB_SUCCESS) {
      error = fail("writing " + name_ + " records", rc);
      return false;
    }
  }
  return true;
}

bool ColumnWriter::flush(MDB_txn* txn, std::string& error) {
  for (auto& [number, block] : blocks_) {
    if (!write_block(txn, number, block, error)) return false;
  }
  blocks_.clear();
  return store_compressed(txn, true, error);
}

// ---------------------------------------------------------------------------------------------

ChunkCache::ChunkCache(MDB_dbi dbi, ColumnShape shape, size_t capacity, size_t byte_budget,
                       SharedChunks* shared)
    : dbi_(dbi), shape_(shape), byte_budget_(byte_budget), shared_(shared), entries_(capacity) {}

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

std::shared_ptr<const InflatedChunk> ChunkCache::inflate(MDB_txn* txn, ZSTD_DCtx* dctx,
                                                         uint32_t slot, std::string& why) {
  auto chunk = std::make_shared<InflatedChunk>();
  // Through a cursor, which returns the key in place: in the leaf page that points to the
  // value (a page of its own, for a value of more than half a page), released with it.
  const Key32 key(shape_.block_of(slot));
  MDB_val k = key.val(), v;
  LmdbCursor cursor;
  int rc = cursor.open(txn, dbi_);
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_KEY);
  if (rc == MDB_NOTFOUND) return chunk;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return nullptr;
  }
  if (!split_block(static_cast<const uint8_t*>(v.mv_data), v.mv_size, shape_.chunks_per_block(),
                   frames_, why)) {
    return nullptr;
  }
  const auto frame = frames_[shape_.chunk_in_block(slot)];
  inflated_ += frame.empty() ? 0 : 1;
  const bool inflated = frame.empty() || inflate_frame(dctx, frame, chunk->bytes, why);
  // After inflating, so that the pages it brought in count.
  const auto* value = static_cast<const uint8_t*>(v.mv_data);
  touched(value, frame.empty() ? value + shape_.chunks_per_block() * 4 : frame.data() + frame.size(),
          static_cast<const uint8_t*>(k.mv_data));
  if (!inflated) return nullptr;
  if (!frame.empty()) {
    if (!check_chunk(chunk->bytes, shape_.chunk_slots, chunk->ends, why)) return nullptr;
    chunk->present = true;
  }
  return chunk;
}

bool ChunkCache::record(MDB_txn* txn, ZSTD_DCtx* dctx, uint32_t slot, std::span<const uint8_t>& out,
                        std::string& why) {
  const uint32_t chunk = shape_.chunk_of(slot);
  Entry* entry = nullptr;
  for (Entry& e : entries_) {
    if (e.inflated && e.chunk == chunk) entry = &e;
  }
  if (!entry) {
    std::shared_ptr<const InflatedChunk> found = shared_ ? shared_->find(chunk) : nullptr;
    if (!found) {
      found = inflate(txn, dctx, slot, why);
      if (!found) return false;
      if (shared_) shared_->insert(chunk, found);
    }
    entry = &*std::min_element(entries_.begin(), entries_.end(),
                               [](const Entry& a, const Entry& b) { return a.used < b.used; });
    if (entry->inflated) held_bytes_ -= entry->inflated->memory_bytes();
    entry->chunk = chunk;
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
  out = c.present ? chunk_record(c.bytes, c.ends, slot % shape_.chunk_slots)
                  : std::span<const uint8_t>();
  return true;
}

}  // namespace plantview::detail
