// The LMDB plant store: opening, imports (one write transaction each), read views.
#include "plantview/store.h"

#include <zdict.h>
#include <zstd.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <unordered_map>
#include <unordered_set>

#include "lmdb_guard.h"
#include "record.h"
#include "spatial.h"

namespace plantview {

using detail::as_val;
using detail::Key32;
using detail::Key64;
using detail::lmdb_message;

namespace {

constexpr size_t kMapSizeBytes = size_t(1) << 40;      // address space only; the file grows as used
constexpr size_t kDictionarySamples = 4000;             // records buffered to train on
constexpr size_t kDictionaryBytes = 32 * 1024;
constexpr int kCompressionLevel = 6;
constexpr size_t kMaxRecordBytes = size_t(1) << 30;     // refuse to inflate anything larger

uint64_t name_hash(std::string_view name) { return object_id("", name); }

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

ModelStatistics statistics_from_json(const nlohmann::json& j) {
  ModelStatistics s;
  s.objects = j.value("objects", uint64_t(0));
  s.primitives = j.value("primitives", uint64_t(0));
  s.triangles = j.value("triangles_full_resolution", uint64_t(0));
  for (int c = 0; c < kObjectClassCount; ++c) {
    const std::string name(class_name(ObjectClass(c)));
    s.objects_by_class[c] = j["objects_by_class"].value(name, uint64_t(0));
    s.primitives_by_class[c] = j["primitives_by_class"].value(name, uint64_t(0));
    s.triangles_by_class[c] = j["triangles_by_class"].value(name, uint64_t(0));
  }
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    const std::string name(kind_name(PrimitiveKind(k)));
    s.primitives_by_kind[k] = j["primitives_by_kind"].value(name, uint64_t(0));
    s.triangles_by_kind[k] = j["triangles_by_kind"].value(name, uint64_t(0));
  }
  if (j.contains("bounds_m")) {
    for (int i = 0; i < 3; ++i) {
      s.bounds.min[i] = j["bounds_m"]["min"][i].get<double>();
      s.bounds.max[i] = j["bounds_m"]["max"][i].get<double>();
    }
  }
  return s;
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

struct ZstdDDictFree {
  void operator()(ZSTD_DDict* d) const { ZSTD_freeDDict(d); }
};
struct ZstdCDictFree {
  void operator()(ZSTD_CDict* d) const { ZSTD_freeCDict(d); }
};
struct ZstdCCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct ZstdDCtxFree {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};

// Frames carry their content size (for exact inflation) but no dictionary id or checksum: a
// store has one dictionary, and LMDB pages are checksummed by nothing we could act on anyway.
ZSTD_CCtx* make_cctx() {
  ZSTD_CCtx* c = ZSTD_createCCtx();
  ZSTD_CCtx_setParameter(c, ZSTD_c_dictIDFlag, 0);
  ZSTD_CCtx_setParameter(c, ZSTD_c_contentSizeFlag, 1);
  ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, kCompressionLevel);
  return c;
}

struct Databases {
  MDB_dbi meta, objects, attributes, ids, names, sources, spatial;
};

}  // namespace

std::string statistics_json(const ModelStatistics& statistics) {
  return statistics_to_json(statistics).dump();
}

// ---------------------------------------------------------------------------------------------

struct Store::State {
  std::string directory;
  Mode mode;
  detail::LmdbEnv env;
  Databases dbs{};
  // The decompression dictionary, loaded once per store (shared by views; ZSTD_DDict is
  // read-only after creation). Null until the store has one. Guarded by dict_mutex.
  std::mutex dict_mutex;
  std::shared_ptr<ZSTD_DDict> ddict;
  std::string ddict_bytes;

  std::string fail(std::string_view what, int rc) const { return lmdb_message(directory, what, rc); }

  // The dictionary as committed in `txn` (empty if none). Caches the decoder for it.
  std::shared_ptr<ZSTD_DDict> decoder_for(MDB_txn* txn) {
    MDB_val key = as_val("dictionary"), val;
    if (mdb_get(txn, dbs.meta, &key, &val) != MDB_SUCCESS || val.mv_size == 0) return nullptr;
    std::lock_guard lock(dict_mutex);
    const std::string_view bytes(static_cast<const char*>(val.mv_data), val.mv_size);
    if (!ddict || ddict_bytes != bytes) {
      ddict_bytes.assign(bytes);
      ddict.reset(ZSTD_createDDict(ddict_bytes.data(), ddict_bytes.size()), ZstdDDictFree());
    }
    return ddict;
  }
};

