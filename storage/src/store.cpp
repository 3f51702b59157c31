// The LMDB plant store: opening, imports (one write transaction each), read views.
#include "plantview/store.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <list>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <unordered_map>
#include <unordered_set>

#include <sys/stat.h>

#include "columns.h"
#include "import_runs.h"
#include "lmdb_guard.h"
#include "record.h"
#include "shared_cache.h"
#include "spatial.h"
#include "tables.h"

namespace plantview {

using detail::as_val;
using detail::ColumnWriter;
using detail::lmdb_message;

namespace {

constexpr size_t kMapSizeBytes = size_t(1) << 40;  // address space only; the file grows as used
// Decompressed chunks a read view keeps: 32 x 64 objects (about 0.5 MB for generated plants)
// and 2 x 256 objects' attributes, each column within 16 MB (chunks of big meshes are big).
constexpr size_t kObjectChunksCached = 32;
constexpr size_t kAttributeChunksCached = 2;
constexpr size_t kViewChunkBytes = size_t(16) << 20;

// The names table keys: 32 bits of FNV-1a 64 (hits are confirmed against the record's name).
uint32_t name_hash(std::string_view name) {
  const uint64_t h = object_id("", name);
  return uint32_t(h ^ (h >> 32));
}

nlohmann::json statistics_to_json(const ModelStatistics& s) {
  nlohmann::json j;
  j["objects"] = s.objects;
  j["primitives"] = s.primitives;
  j["triangles_full_resolution"] = s.triangles;
  for (int c = 0; c < kObjectClassCount; ++c) {
    const std::string name(class_name(ObjectClass(c)));
    j["objects_by_class"][name] = s.objects_by_class[c];
    j["primitives_by_class"][name] = s.primitives_by_class[c];
    j["triangles_by_class"][name] = s.triangles_by_class[c];
  }
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    const std::string name(kind_name(PrimitiveKind(k)));
    j["primitives_by_kind"][name] = s.primitives_by_kind[k];
    j["triangles_by_kind"][name] = s.triangles_by_kind[k];
  }
  if (!s.bounds.empty()) {
    j["bounds_m"] = {{"min", {s.bounds.min.x, s.bounds.min.y, s.bounds.min.z}},
                     {"max", {s.bounds.max.x, s.bounds.max.y, s.bounds.max.z}}};
  }
  return j;
}

// Commit ids (StoreInfo::commit_id): a digest of what each import changed, chained onto the
// previous commit's id.
uint64_t mix_digest(uint64_t digest, uint64_t value) {
  uint64_t x = digest ^ (value + 0x9e3779b97f4a7c15ull + (digest << 6) + (digest >> 2));
  x ^= x >> 30;  // splitmix64's finaliser: every input bit reaches every output bit
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// meta/"commit_id" as committed in `txn`; 0 for a store that has none (empty, or made before
// commit ids).
uint64_t read_commit_id(MDB_txn* txn, MDB_dbi meta) {
  MDB_val k = as_val("commit_id"), v;
  uint64_t id = 0;
  if (mdb_get(txn, meta, &k, &v) == MDB_SUCCESS && v.mv_size == sizeof id)
    std::memcpy(&id, v.mv_data, sizeof id);
  return id;
}

// Reads meta/"statistics" (statistics_to_json's form; absent keys count 0). False, with `why`
// naming the key, when the value is not JSON or a key holds the wrong type: the value is input
// like any other byte of the file, and a damaged one must not take down every command.
bool statistics_from_json(std::string_view text, ModelStatistics& s, std::string& why) {
  s = ModelStatistics{};
  const auto j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded()) {
    why = "not JSON";
    return false;
  }
  if (!j.is_object()) {
    why = std::string("a JSON ") + j.type_name() + ", not an object";
    return false;
  }
  const auto count = [&](const nlohmann::json& in, const std::string& path, const std::string& key,
                         uint64_t& out) {
    const auto it = in.find(key);
    if (it == in.end()) return true;
    if (!it->is_number_unsigned()) {
      why = "\"" + path + key + "\" is a JSON " + it->type_name() + ", not a count";
      return false;
    }
    out = it->get<uint64_t>();
    return true;
  };
  // A map of counts by name: absent, or an object.
  const auto map = [&](const std::string& key) -> const nlohmann::json* {
    static const nlohmann::json kEmpty = nlohmann::json::object();
    const auto it = j.find(key);
    if (it == j.end()) return &kEmpty;
    if (!it->is_object()) {
      why = "\"" + key + "\" is a JSON " + it->type_name() + ", not an object";
      return nullptr;
    }
    return &*it;
  };
  if (!count(j, "", "objects", s.objects) || !count(j, "", "primitives", s.primitives) ||
      !count(j, "", "triangles_full_resolution", s.triangles)) {
    return false;
  }
  const nlohmann::json* objects_by_class = map("objects_by_class");
  const nlohmann::json* primitives_by_class = map("primitives_by_class");
  const nlohmann::json* triangles_by_class = map("triangles_by_class");
  const nlohmann::json* primitives_by_kind = map("primitives_by_kind");
  const nlohmann::json* triangles_by_kind = map("triangles_by_kind");
  if (!objects_by_class || !primitives_by_class || !triangles_by_class || !primitives_by_kind ||
      !triangles_by_kind) {
    return false;
  }
  for (int c = 0; c < kObjectClassCount; ++c) {
    const std::string name(class_name(ObjectClass(c)));
    if (!count(*objects_by_class, "objects_by_class.", name, s.objects_by_class[c]) ||
        !count(*primitives_by_class, "primitives_by_class.", name, s.primitives_by_class[c]) ||
        !count(*triangles_by_class, "triangles_by_class.", name, s.triangles_by_class[c])) {
      return false;
    }
  }
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    const std::string name(kind_name(PrimitiveKind(k)));
    if (!count(*primitives_by_kind, "primitives_by_kind.", name, s.primitives_by_kind[k]) ||
        !count(*triangles_by_kind, "triangles_by_kind.", name, s.triangles_by_kind[k])) {
      return false;
    }
  }
  const auto bounds = j.find("bounds_m");
  if (bounds != j.end()) {
    for (const char* end : {"min", "max"}) {
      const nlohmann::json* corner = bounds->is_object() && bounds->contains(end)
                                         ? &(*bounds)[end]
                                         : nullptr;
      bool ok = corner && corner->is_array() && corner->size() == 3;
      for (size_t i = 0; ok && i < 3; ++i) ok = (*corner)[i].is_number();
      if (!ok) {
        why = std::string("\"bounds_m.") + end + "\" is not an array of 3 numbers";
        return false;
      }
      glm::dvec3& out = end[1] == 'i' ? s.bounds.min : s.bounds.max;
      for (int i = 0; i < 3; ++i) out[i] = (*corner)[size_t(i)].get<double>();
    }
  }
  return true;
}

// meta/"statistics" as committed in `txn` (zero counts when absent). False with `error` naming
// the store and the key when the value is damaged (statistics_from_json).
bool read_statistics(MDB_txn* txn, MDB_dbi meta, const std::string& directory,
                     ModelStatistics& statistics, std::string& error) {
  statistics = ModelStatistics{};
  MDB_val k = as_val("statistics"), v;
  const int rc = mdb_get(txn, meta, &k, &v);
  if (rc == MDB_NOTFOUND) return true;
  std::string why;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
  } else if (statistics_from_json(
                 std::string_view(static_cast<const char*>(v.mv_data), v.mv_size), statistics,
                 why)) {
    return true;
  }
  statistics = ModelStatistics{};
  error = "store " + directory + ": meta/\"statistics\" is damaged: " + why;
  return false;
}

