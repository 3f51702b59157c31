// Internal: the objects/ and attributes/ databases as columns of chunked records (chunks.h):
// writing them inside an import's transaction, and reading them through a small cache of
// decompressed chunks inside a read transaction.
#pragma once

#include <lmdb.h>

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "chunks.h"
#include "shared_cache.h"

namespace plantview::detail {

// How many threads compress the blocks of every ColumnWriter (process-wide): 0, the default,
// means the machine's hardware threads; 1 compresses on the writer's own thread. Speed only: the
// bytes written are the same whatever the count. Any thread may call; writers created afterwards
// use the new count.
void set_compression_threads(unsigned threads);
unsigned compression_threads();

// Puts and erases records of one column in a write transaction. Spans (ColumnShape::span_slots
// aligned slots) that are touched are held decoded in memory (at most kMaxOpenSpans, then all are
// written out) and written by flush(); a span is written as soon as its last slot is put, as
// imports fill slots in order.
//
// Writing a span means cutting its records into chunks and compressing them (cut_chunks()),
// which a pool of threads does (compression_threads()) while the writer goes on: the chunks are
// handed to LMDB on the writer's thread, in the order their spans were completed,
// kMaxSpansInFlight behind (a fixed count, so that the data file is the same whatever the thread
// count). So the memory of an import that appends is a few spans per column whatever its size.
// A span the database held already is written by deleting its chunks and putting the new ones.
//
// Records put in slot order into a span that the database does not hold yet are appended to a
// flat buffer as they come (no allocation per record); any other access decodes the span into
// one buffer per record. put() copies the record's bytes and leaves the vector as it was, so that
// a caller can reuse its capacity.
//
// Single-threaded, like the transaction: every call on the transaction's thread. Messages name
// the store and the slot or span.
class ColumnWriter {
 public:
  // `name`: what the column holds, for messages ("object", "attributes").
  ColumnWriter(std::string directory, std::string name, MDB_dbi dbi, ColumnShape shape);
  // Waits for the writer's spans still being compressed (their results are dropped).
  ~ColumnWriter();
  ColumnWriter(const ColumnWriter&) = delete;
  ColumnWriter& operator=(const ColumnWriter&) = delete;
  // Must come first: finds where appending starts and the data file's page size.
  bool begin(MDB_txn* txn, std::string& error);
  bool put(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>&& record, std::string& error);
  bool erase(MDB_txn* txn, uint32_t slot, std::string& error);
  // The record in `slot` (empty: none). Valid until the next call on this writer.
  bool get(MDB_txn* txn, uint32_t slot, std::span<const uint8_t>& record, std::string& error);
  // Writes every span held in memory or being compressed.
  bool flush(MDB_txn* txn, std::string& error);

 private:
  // 64 K object slots or 256 K attribute slots (tens of MB decoded at most).
  static constexpr size_t kMaxOpenSpans = 16;
  // Spans handed over and not yet in LMDB; the same for every thread count (determinism). Enough
  // (a few MB of records) that the compression threads seldom wait for the writer.
  static constexpr size_t kMaxSpansInFlight = 16;
  struct Span {
    // Appended in slot order (not decoded): a size per slot from the span's first (0: none) up
    // to the last put, and the records back to back.
    std::vector<uint32_t> sizes;
    std::vector<uint8_t> bytes;
    std::vector<std::vector<uint8_t>> records;  // once decoded: span_slots entries, empty: none
    bool decoded = false;
    bool stored = false;  // the database holds chunks of this span
    bool changed = false;
  };
  struct Pending;  // a span handed to the compression threads
  bool open_span(MDB_txn* txn, uint32_t number, Span*& span, std::string& error);
  bool open_record(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>*& record, std::string& error);
  void decode(Span& span);
  bool write_span(MDB_txn* txn, uint32_t number, Span& span, std::string& error);
  // Puts handed-over spans into LMDB, oldest first (waiting for their compression): every one
  // (`all`), else while more than kMaxSpansInFlight are in flight.
  bool store_compressed(MDB_txn* txn, bool all, std::string& error);
  std::string fail(std::string_view what, int rc) const;
  std::string slots_named(uint32_t number) const;  // "object slots 4096-8191", for messages