// Inflates one record (a zstd frame) into `out`. False with a message on corruption.
static bool inflate(ZSTD_DCtx* dctx, const ZSTD_DDict* ddict, const MDB_val& val,
                    std::vector<uint8_t>& out, std::string& error) {
  const unsigned long long size = ZSTD_getFrameContentSize(val.mv_data, val.mv_size);
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN || size > kMaxRecordBytes) {
    error = "record is not a valid zstd frame";
    return false;
  }
  out.resize(size);
  const size_t got = ddict ? ZSTD_decompress_usingDDict(dctx, out.data(), out.size(), val.mv_data,
                                                        val.mv_size, ddict)
                           : ZSTD_decompressDCtx(dctx, out.data(), out.size(), val.mv_data, val.mv_size);
  if (ZSTD_isError(got) || got != size) {
    error = std::string("record does not decompress: ") +
            (ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short");
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

struct Import::State {
  std::shared_ptr<Store::State> store;
  detail::LmdbTxn txn;
  std::string error_prefix;

  ModelStatistics totals;             // as committed before, updated as objects come and go
  uint32_t next_slot = 0;
  bool fresh = false;                 // the store had no objects: ids and names can be appended
  std::unordered_map<uint64_t, uint32_t> new_ids;   // id -> slot, this import's objects
  std::vector<std::pair<uint64_t, uint32_t>> new_names;  // (name hash, slot)
  std::vector<SpatialEntryD> new_entries;               // this import's objects' bounds
  std::unordered_set<uint32_t> removed_slots;           // earlier objects removed by this import
  uint64_t put_count = 0;

  // Compression: a dictionary is trained on the first records of the store's first import.
  std::unique_ptr<ZSTD_CCtx, ZstdCCtxFree> cctx{make_cctx()};
  std::unique_ptr<ZSTD_CDict, ZstdCDictFree> cdict;
  bool dictionary_decided = false;
  struct Pending {
    uint32_t slot;
    std::vector<uint8_t> object, attributes;
  };
  std::vector<Pending> pending;  // raw records waiting for the dictionary
  std::vector<uint8_t> raw, raw_attributes, packed;

  std::string fail(std::string_view what, int rc) const { return store->fail(what, rc); }

  bool compress(const std::vector<uint8_t>& in, std::vector<uint8_t>& out, std::string& error) {
    out.resize(ZSTD_compressBound(in.size()));
    // The context keeps its parameters and, once trained, references the dictionary.
    const size_t n = ZSTD_compress2(cctx.get(), out.data(), out.size(), in.data(), in.size());
    if (ZSTD_isError(n)) {
      error = "store " + store->directory + ": compressing a record: " + ZSTD_getErrorName(n);
      return false;
    }
    out.resize(n);
    return true;
  }

  bool write_records(uint32_t slot, const std::vector<uint8_t>& object,
                     const std::vector<uint8_t>& attributes, std::string& error) {
    const Key32 key(slot);
    for (auto [dbi, raw_record] : {std::pair{store->dbs.objects, &object},
                                   std::pair{store->dbs.attributes, &attributes}}) {
      if (!compress(*raw_record, packed, error)) return false;
      MDB_val k = key.val(), v = as_val(packed.data(), packed.size());
      // Slots only grow, so records append to the end of each database (full pages).
      const int rc = mdb_put(txn.get(), dbi, &k, &v, MDB_APPEND);
      if (rc != MDB_SUCCESS) {
        error = fail("writing an object record", rc);
        return false;
      }
    }
    return true;
  }

  // Trains (or declines) the dictionary on the pending records, then writes them.
  bool decide_dictionary(std::string& error) {
    dictionary_decided = true;
    if (pending.size() >= 64) {
      std::vector<uint8_t> samples;
      std::vector<size_t> sizes;
      for (const Pending& p : pending) {
        for (const auto* r : {&p.object, &p.attributes}) {
          samples.insert(samples.end(), r->begin(), r->end());
          sizes.push_back(r->size());
        }
      }
      std::vector<uint8_t> dict(kDictionaryBytes);
      const size_t n = ZDICT_trainFromBuffer(dict.data(), dict.size(), samples.data(), sizes.data(),
                                             unsigned(sizes.size()));
      if (!ZDICT_isError(n)) {
        dict.resize(n);
        cdict.reset(ZSTD_createCDict(dict.data(), dict.size(), kCompressionLevel));
        ZSTD_CCtx_refCDict(cctx.get(), cdict.get());
        MDB_val k = as_val("dictionary"), v = as_val(dict.data(), dict.size());
        const int rc = mdb_put(txn.get(), store->dbs.meta, &k, &v, 0);
        if (rc != MDB_SUCCESS) {
          error = fail("writing the dictionary", rc);
          return false;
        }
      }
    }
    for (const Pending& p : pending) {
      if (!write_records(p.slot, p.object, p.attributes, error)) return false;
    }
    pending.clear();
    pending.shrink_to_fit();
    return true;
  }

  // Removes the object in `slot` (committed earlier, or put by this import).
  bool remove_slot(uint32_t slot, std::string& error) {
    ZSTD_DCtx* dctx = ZSTD_createDCtx();
    std::unique_ptr<ZSTD_DCtx, ZstdDCtxFree> guard(dctx);
    const Key32 key(slot);
    MDB_val k = key.val(), v;
    int rc = mdb_get(txn.get(), store->dbs.objects, &k, &v);
    Object old;
    if (rc == MDB_SUCCESS) {
      std::vector<uint8_t> record;
      std::string why;
      const auto ddict = store->decoder_for(txn.get());
      if (!inflate(dctx, ddict.get(), v, record, why) ||
          !detail::decode_object(record.data(), record.size(), old, why)) {
        error = "store " + store->directory + ": slot " + std::to_string(slot) + ": " + why;
        return false;
      }
    } else if (rc == MDB_NOTFOUND) {
      // Not yet written: still waiting for the dictionary.
      auto it = std::find_if(pending.begin(), pending.end(), [&](const Pending& p) { return p.slot == slot; });
      if (it == pending.end()) return true;
      std::string why;
      if (!detail::decode_object(it->object.data(), it->object.size(), old, why)) {
        error = "store " + store->directory + ": " + why;
        return false;
      }
      pending.erase(it);
    } else {
      error = fail("reading an object", rc);
      return false;
    }
    ModelStatistics part;
    part.add(old);
    subtract(totals, part);
    for (MDB_dbi dbi : {store->dbs.objects, store->dbs.attributes}) {
      MDB_val dk = key.val();
      rc = mdb_del(txn.get(), dbi, &dk, nullptr);
      if (rc != MDB_SUCCESS && rc != MDB_NOTFOUND) {
        error = fail("deleting an object", rc);
        return false;
      }
    }
    const Key64 id_key(old.id);
    MDB_val ik = id_key.val();
    mdb_del(txn.get(), store->dbs.ids, &ik, nullptr);
    const Key64 name_key(name_hash(old.name));
    MDB_val nk = name_key.val(), nv = key.val();
    mdb_del(txn.get(), store->dbs.names, &nk, &nv);
    MDB_val sk = as_val(old.source), sv = key.val();
    mdb_del(txn.get(), store->dbs.sources, &sk, &sv);
    // This import's own bookkeeping.
    auto it = new_ids.find(old.id);
    if (it != new_ids.end() && it->second == slot) {
      new_ids.erase(it);
      std::erase_if(new_names, [&](const auto& n) { return n.second == slot; });
      std::erase_if(new_entries, [&](const SpatialEntryD& e) { return e.slot == slot; });
    } else {
      removed_slots.insert(slot);
    }
    return true;
  }
};

Import::Import(std::unique_ptr<State> state) : state_(std::move(state)) {}
Import::~Import() = default;
uint64_t Import::objects_put() const { return state_->put_count; }

bool Import::remove_source(std::string_view source, std::string& error) {
  State& s = *state_;
  std::vector<uint32_t> slots;
  {
    detail::LmdbCursor cursor;
    int rc = cursor.open(s.txn.get(), s.store->dbs.sources);
    if (rc != MDB_SUCCESS) {
      error = s.fail("opening the sources index", rc);
      return false;
    }
    MDB_val k = as_val(source), v;
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_KEY);
    while (rc == MDB_SUCCESS) {
      slots.push_back(detail::read_be32(v.mv_data));
      rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT_DUP);
    }
  }
  // The index already holds this import's own objects from the same source.
  for (uint32_t slot : slots) {
    if (!s.remove_slot(slot, error)) return false;
  }
  return true;
}