struct Databases {
  MDB_dbi meta, objects, attributes, sources, ids, names;
  MDB_dbi spatial[2];  // spatial_a, spatial_b: the top says which holds the committed blocks
};

// A value read in a read transaction and inflated once: without readahead (MDB_NORDAHEAD) the
// whole frame is asked for at once, and its pages are dropped from the resident set afterwards.
bool inflate_read_once(const MDB_val& v, ZSTD_DCtx* dctx, std::vector<uint8_t>& raw,
                       std::string& why) {
  const std::span<const uint8_t> frame(static_cast<const uint8_t*>(v.mv_data), v.mv_size);
  detail::prefetch_map_pages(v.mv_data, v.mv_size);
  const bool ok = detail::inflate_frame(dctx, frame, raw, why);
  detail::release_map_pages(v.mv_data, v.mv_size);
  return ok;
}

// meta/"spatial_top" decoded (`found` false, `top` empty, when the store never had geometry).
bool read_top(MDB_txn* txn, MDB_dbi meta, bool read_once, ZSTD_DCtx* dctx, detail::DecodedTop& top,
              bool& found, std::string& why) {
  top = detail::DecodedTop{};
  MDB_val k = as_val("spatial_top"), v;
  const int rc = mdb_get(txn, meta, &k, &v);
  found = rc == MDB_SUCCESS;
  if (rc == MDB_NOTFOUND) return true;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return false;
  }
  std::vector<uint8_t> raw;
  const std::span<const uint8_t> frame(static_cast<const uint8_t*>(v.mv_data), v.mv_size);
  const bool ok = read_once ? inflate_read_once(v, dctx, raw, why)
                            : detail::inflate_frame(dctx, frame, raw, why);
  return ok && detail::decode_top(raw.data(), raw.size(), top, why);
}

uint32_t read_next_slot(MDB_txn* txn, MDB_dbi meta) {
  uint32_t next_slot = 0;
  MDB_val k = as_val("next_slot"), v;
  if (mdb_get(txn, meta, &k, &v) == MDB_SUCCESS && v.mv_size == 4) {
    std::memcpy(&next_slot, v.mv_data, 4);
  }
  return next_slot;
}

// ids/ and names/ are MDB_DUPSORT | MDB_DUPFIXED databases: a short key (the top 16 bits of the
// id or name hash, big-endian) and, under it, sorted fixed-size values packed into pages (the
// rest of the id or hash, then the slot, big-endian): about 11 and 7 bytes an object on disk
// where a key and value per object would take 22 and 18.
constexpr unsigned kIndexFlags = MDB_DUPSORT | MDB_DUPFIXED;

void put_be(unsigned char* out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out[i] = static_cast<unsigned char>(v >> (8 * (bytes - 1 - i)));
}
uint64_t get_be(const void* in, int bytes) {
  const auto* b = static_cast<const unsigned char*>(in);
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = v << 8 | b[i];
  return v;
}

// An entry of ids/ (id, slot) or of names/ (32-bit name hash, slot): key and value bytes.
template <int KeyBits>
struct IndexEntry {
  static constexpr int kRestBytes = (KeyBits - 16) / 8;
  static constexpr int kValueBytes = kRestBytes + 4;
  unsigned char key[2];
  unsigned char value[kValueBytes];
  IndexEntry(uint64_t k, uint32_t slot) {
    put_be(key, k >> (KeyBits - 16), 2);
    put_be(value, k, kRestBytes);
    put_be(value + kRestBytes, slot, 4);
  }
  MDB_val key_val() const { return as_val(key, 2); }
  MDB_val value_val() const { return as_val(value, kValueBytes); }
  uint16_t top() const { return uint16_t(get_be(key, 2)); }
};
using IdEntry = IndexEntry<64>;
using NameEntry = IndexEntry<32>;

// The slots stored under `k` (an id, or a name hash) in ids/ or names/, in slot order: an LMDB
// error code, or MDB_BAD_VALSIZE for a value of the wrong size.
template <int KeyBits>
int index_slots(MDB_txn* txn, MDB_dbi dbi, uint64_t k, std::vector<uint32_t>& slots,
                size_t at_most = SIZE_MAX, const void** last_value = nullptr) {
  using Entry = IndexEntry<KeyBits>;
  slots.clear();
  detail::LmdbCursor cursor;
  int rc = cursor.open(txn, dbi);
  const Entry first(k, 0);
  MDB_val key = first.key_val(), value = first.value_val();
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &key, &value, MDB_GET_BOTH_RANGE);
  while (rc == MDB_SUCCESS && slots.size() < at_most) {
    if (value.mv_size != size_t(Entry::kValueBytes)) return MDB_BAD_VALSIZE;
    if (std::memcmp(value.mv_data, first.value, Entry::kRestBytes) != 0) break;
    slots.push_back(uint32_t(get_be(static_cast<const unsigned char*>(value.mv_data) + Entry::kRestBytes, 4)));
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
  uint16_t last_top = 0;
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

std::atomic<size_t> g_spatial_cache_bytes{kSpatialCacheBytes};
std::atomic<size_t> g_chunk_cache_bytes{kChunkCacheBytes};

// What read views share of one committed state of the store.
struct Snapshot {
  size_t txn_id = 0;
  uint32_t next_slot = 0;
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
bool data_file_complete(MDB_env* env, const std::string& directory, std::string& error) {
  MDB_envinfo info;
  MDB_stat stat;
  mdb_filehandle_t fd;
  struct stat file;
  int rc = mdb_env_info(env, &info);
  if (rc == MDB_SUCCESS) rc = mdb_env_stat(env, &stat);
  if (rc == MDB_SUCCESS) rc = mdb_env_get_fd(env, &fd);
  if (rc == MDB_SUCCESS && fstat(fd, &file) != 0) rc = errno;
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "checking the size of data.mdb", rc);
    return false;
  }
  const uint64_t needed = (uint64_t(info.me_last_pgno) + 1) * stat.ms_psize;
  if (uint64_t(file.st_size) >= needed) return true;
  error = "store " + directory + ": " +
          (std::filesystem::path(directory) / "data.mdb").string() + " is truncated: " +
          std::to_string(file.st_size) + " bytes, but its pages in use (0 to " +
          std::to_string(info.me_last_pgno) + ", " + std::to_string(stat.ms_psize) +
          " bytes each) need " + std::to_string(needed) +
          " (a partial copy, or a disk that was full)";
  return false;
}

}  // namespace

std::string statistics_json(const ModelStatistics& statistics) {
  return statistics_to_json(statistics).dump();
}


namespace detail {

void set_spatial_cache_bytes(size_t bytes) { g_spatial_cache_bytes = bytes; }
void set_chunk_cache_bytes(size_t bytes) { g_chunk_cache_bytes = bytes; }

namespace {
std::atomic<size_t> g_import_run_bytes{size_t(64) << 20};
std::atomic<ImportStageHook> g_stage_hook{nullptr};
}  // namespace

size_t import_run_bytes() { return g_import_run_bytes; }
void set_import_run_bytes(size_t bytes) { g_import_run_bytes = bytes; }
void set_import_stage_hook(ImportStageHook hook) { g_stage_hook = hook; }
void import_stage(const char* stage) {
  if (const ImportStageHook hook = g_stage_hook.load()) hook(stage);
}

void remove_stale_runs(const std::string& directory) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(directory, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("import-", 0) == 0 && name.size() > 4 &&
        name.compare(name.size() - 4, 4, ".run") == 0) {
      std::error_code ignored;
      std::filesystem::remove(entry.path(), ignored);
    }
  }
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------

