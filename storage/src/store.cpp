// The LMDB plant store: opening, imports (one write transaction each), read views.
#include "plantview/store.h"

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <unordered_map>
#include <unordered_set>

#include <sys/stat.h>

#include "columns.h"
#include "lmdb_guard.h"
#include "record.h"
#include "spatial.h"
#include "tables.h"

namespace plantview {

using detail::as_val;
using detail::ColumnWriter;
using detail::GridEntry;
using detail::Key32;
using detail::KeySlot;
using detail::lmdb_message;

namespace {

constexpr size_t kMapSizeBytes = size_t(1) << 40;  // address space only; the file grows as used
// Decompressed chunks a read view keeps: 32 x 64 objects (about 0.5 MB for generated plants)
// and 2 x 256 objects' attributes, each column within 16 MB (chunks of big meshes are big).
constexpr size_t kObjectChunksCached = 32;
constexpr size_t kAttributeChunksCached = 2;
constexpr size_t kChunkCacheBytes = size_t(16) << 20;

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

void subtract(ModelStatistics& total, const ModelStatistics& part) {
  total.objects -= part.objects;
  total.primitives -= part.primitives;
  total.triangles -= part.triangles;
  for (int c = 0; c < kObjectClassCount; ++c) {
    total.objects_by_class[c] -= part.objects_by_class[c];
    total.primitives_by_class[c] -= part.primitives_by_class[c];
    total.triangles_by_class[c] -= part.triangles_by_class[c];
  }
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    total.primitives_by_kind[k] -= part.primitives_by_kind[k];
    total.triangles_by_kind[k] -= part.triangles_by_kind[k];
  }
}

void add(ModelStatistics& total, const ModelStatistics& part) {
  total.objects += part.objects;
  total.primitives += part.primitives;
  total.triangles += part.triangles;
  for (int c = 0; c < kObjectClassCount; ++c) {
    total.objects_by_class[c] += part.objects_by_class[c];
    total.primitives_by_class[c] += part.primitives_by_class[c];
    total.triangles_by_class[c] += part.triangles_by_class[c];
  }
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    total.primitives_by_kind[k] += part.primitives_by_kind[k];
    total.triangles_by_kind[k] += part.triangles_by_kind[k];
  }
}

struct Databases {
  MDB_dbi meta, objects, attributes, indexes, sources;
};

// How the pages of a value read in place stay after reading it (release_map_pages).
enum class MapPages {
  keep,      // a write transaction (its values may be its own copies of pages)
  read_once  // a read transaction that inflates the value and never looks at it again
};

// An index value (indexes/<key>): a zstd frame, inflated into `raw`. `found` false if absent.
bool read_index(MDB_txn* txn, MDB_dbi dbi, std::string_view key, ZSTD_DCtx* dctx,
                std::vector<uint8_t>& raw, bool& found, std::string& why,
                MapPages pages = MapPages::keep) {
  MDB_val k = as_val(key), v;
  const int rc = mdb_get(txn, dbi, &k, &v);
  found = rc == MDB_SUCCESS;
  raw.clear();
  if (rc == MDB_NOTFOUND) return true;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return false;
  }
  const std::span<const uint8_t> frame(static_cast<const uint8_t*>(v.mv_data), v.mv_size);
  if (pages == MapPages::keep) return detail::inflate_frame(dctx, frame, raw, why);
  // Without readahead (MDB_NORDAHEAD) ask for the whole frame at once; drop it once inflated.
  detail::prefetch_map_pages(v.mv_data, v.mv_size);
  const bool ok = detail::inflate_frame(dctx, frame, raw, why);
  detail::release_map_pages(v.mv_data, v.mv_size);
  return ok;
}