bool Import::put(const Object& object, std::string& error) {
  State& s = *state_;
  if (object.id == 0) {
    error = "store " + s.store->directory + ": object '" + object.name + "' has id 0";
    return false;
  }
  // An object with the same id is replaced.
  if (auto it = s.new_ids.find(object.id); it != s.new_ids.end()) {
    if (!s.remove_slot(it->second, error)) return false;
  } else if (!s.fresh) {
    const Key64 id_key(object.id);
    MDB_val k = id_key.val(), v;
    const int rc = mdb_get(s.txn.get(), s.store->dbs.ids, &k, &v);
    if (rc == MDB_SUCCESS) {
      if (!s.remove_slot(detail::read_be32(v.mv_data), error)) return false;
    } else if (rc != MDB_NOTFOUND) {
      error = s.fail("looking up an object id", rc);
      return false;
    }
  }
  const uint32_t slot = s.next_slot++;
  const DAabb bounds = object_bounds(object);
  detail::encode_object(object, s.raw);
  detail::encode_attributes(object.attributes, s.raw_attributes);
  if (!s.dictionary_decided) {
    s.pending.push_back({slot, s.raw, s.raw_attributes});
    if (s.pending.size() >= kDictionarySamples && !s.decide_dictionary(error)) return false;
  } else if (!s.write_records(slot, s.raw, s.raw_attributes, error)) {
    return false;
  }
  const Key32 slot_key(slot);
  MDB_val sk = as_val(object.source), sv = slot_key.val();
  int rc = mdb_put(s.txn.get(), s.store->dbs.sources, &sk, &sv, 0);
  if (rc != MDB_SUCCESS) {
    error = s.fail("writing the sources index", rc);
    return false;
  }
  s.new_ids.emplace(object.id, slot);
  s.new_names.emplace_back(name_hash(object.name), slot);
  if (!bounds.empty()) s.new_entries.push_back({bounds.min, bounds.max, slot});
  ModelStatistics part;
  part.add(object);
  add(s.totals, part);
  ++s.put_count;
  return true;
}