struct Store::State {
  std::string directory;
  Mode mode;
  bool without_lock = false;  // opened with MDB_NOLOCK (read-only directory or file system)
  detail::LmdbEnv env;
  Databases dbs{};
  // The snapshot of the newest state a view has read. Guarded by snapshot_mutex.
  std::mutex snapshot_mutex;
  std::shared_ptr<Snapshot> latest;

  std::string fail(std::string_view what, int rc) const { return lmdb_message(directory, what, rc); }

  // The snapshot a read transaction sees (metadata only: the top waits for its first use).
  std::shared_ptr<Snapshot> snapshot_for(MDB_txn* txn) {
    const size_t txn_id = mdb_txn_id(txn);
    std::lock_guard lock(snapshot_mutex);
    if (latest && latest->txn_id == txn_id) return latest;
    auto s = std::make_shared<Snapshot>();
    s->txn_id = txn_id;
    s->next_slot = read_next_slot(txn, dbs.meta);
    if (!latest || latest->txn_id < txn_id) latest = s;
    return s;
  }
};

// ---------------------------------------------------------------------------------------------

namespace {

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

}  // namespace

struct Import::State {
  std::shared_ptr<Store::State> store;
  detail::LmdbTxn txn;

  ModelStatistics totals;        // as committed before, updated as objects come and go
  uint32_t next_slot = 0;
  uint32_t first_new_slot = 0;   // this import's objects are in [first_new_slot, next_slot)
  bool has_origin = false;       // the spatial origin is fixed (committed, or by this import)
  glm::dvec3 origin{0.0};
  // Every slot this import removed, one bit a slot (slots are never reused): the import's only
  // memory per slot.
  std::vector<uint64_t> removed_bits;
  // This import's index data, spilled to sorted runs when a buffer fills.
  detail::SpilledRuns<IdSlot, IdSlotLess> new_ids;
  detail::SpilledRuns<HashSlot, HashSlotLess> new_names;
  detail::SpilledRuns<SpatialItem, SpatialItemLess> new_spatial;
  // Sources this import touched: every slot they had or got, as runs (removed ones included,
  // filtered out at commit).
  std::map<std::string, std::vector<detail::SlotRun>, std::less<>> sources;
  std::vector<detail::SlotRun>* last_source = nullptr;
  std::string last_source_name;
  ColumnWriter objects, attributes;
  std::vector<uint8_t> raw;
  std::vector<uint32_t> slots;  // scratch
  uint64_t put_count = 0;
  ModelStatistics put_statistics;  // of the objects put (Import::put_statistics())
  // What this import changed, in the order it did (each record put and slot removed): with the
  // previous commit's id it makes this commit's (meta/"commit_id").
  uint64_t changes_digest = 0;
  void digest(uint64_t value) { changes_digest = mix_digest(changes_digest, value); }
  void digest(const std::vector<uint8_t>& bytes) {
    digest(std::hash<std::string_view>()(
        std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size())));
  }
  detail::ZstdCCtx compressor = detail::make_compressor();
  detail::ZstdDCtx dctx{ZSTD_createDCtx()};

  explicit State(std::shared_ptr<Store::State> s, size_t run_bytes)
      : store(std::move(s)),
        new_ids(store->directory, "ids", run_bytes / sizeof(IdSlot)),
        new_names(store->directory, "names", run_bytes / sizeof(HashSlot)),
        new_spatial(store->directory, "spatial", run_bytes / sizeof(SpatialItem)),
        objects(store->directory, "object", store->dbs.objects, detail::kObjectShape),
        attributes(store->directory, "attributes", store->dbs.attributes,
                   detail::kAttributeShape) {}

  std::string fail(std::string_view what, int rc) const { return store->fail(what, rc); }
  std::string message(const std::string& what) const { return "store " + store->directory + ": " + what; }

  bool is_removed(uint32_t slot) const {
    const size_t word = slot / 64;
    return word < removed_bits.size() && (removed_bits[word] >> (slot % 64) & 1u);
  }
  void mark_removed(uint32_t slot) {
    const size_t word = slot / 64;
    if (word >= removed_bits.size()) removed_bits.resize(word + 1 + word / 4, 0);
    removed_bits[word] |= uint64_t(1) << (slot % 64);
  }

  // The slot runs of a source (as committed, plus this import's), loaded on first use.
  bool source_runs(std::string_view source, std::vector<detail::SlotRun>*& out, std::string& error) {
    if (last_source && last_source_name == source) {
      out = last_source;
      return true;
    }
    auto it = sources.find(source);
    if (it == sources.end()) {
      std::vector<detail::SlotRun> runs;
      MDB_val k = as_val(source), v;
      const int rc = mdb_get(txn.get(), store->dbs.sources, &k, &v);
      std::string why;
      if (rc == MDB_SUCCESS) {
        if (!detail::decode_slot_runs(static_cast<const uint8_t*>(v.mv_data), v.mv_size,
                                      first_new_slot, runs, why)) {
          error = message("slots of source '" + std::string(source) + "': " + why);
          return false;
        }
      } else if (rc != MDB_NOTFOUND) {
        error = fail("reading the sources index", rc);
        return false;
      }
      it = sources.emplace(std::string(source), std::move(runs)).first;
    }
    last_source = &it->second;
    last_source_name = it->first;
    out = last_source;
    return true;
  }

  // Removes the object in `slot` (committed earlier, or put by this import). A committed one's
  // id and name keys go now; this import's are left out of the merge at commit.
  bool remove_slot(uint32_t slot, std::string& error) {
    if (is_removed(slot)) return true;
    digest(slot);
    std::span<const uint8_t> record;
    if (!objects.get(txn.get(), slot, record, error)) return false;
    Object old;
    std::string why;
    if (record.empty()) {
      error = message("slot " + std::to_string(slot) + " is indexed but holds no object");
      return false;
    }
    if (!detail::decode_object(record.data(), record.size(), old, why)) {
      error = message("object slot " + std::to_string(slot) + ": " + why);
      return false;
    }
    if (!objects.erase(txn.get(), slot, error) || !attributes.erase(txn.get(), slot, error)) {
      return false;
    }
    ModelStatistics part;
    part.add(old);
    totals.subtract_counts(part);
    mark_removed(slot);
    // The source's list is rewritten at commit (without the removed slots).
    std::vector<detail::SlotRun>* unused;
    if (!source_runs(old.source, unused, error)) return false;
    if (slot < first_new_slot) {
      const IdEntry id(old.id, slot);
      MDB_val k = id.key_val(), v = id.value_val();
      int rc = mdb_del(txn.get(), store->dbs.ids, &k, &v);
      if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;  // the id is another slot's (or nobody's)
      if (rc == MDB_SUCCESS) {
        const NameEntry name(name_hash(old.name), slot);
        MDB_val nk = name.key_val(), nv = name.value_val();
        rc = mdb_del(txn.get(), store->dbs.names, &nk, &nv);
        if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;
      }
      if (rc != MDB_SUCCESS) {
        error = fail("removing slot " + std::to_string(slot) + " from the ids and names", rc);
        return false;
      }
    }
    return true;
  }

  // Compresses and stores `raw_value` under `key` of `dbi`.
  bool put_frame(MDB_dbi dbi, MDB_val key, const std::vector<uint8_t>& raw_value, unsigned flags,
                 const std::string& what, std::string& error) {
    std::vector<uint8_t> frame;
    std::string why;
    if (!detail::compress_frame(compressor.get(), raw_value, frame, why)) {
      error = message(what + ": " + why);
      return false;
    }
    MDB_val v = as_val(frame.data(), frame.size());
    const int rc = mdb_put(txn.get(), dbi, &key, &v, flags);
    if (rc != MDB_SUCCESS) {
      error = fail("writing " + what, rc);
      return false;
    }
    return true;
  }

  bool database_empty(MDB_dbi dbi, bool& empty, std::string& error) {
    MDB_stat stat;
    const int rc = mdb_stat(txn.get(), dbi, &stat);
    if (rc != MDB_SUCCESS) {
      error = fail("reading database statistics", rc);
      return false;
    }
    empty = stat.ms_entries == 0;
    return true;
  }

  bool merge_ids(std::string& error);
  bool merge_names(std::string& error);
  bool write_sources(std::string& error);
  bool write_spatial(std::string& error);
  bool commit(std::string& error);
};