// The key/slot table under indexes/<key> (empty if absent), whole: for an import.
bool read_table(MDB_txn* txn, MDB_dbi dbi, std::string_view key, ZSTD_DCtx* dctx,
                std::vector<KeySlot>& table, std::string& why) {
  std::vector<uint8_t> raw;
  bool found;
  table.clear();
  if (!read_index(txn, dbi, key, dctx, raw, found, why)) return false;
  return !found || detail::decode_key_slots(raw.data(), raw.size(), table, why);
}

// An entry of the name table as read views keep it (sorted by hash, then slot): the name hash
// fits in 32 bits.
struct NameSlot {
  uint32_t hash, slot;
};

// A table a snapshot builds on first use: once, by whichever view first needs it (in that
// view's own read transaction, which reads the same committed state as every other view of the
// snapshot), and read-only afterwards.
template <typename Table>
struct LazyTable {
  std::once_flag once;
  Table table;
  std::string error;  // set (and the table left empty) if the stored table could not be read
};

// What read views need decoded from one committed state of the store, shared by every view of
// that state. Sizes per object (slot) at 4 million objects in comments.
struct Snapshot {
  size_t txn_id = 0;
  // Decoded by the first view of the state (Store::read):
  std::vector<uint64_t> id_by_slot;  // 0: no object in that slot; up to the highest slot (8 B)
  glm::dvec3 origin{0.0};
  std::vector<SpatialNode> nodes;     // about one per 4 objects (32 B each)
  std::vector<SpatialEntry> entries;  // one per object with geometry (16 B)
  // Built by the first slot_of() or slots_named() that needs them:
  mutable LazyTable<std::vector<uint32_t>> slots_by_id;  // every slot, by (id, slot) (4 B)
  mutable LazyTable<std::vector<NameSlot>> names;        // sorted (8 B)
};

// The id of every slot from the id table (checking the table on the way): an array indexed by
// slot, allocated once to its exact size. `next_slot` bounds the slots (and so the memory a
// corrupt table can ask for).
bool decode_id_by_slot(const std::vector<uint8_t>& raw, uint32_t next_slot,
                       std::vector<uint64_t>& id_by_slot, std::string& why) {
  detail::KeySlotReader reader;
  KeySlot pair;
  // First pass: check every pair and find the highest slot.
  if (!reader.open(raw.data(), raw.size(), why)) return false;
  uint32_t end = 0;
  for (uint64_t i = 0; i < reader.size(); ++i) {
    if (!reader.next(pair, why)) return false;
    if (pair.key == 0) {
      why = "entry " + std::to_string(i) + " has id 0";
      return false;
    }
    if (pair.slot >= next_slot) {
      why = "entry " + std::to_string(i) + " has slot " + std::to_string(pair.slot) +
            ", beyond the store's next slot " + std::to_string(next_slot);
      return false;
    }
    end = std::max(end, pair.slot + 1);
  }
  if (!reader.finish(why)) return false;
  // Second pass: fill in the ids.
  id_by_slot.assign(end, 0);
  reader.open(raw.data(), raw.size(), why);  // checked above
  for (uint64_t i = 0; i < reader.size(); ++i) {
    reader.next(pair, why);
    if (id_by_slot[pair.slot] != 0) {
      why = "slot " + std::to_string(pair.slot) + " has two ids";
      return false;
    }
    id_by_slot[pair.slot] = pair.key;
  }
  return true;
}

// The slots of the id table in its order (by id, then slot), to be looked up through
// `id_by_slot` (which was decoded from the same table).
bool decode_slots_by_id(const std::vector<uint8_t>& raw, const std::vector<uint64_t>& id_by_slot,
                        std::vector<uint32_t>& slots, std::string& why) {
  detail::KeySlotReader reader;
  KeySlot pair;
  if (!reader.open(raw.data(), raw.size(), why)) return false;
  slots.reserve(reader.size());
  for (uint64_t i = 0; i < reader.size(); ++i) {
    if (!reader.next(pair, why)) return false;
    // The table was checked against the store's slots when the snapshot was made; this keeps
    // lookups within id_by_slot should the bytes have changed since (a damaged disk).
    if (pair.slot >= id_by_slot.size()) {
      why = "entry " + std::to_string(i) + " has slot " + std::to_string(pair.slot) +
            ", beyond the highest slot the snapshot was opened with";
      return false;
    }
    slots.push_back(pair.slot);
  }
  return reader.finish(why);
}

