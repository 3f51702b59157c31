// The store's meta/ keys: statistics (as JSON), the commit id, the next slot, the ids' and names'
// key width, the spatial top.
#include "plantview/store.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "store_internal.h"

namespace plantview {


namespace detail {

namespace {

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

}  // namespace

uint64_t mix_digest(uint64_t digest, uint64_t value) {
  uint64_t x = digest ^ (value + 0x9e3779b97f4a7c15ull + (digest << 6) + (digest >> 2));
  x ^= x >> 30;  // splitmix64's finaliser: every input bit reaches every output bit
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// meta/"commit_id" as committed in `txn`; 0 for a store that has none (empty, or made before

uint64_t read_commit_id(MDB_txn* txn, MDB_dbi meta) {
  MDB_val k = as_val("commit_id"), v;
  uint64_t id = 0;
  if (mdb_get(txn, meta, &k, &v) == MDB_SUCCESS && v.mv_size == sizeof id)
    std::memcpy(&id, v.mv_data, sizeof id);
  return id;
}


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

unsigned index_key_bits(uint64_t objects, unsigned current) {
  if (current != 0) {
    const uint64_t keys = uint64_t(1) << current;
    const bool few = objects < 16 * keys && current > kMinIndexKeyBits;
    const bool many = objects >= 64 * keys && current < kMaxIndexKeyBits;
    if (!few && !many) return current;
  }
  const long ideal = std::lround(std::log2(double(std::max<uint64_t>(objects, 1)) / 32.0));
  return unsigned(std::clamp<long>(ideal, kMinIndexKeyBits, kMaxIndexKeyBits));
}

bool read_index_key_bits(MDB_txn* txn, MDB_dbi meta, unsigned& bits) {
  bits = kMinIndexKeyBits;
  MDB_val k = as_val("index_key_bits"), v;
  if (mdb_get(txn, meta, &k, &v) != MDB_SUCCESS) return true;
  uint32_t value = 0;
  if (v.mv_size != 4) return false;
  std::memcpy(&value, v.mv_data, 4);
  if (value < kMinIndexKeyBits || value > kMaxIndexKeyBits) return false;
  bits = value;
  return true;
}

}  // namespace detail

std::string statistics_json(const ModelStatistics& statistics) {
  return detail::statistics_to_json(statistics).dump();
}

}  // namespace plantview