// The ids: this import's (id, slot) in id order; of an id put more than once the latest slot
// wins and the earlier ones are removed now. Appended when the database was empty.
bool Import::State::merge_ids(std::string& error) {
  bool empty;
  if (!database_empty(store->dbs.ids, empty, error)) return false;
  decltype(new_ids)::Merger merger(new_ids);
  std::string why;
  if (!merger.start(why)) {
    error = message("merging the ids: " + why);
    return false;
  }
  IdSlot current{}, next{};
  bool have = false, done = false;
  IndexAppender<64> out{txn.get(), store->dbs.ids, empty};
  const auto write = [&](const IdSlot& e) {
    if (is_removed(e.slot)) return true;
    const int rc = out.put(IdEntry(e.id, e.slot));
    if (rc != MDB_SUCCESS) error = fail("writing the ids", rc);
    return rc == MDB_SUCCESS;
  };
  for (;;) {
    const bool got = merger.next(next, done, why);
    if (!got && !done) {
      error = message("merging the ids: " + why);
      return false;
    }
    if (!got) break;
    if (have && next.id == current.id) {
      // The same id put twice: the earlier slot goes.
      if (!remove_slot(current.slot, error)) return false;
    } else if (have && !write(current)) {
      return false;
    }
    current = next;
    have = true;
  }
  return !have || write(current);
}

bool Import::State::merge_names(std::string& error) {
  bool empty;
  if (!database_empty(store->dbs.names, empty, error)) return false;
  decltype(new_names)::Merger merger(new_names);
  std::string why;
  if (!merger.start(why)) {
    error = message("merging the names: " + why);
    return false;
  }
  HashSlot e{};
  bool done = false;
  IndexAppender<32> out{txn.get(), store->dbs.names, empty};
  while (merger.next(e, done, why)) {
    if (is_removed(e.slot)) continue;
    const int rc = out.put(NameEntry(e.hash, e.slot));
    if (rc != MDB_SUCCESS) {
      error = fail("writing the names", rc);
      return false;
    }
  }
  if (!done) {
    error = message("merging the names: " + why);
    return false;
  }
  return true;
}

// The sources touched: their slots, less what was removed.
bool Import::State::write_sources(std::string& error) {
  std::vector<detail::SlotRun> kept;
  std::vector<uint8_t> raw_value;
  for (auto& [source, runs] : sources) {
    kept.clear();
    for (const detail::SlotRun& r : runs) {
      for (uint32_t s = r.first; s < r.first + r.length; ++s) {
        if (is_removed(s)) continue;
        if (!kept.empty() && kept.back().first + kept.back().length == s) {
          ++kept.back().length;
        } else {
          kept.push_back({s, 1});
        }
      }
    }
    MDB_val k = as_val(source);
    int rc;
    if (kept.empty()) {
      rc = mdb_del(txn.get(), store->dbs.sources, &k, nullptr);
      if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;
    } else {
      detail::encode_slot_runs(kept, raw_value);
      MDB_val v = as_val(raw_value.data(), raw_value.size());
      rc = mdb_put(txn.get(), store->dbs.sources, &k, &v, 0);
    }
    if (rc != MDB_SUCCESS) {
      error = fail("writing the sources index", rc);
      return false;
    }
  }
  return true;
}

// The spatial blocks: the committed ones' entries (block by block, less removed slots) merged
// with this import's by (Morton key, slot), written into the other block database as they fill;
// then the top. Sets totals.bounds.
bool Import::State::write_spatial(std::string& error) {
  const Databases& dbs = store->dbs;
  MDB_txn* t = txn.get();
  detail::DecodedTop old;
  bool found;
  std::string why;
  if (!read_top(t, dbs.meta, false, dctx.get(), old, found, why)) {
    error = message("spatial top (meta/\"spatial_top\"): " + why);
    return false;
  }
  const uint8_t target = found ? uint8_t(1 - old.database) : 0;
  const MDB_dbi in = dbs.spatial[old.database], out = dbs.spatial[target];
  int rc = mdb_drop(t, out, 0);  // left empty by the last commit; emptied again to be sure
  if (rc != MDB_SUCCESS) {
    error = fail("emptying the spatial blocks", rc);
    return false;
  }
  // The committed entries, in order.
  uint32_t old_block = 0;
  std::vector<detail::BlockEntry> old_entries;
  size_t old_at = 0;
  std::vector<uint8_t> raw_value;
  const auto next_old = [&](SpatialItem& item, bool& ok) {
    ok = true;
    for (;;) {
      while (old_at < old_entries.size()) {
        const detail::BlockEntry& e = old_entries[old_at++];
        if (is_removed(e.grid.slot)) continue;
        item = {detail::morton_key(e.grid), e};
        return true;
      }
      if (old_block >= old.block_entries.size()) return false;
      const detail::Key32 key(old_block);
      MDB_val k = key.val(), v;
      rc = mdb_get(t, in, &k, &v);
      const std::span<const uint8_t> frame(static_cast<const uint8_t*>(v.mv_data), v.mv_size);
      if (rc != MDB_SUCCESS) {
        error = fail("reading spatial block " + std::to_string(old_block), rc);
      } else if (!detail::inflate_frame(dctx.get(), frame, raw_value, why) ||
                 !detail::decode_block(raw_value.data(), raw_value.size(), old_entries, why)) {
        error = message("spatial block " + std::to_string(old_block) + ": " + why);
        rc = -1;
      }
      if (rc != MDB_SUCCESS) {
        ok = false;
        return false;
      }
      old_at = 0;
      ++old_block;
    }
  };
  decltype(new_spatial)::Merger merger(new_spatial);
  if (!merger.start(why)) {
    error = message("merging the spatial entries: " + why);
    return false;
  }
  std::vector<detail::BlockSummary> summaries;
  std::vector<detail::BlockEntry> block;
  block.reserve(kSpatialBlockObjects);
  const auto flush_block = [&]() {
    if (block.empty()) return true;
    detail::encode_block(block.data(), uint32_t(block.size()), raw_value);
    const detail::Key32 key(uint32_t(summaries.size()));
    if (!put_frame(out, key.val(), raw_value, MDB_APPEND,
                   "spatial block " + std::to_string(summaries.size()), error)) {
      return false;
    }
    summaries.emplace_back();
    detail::summarise_block(block.data(), uint32_t(block.size()), summaries.back());
    block.clear();
    return true;
  };
  SpatialItem a{}, b{};
  bool have_a = false, have_b = false, ok = true, done = false;
  have_a = next_old(a, ok);
  if (!ok) return false;
  have_b = merger.next(b, done, why);
  for (;;) {
    if (!have_b && !done) {
      error = message("merging the spatial entries: " + why);
      return false;
    }
    if (have_b && is_removed(b.entry.grid.slot)) {
      have_b = merger.next(b, done, why);
      continue;
    }
    if (!have_a && !have_b) break;
    const bool take_a = have_a && (!have_b || SpatialItemLess{}(a, b));
    block.push_back(take_a ? a.entry : b.entry);
    if (block.size() == kSpatialBlockObjects && !flush_block()) return false;
    if (take_a) {
      have_a = next_old(a, ok);
      if (!ok) return false;
    } else {
      have_b = merger.next(b, done, why);
    }
  }
  if (!flush_block()) return false;
  detail::import_stage("blocks written");
  if (found) {
    rc = mdb_drop(t, in, 0);
    if (rc != MDB_SUCCESS) {
      error = fail("emptying the old spatial blocks", rc);
      return false;
    }
  }
  totals.bounds = DAabb{};
  if (!summaries.empty()) {
    detail::GroupSummary all;
    for (const detail::BlockSummary& s : summaries) all.add(s.nodes[0]);
    detail::GridEntry g;
    std::copy(all.min, all.min + 3, g.min);
    std::copy(all.max, all.max + 3, g.max);
    totals.bounds = detail::grid_bounds(g, origin);
  }
  if (!has_origin) return true;  // never any geometry: no top
  detail::encode_top(origin, target, summaries, raw_value);
  MDB_val k = as_val("spatial_top");
  return put_frame(dbs.meta, k, raw_value, 0, "the spatial top", error);
}

