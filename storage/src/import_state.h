// Internal: an import's state (Import::State), shared by import.cpp (putting and removing
// objects) and import_commit.cpp (merging the runs and committing).
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "import_runs.h"
#include "revisions.h"
#include "store_internal.h"
#include "tables.h"
#include "writer_lock.h"

namespace plantview::detail {

// An import's run records (import_runs.h), each sorted as the merge needs it.
struct IdSlot {
  uint64_t id;
  uint32_t slot;
  uint32_t unused = 0;
};
struct IdSlotLess {
  bool operator()(const IdSlot& a, const IdSlot& b) const {
    return a.id != b.id ? a.id < b.id : a.slot < b.slot;
  }
};
struct HashSlot {
  uint32_t hash, slot;
};
struct HashSlotLess {
  bool operator()(const HashSlot& a, const HashSlot& b) const {
    return a.hash != b.hash ? a.hash < b.hash : a.slot < b.slot;
  }
};
struct SpatialItem {
  detail::MortonKey key;
  detail::BlockEntry entry;
};
struct SpatialItemLess {
  bool operator()(const SpatialItem& a, const SpatialItem& b) const {
    return a.key != b.key ? a.key < b.key : a.entry.grid.slot < b.entry.grid.slot;
  }
};

}  // namespace plantview::detail

namespace plantview {

struct Import::State {
  std::shared_ptr<Store::State> store;
  // Held from before the transaction begins until after it ends (declared first: released last).
  detail::WriterLock writer_lock;
  detail::LmdbTxn txn;

  ModelStatistics totals;        // as committed before, updated as objects come and go
  uint32_t next_slot = 0;
  uint32_t first_new_slot = 0;   // this import's objects are in [first_new_slot, next_slot)
  bool has_origin = false;       // the spatial origin is fixed (committed, or by this import)
  // The key width of ids/ and names/ as they are in this transaction (the committed one until
  // the commit re-keys them; see rekey_indexes()).
  unsigned index_key_bits = detail::kMinIndexKeyBits;
  glm::dvec3 origin{0.0};
  // Every slot this import removed, one bit a slot (slots are never reused), and every
  // committed slot whose removal waits for the commit (remove_source() marks a source's slots so:
  // one put again unchanged keeps its slot and clears its bit; commit() removes the rest): the
  // import's only memory per slot.
  std::vector<uint64_t> removed_bits, pending_bits;
  // This import's index data, spilled to sorted runs when a buffer fills.
  detail::SpilledRuns<detail::IdSlot, detail::IdSlotLess> new_ids;
  detail::SpilledRuns<detail::HashSlot, detail::HashSlotLess> new_names;
  detail::SpilledRuns<detail::SpatialItem, detail::SpatialItemLess> new_spatial;
  // Sources this import touched: every slot they had or got, as runs (removed ones included,
  // filtered out at commit).
  std::map<std::string, std::vector<detail::SlotRun>, std::less<>> sources;
  std::vector<detail::SlotRun>* last_source = nullptr;
  std::string last_source_name;
  detail::ColumnWriter objects, attributes;
  std::vector<uint8_t> raw;
  std::vector<uint32_t> slots;  // scratch
  uint64_t put_count = 0;
  ModelStatistics put_statistics;  // of the objects put (Import::put_statistics())
  // What this import changed, in the order it did (each record put and slot removed): with the
  // previous commit's id it makes this commit's (meta/"commit_id").
  uint64_t changes_digest = 0;
  void digest(uint64_t value) { changes_digest = detail::mix_digest(changes_digest, value); }
  void digest(const std::vector<uint8_t>& bytes) {
    digest(std::hash<std::string_view>()(
        std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size())));
  }
  detail::ZstdCCtx compressor = detail::make_compressor();
  detail::ZstdDCtx dctx{ZSTD_createDCtx()};
  std::vector<uint8_t> raw_attributes;  // scratch: the attributes of the object being put
  // Committed records, read to compare an object put again with the one it would replace:
  // through a read transaction on the state this import began from (committed records are
  // never changed in place, only erased), begun on first use and ended by commit().
  detail::LmdbTxn committed;
  detail::ChunkCache committed_objects{store->dbs.objects, 8, size_t(16) << 20};
  detail::ChunkCache committed_attributes{store->dbs.attributes, 8, size_t(16) << 20};

