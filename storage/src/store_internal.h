// Internal: what the parts of the store (store_open.cpp, store_meta.cpp, import.cpp,
// import_commit.cpp, read_view.cpp) share: the named databases, the meta/ keys' readers, the ids/
// and names/ index entries, what read views of one committed state share, and Store::State.
#pragma once

#include <lmdb.h>

#include <atomic>
#include <cassert>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "columns.h"
#include "lmdb_guard.h"
#include "plantview/store.h"
#include "shared_cache.h"
#include "spatial.h"

namespace plantview::detail {

// The names table keys: 32 bits of FNV-1a 64 (hits are confirmed against the record's name).
inline uint32_t name_hash(std::string_view name) {
  const uint64_t h = object_id("", name);
  return uint32_t(h ^ (h >> 32));
}

// Commit ids (StoreInfo::commit_id): a digest of what each import changed, chained onto the
// previous commit's id.
uint64_t mix_digest(uint64_t digest, uint64_t value);

// meta/"commit_id" as committed in `txn`; 0 for a store that has none (empty, or made before
// commit ids).
uint64_t read_commit_id(MDB_txn* txn, MDB_dbi meta);

// meta/"statistics" as committed in `txn` (zero counts when absent). False with `error` naming
// the store and the key when the value is damaged (statistics_from_json).
bool read_statistics(MDB_txn* txn, MDB_dbi meta, const std::string& directory,
                     ModelStatistics& statistics, std::string& error);

struct Databases {
  MDB_dbi meta, objects, attributes, sources, ids, names;
  MDB_dbi spatial[2];  // spatial_a, spatial_b: the top says which holds the committed blocks
  MDB_dbi revisions, changes, history;  // format 6
};


// A value read in a read transaction and inflated once: without readahead (MDB_NORDAHEAD) the
// whole frame is asked for at once, and its pages are dropped from the resident set afterwards.
bool inflate_read_once(const MDB_val& v, ZSTD_DCtx* dctx, std::vector<uint8_t>& raw,
                       std::string& why);

// meta/"spatial_top" decoded (`found` false, `top` empty, when the store never had geometry).
bool read_top(MDB_txn* txn, MDB_dbi meta, bool read_once, ZSTD_DCtx* dctx, detail::DecodedTop& top,
              bool& found, std::string& why);

uint32_t read_next_slot(MDB_txn* txn, MDB_dbi meta);

// ids/ and names/ are MDB_DUPSORT | MDB_DUPFIXED databases: a short key (the top `bits` bits of
// the id or name hash, big-endian in (bits + 7) / 8 bytes) and, under it, sorted fixed-size
// values packed into pages (the rest of the id or hash, big-endian in as few bytes as hold it,
// then the slot, big-endian). LMDB costs a key about 28 bytes (node, sub-page header and index)
// and keeps up to about 200 of its values in a sub-page of the leaf (beyond that a B-tree of its
// own, of whole pages), so a key should hold tens of values: the width follows the store's
// object count (index_key_bits()), kept in meta/"index_key_bits".
constexpr unsigned kIndexFlags = MDB_DUPSORT | MDB_DUPFIXED;
inline constexpr unsigned kMinIndexKeyBits = 8;
inline constexpr unsigned kMaxIndexKeyBits = 24;

// The key width for a store of `objects` objects whose indexes have keys of `current` bits (0:
// the indexes are empty, any width will do): about 32 values a key (measured on preset c and
// its x100: the ids take 15.3 and 13.3 bytes an object, the names 9.5 and 7.9; 16 bits took
// 19.9 and 14.3, 14.6 and 7.8). A width is kept while its keys hold 16 to 64 values on
// average, so that the indexes are written again (re-keyed) only after the count has doubled
// or halved.
unsigned index_key_bits(uint64_t objects, unsigned current);

// meta/"index_key_bits" as committed in `txn` (kMinIndexKeyBits when absent: the indexes are
// empty). False when the value is not a u32 within [kMinIndexKeyBits, kMaxIndexKeyBits].
bool read_index_key_bits(MDB_txn* txn, MDB_dbi meta, unsigned& bits);

inline void put_be(unsigned char* out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out[i] = static_cast<unsigned char>(v >> (8 * (bytes - 1 - i)));
}
inline uint64_t get_be(const void* in, int bytes) {
  const auto* b = static_cast<const unsigned char*>(in);
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = v << 8 | b[i];
  return v;
}

// An entry of ids/ (id, slot: KeyBits 64) or of names/ (32-bit name hash, slot: KeyBits 32)
// with keys of `bits` bits: key and value bytes.
template <int KeyBits>
struct IndexEntry {
  static_assert(KeyBits - int(kMaxIndexKeyBits) >= 8, "the rest needs a byte at least");
  int key_bytes, rest_bytes;
  unsigned char key[(kMaxIndexKeyBits + 7) / 8];
  unsigned char value[(KeyBits - kMinIndexKeyBits + 7) / 8 + 4];
  IndexEntry(uint64_t k, uint32_t slot, unsigned bits)
      : key_bytes(int(bits + 7) / 8), rest_bytes((KeyBits - int(bits) + 7) / 8) {
    assert(bits >= kMinIndexKeyBits && bits <= kMaxIndexKeyBits);
    const int rest_bits = KeyBits - int(bits);
    put_be(key, k >> rest_bits, key_bytes);
    put_be(value, k & ((uint64_t(1) << rest_bits) - 1), rest_bytes);
    put_be(value + rest_bytes, slot, 4);
  }
  int value_bytes() const { return rest_bytes + 4; }
  MDB_val key_val() const { return as_val(key, size_t(key_bytes)); }
  MDB_val value_val() const { return as_val(value, size_t(value_bytes())); }
  uint32_t top() const { return uint32_t(get_be(key, key_bytes)); }
  // The id or hash and the slot of an entry read from a database with keys of `bits` bits:
  // false when the key or value has another size.
  static bool decode(const MDB_val& k, const MDB_val& v, unsigned bits, uint64_t& out,
                     uint32_t& slot) {
    const int kb = int(bits + 7) / 8, rb = (KeyBits - int(bits) + 7) / 8;
    if (k.mv_size != size_t(kb) || v.mv_size != size_t(rb + 4)) return false;
    out = get_be(k.mv_data, kb) << (KeyBits - int(bits)) | get_be(v.mv_data, rb);
    slot = uint32_t(get_be(static_cast<const unsigned char*>(v.mv_data) + rb, 4));
    return true;
  }
};
using IdEntry = IndexEntry<64>;
using NameEntry = IndexEntry<32>;

// The slots stored under `k` (an id, or a name hash) in ids/ or names/ with keys of `bits` bits,
// in slot order: an LMDB error code, or MDB_BAD_VALSIZE for a value of the wrong size.
template <int KeyBits>
int index_slots(MDB_txn* txn, MDB_dbi dbi, unsigned bits, uint64_t k, std::vector<uint32_t>& slots,
                size_t at_most = SIZE_MAX, const void** last_value = nullptr) {
  using Entry = IndexEntry<KeyBits>;
  slots.clear();
  detail::LmdbCursor cursor;
  int rc = cursor.open(txn, dbi);
  const Entry first(k, 0, bits);
  MDB_val key = first.key_val(), value = first.value_val();
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &key, &value, MDB_GET_BOTH_RANGE);
  while (rc == MDB_SUCCESS && slots.size() < at_most) {
    if (value.mv_size != size_t(first.value_bytes())) return MDB_BAD_VALSIZE;
    if (std::memcmp(value.mv_data, first.value, size_t(first.rest_bytes)) != 0) break;
    slots.push_back(uint32_t(
        get_be(static_cast<const unsigned char*>(value.mv_data) + first.rest_bytes, 4)));
    if (last_value) *last_value = value.mv_data;
    rc = mdb_cursor_get(cursor.get(), &key, &value, MDB_NEXT_DUP);
  }
  return rc == MDB_NOTFOUND ? MDB_SUCCESS : rc;
}