Import::Import(std::unique_ptr<State> state) : state_(std::move(state)) {}
Import::~Import() = default;
uint64_t Import::objects_put() const { return state_->put_count; }
const ModelStatistics& Import::put_statistics() const { return state_->put_statistics; }

bool Import::remove_source(std::string_view source, std::string& error) {
  State& s = *state_;
  assert(s.txn.get() && "remove_source() on a spent Import");
  std::vector<detail::SlotRun>* runs;
  if (!s.source_runs(source, runs, error)) return false;
  // remove_slot may load other sources (never this one again), which leaves `runs` in place.
  const std::vector<detail::SlotRun> copy = *runs;
  for (const detail::SlotRun& r : copy) {
    for (uint32_t slot = r.first; slot < r.first + r.length; ++slot) {
      if (!s.remove_slot(slot, error)) return false;
    }
  }
  return true;
}

bool Import::put(const Object& object, std::string& error) {
  State& s = *state_;
  assert(s.txn.get() && "put() on a spent Import");
  if (object.id == 0) {
    error = s.message("object '" + object.name + "' has id 0");
    return false;
  }
  if (s.next_slot == UINT32_MAX) {
    error = s.message("no slots left (4 billion objects put)");
    return false;
  }
  // An object committed with the same id is replaced (one put twice in this import is resolved
  // at commit: the later wins).
  {
    const int rc = index_slots<64>(s.txn.get(), s.store->dbs.ids, object.id, s.slots, 1);
    if (rc != MDB_SUCCESS) {
      error = s.fail("looking up id " + std::to_string(object.id), rc);
      return false;
    }
    if (!s.slots.empty() && !s.remove_slot(s.slots[0], error)) return false;
  }
  const uint32_t slot = s.next_slot;
  // The object's statistics, whose bounds are its object_bounds() (computed once). Bounds first:
  // an object the grid cannot hold is refused before anything of it is written.
  ModelStatistics part;
  part.add(object);
  const DAabb& bounds = part.bounds;
  SpatialItem item{};
  if (!bounds.empty()) {
    if (!s.has_origin) {
      // The origin is fixed by the first object with geometry: whole metres near its centre.
      s.origin = glm::floor(0.5 * (bounds.min + bounds.max));
      s.has_origin = true;
    }
    if (!detail::quantise_bounds(bounds, s.origin, slot, item.entry.grid)) {
      error = s.message("object slot " + std::to_string(slot) +
                        ": bounds are not finite or lie more than 2000 km from the model's origin");
      return false;
    }
    item.key = detail::morton_key(item.entry.grid);
    item.entry.colour = detail::pack_colour(object.colour);
  }
  std::vector<detail::SlotRun>* runs;
  if (!s.source_runs(object.source, runs, error)) return false;
  detail::encode_object(object, s.raw);
  s.digest(slot);
  s.digest(s.raw);
  if (!s.objects.put(s.txn.get(), slot, std::move(s.raw), error)) return false;
  detail::encode_attributes(object.attributes, s.raw);
  s.digest(s.raw);
  if (!s.attributes.put(s.txn.get(), slot, std::move(s.raw), error)) return false;
  ++s.next_slot;
  if (!runs->empty() && runs->back().first + runs->back().length == slot) {
    ++runs->back().length;
  } else {
    runs->push_back({slot, 1});
  }
  std::string why;
  if (!s.new_ids.add({object.id, slot}, why) ||
      !s.new_names.add({name_hash(object.name), slot}, why) ||
      (!bounds.empty() && !s.new_spatial.add(item, why))) {
    error = s.message(why);
    return false;
  }
  s.totals.add_counts(part);
  s.put_statistics.add_counts(part);
  s.put_statistics.bounds.extend(part.bounds);
  ++s.put_count;
  return true;
}

bool Import::commit(std::string& error) {
  assert(state_->txn.get() && "commit() on a spent Import");
  // Spent either way: a failed commit leaves the store as it was.
  const bool ok = state_->commit(error);
  state_->txn.abort();
  return ok;
}

