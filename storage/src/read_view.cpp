// Read views: one LMDB read transaction each, and what the views of one committed state
// share (the spatial top, decoded blocks and chunks).
#include "plantview/store.h"

#include <algorithm>
#include <cassert>
#include <filesystem>

#include <map>

#include "record.h"
#include "revisions.h"
#include "store_internal.h"

namespace plantview {

using detail::as_val;
using detail::lmdb_message;
using detail::name_hash;
using detail::read_commit_id;
using detail::read_statistics;
using detail::Databases;
using detail::inflate_read_once;
using detail::read_top;
using detail::index_slots;
using detail::g_spatial_cache_bytes;
using detail::g_chunk_cache_bytes;
using detail::Snapshot;
using detail::data_file_complete;

namespace {

// Decompressed chunks a read view keeps: 32 chunks of about 150 objects (about 1 MB for
// generated plants) and 2 chunks of attributes, each column within 16 MB (chunks of big meshes
// are big).
constexpr size_t kObjectChunksCached = 32;
constexpr size_t kAttributeChunksCached = 2;
constexpr size_t kViewChunkBytes = size_t(16) << 20;

}  // namespace

namespace detail {

std::atomic<size_t> g_spatial_cache_bytes{kSpatialCacheBytes};
std::atomic<size_t> g_chunk_cache_bytes{kChunkCacheBytes};

void set_spatial_cache_bytes(size_t bytes) { g_spatial_cache_bytes = bytes; }
void set_chunk_cache_bytes(size_t bytes) { g_chunk_cache_bytes = bytes; }

}  // namespace detail

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
        objects(s->dbs.objects, kObjectChunksCached, kViewChunkBytes),
        attributes(s->dbs.attributes, kAttributeChunksCached, kViewChunkBytes) {}

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

  // Whether the snapshot knows the key width of the ids and names (else `error` says why).
  bool index_readable(const std::string& what, std::string& error) const {
    if (snapshot->index_key_bits != 0) return true;
    error = "store " + store->directory + ": " + what +
            ": meta/\"index_key_bits\" is damaged (not a u32 from " +
            std::to_string(detail::kMinIndexKeyBits) + " to " +
            std::to_string(detail::kMaxIndexKeyBits) + ")";
    return false;
  }

  // The slots under the hash of `name` in the names database, in slot order (unconfirmed).
  bool name_candidates(std::string_view name, std::vector<uint32_t>& candidates,
                       std::string& error) {
    if (!index_readable("reading the names", error)) return false;
    const int rc = index_slots<32>(txn.get(), store->dbs.names, snapshot->index_key_bits,
                                   name_hash(name), candidates);
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
  Revision last;
  bool found;
  std::string why;
  if (detail::read_last_revision(txn, dbs.revisions, last, found, why) && found) {
    info.revision = last.number;
    info.revision_time_unix_ms = last.time_unix_ms;
  }
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
  if (!s.index_readable("looking up id " + std::to_string(id), error)) return false;
  const int rc = index_slots<64>(s.txn.get(), s.store->dbs.ids, s.snapshot->index_key_bits, id,
                                 slots, 1, &value);
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

bool ReadView::revisions(std::vector<Revision>& out, std::string& error) const {
  State& s = *state_;
  out.clear();
  detail::LmdbCursor cursor;
  int rc = cursor.open(s.txn.get(), s.store->dbs.revisions);
  MDB_val k, v;
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_FIRST);
  while (rc == MDB_SUCCESS) {
    Revision r;
    bool unknown;
    std::string why;
    if (!detail::revision_from_json(std::string_view(static_cast<const char*>(v.mv_data), v.mv_size),
                                    r, unknown, why)) {
      error = "store " + s.store->directory + ": revision " +
              std::to_string(k.mv_size == 4 ? detail::read_be32(k.mv_data) : 0) + ": " + why;
      return false;
    }
    out.push_back(std::move(r));
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT);
  }
  if (rc != MDB_NOTFOUND) {
    error = lmdb_message(s.store->directory, "reading the revisions", rc);
    return false;
  }
  return true;
}