bool decode_names(const std::vector<uint8_t>& raw, std::vector<NameSlot>& names,
                  std::string& why) {
  detail::KeySlotReader reader;
  KeySlot pair;
  if (!reader.open(raw.data(), raw.size(), why)) return false;
  names.reserve(reader.size());
  for (uint64_t i = 0; i < reader.size(); ++i) {
    if (!reader.next(pair, why)) return false;
    if (pair.key > UINT32_MAX) {
      why = "entry " + std::to_string(i) + " has a name hash over 32 bits";
      return false;
    }
    names.push_back({uint32_t(pair.key), pair.slot});
  }
  return reader.finish(why);
}

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

// ---------------------------------------------------------------------------------------------

struct Store::State {
  std::string directory;
  Mode mode;
  bool without_lock = false;  // opened with MDB_NOLOCK (read-only directory or file system)
  detail::LmdbEnv env;
  Databases dbs{};
  // The snapshot of the newest state a view has read. Guarded by snapshot_mutex.
  std::mutex snapshot_mutex;
  std::shared_ptr<const Snapshot> latest;

  std::string fail(std::string_view what, int rc) const { return lmdb_message(directory, what, rc); }

  // The decoded snapshot a read transaction sees (decoding it unless the latest is that one).
  // Each stage frees its buffers before the next allocates, so that the peak stays near what is
  // kept.
  std::shared_ptr<const Snapshot> snapshot_for(MDB_txn* txn, std::string& error) {
    const size_t txn_id = mdb_txn_id(txn);
    std::lock_guard lock(snapshot_mutex);
    if (latest && latest->txn_id == txn_id) return latest;
    auto s = std::make_shared<Snapshot>();
    s->txn_id = txn_id;
    detail::ZstdDCtx dctx(ZSTD_createDCtx());
    std::string why;
    bool found;
    // The id of every slot, for object() and for_each_object() (the slot lookups wait until
    // slot_of() or slots_named() is called).
    {
      uint32_t next_slot = 0;
      MDB_val k = as_val("next_slot"), v;
      if (mdb_get(txn, dbs.meta, &k, &v) == MDB_SUCCESS && v.mv_size == 4) {
        std::memcpy(&next_slot, v.mv_data, 4);
      }
      std::vector<uint8_t> raw;
      if (!read_index(txn, dbs.indexes, "ids", dctx.get(), raw, found, why,
                      MapPages::read_once) ||
          (found && !decode_id_by_slot(raw, next_slot, s->id_by_slot, why))) {
        error = "store " + directory + ": id table: " + why;
        return nullptr;
      }
    }
    // The spatial hierarchy, straight into the readers' form.
    {
      std::vector<uint8_t> raw;
      if (!read_index(txn, dbs.indexes, "spatial", dctx.get(), raw, found, why,
                      MapPages::read_once) ||
          (found && !detail::decode_spatial_expanded(raw.data(), raw.size(), s->origin, s->nodes,
                                                     s->entries, why))) {
        error = "store " + directory + ": spatial index: " + why;
        return nullptr;
      }
    }
    if (!latest || latest->txn_id < txn_id) latest = s;
    return s;
  }
};

// ---------------------------------------------------------------------------------------------

struct Import::State {
  std::shared_ptr<Store::State> store;
  detail::LmdbTxn txn;