bool Import::State::commit(std::string& error) {
  State& s = *this;
  const Databases& dbs = s.store->dbs;
  // Ids first: resolving an id put twice removes slots, which the other merges then leave out.
  if (!s.merge_ids(error)) return false;
  detail::import_stage("ids merged");
  if (!s.objects.flush(s.txn.get(), error) || !s.attributes.flush(s.txn.get(), error)) return false;
  if (!s.merge_names(error) || !s.write_sources(error) || !s.write_spatial(error)) return false;

  auto put_meta = [&](std::string_view key, const void* data, size_t size) {
    MDB_val k = as_val(key), v = as_val(data, size);
    const int rc = mdb_put(s.txn.get(), dbs.meta, &k, &v, 0);
    if (rc != MDB_SUCCESS) error = s.fail("writing " + std::string(key), rc);
    return rc == MDB_SUCCESS;
  };
  const std::string stats = statistics_json(s.totals);
  const uint32_t version = kStoreFormatVersion;
  const uint64_t commit_id = mix_digest(read_commit_id(s.txn.get(), dbs.meta), s.changes_digest);
  if (!put_meta("statistics", stats.data(), stats.size()) ||
      !put_meta("next_slot", &s.next_slot, sizeof s.next_slot) ||
      !put_meta("format", &version, sizeof version) ||
      !put_meta("commit_id", &commit_id, sizeof commit_id)) {
    return false;
  }
  const int rc = s.txn.commit();
  if (rc != MDB_SUCCESS) {
    error = s.fail("committing the import", rc);
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

struct ReadView::State {
  std::shared_ptr<Store::State> store;
  detail::LmdbTxn txn;
  std::shared_ptr<Snapshot> snapshot;
  detail::ZstdDCtx dctx{ZSTD_createDCtx()};
  std::vector<uint8_t> raw;
  std::vector<detail::BlockEntry> block_entries;
  // Decompressed chunks of this view: object() on neighbouring slots decompresses once.
  detail::ChunkCache objects, attributes;
  // slot_of()'s pages: the span of the file its lookups touched, given back every so many.
  uint32_t lookups_since_release = 0;
  const uint8_t* looked_up_begin = nullptr;
  const uint8_t* looked_up_end = nullptr;

  explicit State(const std::shared_ptr<Store::State>& s)
      : store(s),
        objects(s->dbs.objects, detail::kObjectShape, kObjectChunksCached, kViewChunkBytes),
        attributes(s->dbs.attributes, detail::kAttributeShape, kAttributeChunksCached,
                   kViewChunkBytes) {}

  // The snapshot's spatial top, decoded on first use (by this or another view of the state).
  const detail::DecodedTop& top() {
    std::call_once(snapshot->top_once, [&] {
      detail::ZstdDCtx top_dctx(ZSTD_createDCtx());
      bool found;
      std::string why;
      if (!read_top(txn.get(), store->dbs.meta, true, top_dctx.get(), snapshot->top, found, why)) {
        snapshot->top = detail::DecodedTop{};
        snapshot->top_error =
            "store " + store->directory + ": spatial top (meta/\"spatial_top\"): " + why;
      }
    });
    return snapshot->top;
  }
  bool top_ready(std::string& error) {
    top();
    if (snapshot->top_error.empty()) return true;
    error = snapshot->top_error;
    return false;
  }

  // Block `b` read from LMDB and expanded, checked against the top.
  std::shared_ptr<const SpatialBlock> decode_block(uint32_t b, std::string& error) {
    const detail::DecodedTop& top = this->top();
    const detail::Key32 key(b);
    MDB_val k = key.val(), v;
    const int rc = mdb_get(txn.get(), store->dbs.spatial[top.database], &k, &v);
    const std::string what = "store " + store->directory + ": spatial block " + std::to_string(b);
    if (rc != MDB_SUCCESS) {
      error = what + ": " + mdb_strerror(rc);
      return nullptr;
    }
    std::string why;
    if (!inflate_read_once(v, dctx.get(), raw, why) ||
        !detail::decode_block(raw.data(), raw.size(), block_entries, why)) {
      error = what + ": " + why;
      return nullptr;
    }
    // What the top says of it must hold: the renderer relies on both.
    int64_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = INT64_MAX, hi[a] = INT64_MIN;
    for (const detail::BlockEntry& e : block_entries) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min<int64_t>(lo[a], e.grid.min[a]);
        hi[a] = std::max<int64_t>(hi[a], e.grid.max[a]);
      }
    }
    bool agrees = block_entries.size() == top.block_entries[b];
    for (int a = 0; a < 3; ++a) {
      agrees = agrees && lo[a] == top.block_grid[b][a] && hi[a] == top.block_grid[b][3 + a];
    }
    if (!agrees) {
      error = what + ": its entries or bounds differ from what the spatial top says of it";
      return nullptr;
    }
    auto out = std::make_shared<SpatialBlock>();
    detail::expand_block(block_entries, *out);
    return out;
  }

  // The slots under the hash of `name` in the names database, in slot order (unconfirmed).
  bool name_candidates(std::string_view name, std::vector<uint32_t>& candidates,
                       std::string& error) {
    const int rc = index_slots<32>(txn.get(), store->dbs.names, name_hash(name), candidates);
    if (rc != MDB_SUCCESS) {
      error = lmdb_message(store->directory, "reading the names", rc);
      return false;
    }
    return true;
  }
};

ReadView::ReadView(std::unique_ptr<State> state) : state_(std::move(state)) {}
ReadView::~ReadView() {
  if (state_ && state_->looked_up_begin) {
    detail::release_map_pages(state_->looked_up_begin,
                              size_t(state_->looked_up_end - state_->looked_up_begin));
  }
}

std::unique_ptr<ReadView> ReadView::sibling(std::string& error) const {
  const State& s = *state_;
  auto other = std::make_unique<State>(s.store);
  const int rc = other->txn.begin(s.store->env.get(), MDB_RDONLY);
  if (rc != MDB_SUCCESS) {
    error = s.store->fail("starting a sibling read", rc);
    return nullptr;
  }
  if (mdb_txn_id(other->txn.get()) != mdb_txn_id(s.txn.get())) {
    error = "store " + s.store->directory + ": an import committed since this view began";
    return nullptr;
  }
  other->snapshot = s.snapshot;
  other->objects.share(&other->snapshot->object_chunks);
  return std::unique_ptr<ReadView>(new ReadView(std::move(other)));
}

StoreInfo ReadView::info() const {
  StoreInfo info;
  MDB_txn* txn = state_->txn.get();
  const Databases& dbs = state_->store->dbs;
  MDB_val k = as_val("format"), v;
  if (mdb_get(txn, dbs.meta, &k, &v) == MDB_SUCCESS && v.mv_size == 4) {
    std::memcpy(&info.format_version, v.mv_data, 4);
  }
  // Store::open refused a store whose statistics are damaged; should they be damaged since (a
  // disk fault), info() has no error to give and reports zero counts and no bounds.
  std::string ignored;
  read_statistics(txn, dbs.meta, state_->store->directory, info.statistics, ignored);
  info.objects = info.statistics.objects;
  info.commit_id = read_commit_id(txn, dbs.meta);
  std::error_code ec;
  const auto size = std::filesystem::file_size(
      std::filesystem::path(state_->store->directory) / "data.mdb", ec);
  info.store_bytes = ec ? 0 : size;
  return info;
}

bool ReadView::spatial_ready(std::string& error) const { return state_->top_ready(error); }
std::span<const SpatialNode> ReadView::spatial_top() const { return state_->top().nodes; }
std::span<const uint32_t> ReadView::spatial_top_objects() const {
  return state_->top().objects;
}
uint64_t ReadView::spatial_objects() const { return state_->top().entries; }
uint32_t ReadView::spatial_block_count() const {
  return uint32_t(state_->top().block_entries.size());
}
glm::dvec3 ReadView::spatial_origin() const { return state_->top().origin; }

std::span<const ProxyBox> ReadView::spatial_proxy(uint32_t top_node) const {
  const detail::DecodedTop& top = state_->top();
  assert(top_node < top.nodes.size() && "spatial_proxy() of a node past the top");
  if (top_node >= top.nodes.size()) return {};
  return std::span<const ProxyBox>(top.proxies)
      .subspan(top.proxy_first[top_node], top.proxy_first[top_node + 1] - top.proxy_first[top_node]);
}

std::shared_ptr<const SpatialBlock> ReadView::spatial_block(uint32_t block,
                                                            std::string& error) const {
  State& s = *state_;
  if (!s.top_ready(error)) return nullptr;
  assert(block < spatial_block_count() && "spatial_block() past the last block");
  if (block >= spatial_block_count()) {
    error = "store " + s.store->directory + ": no spatial block " + std::to_string(block) +
            " (the store has " + std::to_string(spatial_block_count()) + ")";
    return nullptr;
  }
  if (auto cached = s.snapshot->blocks.find(block)) return cached;
  auto decoded = s.decode_block(block, error);
  if (decoded) s.snapshot->blocks.insert(block, decoded);
  return decoded;
}