  std::string directory_, name_;
  MDB_dbi dbi_;
  ColumnShape shape_;
  unsigned threads_;
  size_t frame_budget_ = 0;     // chunk_frame_budget() of the data file's pages (begin())
  int64_t last_stored_ = -1;    // the highest key in the database (-1: none)
  size_t span_bytes_ = 0;       // the size of the last span appended by put()
  std::map<uint32_t, Span> spans_;
  std::deque<std::shared_ptr<Pending>> in_flight_;  // in the order they were completed
  ZstdCCtx cctx_ = make_compressor();
  ZstdDCtx dctx_{ZSTD_createDCtx()};
  std::vector<uint8_t> inflated_;
  std::vector<uint32_t> ends_;
};

// A decompressed chunk of a column: slots [first, first + slot_count) and their records
// (check_chunk() done). Immutable once made, so that views on several threads may read it at once.
struct InflatedChunk {
  uint32_t first = 0, slot_count = 0;
  std::vector<uint8_t> bytes;
  std::vector<uint32_t> ends;  // check_chunk()
  size_t memory_bytes() const {
    return sizeof(InflatedChunk) + bytes.capacity() + ends.capacity() * sizeof(uint32_t);
  }
};

// Decompressed chunks shared by the views of one committed state, by first slot: at most
// its bound of chunks, least recently used going first; a chunk a view still holds lives on
// with it (ChunkCache).
class SharedChunks {
 public:
  explicit SharedChunks(size_t bound_bytes) : cache_(bound_bytes, false) {}
  std::shared_ptr<const InflatedChunk> find(uint32_t chunk) { return cache_.find(chunk); }
  void insert(uint32_t chunk, const std::shared_ptr<const InflatedChunk>& inflated) {
    cache_.insert(chunk, inflated, inflated->memory_bytes());
  }
  size_t bytes() const { return cache_.bytes(); }

 private:
  SharedCache<InflatedChunk> cache_;
};

// The shared chunk bound of states first read after the call (kChunkCacheBytes by default);
// tests change it.
void set_chunk_cache_bytes(size_t bytes);

// Reads records of one column in a read transaction, keeping the `capacity` most recently used
// decompressed chunks (fewer when they hold more than `byte_budget` bytes together), so that
// neighbouring slots cost one decompression. A slot in none of them is looked up in the
// database (a cursor lookup: the chunk with the greatest first slot not above it), and its chunk
// is looked for in `shared`
// (when given: the chunks of every view of the same committed state) before it is inflated,
// and one inflated is put there. Belongs to one view; must be destroyed while the environment
// is open; `shared` must outlive it.
// Every kReadsPerRelease chunks read from the map, and on destruction, the span of the map read
// since is taken out of the process's resident set (release_map_pages): a view that reads the
// whole store would otherwise end up holding the data file in its memory. (Releasing after every
// chunk costs more than it saves: a madvise takes about as long as inflating a chunk.)
class ChunkCache {
 public:
  ChunkCache(MDB_dbi dbi, size_t capacity, size_t byte_budget, SharedChunks* shared = nullptr);
  ~ChunkCache();
  ChunkCache(const ChunkCache&) = delete;
  ChunkCache& operator=(const ChunkCache&) = delete;
  // The record in `slot` (empty: none). Valid until the next call. False with a reason (without
  // the store or slot, which the caller adds) on an LMDB error or a corrupt block or chunk.
  bool record(MDB_txn* txn, ZSTD_DCtx* dctx, uint32_t slot, std::span<const uint8_t>& out,
              std::string& why);
  // From now on chunks are looked for in `shared` (which must outlive this) before inflating.
  void share(SharedChunks* shared) { shared_ = shared; }
  // Chunks this cache read from the map and inflated (found neither among its own nor shared).
  uint64_t inflated() const { return inflated_; }

 private:
  struct Entry {
    uint64_t used = 0;
    std::shared_ptr<const InflatedChunk> inflated;  // null: the entry is free
  };
  static constexpr uint32_t kReadsPerRelease = 256;
  // The chunk holding `slot`, from the shared chunks or read from the map and inflated: null
  // with `why` empty when no chunk holds the slot, with `why` set on an error.
  std::shared_ptr<const InflatedChunk> find_or_inflate(MDB_txn* txn, ZSTD_DCtx* dctx,
                                                       uint32_t slot, std::string& why);
  // Notes mapped bytes [begin, end) as read (after reading them), and the page at `leaf` (the
  // B-tree leaf that led to them: elsewhere in the file when the value has pages of its own),
  // releasing what was read when it is time.
  void touched(const uint8_t* begin, const uint8_t* end, const uint8_t* leaf);
  void release_touched();

  MDB_dbi dbi_;
  size_t byte_budget_;
  SharedChunks* shared_;
  std::vector<Entry> entries_;
  size_t held_bytes_ = 0;  // of the entries' chunks
  uint64_t inflated_ = 0;
  // The span of the mapping read since the last release (null: none).
  const uint8_t* touched_begin_ = nullptr;
  const uint8_t* touched_end_ = nullptr;
  // The same for the leaf pages read (kept apart: they may lie far from the values).
  const uint8_t* leaves_begin_ = nullptr;
  const uint8_t* leaves_end_ = nullptr;
  uint32_t reads_since_release_ = 0;
  uint64_t clock_ = 0;
};

}  // namespace plantview::detail