  ModelStatistics totals;        // as committed before, updated as objects come and go
  uint32_t next_slot = 0;
  uint32_t first_new_slot = 0;   // this import's objects are in [first_new_slot, next_slot)
  std::vector<KeySlot> ids, names;                 // as committed (sorted)
  std::unordered_map<uint64_t, uint32_t> new_ids;  // id -> slot, this import's live objects
  std::vector<uint64_t> new_slot_ids;              // id by slot - first_new_slot
  std::vector<KeySlot> new_names;                  // (name hash, slot), this import's objects
  struct NewBounds {
    DAabb bounds;
    uint32_t slot;
  };
  std::vector<NewBounds> new_bounds;
  std::unordered_set<uint32_t> removed;  // every slot this import removed (slots are never reused)
  // Sources this import touched: every slot they had or got (removed ones included, filtered
  // out at commit).
  std::map<std::string, std::vector<uint32_t>, std::less<>> sources;
  std::vector<uint32_t>* last_source = nullptr;
  std::string last_source_name;
  ColumnWriter objects, attributes;
  std::vector<uint8_t> raw;
  uint64_t put_count = 0;

  explicit State(std::shared_ptr<Store::State> s)
      : store(std::move(s)),
        objects(store->directory, "object", store->dbs.objects, detail::kObjectShape),
        attributes(store->directory, "attributes", store->dbs.attributes,
                   detail::kAttributeShape) {}

  std::string fail(std::string_view what, int rc) const { return store->fail(what, rc); }

  // The slots of a source (as committed, plus this import's), loaded on first use.
  bool source_slots(std::string_view source, std::vector<uint32_t>*& out, std::string& error) {
    if (last_source && last_source_name == source) {
      out = last_source;
      return true;
    }
    auto it = sources.find(source);
    if (it == sources.end()) {
      std::vector<uint32_t> slots;
      MDB_val k = as_val(source), v;
      const int rc = mdb_get(txn.get(), store->dbs.sources, &k, &v);
      std::string why;
      if (rc == MDB_SUCCESS) {
        if (!detail::decode_slot_runs(static_cast<const uint8_t*>(v.mv_data), v.mv_size,
                                      first_new_slot, slots, why)) {
          error = "store " + store->directory + ": slots of source '" + std::string(source) +
                  "': " + why;
          return false;
        }
      } else if (rc != MDB_NOTFOUND) {
        error = fail("reading the sources index", rc);
        return false;
      }
      it = sources.emplace(std::string(source), std::move(slots)).first;
    }
    last_source = &it->second;
    last_source_name = it->first;
    out = last_source;
    return true;
  }

  // Removes the object in `slot` (committed earlier, or put by this import).
  bool remove_slot(uint32_t slot, std::string& error) {
    if (removed.count(slot)) return true;
    std::span<const uint8_t> record;
    if (!objects.get(txn.get(), slot, record, error)) return false;
    Object old;
    std::string why;
    if (record.empty()) {
      error = "store " + store->directory + ": slot " + std::to_string(slot) +
              " is indexed but holds no object";
      return false;
    }
    if (!detail::decode_object(record.data(), record.size(), old, why)) {
      error = "store " + store->directory + ": object slot " + std::to_string(slot) + ": " + why;
      return false;
    }
    if (!objects.erase(txn.get(), slot, error) || !attributes.erase(txn.get(), slot, error)) {
      return false;
    }
    ModelStatistics part;
    part.add(old);
    subtract(totals, part);
    removed.insert(slot);
    // The source's list is rewritten at commit (without the removed slots).
    std::vector<uint32_t>* unused;
    if (!source_slots(old.source, unused, error)) return false;
    if (slot >= first_new_slot) {
      auto it = new_ids.find(new_slot_ids[slot - first_new_slot]);
      if (it != new_ids.end() && it->second == slot) new_ids.erase(it);
    }
    return true;
  }

  // The committed slot of an id, unless this import removed it.
  std::optional<uint32_t> committed_slot(uint64_t id) const {
    auto it = std::lower_bound(ids.begin(), ids.end(), KeySlot{id, 0});
    for (; it != ids.end() && it->key == id; ++it) {
      if (!removed.count(it->slot)) return it->slot;
    }
    return std::nullopt;
  }