namespace {

// Whether revision `number`'s changes can be read in `txn`: false with a message naming it (and
// the store) when it never existed, was pruned, or came from upgrading a format 5 store.
bool changes_readable(MDB_txn* txn, MDB_dbi revisions, const std::string& directory,
                      uint32_t number, uint32_t newest, std::string& error) {
  Revision r;
  bool unknown, found;
  std::string why;
  if (!detail::read_revision(txn, revisions, number, r, unknown, found, why)) {
    error = "store " + directory + ": " + why;
    return false;
  }
  if (!found) {
    error = "store " + directory + ": no revision " + std::to_string(number) +
            " (the newest is " + std::to_string(newest) + ")";
    return false;
  }
  if (unknown) {
    error = "store " + directory + ": revision " + std::to_string(number) +
            "'s changes are not known: it upgraded a format 5 store";
    return false;
  }
  if (!r.changes_kept) {
    Revision last;
    bool any;
    uint32_t keep = kDefaultKeepRevisions;
    if (detail::read_last_revision(txn, revisions, last, any, why) && any)
      keep = last.keep_revisions;
    error = "store " + directory + ": revision " + std::to_string(number) +
            "'s changes were pruned: the store keeps the last " + std::to_string(keep) +
            " (--keep-revisions)";
    return false;
  }
  return true;
}

// The block of `dbi` (changes/ or history/: keys (revision, first id)) that would hold object
// `id` of revision `number`, inflated into `raw`: the value of the greatest key not above
// (number, id). `found` false when revision `number` has no such block.
bool find_block(MDB_txn* txn, MDB_dbi dbi, ZSTD_DCtx* dctx, uint32_t number, uint64_t id,
                std::vector<uint8_t>& raw, bool& found, std::string& why) {
  found = false;
  detail::LmdbCursor cursor;
  int rc = cursor.open(txn, dbi);
  const detail::ChangeKey key(number, id);
  MDB_val k = key.val(), v;
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_RANGE);
  uint32_t n = 0;
  uint64_t first = 0;
  const bool exact = rc == MDB_SUCCESS && detail::ChangeKey::decode(k, n, first) &&
                     n == number && first == id;
  if (!exact && (rc == MDB_SUCCESS || rc == MDB_NOTFOUND)) {
    rc = mdb_cursor_get(cursor.get(), &k, &v, rc == MDB_NOTFOUND ? MDB_LAST : MDB_PREV);
    if (rc == MDB_NOTFOUND) return true;
  }
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return false;
  }
  if (!detail::ChangeKey::decode(k, n, first)) {
    why = "a malformed key";
    return false;
  }
  if (n != number) return true;
  found = true;
  return detail::inflate_frame(dctx, std::span(static_cast<const uint8_t*>(v.mv_data), v.mv_size),
                               raw, why);
}

// The change revision `number` made to object `id` (`found` false: none).
bool find_change(MDB_txn* txn, MDB_dbi changes, ZSTD_DCtx* dctx, uint32_t number, uint64_t id,
                 detail::ChangeEntry& out, bool& found, std::string& why) {
  std::vector<uint8_t> raw;
  std::vector<detail::ChangeEntry> entries;
  if (!find_block(txn, changes, dctx, number, id, raw, found, why)) return false;
  if (found && !detail::decode_change_block(raw, entries, why)) return false;
  found = false;
  for (detail::ChangeEntry& e : entries) {
    if (e.id != id) continue;
    out = std::move(e);
    found = true;
    break;
  }
  return true;
}

}  // namespace

bool ReadView::changes(uint32_t from, uint32_t to, std::vector<ObjectChange>& out,
                       std::string& error) const {
  State& s = *state_;
  out.clear();
  const uint32_t newest = info().revision;
  if (to > newest || from >= to) {
    const uint32_t missing = from > newest ? from : to;
    error = "store " + s.store->directory + ": " +
            (missing > newest ? "no revision " + std::to_string(missing) + " (the newest is " +
                                    std::to_string(newest) + ")"
                              : "no changes from revision " + std::to_string(from) + " to " +
                                    std::to_string(to) + ": the first must come before the second");
    return false;
  }
  for (uint32_t n = from + 1; n <= to; ++n) {
    if (!changes_readable(s.txn.get(), s.store->dbs.revisions, s.store->directory, n, newest, error)) return false;
  }
  // Each object's first and last change in the range, by id.
  struct Net {
    bool existed = false, exists = false;
    uint64_t hash_before = 0, hash_after = 0;
    uint8_t object_class = 0;
    std::string name;
    uint32_t revision = 0;
  };
  std::map<uint64_t, Net> net;
  detail::LmdbCursor cursor;
  int rc = cursor.open(s.txn.get(), s.store->dbs.changes);
  const detail::ChangeKey first(from + 1, 0);
  MDB_val k = first.val(), v;
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_SET_RANGE);
  std::vector<uint8_t> raw;
  std::vector<detail::ChangeEntry> entries;
  while (rc == MDB_SUCCESS) {
    uint32_t number;
    uint64_t first_id;
    std::string why = "a malformed key";
    if (!detail::ChangeKey::decode(k, number, first_id) ||
        !detail::inflate_read_once(v, s.dctx.get(), raw, why) ||
        !detail::decode_change_block(raw, entries, why)) {
      error = "store " + s.store->directory + ": the changes of revision " +
              std::to_string(k.mv_size == 12 ? detail::read_be32(k.mv_data) : 0) + ": " + why;
      return false;
    }
    if (number > to) break;
    for (detail::ChangeEntry& change : entries) {
      auto [it, is_new] = net.try_emplace(change.id);
      Net& n = it->second;
      if (is_new) {
        n.existed = change.kind != ChangeKind::added;
        n.hash_before = change.hash_before;
      }
      n.exists = change.kind != ChangeKind::removed;
      n.hash_after = change.hash_after;
      n.object_class = change.object_class;
      n.name = std::move(change.name);
      n.revision = number;
    }
    rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT);
  }
  if (rc != MDB_SUCCESS && rc != MDB_NOTFOUND) {
    error = lmdb_message(s.store->directory, "reading the changes", rc);
    return false;
  }
  for (auto& [id, n] : net) {
    if (!n.existed && !n.exists) continue;                               // came and went
    if (n.existed && n.exists && n.hash_before == n.hash_after) continue;  // back as it was
    ObjectChange c;
    c.id = id;
    c.kind = !n.existed ? ChangeKind::added : !n.exists ? ChangeKind::removed : ChangeKind::modified;
    c.name = std::move(n.name);
    c.object_class = ObjectClass(n.object_class);
    c.hash_before = n.existed ? n.hash_before : 0;
    c.hash_after = n.exists ? n.hash_after : 0;
    c.revision = n.revision;
    if (c.kind != ChangeKind::removed && !slot_of(id, c.slot, error)) return false;
    out.push_back(std::move(c));
  }
  return true;
}

