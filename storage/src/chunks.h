// Internal: how object and attribute records are grouped, compressed and laid out in LMDB.
//
// The records of consecutive slots are compressed together: a chunk is the records of
// `chunk_slots` consecutive slots (64 for objects, 256 for attributes) as one zstd frame, so that
// frames are big enough to compress well without a dictionary; a block is the frames of
// `block_slots` consecutive slots as one LMDB value. A reader decompresses only the chunk it
// needs.
//
// Format 4 stores one chunk a block (block_slots == chunk_slots): a value of about 3.5 KB (one
// page of the data file, seldom two). Format 3 grouped 32 chunks a block (2048 and 4096 slots,
// values of about 100 KB), which made an import's memory grow with the plant: LMDB keeps a
// write transaction's dirty pages in memory and spills them to the data file only when its dirty
// list is full, and that list counts entries (131071 at most), not bytes; a value bigger than
// half a page is one entry whatever its pages. With values of one or two pages the dirty pages
// stay under about 1 GB however big the import (preset c x1000 held 2.5 GB of values dirty).
// The price is LMDB's rounding of each value to whole pages: about 10% more bytes than format 3.
//
// Block (the value under key slot / block_slots, u32 big-endian, in objects/ and attributes/):
//   u32 frame_end[chunks per block] | frames
//   Chunk i's frame is bytes [frame_end[i - 1], frame_end[i]) after the header (frame_end[-1] is
//   0); an empty frame: nothing in the chunk's slots.
// Chunk (a frame's content):
//   u32 record_size[chunk_slots] | records, in slot order
//   Size 0: no object in that slot (records themselves are never empty). Sizes rather than
//   offsets, because small repeated numbers compress better.
// Integers little-endian. Frames carry their content size, and no checksum or dictionary.
#pragma once

#include <zstd.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace plantview::detail {

struct ColumnShape {
  uint32_t chunk_slots, block_slots;  // block_slots a multiple of chunk_slots
  // The zstd level a writer compresses chunks at (a reader needs no level). Measured on preset c
  // x10 (bench: every chunk recompressed): object chunks 21.1 MB at 3, 22.4 MB at 1 (20% faster),
  // 20.0 MB at 6 (3.4 times slower); attribute chunks 4.9 MB at 1 and 3 alike, 1 the faster.
  int zstd_level = 3;
  constexpr uint32_t chunks_per_block() const { return block_slots / chunk_slots; }
  constexpr uint32_t chunk_of(uint32_t slot) const { return slot / chunk_slots; }
  constexpr uint32_t block_of(uint32_t slot) const { return slot / block_slots; }
  // The chunk's place in its block.
  constexpr uint32_t chunk_in_block(uint32_t slot) const {
    return (slot % block_slots) / chunk_slots;
  }
};
inline constexpr ColumnShape kObjectShape{64, 64, 3};
inline constexpr ColumnShape kAttributeShape{256, 256, 1};

// Splits a block into its frames (spans into `data`). False if the header is malformed.
bool split_block(const uint8_t* data, size_t size, uint32_t chunks,
                 std::vector<std::span<const uint8_t>>& frames, std::string& error);
void join_block(const std::vector<std::vector<uint8_t>>& frames, std::vector<uint8_t>& out);

// Lays out a chunk; `records` has chunk_slots entries, empty where there is no object.
void pack_chunk(const std::vector<std::vector<uint8_t>>& records, std::vector<uint8_t>& out);
// Checks a chunk's header against its size and sets `ends` to where each record ends (after
// the header); afterwards chunk_record() may be used on it.
bool check_chunk(const std::vector<uint8_t>& chunk, uint32_t chunk_slots,
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

ZstdCCtx make_compressor();  // the store's frame parameters (level 3, content size, no checksum)
// False with zstd's reason (only on allocation failure in practice).
bool compress_frame(ZSTD_CCtx* cctx, std::span<const uint8_t> in, std::vector<uint8_t>& out,
                    std::string& error);
// Inflates one frame into `out`. False with a message if it is not a valid frame (or would
// inflate to more than 1 GiB).
bool inflate_frame(ZSTD_DCtx* dctx, std::span<const uint8_t> frame, std::vector<uint8_t>& out,
                   std::string& error);

}  // namespace plantview::detail