  // A table as committed, less removed slots, plus this import's entries; sorted.
  std::vector<KeySlot> merged(const std::vector<KeySlot>& committed,
                              std::vector<KeySlot> added) const {
    std::vector<KeySlot> out;
    out.reserve(committed.size() + added.size());
    for (const KeySlot& e : committed) {
      if (!removed.count(e.slot)) out.push_back(e);
    }
    const size_t middle = out.size();
    for (const KeySlot& e : added) {
      if (!removed.count(e.slot)) out.push_back(e);
    }
    std::sort(out.begin() + middle, out.end());
    std::inplace_merge(out.begin(), out.begin() + middle, out.end());
    return out;
  }

  // Compresses and stores an index value under indexes/<key>.
  bool put_index(std::string_view key, const std::vector<uint8_t>& raw_value, std::string& error) {
    std::vector<uint8_t> frame;
    std::string why;
    if (!detail::compress_frame(compressor.get(), raw_value, frame, why)) {
      error = "store " + store->directory + ": " + std::string(key) + ": " + why;
      return false;
    }
    MDB_val k = as_val(key), v = as_val(frame.data(), frame.size());
    const int rc = mdb_put(txn.get(), store->dbs.indexes, &k, &v, 0);
    if (rc != MDB_SUCCESS) {
      error = fail("writing the " + std::string(key) + " index", rc);
      return false;
    }
    return true;
  }

  // The spatial hierarchy over every object's bounds, rebuilt; sets totals.bounds.
  bool write_spatial(std::string& error) {
    detail::ZstdDCtx dctx(ZSTD_createDCtx());
    std::vector<uint8_t> raw_value;
    std::vector<GridEntry> entries;
    glm::dvec3 origin(0.0);
    bool found;
    std::string why;
    if (!read_index(txn.get(), store->dbs.indexes, "spatial", dctx.get(), raw_value, found, why) ||
        (found &&
         !detail::decode_spatial(raw_value.data(), raw_value.size(), origin, entries, why))) {
      error = "store " + store->directory + ": spatial index: " + why;
      return false;
    }
    std::erase_if(entries, [&](const GridEntry& e) { return removed.count(e.slot) > 0; });
    std::erase_if(new_bounds, [&](const NewBounds& b) { return removed.count(b.slot) > 0; });
    // The origin is fixed by the first objects with geometry: whole metres near their centre.
    if (entries.empty() && !new_bounds.empty()) {
      DAabb all;
      for (const NewBounds& b : new_bounds) all.extend(b.bounds);
      origin = glm::floor(0.5 * (all.min + all.max));
    }
    for (const NewBounds& b : new_bounds) {
      GridEntry e;
      if (!detail::quantise_bounds(b.bounds, origin, b.slot, e)) {
        error = "store " + store->directory + ": object slot " + std::to_string(b.slot) +
                ": bounds are not finite or lie more than 2000 km from the model's origin";
        return false;
      }
      entries.push_back(e);
    }
    detail::build_spatial_tree(entries);
    DAabb bounds;
    for (const GridEntry& e : entries) bounds.extend(detail::grid_bounds(e, origin));
    totals.bounds = bounds;
    detail::encode_spatial(origin, entries, raw_value);
    return put_index("spatial", raw_value, error);
  }

  bool commit(std::string& error);

  detail::ZstdCCtx compressor = detail::make_compressor();
};

Import::Import(std::unique_ptr<State> state) : state_(std::move(state)) {}
Import::~Import() = default;
uint64_t Import::objects_put() const { return state_->put_count; }

bool Import::remove_source(std::string_view source, std::string& error) {
  State& s = *state_;
  assert(s.txn.get() && "remove_source() on a spent Import");
  std::vector<uint32_t>* slots;
  if (!s.source_slots(source, slots, error)) return false;
  // remove_slot may load other sources (never this one again), which leaves `slots` in place.
  const std::vector<uint32_t> copy = *slots;
  for (uint32_t slot : copy) {
    if (!s.remove_slot(slot, error)) return false;
  }
  return true;
}

