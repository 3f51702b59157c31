#include "columns.h"

#include <algorithm>

#include "lmdb_guard.h"

namespace plantview::detail {

ColumnWriter::ColumnWriter(std::string directory, std::string name, MDB_dbi dbi, ColumnShape shape)
    : directory_(std::move(directory)), name_(std::move(name)), dbi_(dbi), shape_(shape) {}

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

bool ColumnWriter::open_record(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>*& record,
                               std::string& error) {
  Block* block;
  if (!open_block(txn, shape_.block_of(slot), block, error)) return false;
  Chunk& chunk = block->chunks[shape_.chunk_in_block(slot)];
  if (!chunk.decoded) {
    chunk.records.assign(shape_.chunk_slots, {});
    if (!chunk.frame.empty()) {
      std::string why;
      if (!inflate_frame(dctx_.get(), chunk.frame, chunk_, why) ||
          !check_chunk(chunk_, shape_.chunk_slots, ends_, why)) {
        error = "store " + directory_ + ": " + name_ + " slot " + std::to_string(slot) + ": " + why;
        return false;
      }
      for (uint32_t i = 0; i < shape_.chunk_slots; ++i) {
        const auto r = chunk_record(chunk_, ends_, i);
        chunk.records[i].assign(r.begin(), r.end());
      }
    }
    chunk.frame.clear();
    chunk.frame.shrink_to_fit();
    chunk.decoded = true;
  }
  record = &chunk.records[slot % shape_.chunk_slots];
  return true;
}

bool ColumnWriter::put(MDB_txn* txn, uint32_t slot, std::vector<uint8_t>&& record,
                       std::string& error) {
  std::vector<uint8_t>* at;
  if (!open_record(txn, slot, at, error)) return false;
  *at = std::move(record);
  const uint32_t number = shape_.block_of(slot);
  Block& block = blocks_.at(number);
  block.changed = true;
  // Imports fill slots in order: a block whose last slot is put is complete.
  if (slot % shape_.block_slots == shape_.block_slots - 1) {
    if (!write_block(txn, number, block, error)) return false;
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

bool ColumnWriter::write_block(MDB_txn* txn, uint32_t number, Block& block, std::string& error) {
  if (!block.changed) return true;
  frames_.resize(block.chunks.size());
  bool any = false;
  for (size_t i = 0; i < block.chunks.size(); ++i) {
    Chunk& chunk = block.chunks[i];
    if (!chunk.decoded) {
      frames_[i] = chunk.frame;
    } else if (std::all_of(chunk.records.begin(), chunk.records.end(),
                           [](const std::vector<uint8_t>& r) { return r.empty(); })) {
      frames_[i].clear();
    } else {
      pack_chunk(chunk.records, chunk_);
      std::string why;
      if (!compress_frame(cctx_.get(), chunk_, frames_[i], why)) {
        error =
            "store " + directory_ + ": " + name_ + " block " + std::to_string(number) + ": " + why;
        return false;
      }
    }
    any = any || !frames_[i].empty();
  }
  const Key32 key(number);
  MDB_val k = key.val();
  int rc = MDB_SUCCESS;
  if (!any) {
    if (block.stored) rc = mdb_del(txn, dbi_, &k, nullptr);
    if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;
    block.stored = false;
  } else {
    join_block(frames_, value_);
    MDB_val v = as_val(value_.data(), value_.size());
    // Blocks past the last one stored append to full pages.
    rc = mdb_put(txn, dbi_, &k, &v, int64_t(number) > last_stored_ ? MDB_APPEND : 0);
    last_stored_ = std::max<int64_t>(last_stored_, number);
    block.stored = true;
  }
  if (rc != MDB_SUCCESS) {
    error = fail("writing " + name_ + " records", rc);
    return false;
  }
  block.changed = false;
  return true;
}

bool ColumnWriter::flush(MDB_txn* txn, std::string& error) {
  for (auto& [number, block] : blocks_) {
    if (!write_block(txn, number, block, error)) return false;
  }
  blocks_.clear();
  return true;
}

// ---------------------------------------------------------------------------------------------

ChunkCache::ChunkCache(MDB_dbi dbi, ColumnShape shape, size_t capacity, size_t byte_budget)
    : dbi_(dbi), shape_(shape), byte_budget_(byte_budget), entries_(capacity) {}

ChunkCache::~ChunkCache() { release_touched(); }

void ChunkCache::touched(const uint8_t* begin, const uint8_t* end) {
  touched_begin_ = touched_begin_ ? std::min(touched_begin_, begin) : begin;
  touched_end_ = std::max(touched_end_, end);
  if (++reads_since_release_ == kReadsPerRelease) release_touched();
}

void ChunkCache::release_touched() {
  if (!touched_begin_) return;
  release_map_pages(touched_begin_, size_t(touched_end_ - touched_begin_));
  touched_begin_ = touched_end_ = nullptr;
  reads_since_release_ = 0;
}

bool ChunkCache::record(MDB_txn* txn, ZSTD_DCtx* dctx, uint32_t slot, std::span<const uint8_t>& out,
                        std::string& why) {
  const uint32_t chunk = shape_.chunk_of(slot);
  Entry* entry = nullptr;
  for (Entry& e : entries_) {
    if (e.valid && e.chunk == chunk) entry = &e;
  }
  if (!entry) {
    entry = &*std::min_element(entries_.begin(), entries_.end(),
                               [](const Entry& a, const Entry& b) { return a.used < b.used; });
    entry->valid = false;
    const Key32 key(shape_.block_of(slot));
    MDB_val k = key.val(), v;
    const int rc = mdb_get(txn, dbi_, &k, &v);
    entry->present = false;
    if (rc == MDB_SUCCESS) {
      if (!split_block(static_cast<const uint8_t*>(v.mv_data), v.mv_size, shape_.chunks_per_block(),
                       frames_, why)) {
        return false;
      }
      const auto frame = frames_[shape_.chunk_in_block(slot)];
      const bool inflated = frame.empty() || inflate_frame(dctx, frame, entry->bytes, why);
      // After inflating, so that the pages it brought in count.
      const auto* value = static_cast<const uint8_t*>(v.mv_data);
      touched(value, frame.empty() ? value + shape_.chunks_per_block() * 4
                                   : frame.data() + frame.size());
      if (!inflated) return false;
      if (!frame.empty()) {
        if (!check_chunk(entry->bytes, shape_.chunk_slots, entry->ends, why)) return false;
        entry->present = true;
      }
    } else if (rc != MDB_NOTFOUND) {
      why = mdb_strerror(rc);
      return false;
    }
    entry->chunk = chunk;
    entry->valid = true;
    // Chunks of big meshes can be megabytes: keep the cache within its byte budget, least
    // recently used first, the chunk just read always.
    size_t held = 0;
    for (const Entry& e : entries_) held += e.bytes.capacity();
    while (held > byte_budget_) {
      Entry* oldest = nullptr;
      for (Entry& e : entries_) {
        if (&e != entry && e.bytes.capacity() > 0 && (!oldest || e.used < oldest->used)) oldest = &e;
      }
      if (!oldest) break;
      held -= oldest->bytes.capacity();
      oldest->bytes = {};
      oldest->valid = false;
    }
  }
  entry->used = ++clock_;
  out = entry->present ? chunk_record(entry->bytes, entry->ends, slot % shape_.chunk_slots)
                       : std::span<const uint8_t>();
  return true;
}

}  // namespace plantview::detail