bool ReadView::for_each_spatial_entry(
    const std::function<bool(const SpatialNode& leaf, const SpatialEntry& entry)>& fn,
    std::string& error) const {
  State& s = *state_;
  if (!s.top_ready(error)) return false;
  std::vector<uint32_t> stack;
  for (uint32_t b = 0; b < spatial_block_count(); ++b) {
    // A whole-plant pass leaves the cache to the views that page: a block not cached is decoded
    // for its turn only.
    auto block = s.snapshot->blocks.find(b);
    if (!block) block = s.decode_block(b, error);
    if (!block) return false;
    stack.assign(1, 0);
    while (!stack.empty()) {
      const SpatialNode& node = block->nodes[stack.back()];
      stack.pop_back();
      if (node.count == 0) {
        stack.push_back(node.first + 1);
        stack.push_back(node.first);
        continue;
      }
      for (uint32_t k = node.first; k < node.first + node.count; ++k) {
        if (!fn(node, block->entries[k])) return true;
      }
    }
  }
  return true;
}

bool ReadView::object(uint32_t slot, Object& out, bool with_attributes, std::string& error) const {
  State& s = *state_;
  std::span<const uint8_t> record;
  std::string why;
  bool ok = s.objects.record(s.txn.get(), s.dctx.get(), slot, record, why);
  if (ok && record.empty()) {
    error = "store " + s.store->directory + ": no object in slot " + std::to_string(slot);
    return false;
  }
  if (!ok || !detail::decode_object(record.data(), record.size(), out, why)) {
    error = "store " + s.store->directory + ": object slot " + std::to_string(slot) + ": " + why;
    return false;
  }
  if (!with_attributes) return true;
  ok = s.attributes.record(s.txn.get(), s.dctx.get(), slot, record, why);
  if (ok && record.empty()) {
    why = "the record is missing";
    ok = false;
  }
  if (!ok || !detail::decode_attributes(record.data(), record.size(), out.attributes, why)) {
    error = "store " + s.store->directory + ": attributes of slot " + std::to_string(slot) +
            ": " + why;
    return false;
  }
  return true;
}

bool ReadView::object_key(uint32_t slot, uint64_t& id, uint64_t& pipeline_id,
                          std::string& error) const {
  State& s = *state_;
  std::span<const uint8_t> record;
  std::string why;
  const bool ok = s.objects.record(s.txn.get(), s.dctx.get(), slot, record, why);
  if (ok && record.empty()) {
    error = "store " + s.store->directory + ": no object in slot " + std::to_string(slot);
    return false;
  }
  if (!ok || !detail::decode_object_key(record.data(), record.size(), id, pipeline_id, why)) {
    error = "store " + s.store->directory + ": object slot " + std::to_string(slot) + ": " + why;
    return false;
  }
  return true;
}

namespace {
constexpr uint32_t kLookupsPerRelease = 256;
}

bool ReadView::slot_of(uint64_t id, std::optional<uint32_t>& slot, std::string& error) const {
  State& s = *state_;
  slot.reset();
  std::vector<uint32_t> slots;
  const void* value = nullptr;
  const int rc = index_slots<64>(s.txn.get(), s.store->dbs.ids, id, slots, 1, &value);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(s.store->directory, "looking up id " + std::to_string(id), rc);
    return false;
  }
  // Ids are looked up in random order across the whole table (a pipeline's members, picks), and
  // each lookup maps its pages and the kernel's fault-around windows beside them: at 40 M objects
  // a walkthrough kept over 100 MB of the table resident. Every kLookupsPerRelease lookups the
  // view gives back the span of the file they touched (the page cache keeps it; nothing the view
  // holds points into it).
  if (value) {
    const auto* p = static_cast<const uint8_t*>(value);
    s.looked_up_begin = s.looked_up_begin ? std::min(s.looked_up_begin, p) : p;
    s.looked_up_end = std::max(s.looked_up_end, p + 1);
  }
  if (++s.lookups_since_release == kLookupsPerRelease && s.looked_up_begin) {
    detail::release_map_pages(s.looked_up_begin, size_t(s.looked_up_end - s.looked_up_begin));
    s.looked_up_begin = s.looked_up_end = nullptr;
    s.lookups_since_release = 0;
  }
  if (!slots.empty()) slot = slots[0];
  return true;
}

std::optional<uint32_t> ReadView::slot_of(uint64_t id) const {
  std::optional<uint32_t> slot;
  std::string error;
  slot_of(id, slot, error);
  return slot;
}

bool ReadView::slots_named(std::string_view name, std::vector<uint32_t>& slots,
                           std::string& error) const {
  slots.clear();
  std::vector<uint32_t> candidates;
  if (!state_->name_candidates(name, candidates, error)) return false;
  // A hash may collide: confirm by the name itself.
  for (uint32_t slot : candidates) {
    Object o;
    if (!object(slot, o, false, error)) return false;
    if (o.name == name) slots.push_back(slot);
  }
  return true;
}

std::vector<uint32_t> ReadView::slots_named(std::string_view name) const {
  std::vector<uint32_t> candidates, out;
  std::string error;
  if (!state_->name_candidates(name, candidates, error)) return out;
  for (uint32_t slot : candidates) {
    Object o;
    if (object(slot, o, false, error) && o.name == name) out.push_back(slot);
  }
  return out;
}

bool ReadView::for_each_object(const std::function<bool(uint32_t, Object&&)>& fn,
                               bool with_attributes, std::string& error) const {
  return visit_objects(nullptr, fn, with_attributes, error);
}

bool ReadView::for_each_object_of_class(ObjectClass object_class,
                                        const std::function<bool(uint32_t, Object&&)>& fn,
                                        bool with_attributes, std::string& error) const {
  return visit_objects(&object_class, fn, with_attributes, error);
}

bool ReadView::visit_objects(const ObjectClass* only,
                             const std::function<bool(uint32_t, Object&&)>& fn,
                             bool with_attributes, std::string& error) const {
  State& s = *state_;
  for (uint32_t slot = 0; slot < s.snapshot->next_slot; ++slot) {
    std::span<const uint8_t> record;
    std::string why;
    if (!s.objects.record(s.txn.get(), s.dctx.get(), slot, record, why)) {
      error = "store " + s.store->directory + ": object slot " + std::to_string(slot) + ": " + why;
      return false;
    }
    if (record.empty()) continue;  // removed (or replaced) objects leave their slot empty
    // The class is the record's second byte (record.h); a record that is not passed over is
    // decoded, which checks everything (an unknown class included).
    if (only && record.size() >= 2 && record[1] < kObjectClassCount && record[1] != uint8_t(*only))
      continue;
    Object o;
    if (!object(slot, o, with_attributes, error)) return false;
    if (!fn(slot, std::move(o))) return true;
  }
  return true;
}

uint32_t ReadView::slot_count() const { return state_->snapshot->next_slot; }

size_t ReadView::spatial_cache_bytes() const { return state_->snapshot->blocks.bytes(); }
size_t ReadView::chunk_cache_bytes() const { return state_->snapshot->object_chunks.bytes(); }
uint64_t ReadView::chunks_decompressed() const { return state_->objects.inflated(); }
// ---------------------------------------------------------------------------------------------

Store::Store(std::unique_ptr<State> state) : state_(std::move(state)) {}
Store::~Store() = default;
const std::string& Store::directory() const { return state_->directory; }
bool Store::without_lock_file() const { return state_->without_lock; }