bool ReadView::object_at(uint32_t revision, uint64_t id, Object& out, bool& found,
                         bool with_attributes, std::string& error) const {
  State& s = *state_;
  found = false;
  const uint32_t newest = info().revision;
  assert(revision <= newest && "object_at() of a revision after the view's");
  for (uint32_t n = revision + 1; n <= newest; ++n) {
    if (!changes_readable(s.txn.get(), s.store->dbs.revisions, s.store->directory, n, newest, error)) return false;
    detail::ChangeEntry change;
    bool changed;
    std::string why;
    if (!find_change(s.txn.get(), s.store->dbs.changes, s.dctx.get(), n, id, change, changed,
                     why)) {
      error = "store " + s.store->directory + ": the changes of revision " + std::to_string(n) +
              ": " + why;
      return false;
    }
    if (!changed) continue;
    if (change.kind == ChangeKind::added) return true;  // it did not exist then
    std::vector<uint8_t> raw;
    std::span<const uint8_t> record, attributes;
    bool in_block = false, listed = false;
    const std::string what = "store " + s.store->directory + ": the record of object " +
                             std::to_string(id) + " before revision " + std::to_string(n);
    bool ok = find_block(s.txn.get(), s.store->dbs.history, s.dctx.get(), n, id, raw, in_block,
                         why) &&
              (!in_block || detail::find_history(raw, id, record, attributes, listed, why));
    if (ok && !listed) ok = false, why = "missing from the history";
    ok = ok && detail::decode_object(record.data(), record.size(), out, why);
    if (ok && with_attributes) {
      ok = detail::decode_attributes(attributes.data(), attributes.size(), out.attributes, why);
    }
    if (!ok) {
      error = what + ": " + why;
      return false;
    }
    found = true;
    return true;
  }
  std::optional<uint32_t> slot;
  if (!slot_of(id, slot, error)) return false;
  if (!slot) return true;
  found = object(*slot, out, with_attributes, error);
  return found;
}

bool ReadView::content_hash(uint32_t slot, uint64_t& hash, std::string& error) const {
  State& s = *state_;
  std::span<const uint8_t> record;
  std::string why;
  bool ok = s.objects.record(s.txn.get(), s.dctx.get(), slot, record, why);
  if (ok && record.empty()) {
    error = "store " + s.store->directory + ": no object in slot " + std::to_string(slot);
    return false;
  }
  detail::ContentHasher hasher;
  if (ok) hasher.record(record);
  if (ok) ok = s.attributes.record(s.txn.get(), s.dctx.get(), slot, record, why);
  if (!ok) {
    error = "store " + s.store->directory + ": object slot " + std::to_string(slot) + ": " + why;
    return false;
  }
  hash = hasher.attributes(record);
  return true;
}

size_t ReadView::spatial_cache_bytes() const { return state_->snapshot->blocks.bytes(); }
size_t ReadView::chunk_cache_bytes() const { return state_->snapshot->object_chunks.bytes(); }
uint64_t ReadView::chunks_decompressed() const { return state_->objects.inflated(); }

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

namespace plantview {

uint64_t ReadView::commit() const { return uint64_t(mdb_txn_id(state_->txn.get())); }

uint64_t Store::last_commit() const {
  MDB_envinfo info;
  // mdb_env_info reads the newer of the two meta pages through the map: no lock, no system
  // call. It fails only for null arguments.
  if (mdb_env_info(state_->env.get(), &info) != MDB_SUCCESS) return 0;
  return uint64_t(info.me_last_txnid);
}

}  // namespace plantview