bool Import::put(const Object& object, std::string& error) {
  State& s = *state_;
  assert(s.txn.get() && "put() on a spent Import");
  if (object.id == 0) {
    error = "store " + s.store->directory + ": object '" + object.name + "' has id 0";
    return false;
  }
  if (s.next_slot == UINT32_MAX) {
    error = "store " + s.store->directory + ": no slots left (4 billion objects put)";
    return false;
  }
  // An object with the same id is replaced.
  if (auto it = s.new_ids.find(object.id); it != s.new_ids.end()) {
    if (!s.remove_slot(it->second, error)) return false;
  } else if (auto slot = s.committed_slot(object.id)) {
    if (!s.remove_slot(*slot, error)) return false;
  }
  const uint32_t slot = s.next_slot++;
  std::vector<uint32_t>* source_slots;
  if (!s.source_slots(object.source, source_slots, error)) return false;
  detail::encode_object(object, s.raw);
  if (!s.objects.put(s.txn.get(), slot, std::move(s.raw), error)) return false;
  detail::encode_attributes(object.attributes, s.raw);
  if (!s.attributes.put(s.txn.get(), slot, std::move(s.raw), error)) return false;
  source_slots->push_back(slot);
  s.new_ids[object.id] = slot;
  s.new_slot_ids.push_back(object.id);
  s.new_names.push_back({name_hash(object.name), slot});
  const DAabb bounds = object_bounds(object);
  if (!bounds.empty()) s.new_bounds.push_back({bounds, slot});
  ModelStatistics part;
  part.add(object);
  add(s.totals, part);
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
  MDB_txn* write = s.txn.get();
  const Databases& dbs = s.store->dbs;
  if (!s.objects.flush(write, error) || !s.attributes.flush(write, error)) return false;

  // Id and name tables, rewritten whole: as committed, less what was removed, plus what came.
  std::vector<KeySlot> added;
  added.reserve(s.new_ids.size());
  for (const auto& [id, slot] : s.new_ids) added.push_back({id, slot});
  std::vector<uint8_t> raw_value;
  detail::encode_key_slots(s.merged(s.ids, std::move(added)), raw_value);
  if (!s.put_index("ids", raw_value, error)) return false;
  detail::encode_key_slots(s.merged(s.names, std::move(s.new_names)), raw_value);
  if (!s.put_index("names", raw_value, error)) return false;

  // The sources touched: their slots, less what was removed.
  for (auto& [source, slots] : s.sources) {
    std::erase_if(slots, [&](uint32_t slot) { return s.removed.count(slot) > 0; });
    MDB_val k = as_val(source);
    int rc;
    if (slots.empty()) {
      rc = mdb_del(write, dbs.sources, &k, nullptr);
      if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;
    } else {
      detail::encode_slot_runs(slots, raw_value);
      MDB_val v = as_val(raw_value.data(), raw_value.size());
      rc = mdb_put(write, dbs.sources, &k, &v, 0);
    }
    if (rc != MDB_SUCCESS) {
      error = s.fail("writing the sources index", rc);
      return false;
    }
  }

  if (!s.write_spatial(error)) return false;

  auto put_meta = [&](std::string_view key, const void* data, size_t size) {
    MDB_val k = as_val(key), v = as_val(data, size);
    const int rc = mdb_put(write, dbs.meta, &k, &v, 0);
    if (rc != MDB_SUCCESS) error = s.fail("writing " + std::string(key), rc);
    return rc == MDB_SUCCESS;
  };
  const std::string stats = statistics_json(s.totals);
  const uint32_t version = kStoreFormatVersion;
  if (!put_meta("statistics", stats.data(), stats.size()) ||
      !put_meta("next_slot", &s.next_slot, sizeof s.next_slot) ||
      !put_meta("format", &version, sizeof version)) {
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
  std::shared_ptr<const Snapshot> snapshot;
  detail::ZstdDCtx dctx{ZSTD_createDCtx()};
  // Decompressed chunks of this view: object() on neighbouring slots decompresses once.
  detail::ChunkCache objects, attributes;

  explicit State(const std::shared_ptr<Store::State>& s)
      : store(s),
        objects(s->dbs.objects, detail::kObjectShape, kObjectChunksCached, kChunkCacheBytes),
        attributes(s->dbs.attributes, detail::kAttributeShape, kAttributeChunksCached,
                   kChunkCacheBytes) {}

  // Builds a lazy table of the snapshot from indexes/<key> unless it is built already (by this
  // or another view of the snapshot). False with a message naming the store and `what`.
  template <typename Table, typename Decode>
  bool build_once(LazyTable<Table>& lazy, std::string_view key, std::string_view what,
                  Decode decode, std::string& error) {
    std::call_once(lazy.once, [&] {
      lazy.table = {};  // a decoding that threw (out of memory) may have left some behind
      std::vector<uint8_t> raw;
      bool found;
      std::string why;
      if (!read_index(txn.get(), store->dbs.indexes, key, dctx.get(), raw, found, why,
                      MapPages::read_once) ||
          (found && !decode(raw, lazy.table, why))) {
        lazy.table = {};
        lazy.error = "store " + store->directory + ": " + std::string(what) + ": " + why;
      }
    });
    if (!lazy.error.empty()) {
      error = lazy.error;
      return false;
    }
    return true;
  }
  bool slots_by_id_ready(std::string& error) {
    return build_once(
        snapshot->slots_by_id, "ids", "id table",
        [this](const std::vector<uint8_t>& raw, std::vector<uint32_t>& slots, std::string& why) {
          return decode_slots_by_id(raw, snapshot->id_by_slot, slots, why);
        },
        error);
  }
  bool names_ready(std::string& error) {
    return build_once(snapshot->names, "names", "name table", decode_names, error);
  }
  // The entries of the names table with the hash of `name` (after names_ready()).
  std::span<const NameSlot> name_candidates(std::string_view name) const {
    const auto& names = snapshot->names.table;
    const uint32_t hash = name_hash(name);
    const auto [first, last] = std::equal_range(
        names.begin(), names.end(), NameSlot{hash, 0},
        [](const NameSlot& a, const NameSlot& b) { return a.hash < b.hash; });
    return {first, last};
  }
};

ReadView::ReadView(std::unique_ptr<State> state) : state_(std::move(state)) {}
ReadView::~ReadView() = default;

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
  std::error_code ec;
  const auto size = std::filesystem::file_size(
      std::filesystem::path(state_->store->directory) / "data.mdb", ec);
  info.store_bytes = ec ? 0 : size;
  return info;
}