// Writes sorted entries into ids/ or names/: appended when the database was empty.
template <int KeyBits>
struct IndexAppender {
  MDB_txn* txn;
  MDB_dbi dbi;
  bool append;
  bool any = false;
  uint32_t last_top = 0;
  int put(const IndexEntry<KeyBits>& e) {
    MDB_val k = e.key_val(), v = e.value_val();
    unsigned flags = 0;
    if (append) flags = any && e.top() == last_top ? MDB_APPENDDUP : MDB_APPEND;
    any = true;
    last_top = e.top();
    return mdb_put(txn, dbi, &k, &v, flags);
  }
};

// Decoded spatial blocks of one committed state, shared by its views: bounded by `bound_bytes`
// among blocks nobody holds, least recently used first.
class BlockCache {
 public:
  explicit BlockCache(size_t bound_bytes) : cache_(bound_bytes, true) {}
  std::shared_ptr<const SpatialBlock> find(uint32_t block) { return cache_.find(block); }
  void insert(uint32_t block, const std::shared_ptr<const SpatialBlock>& decoded) {
    cache_.insert(block, decoded,
                  sizeof(SpatialBlock) + decoded->nodes.capacity() * sizeof(SpatialNode) +
                      decoded->entries.capacity() * sizeof(SpatialEntry));
  }
  size_t bytes() const { return cache_.bytes(); }