bool Import::commit(std::string& error) {
  State& s = *state_;
  assert(s.txn.get() && "commit() on a spent Import");
  MDB_txn* txn = s.txn.get();
  const Databases& dbs = s.store->dbs;
  if (!s.dictionary_decided && !s.decide_dictionary(error)) return false;

  // Ids and name hashes, sorted: appended to full pages in a fresh store.
  std::vector<std::pair<uint64_t, uint32_t>> ids(s.new_ids.begin(), s.new_ids.end());
  std::sort(ids.begin(), ids.end());
  for (const auto& [id, slot] : ids) {
    const Key64 k(id);
    const Key32 v(slot);
    MDB_val kv = k.val(), vv = v.val();
    const int rc = mdb_put(txn, dbs.ids, &kv, &vv, s.fresh ? MDB_APPEND : 0);
    if (rc != MDB_SUCCESS) {
      error = s.fail("writing the id index", rc);
      return false;
    }
  }
  std::sort(s.new_names.begin(), s.new_names.end());
  for (const auto& [hash, slot] : s.new_names) {
    const Key64 k(hash);
    const Key32 v(slot);
    MDB_val kv = k.val(), vv = v.val();
    const int rc = mdb_put(txn, dbs.names, &kv, &vv, s.fresh ? MDB_APPENDDUP : 0);
    if (rc != MDB_SUCCESS) {
      error = s.fail("writing the name index", rc);
      return false;
    }
  }

  // The spatial hierarchy over every object's bounds, rebuilt.
  glm::dvec3 origin(0.0);
  std::vector<SpatialEntryD> entries;
  {
    MDB_val ok = as_val("origin"), ov;
    bool have_origin = mdb_get(txn, dbs.spatial, &ok, &ov) == MDB_SUCCESS && ov.mv_size == 24;
    if (have_origin) std::memcpy(&origin, ov.mv_data, 24);
    MDB_val ek = as_val("entries"), ev;
    if (have_origin && mdb_get(txn, dbs.spatial, &ek, &ev) == MDB_SUCCESS) {
      const size_t n = ev.mv_size / sizeof(SpatialEntry);
      for (size_t i = 0; i < n; ++i) {
        SpatialEntry e;
        std::memcpy(&e, static_cast<const char*>(ev.mv_data) + i * sizeof(SpatialEntry), sizeof e);
        if (s.removed_slots.count(e.slot)) continue;
        entries.push_back({origin + glm::dvec3(e.min[0], e.min[1], e.min[2]),
                           origin + glm::dvec3(e.max[0], e.max[1], e.max[2]), e.slot});
      }
    }
    entries.insert(entries.end(), s.new_entries.begin(), s.new_entries.end());
    if (!have_origin && !entries.empty()) {
      DAabb all;
      for (const auto& e : entries) all.extend(DAabb{e.min, e.max});
      origin = glm::floor(0.5 * (all.min + all.max));  // whole metres: exact in float and double
    }
  }
  std::vector<SpatialNode> nodes;
  std::vector<SpatialEntry> packed_entries;
  build_spatial_tree(entries, origin, nodes, packed_entries);
  DAabb bounds;
  for (const SpatialEntry& e : packed_entries) {
    bounds.extend(origin + glm::dvec3(e.min[0], e.min[1], e.min[2]));
    bounds.extend(origin + glm::dvec3(e.max[0], e.max[1], e.max[2]));
  }
  s.totals.bounds = bounds;

  auto put_meta = [&](MDB_dbi dbi, std::string_view key, const void* data, size_t size) {
    MDB_val k = as_val(key), v = as_val(data, size);
    const int rc = mdb_put(txn, dbi, &k, &v, 0);
    if (rc != MDB_SUCCESS) error = s.fail("writing " + std::string(key), rc);
    return rc == MDB_SUCCESS;
  };
  const std::string stats = statistics_json(s.totals);
  const uint32_t version = kStoreFormatVersion;
  if (!put_meta(dbs.spatial, "origin", &origin, sizeof origin) ||
      !put_meta(dbs.spatial, "nodes", nodes.data(), nodes.size() * sizeof(SpatialNode)) ||
      !put_meta(dbs.spatial, "entries", packed_entries.data(),
                packed_entries.size() * sizeof(SpatialEntry)) ||
      !put_meta(dbs.meta, "statistics", stats.data(), stats.size()) ||
      !put_meta(dbs.meta, "next_slot", &s.next_slot, sizeof s.next_slot) ||
      !put_meta(dbs.meta, "format", &version, sizeof version)) {
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
  std::shared_ptr<ZSTD_DDict> ddict;
  std::unique_ptr<ZSTD_DCtx, ZstdDCtxFree> dctx{ZSTD_createDCtx()};
  mutable std::vector<uint8_t> scratch;
  std::span<const SpatialNode> nodes;
  std::span<const SpatialEntry> entries;
  std::vector<SpatialNode> nodes_copy;      // used when the map's bytes are not aligned
  std::vector<SpatialEntry> entries_copy;
  glm::dvec3 origin{0.0};
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
  k = as_val("statistics");
  if (mdb_get(txn, dbs.meta, &k, &v) == MDB_SUCCESS) {
    const auto j = nlohmann::json::parse(
        std::string_view(static_cast<const char*>(v.mv_data), v.mv_size), nullptr, false);
    if (!j.is_discarded()) info.statistics = statistics_from_json(j);
  }
  info.objects = info.statistics.objects;
  std::error_code ec;
  const auto size = std::filesystem::file_size(
      std::filesystem::path(state_->store->directory) / "data.mdb", ec);
  info.store_bytes = ec ? 0 : size;
  return info;
}

std::span<const SpatialNode> ReadView::spatial_nodes() const { return state_->nodes; }
std::span<const SpatialEntry> ReadView::spatial_entries() const { return state_->entries; }
glm::dvec3 ReadView::spatial_origin() const { return state_->origin; }

bool ReadView::object(uint32_t slot, Object& out, bool with_attributes, std::string& error) const {
  State& s = *state_;
  const Key32 key(slot);
  MDB_val k = key.val(), v;
  int rc = mdb_get(s.txn.get(), s.store->dbs.objects, &k, &v);
  if (rc != MDB_SUCCESS) {
    error = s.store->fail("object slot " + std::to_string(slot), rc);
    return false;
  }
  std::string why;
  if (!inflate(s.dctx.get(), s.ddict.get(), v, s.scratch, why) ||
      !detail::decode_object(s.scratch.data(), s.scratch.size(), out, why)) {
    error = "store " + s.store->directory + ": object slot " + std::to_string(slot) + ": " + why;
    return false;
  }
  if (!with_attributes) return true;
  MDB_val ak = key.val();
  rc = mdb_get(s.txn.get(), s.store->dbs.attributes, &ak, &v);
  if (rc != MDB_SUCCESS) {
    error = s.store->fail("attributes of slot " + std::to_string(slot), rc);
    return false;
  }
  if (!inflate(s.dctx.get(), s.ddict.get(), v, s.scratch, why) ||
      !detail::decode_attributes(s.scratch.data(), s.scratch.size(), out.attributes, why)) {
    error = "store " + s.store->directory + ": attributes of slot " + std::to_string(slot) + ": " + why;
    return false;
  }
  return true;
}

std::optional<uint32_t> ReadView::slot_of(uint64_t id) const {
  const Key64 key(id);
  MDB_val k = key.val(), v;
  if (mdb_get(state_->txn.get(), state_->store->dbs.ids, &k, &v) != MDB_SUCCESS || v.mv_size != 4) {
    return std::nullopt;
  }
  return detail::read_be32(v.mv_data);
}

std::vector<uint32_t> ReadView::slots_named(std::string_view name) const {
  std::vector<uint32_t> candidates, out;
  detail::LmdbCursor cursor;
  if (cursor.open(state_->txn.get(), state_->store->dbs.names) != MDB_SUCCESS) return out;
  const Key64 key(name_hash(name));
  MDB_val k = key.val(), v;
  int rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_KEY);
  while (rc == MDB_SUCCESS) {
    candidates.push_back(detail::read_be32(v.mv_data));
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT_DUP);
  }
  // A hash may collide: confirm by the name itself.
  for (uint32_t slot : candidates) {
    Object o;
    std::string error;
    if (object(slot, o, false, error) && o.name == name) out.push_back(slot);
  }
  return out;
}