std::span<const SpatialNode> ReadView::spatial_nodes() const { return state_->snapshot->nodes; }
std::span<const SpatialEntry> ReadView::spatial_entries() const {
  return state_->snapshot->entries;
}
glm::dvec3 ReadView::spatial_origin() const { return state_->snapshot->origin; }

bool ReadView::object(uint32_t slot, Object& out, bool with_attributes, std::string& error) const {
  State& s = *state_;
  const auto& id_by_slot = s.snapshot->id_by_slot;
  if (slot >= id_by_slot.size() || id_by_slot[slot] == 0) {
    error = "store " + s.store->directory + ": no object in slot " + std::to_string(slot);
    return false;
  }
  std::span<const uint8_t> record;
  std::string why;
  bool ok = s.objects.record(s.txn.get(), s.dctx.get(), slot, record, why);
  if (ok && record.empty()) {
    why = "the record is missing";
    ok = false;
  }
  if (!ok || !detail::decode_object(record.data(), record.size(), out, why)) {
    error = "store " + s.store->directory + ": object slot " + std::to_string(slot) + ": " + why;
    return false;
  }
  out.id = id_by_slot[slot];
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

bool ReadView::slot_of(uint64_t id, std::optional<uint32_t>& slot, std::string& error) const {
  State& s = *state_;
  slot.reset();
  if (!s.slots_by_id_ready(error)) return false;
  const auto& id_by_slot = s.snapshot->id_by_slot;
  const auto& slots = s.snapshot->slots_by_id.table;
  const auto it = std::partition_point(slots.begin(), slots.end(),
                                       [&](uint32_t k) { return id_by_slot[k] < id; });
  if (it != slots.end() && id_by_slot[*it] == id) slot = *it;
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
  if (!state_->names_ready(error)) return false;
  // A hash may collide: confirm by the name itself.
  for (const NameSlot& e : state_->name_candidates(name)) {
    Object o;
    if (!object(e.slot, o, false, error)) return false;
    if (o.name == name) slots.push_back(e.slot);
  }
  return true;
}

std::vector<uint32_t> ReadView::slots_named(std::string_view name) const {
  std::vector<uint32_t> out;
  std::string error;
  if (!state_->names_ready(error)) return out;
  for (const NameSlot& e : state_->name_candidates(name)) {
    Object o;
    if (object(e.slot, o, false, error) && o.name == name) out.push_back(e.slot);
  }
  return out;
}

bool ReadView::for_each_object(const std::function<bool(uint32_t, Object&&)>& fn,
                               bool with_attributes, std::string& error) const {
  const auto& id_by_slot = state_->snapshot->id_by_slot;
  for (uint32_t slot = 0; slot < id_by_slot.size(); ++slot) {
    if (id_by_slot[slot] == 0) continue;  // removed (or replaced) objects leave their slot empty
    Object o;
    if (!object(slot, o, with_attributes, error)) return false;
    if (!fn(slot, std::move(o))) return true;
  }
  return true;
}

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
    if (rc == MDB_SUCCESS) rc = mdb_env_set_maxdbs(state->env.get(), 8);
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
      error = "store " + directory + ": store format version " + std::to_string(version) +
              ", but this plantview reads only version " + std::to_string(kStoreFormatVersion) +
              (version < kStoreFormatVersion
                   ? " (an older plantview wrote it: import the model again into a new store)"
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
  };
  const Named named[] = {
      {"objects", &d.objects},
      {"attributes", &d.attributes},
      {"indexes", &d.indexes},
      {"sources", &d.sources},
  };
  for (const Named& n : named) {
    rc = mdb_dbi_open(txn.get(), n.name, create, n.dbi);
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
  auto s = std::make_unique<Import::State>(state_);
  int rc = s->txn.begin(state_->env.get(), 0);
  if (rc != MDB_SUCCESS) {
    error = state_->fail("starting an import", rc);
    return nullptr;
  }
  MDB_txn* txn = s->txn.get();
  if (!read_statistics(txn, state_->dbs.meta, state_->directory, s->totals, error)) {
    return nullptr;
  }
  MDB_val k = as_val("next_slot"), v;
  if (mdb_get(txn, state_->dbs.meta, &k, &v) == MDB_SUCCESS && v.mv_size == 4) {
    std::memcpy(&s->next_slot, v.mv_data, 4);
  }
  s->first_new_slot = s->next_slot;
  detail::ZstdDCtx dctx(ZSTD_createDCtx());
  std::string why;
  if (!read_table(txn, state_->dbs.indexes, "ids", dctx.get(), s->ids, why)) {
    error = "store " + state_->directory + ": id table: " + why;
    return nullptr;
  }
  if (!read_table(txn, state_->dbs.indexes, "names", dctx.get(), s->names, why)) {
    error = "store " + state_->directory + ": name table: " + why;
    return nullptr;
  }
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
  s->snapshot = state_->snapshot_for(s->txn.get(), error);
  if (!s->snapshot) return nullptr;
  return std::unique_ptr<ReadView>(new ReadView(std::move(s)));
}

}  // namespace plantview
