// Internal: how object and attribute records are grouped, compressed and laid out in LMDB.
//
// A column (objects/, attributes/) is a sequence of chunks: the records of consecutive slots,
// compressed together as one zstd frame (big enough to compress well without a dictionary), one
// LMDB value each, under the key of the chunk's first slot (u32 big-endian). A reader finds the
// chunk of a slot with one cursor lookup (the greatest key not above the slot) and decompresses
// that chunk only.
//
// Chunks are cut by compressed bytes, not by slot count: a writer makes each value as big as fits
// in `value_pages` pages of the data file (LMDB stores a value of more than about half a page in
// pages of its own, behind a 16-byte page header, and rounds it up to whole pages), so that the
// pages hold records rather than rounding. Format 4 cut a chunk every 64 (objects) or 256
// (attributes) slots, values of about 3.5 KB of which LMDB's rounding made 5.4 MB of preset c
// where the records took 3.5 (format 3 held 32 chunks a value, of about 100 KB). Values of a page
// or two are what bound an import's memory: LMDB keeps a write transaction's dirty pages in memory
// until its dirty list is full, and that list counts entries (131071 at most), not bytes; a
// value of several pages is one entry. With values of two pages the dirty pages stay under
// about 1 GB however big the import. A single record bigger than that is a chunk of its own
// (a value of as many pages as it takes).
//
// Writers cut within spans of `span_slots` slots (aligned), never across one, so that rewriting
// a span (a record in it replaced or removed) means rewriting the values keyed within it. The
// last chunk of a span is a part-filled value; a span holds some 30 of them.
//
// Chunk value: u32 slot_count | zstd frame. The chunk holds slots [key, key + slot_count),
//   slot_count >= 1; its first slot holds a record. Slots in no chunk hold nothing.
// Frame content (the chunk's layout): u32 record_size[slot_count] | records, in slot order.
//   Size 0: no object in that slot (records themselves are never empty). Sizes rather than
//   offsets, because small repeated numbers compress better.
// Integers little-endian (keys big-endian). Frames carry their content size, and no checksum or
// dictionary.
#pragma once

#include <zstd.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace plantview::detail {

struct ColumnShape {
  uint32_t span_slots;   // slots a writer cuts chunks within (aligned spans)
  uint32_t value_pages;  // the pages of the data file a chunk value fills, at most
  // The zstd level a writer compresses chunks at (a reader needs no level). Measured on preset c
  // x10 (format 4, bench: every chunk recompressed): object chunks 21.1 MB at 3, 22.4 MB at 1
  // (20% faster), 20.0 MB at 6 (3.4 times slower); attribute chunks 4.9 MB at 1 and 3 alike, 1
  // the faster. Format 5, preset c's object chunks: 540 pages at 3, 518 at 4, 506 at 5, 496 at
  // 6; gen --scale 100 took 28 s of CPU at 3 and 4 alike, 40 s at 6.
  int zstd_level = 3;
  constexpr uint32_t span_of(uint32_t slot) const { return slot / span_slots; }
};
inline constexpr ColumnShape kObjectShape{4096, 2, 4};
inline constexpr ColumnShape kAttributeShape{16384, 2, 1};

// LMDB's header on the first page of a value stored in pages of its own (PAGEHDRSZ).
inline constexpr size_t kLmdbPageHeaderBytes = 16;
// The most bytes of a chunk's frame that keep its value within `pages` pages of `page_bytes`.
constexpr size_t chunk_frame_budget(size_t page_bytes, uint32_t pages) {
  return pages * page_bytes - kLmdbPageHeaderBytes - 4;
}

// Splits a chunk value into its slot count and frame (a span into `data`). False if the header
// is malformed (a value shorter than its header, a slot count of 0, no frame).
bool split_chunk_value(const uint8_t* data, size_t size, uint32_t& slot_count,
                       std::span<const uint8_t>& frame, std::string& error);
void join_chunk_value(uint32_t slot_count, std::span<const uint8_t> frame,
                      std::vector<uint8_t>& out);

// Lays out a chunk; `records` has an entry per slot, empty where there is no object.
void pack_chunk(const std::vector<std::vector<uint8_t>>& records, std::vector<uint8_t>& out);
// The same from records kept flat: `sizes` one per slot (0: none), `bytes` the records in slot
// order, back to back.
void pack_chunk(std::span<const uint32_t> sizes, std::span<const uint8_t> bytes,
                std::vector<uint8_t>& out);
// Checks a chunk's header against its size and sets `ends` to where each record ends (after
// the header); afterwards chunk_record() may be used on it.
bool check_chunk(const std::vector<uint8_t>& chunk, uint32_t slot_count,
                 std::vector<uint32_t>& ends, std::string& error);
// The record at `index` of a checked chunk (empty: none). Valid while `chunk` is unchanged.
std::span<const uint8_t> chunk_record(const std::vector<uint8_t>& chunk,
                                      const std::vector<uint32_t>& ends, uint32_t index);

struct ZstdCCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct ZstdDCtxFree {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};
using ZstdCCtx = std::unique_ptr<ZSTD_CCtx, ZstdCCtxFree>;
using ZstdDCtx = std::unique_ptr<ZSTD_DCtx, ZstdDCtxFree>;

ZstdCCtx make_compressor();  // the store's frame parameters (level 6, content size, no checksum)
// False with zstd's reason (only on allocation failure in practice).
bool compress_frame(ZSTD_CCtx* cctx, std::span<const uint8_t> in, std::vector<uint8_t>& out,
                    std::string& error);
// Inflates one frame into `out`. False with a message if it is not a valid frame (or would
// inflate to more than 1 GiB).
bool inflate_frame(ZSTD_DCtx* dctx, std::span<const uint8_t> frame, std::vector<uint8_t>& out,
                   std::string& error);

// A chunk cut by cut_chunks(): its first slot (the key) and its value, ready for LMDB.
struct ChunkValue {
  uint32_t first_slot = 0;
  std::vector<uint8_t> value;
};
// Cuts the records of consecutive slots from `first_slot` (`sizes`, one per slot, 0: none;
// `bytes`, the records back to back) into chunks, each as many slots as compress (with `cctx`,
// at its level) into a frame of at most `frame_budget` bytes, or one record where that alone is
// bigger: every slot with a record is in one chunk, each chunk starts with a record, and no
// chunk is followed by a record that would have fit (bar a slack of 1/32 of the budget, which
// spares trial compressions). Appends to `out`; a pure function of its inputs (the same values
// whatever thread runs it). False with zstd's reason.
bool cut_chunks(ZSTD_CCtx* cctx, uint32_t first_slot, std::span<const uint32_t> sizes,
                std::span<const uint8_t> bytes, size_t frame_budget, std::vector<ChunkValue>& out,
                std::string& error);

}  // namespace plantview::detail