std::unique_ptr<Store> Store::open(const std::string& directory, Mode mode, std::string& error) {
  auto state = std::make_unique<State>();
  state->directory = directory;
  state->mode = mode;
  std::error_code ec;
  if (mode == Mode::read_write) {
    std::filesystem::create_directories(directory, ec);
    if (ec) {
      error = "store " + directory + ": cannot create the directory: " + ec.message();
      return nullptr;
    }
  } else if (!std::filesystem::exists(std::filesystem::path(directory) / "data.mdb", ec)) {
    error = "store " + directory + ": no store there (no data.mdb)";
    return nullptr;
  }
  // An empty data file is refused before LMDB sees it: opened for writing, LMDB would take it
  // for a new environment and write to it.
  const std::filesystem::path data_file = std::filesystem::path(directory) / "data.mdb";
  if (std::filesystem::is_regular_file(data_file, ec) &&
      std::filesystem::file_size(data_file, ec) == 0 && !ec) {
    error = "store " + directory + ": " + data_file.string() +
            " is empty: not a plantview store (or a truncated copy)";
    return nullptr;
  }
  // No readahead: readers fetch chunks of a few kilobytes at random, and readahead would bring
  // (and count in the process's memory) most of the file around them.
  const auto open_env = [&](unsigned extra_flags) {
    state->env.reset();
    int rc = mdb_env_create(state->env.out());
    if (rc == MDB_SUCCESS) rc = mdb_env_set_maxdbs(state->env.get(), 12);
    if (rc == MDB_SUCCESS) rc = mdb_env_set_mapsize(state->env.get(), kMapSizeBytes);
    if (rc == MDB_SUCCESS) rc = mdb_env_set_maxreaders(state->env.get(), 254);
    const unsigned flags = MDB_NOTLS | MDB_NORDAHEAD | (mode == Mode::read_only ? MDB_RDONLY : 0u) | extra_flags;
    if (rc == MDB_SUCCESS) rc = mdb_env_open(state->env.get(), directory.c_str(), flags, 0644);
    return rc;
  };
  int rc = open_env(0);
  // A read-only directory or file system (a shared copy, a read-only volume): LMDB cannot
  // create or open lock.mdb for writing. Read without the lock table then; the manual says what
  // that requires (no writer while readers run).
  if ((rc == EACCES || rc == EROFS) && mode == Mode::read_only) {
    rc = open_env(MDB_NOLOCK);
    state->without_lock = rc == MDB_SUCCESS;
  }
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    // LMDB reads its two meta pages with read(): a file too short to hold them is "not an LMDB
    // file"; say how short.
    const auto size = std::filesystem::file_size(data_file, ec);
    if (rc == MDB_INVALID && !ec) {
      error += " (" + data_file.string() + " is " + std::to_string(size) +
               " bytes: not a plantview store, or a truncated copy)";
    }
    return nullptr;
  }
  // Before anything reads a page through the mapping.
  if (!data_file_complete(state->env.get(), directory, error)) return nullptr;
  // Open (or create) the named databases once; their handles serve every later transaction.
  detail::LmdbTxn txn;
  rc = txn.begin(state->env.get(), mode == Mode::read_only ? MDB_RDONLY : 0u);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    return nullptr;
  }
  const unsigned create = mode == Mode::read_only ? 0u : MDB_CREATE;
  Databases& d = state->dbs;
  rc = mdb_dbi_open(txn.get(), "meta", create, &d.meta);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening database 'meta'", rc);
    return nullptr;
  }
  // The format comes first: another version's databases are not to be opened, let alone read.
  MDB_val k = as_val("format"), v;
  if (mdb_get(txn.get(), d.meta, &k, &v) == MDB_SUCCESS) {
    uint32_t version = 0;
    if (v.mv_size == 4) std::memcpy(&version, v.mv_data, 4);
    if (version != kStoreFormatVersion) {
      error = "store " + directory + " has format " + std::to_string(version) +
              "; this build reads format " + std::to_string(kStoreFormatVersion) +
              (version < kStoreFormatVersion ? ": import or generate it again"
                                             : " (a newer plantview wrote it)");
      return nullptr;
    }
  }
  // Statistics that cannot be read would leave `info` without counts and an import without its
  // totals: refuse the store now, naming the key, rather than misreport it later.
  ModelStatistics statistics;
  if (!read_statistics(txn.get(), d.meta, directory, statistics, error)) return nullptr;
  struct Named {
    const char* name;
    MDB_dbi* dbi;
    unsigned flags;
  };
  const Named named[] = {
      {"objects", &d.objects, 0},
      {"attributes", &d.attributes, 0},
      {"sources", &d.sources, 0},
      {"ids", &d.ids, kIndexFlags},
      {"names", &d.names, kIndexFlags},
      {"spatial_a", &d.spatial[0], 0},
      {"spatial_b", &d.spatial[1], 0},
  };
  for (const Named& n : named) {
    rc = mdb_dbi_open(txn.get(), n.name, create | n.flags, n.dbi);
    if (rc != MDB_SUCCESS) {
      error = lmdb_message(directory, std::string("opening database '") + n.name + "'", rc);
      return nullptr;
    }
  }
  rc = txn.commit();
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    return nullptr;
  }
  return std::unique_ptr<Store>(new Store(std::move(state)));
}

std::unique_ptr<Import> Store::begin_import(std::string& error) {
  if (state_->mode == Mode::read_only) {
    error = "store " + state_->directory + ": opened read-only";
    return nullptr;
  }
  auto s = std::make_unique<Import::State>(state_, detail::import_run_bytes());
  int rc = s->txn.begin(state_->env.get(), 0);
  if (rc != MDB_SUCCESS) {
    error = state_->fail("starting an import", rc);
    return nullptr;
  }
  // This transaction holds LMDB's writer lock: no other import runs, and run files left in the
  // directory are a killed import's.
  detail::remove_stale_runs(state_->directory);
  MDB_txn* txn = s->txn.get();
  if (!read_statistics(txn, state_->dbs.meta, state_->directory, s->totals, error)) {
    return nullptr;
  }
  s->next_slot = read_next_slot(txn, state_->dbs.meta);
  s->first_new_slot = s->next_slot;
  // The spatial origin, fixed by the first objects with geometry ever imported.
  detail::DecodedTop top;
  bool found;
  std::string why;
  if (!read_top(txn, state_->dbs.meta, false, s->dctx.get(), top, found, why)) {
    error = "store " + state_->directory + ": spatial top (meta/\"spatial_top\"): " + why;
    return nullptr;
  }
  s->has_origin = found;
  s->origin = top.origin;
  if (!s->objects.begin(txn, error) || !s->attributes.begin(txn, error)) return nullptr;
  return std::unique_ptr<Import>(new Import(std::move(s)));
}

std::unique_ptr<ReadView> Store::read(std::string& error) const {
  auto s = std::make_unique<ReadView::State>(state_);
  const int rc = s->txn.begin(state_->env.get(), MDB_RDONLY);
  if (rc != MDB_SUCCESS) {
    error = state_->fail("starting a read", rc);
    return nullptr;
  }
  // The data file may have been cut short since the store was opened (another process, a copy
  // over it): refuse the view rather than fault on its first page.
  if (!data_file_complete(state_->env.get(), state_->directory, error)) return nullptr;
  s->snapshot = state_->snapshot_for(s->txn.get());
  s->objects.share(&s->snapshot->object_chunks);
  return std::unique_ptr<ReadView>(new ReadView(std::move(s)));
}

}  // namespace plantview