  // The revision this commit records (store.h, "Revisions"): every object put, and every
  // committed object removed, with its content hash, merged by id at commit.
  std::string note;
  uint32_t keep_revisions = kDefaultKeepRevisions;
  detail::SpilledRuns<detail::ChangeItem, detail::ChangeItemLess> put_items, removed_items;
  detail::NameLog change_names;
  detail::ContentHasher hasher;

  explicit State(std::shared_ptr<Store::State> s, size_t run_bytes)
      : store(std::move(s)),
        new_ids(store->directory, "ids", run_bytes / sizeof(detail::IdSlot)),
        new_names(store->directory, "names", run_bytes / sizeof(detail::HashSlot)),
        new_spatial(store->directory, "spatial", run_bytes / sizeof(detail::SpatialItem)),
        objects(store->directory, "object", store->dbs.objects, detail::kObjectShape),
        attributes(store->directory, "attributes", store->dbs.attributes,
                   detail::kAttributeShape),
        put_items(store->directory, "puts", run_bytes / 2 / sizeof(detail::ChangeItem)),
        removed_items(store->directory, "removals", run_bytes / 2 / sizeof(detail::ChangeItem)),
        change_names(store->directory) {}

  std::string fail(std::string_view what, int rc) const { return store->fail(what, rc); }
  std::string message(const std::string& what) const { return "store " + store->directory + ": " + what; }

  bool is_removed(uint32_t slot) const {
    const size_t word = slot / 64;
    return word < removed_bits.size() && (removed_bits[word] >> (slot % 64) & 1u);
  }
  void mark_removed(uint32_t slot) { set_bit(removed_bits, slot); }
  bool is_pending(uint32_t slot) const {
    const size_t word = slot / 64;
    return word < pending_bits.size() && (pending_bits[word] >> (slot % 64) & 1u);
  }
  void mark_pending(uint32_t slot) { set_bit(pending_bits, slot); }
  void clear_pending(uint32_t slot) {
    const size_t word = slot / 64;
    if (word < pending_bits.size()) pending_bits[word] &= ~(uint64_t(1) << (slot % 64));
  }
  static void set_bit(std::vector<uint64_t>& bits, uint32_t slot) {
    const size_t word = slot / 64;
    if (word >= bits.size()) bits.resize(word + 1 + word / 4, 0);
    bits[word] |= uint64_t(1) << (slot % 64);
  }

  // The content hash (detail::content_hash) of the committed object in `slot`; false with a
  // message naming the slot when it cannot be read.
  bool committed_hash(uint32_t slot, uint64_t& hash, std::string& error);
  // Removes every slot still pending (in slot order). The first step of commit().
  bool remove_pending(std::string& error);

  // The slot runs of a source (as committed, plus this import's), loaded on first use.
  bool source_runs(std::string_view source, std::vector<detail::SlotRun>*& out, std::string& error);

  // Removes the object in `slot` (committed earlier, or put by this import; pending or not). A
  // committed one's id and name keys go now; this import's are left out of the merge at commit.
  bool remove_slot(uint32_t slot, std::string& error);

  // Compresses and stores `raw_value` under `key` of `dbi`.
  bool put_frame(MDB_dbi dbi, MDB_val key, const std::vector<uint8_t>& raw_value, unsigned flags,
                 const std::string& what, std::string& error);

  bool database_empty(MDB_dbi dbi, bool& empty, std::string& error);

  // Chooses the key width of ids/ and names/ for the store's count after this import
  // (index_key_bits()); when it differs from theirs, moves their entries into this import's
  // runs and empties them, so that the merges write everything again with the new width.
  bool rekey_indexes(std::string& error);
  bool merge_ids(std::string& error);
  bool merge_names(std::string& error);
  bool write_sources(std::string& error);
  bool write_spatial(std::string& error);
  // Adds `object`'s change item (slot, content hash `hash`) to `items`.
  bool add_change_item(detail::SpilledRuns<detail::ChangeItem, detail::ChangeItemLess>& items,
                       const Object& object, uint32_t slot, uint64_t hash, std::string& error);
  // The revision: the change list (merging the puts and the removals by id), the previous
  // records of what was removed or modified, pruning, revisions/. After merge_ids (which settles
  // which puts stand).
  bool write_revision(std::string& error);
  bool commit(std::string& error);
};

// The ids: this import's (id, slot) in id order; of an id put more than once the latest slot

}  // namespace plantview