bool ReadView::for_each_object(const std::function<bool(uint32_t, Object&&)>& fn,
                               bool with_attributes, std::string& error) const {
  detail::LmdbCursor cursor;
  int rc = cursor.open(state_->txn.get(), state_->store->dbs.objects);
  if (rc != MDB_SUCCESS) {
    error = state_->store->fail("listing objects", rc);
    return false;
  }
  MDB_val k, v;
  rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_FIRST);
  while (rc == MDB_SUCCESS) {
    const uint32_t slot = detail::read_be32(k.mv_data);
    Object o;
    if (!object(slot, o, with_attributes, error)) return false;
    if (!fn(slot, std::move(o))) return true;
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT);
  }
  if (rc != MDB_NOTFOUND) {
    error = state_->store->fail("listing objects", rc);
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

Store::Store(std::unique_ptr<State> state) : state_(std::move(state)) {}
Store::~Store() = default;
const std::string& Store::directory() const { return state_->directory; }

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
  int rc = mdb_env_create(state->env.out());
  if (rc == MDB_SUCCESS) rc = mdb_env_set_maxdbs(state->env.get(), 8);
  if (rc == MDB_SUCCESS) rc = mdb_env_set_mapsize(state->env.get(), kMapSizeBytes);
  if (rc == MDB_SUCCESS) rc = mdb_env_set_maxreaders(state->env.get(), 254);
  const unsigned flags = MDB_NOTLS | (mode == Mode::read_only ? MDB_RDONLY : 0u);
  if (rc == MDB_SUCCESS) rc = mdb_env_open(state->env.get(), directory.c_str(), flags, 0644);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    return nullptr;
  }
  // Open (or create) the named databases once; their handles serve every later transaction.
  detail::LmdbTxn txn;
  rc = txn.begin(state->env.get(), mode == Mode::read_only ? MDB_RDONLY : 0u);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    return nullptr;
  }
  const unsigned create = mode == Mode::read_only ? 0u : MDB_CREATE;
  struct Named {
    const char* name;
    MDB_dbi* dbi;
    unsigned flags;
  };
  Databases& d = state->dbs;
  const Named named[] = {
      {"meta", &d.meta, 0},
      {"objects", &d.objects, 0},
      {"attributes", &d.attributes, 0},
      {"ids", &d.ids, 0},
      {"names", &d.names, MDB_DUPSORT | MDB_DUPFIXED},
      {"sources", &d.sources, MDB_DUPSORT | MDB_DUPFIXED},
      {"spatial", &d.spatial, 0},
  };
  for (const Named& n : named) {
    rc = mdb_dbi_open(txn.get(), n.name, n.flags | create, n.dbi);
    if (rc != MDB_SUCCESS) {
      error = lmdb_message(directory, std::string("opening database '") + n.name + "'", rc);
      return nullptr;
    }
  }
  MDB_val k = as_val("format"), v;
  if (mdb_get(txn.get(), d.meta, &k, &v) == MDB_SUCCESS) {
    uint32_t version = 0;
    if (v.mv_size == 4) std::memcpy(&version, v.mv_data, 4);
    if (version != kStoreFormatVersion) {
      error = "store " + directory + ": format version " + std::to_string(version) +
              ", this plantview reads version " + std::to_string(kStoreFormatVersion);
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
  auto s = std::make_unique<Import::State>();
  s->store = state_;
  int rc = s->txn.begin(state_->env.get(), 0);
  if (rc != MDB_SUCCESS) {
    error = state_->fail("starting an import", rc);
    return nullptr;
  }
  MDB_txn* txn = s->txn.get();
  MDB_val k = as_val("statistics"), v;
  if (mdb_get(txn, state_->dbs.meta, &k, &v) == MDB_SUCCESS) {
    const auto j = nlohmann::json::parse(
        std::string_view(static_cast<const char*>(v.mv_data), v.mv_size), nullptr, false);
    if (!j.is_discarded()) s->totals = statistics_from_json(j);
  }
  k = as_val("next_slot");
  if (mdb_get(txn, state_->dbs.meta, &k, &v) == MDB_SUCCESS && v.mv_size == 4) {
    std::memcpy(&s->next_slot, v.mv_data, 4);
  }
  MDB_stat stat;
  s->fresh = mdb_stat(txn, state_->dbs.ids, &stat) == MDB_SUCCESS && stat.ms_entries == 0;
  // An existing dictionary stays: earlier records need it.
  k = as_val("dictionary");
  if (mdb_get(txn, state_->dbs.meta, &k, &v) == MDB_SUCCESS) {
    s->dictionary_decided = true;
    if (v.mv_size > 0) {
      s->cdict.reset(ZSTD_createCDict(v.mv_data, v.mv_size, kCompressionLevel));
      ZSTD_CCtx_refCDict(s->cctx.get(), s->cdict.get());
    }
  } else if (s->next_slot > 0) {
    s->dictionary_decided = true;  // a store that chose no dictionary keeps plain frames
  }
  return std::unique_ptr<Import>(new Import(std::move(s)));
}

std::unique_ptr<ReadView> Store::read(std::string& error) const {
  auto s = std::make_unique<ReadView::State>();
  s->store = state_;
  const int rc = s->txn.begin(state_->env.get(), MDB_RDONLY);
  if (rc != MDB_SUCCESS) {
    error = state_->fail("starting a read", rc);
    return nullptr;
  }
  MDB_txn* txn = s->txn.get();
  s->ddict = state_->decoder_for(txn);
  MDB_val k = as_val("origin"), v;
  if (mdb_get(txn, state_->dbs.spatial, &k, &v) == MDB_SUCCESS && v.mv_size == 24) {
    std::memcpy(&s->origin, v.mv_data, 24);
  }
  auto load = [&](std::string_view key, auto& span, auto& copy) {
    using T = typename std::decay_t<decltype(copy)>::value_type;
    MDB_val kk = as_val(key), vv;
    if (mdb_get(txn, state_->dbs.spatial, &kk, &vv) != MDB_SUCCESS) return;
    const size_t n = vv.mv_size / sizeof(T);
    if (reinterpret_cast<uintptr_t>(vv.mv_data) % alignof(T) == 0) {
      span = std::span<const T>(static_cast<const T*>(vv.mv_data), n);  // zero-copy from the map
    } else {
      copy.resize(n);
      std::memcpy(copy.data(), vv.mv_data, n * sizeof(T));
      span = copy;
    }
  };
  load("nodes", s->nodes, s->nodes_copy);
  load("entries", s->entries, s->entries_copy);
  return std::unique_ptr<ReadView>(new ReadView(std::move(s)));
}

}  // namespace plantview