 private:
  detail::SharedCache<SpatialBlock> cache_;
};

// The cache bounds of states first read from now on (set_spatial_cache_bytes(),
// set_chunk_cache_bytes(); read_view.cpp).
extern std::atomic<size_t> g_spatial_cache_bytes;
extern std::atomic<size_t> g_chunk_cache_bytes;

// What read views share of one committed state of the store.
struct Snapshot {
  size_t txn_id = 0;
  uint32_t next_slot = 0;
  // The key width of ids/ and names/ (meta/"index_key_bits"); 0 when that value is damaged,
  // which fails every lookup.
  unsigned index_key_bits = 0;
  // The spatial top, decoded by the first view of the state that asks for anything spatial (in
  // its own read transaction, which sees the same committed state as every other view of it);
  // read-only afterwards. On failure the top stays empty and top_error says why.
  std::once_flag top_once;
  detail::DecodedTop top;
  std::string top_error;
  BlockCache blocks{g_spatial_cache_bytes.load()};
  detail::SharedChunks object_chunks{g_chunk_cache_bytes.load()};
};

// Whether the data file holds every page the environment's newest meta page says is in use.
// LMDB maps the file and reads pages in place, so a page beyond the end of the file (a partial
// copy, a full disk, a file cut short while open) would be a SIGBUS at the first read, not an
// error. False with a message naming the file, its size and the size it needs.
bool data_file_complete(MDB_env* env, const std::string& directory, std::string& error);

// Makes the data file as long as data_file_complete() asks, after a commit. LMDB may end a
// commit with its last pages free and never written (pages the transaction allocated and freed
// again, which it lists as free rather than writing them; an import that re-keys the indexes
// after removing many objects does this): the file is extended over them (a hole, read as
// zeros, never as pages in use). False with a message naming the file on a system error. (A
// failure, or a crash between the commit and this, leaves a file that open() refuses as
// truncated, which it is not: extending data.mdb to the size named mends it.)
bool cover_free_tail(MDB_env* env, const std::string& directory, std::string& error);

}  // namespace plantview::detail

namespace plantview {

struct Store::State {
  std::string directory;
  Mode mode;
  bool without_lock = false;  // opened with MDB_NOLOCK (read-only directory or file system)
  detail::LmdbEnv env;
  detail::Databases dbs{};
  // The snapshot of the newest state a view has read. Guarded by snapshot_mutex.
  std::mutex snapshot_mutex;
  std::shared_ptr<detail::Snapshot> latest;

  std::string fail(std::string_view what, int rc) const { return detail::lmdb_message(directory, what, rc); }

  // The snapshot a read transaction sees (metadata only: the top waits for its first use).
  std::shared_ptr<detail::Snapshot> snapshot_for(MDB_txn* txn) {
    const size_t txn_id = mdb_txn_id(txn);
    std::lock_guard lock(snapshot_mutex);
    if (latest && latest->txn_id == txn_id) return latest;
    auto s = std::make_shared<detail::Snapshot>();
    s->txn_id = txn_id;
    s->next_slot = detail::read_next_slot(txn, dbs.meta);
    if (!detail::read_index_key_bits(txn, dbs.meta, s->index_key_bits)) s->index_key_bits = 0;
    if (!latest || latest->txn_id < txn_id) latest = s;
    return s;
  }
};

}  // namespace plantview
