// Imports: beginning one, putting and removing objects (one LMDB write transaction each).
#include "plantview/store.h"

#include <bit>
#include <cassert>
#include <filesystem>

#include "import_state.h"
#include "record.h"

namespace plantview {

using detail::as_val;
using detail::lmdb_message;
using detail::name_hash;
using detail::read_statistics;
using detail::read_top;
using detail::read_next_slot;
using detail::IdEntry;
using detail::NameEntry;
using detail::index_slots;
using detail::SpatialItem;

namespace detail {

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

// The slot runs of a source (as committed, plus this import's), loaded on first use.
bool Import::State::source_runs(std::string_view source, std::vector<detail::SlotRun>*& out, std::string& error) {
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
bool Import::State::remove_slot(uint32_t slot, std::string& error) {
  if (is_removed(slot)) return true;
  clear_pending(slot);
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
  // A committed object's content hash, for the change list (one put by this import was not
  // there before it, and is left out).
  if (slot < first_new_slot) {
    hasher.record(record);  // (the span stays valid: attributes is another writer)
    std::span<const uint8_t> old_attributes;
    if (!attributes.get(txn.get(), slot, old_attributes, error)) return false;
    if (!add_change_item(removed_items, old, slot, hasher.attributes(old_attributes), error)) {
      return false;
    }
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
    const IdEntry id(old.id, slot, index_key_bits);
    MDB_val k = id.key_val(), v = id.value_val();
    int rc = mdb_del(txn.get(), store->dbs.ids, &k, &v);
    if (rc == MDB_NOTFOUND) rc = MDB_SUCCESS;  // the id is another slot's (or nobody's)
    if (rc == MDB_SUCCESS) {
      const NameEntry name(name_hash(old.name), slot, index_key_bits);
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

bool Import::State::committed_hash(uint32_t slot, uint64_t& hash, std::string& error) {
  if (!committed.get()) {
    const int rc = committed.begin(store->env.get(), MDB_RDONLY);
    if (rc != MDB_SUCCESS) {
      error = fail("starting a read of the committed records", rc);
      return false;
    }
  }
  std::span<const uint8_t> record, attribute_record;
  std::string why;
  bool ok = committed_objects.record(committed.get(), dctx.get(), slot, record, why);
  if (ok && record.empty()) ok = false, why = "indexed but holds no object";
  if (ok) hasher.record(record);  // (the span is valid until the next read of objects)
  if (ok) ok = committed_attributes.record(committed.get(), dctx.get(), slot, attribute_record, why);
  if (!ok) {
    error = message("object slot " + std::to_string(slot) + ": " + why);
    return false;
  }
  hash = hasher.attributes(attribute_record);
  return true;
}

bool Import::State::remove_pending(std::string& error) {
  for (size_t word = 0; word < pending_bits.size(); ++word) {
    while (pending_bits[word] != 0) {
      const uint32_t slot = uint32_t(word * 64 + size_t(std::countr_zero(pending_bits[word])));
      if (!remove_slot(slot, error)) return false;  // clears the bit
    }
  }
  return true;
}

// Compresses and stores `raw_value` under `key` of `dbi`.
bool Import::State::put_frame(MDB_dbi dbi, MDB_val key, const std::vector<uint8_t>& raw_value, unsigned flags,
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

bool Import::State::database_empty(MDB_dbi dbi, bool& empty, std::string& error) {
  MDB_stat stat;
  const int rc = mdb_stat(txn.get(), dbi, &stat);
  if (rc != MDB_SUCCESS) {
    error = fail("reading database statistics", rc);
    return false;
  }
  empty = stat.ms_entries == 0;
  return true;
}

bool Import::State::add_change_item(
    detail::SpilledRuns<detail::ChangeItem, detail::ChangeItemLess>& items, const Object& object,
    uint32_t slot, uint64_t hash, std::string& error) {
  detail::ChangeItem item;
  item.id = object.id;
  item.hash = hash;
  item.slot = slot;
  item.object_class = uint8_t(object.object_class);
  item.name_bytes = uint32_t(object.name.size());
  std::string why;
  if (!change_names.add(object.name, item.name_at, why) || !items.add(item, why)) {
    error = message(why);
    return false;
  }
  return true;
}

Import::Import(std::unique_ptr<State> state) : state_(std::move(state)) {}

void Import::set_note(std::string note) { state_->note = std::move(note); }

void Import::set_keep_revisions(uint32_t revisions) {
  assert(revisions >= 1 && "set_keep_revisions(0)");
  state_->keep_revisions = revisions < 1 ? 1 : revisions;
}
Import::~Import() = default;
uint64_t Import::objects_put() const { return state_->put_count; }
const ModelStatistics& Import::put_statistics() const { return state_->put_statistics; }

bool Import::remove_source(std::string_view source, std::string& error) {
  State& s = *state_;
  assert(s.txn.get() && "remove_source() on a spent Import");
  std::vector<detail::SlotRun>* runs;
  if (!s.source_runs(source, runs, error)) return false;
  // Committed slots wait for the commit (put() keeps those put again unchanged); this import's
  // go now. remove_slot may load other sources (never this one again), which leaves `runs` in
  // place.
  const std::vector<detail::SlotRun> copy = *runs;
  for (const detail::SlotRun& r : copy) {
    for (uint32_t slot = r.first; slot < r.first + r.length; ++slot) {
      if (slot < s.first_new_slot) {
        if (!s.is_removed(slot)) s.mark_pending(slot);
      } else if (!s.remove_slot(slot, error)) {
        return false;
      }
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
  // The object's statistics, whose bounds are its object_bounds() (computed once).
  ModelStatistics part;
  part.add(object);
  detail::encode_object(object, s.raw);
  detail::encode_attributes(object.attributes, s.raw_attributes);
  const uint64_t hash = detail::content_hash(s.raw, s.raw_attributes);
  // An object committed with the same id (in the ids: not removed, maybe pending) stays where it
  // is when its content is the same, and is replaced otherwise (one put twice in this import is
  // resolved at commit: the later wins).
  {
    const int rc = index_slots<64>(s.txn.get(), s.store->dbs.ids, s.index_key_bits, object.id,
                                   s.slots, 1);
    if (rc != MDB_SUCCESS) {
      error = s.fail("looking up id " + std::to_string(object.id), rc);
      return false;
    }
    if (!s.slots.empty()) {
      const uint32_t committed = s.slots[0];
      uint64_t committed_hash;
      if (!s.committed_hash(committed, committed_hash, error)) return false;
      if (committed_hash == hash) {
        // Kept: nothing written, no change. The hash covers the source, so the slot is in this
        // source's runs already (loaded here so that they are written again at commit).
        s.clear_pending(committed);
        std::vector<detail::SlotRun>* runs;
        if (!s.source_runs(object.source, runs, error)) return false;
        s.put_statistics.add_counts(part);
        s.put_statistics.bounds.extend(part.bounds);
        ++s.put_count;
        return true;
      }
      if (!s.remove_slot(committed, error)) return false;
    }
  }
  const uint32_t slot = s.next_slot;
  // Bounds first: an object the grid cannot hold is refused before anything of it is written.
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
  s.digest(slot);
  s.digest(s.raw);
  if (!s.objects.put(s.txn.get(), slot, std::move(s.raw), error)) return false;
  s.digest(s.raw_attributes);
  if (!s.attributes.put(s.txn.get(), slot, std::move(s.raw_attributes), error)) return false;
  if (!s.add_change_item(s.put_items, object, slot, hash, error)) return false;
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

std::unique_ptr<Import> Store::begin_import(std::string& error) {
  if (state_->mode == Mode::read_only) {
    error = "store " + state_->directory + ": opened read-only";
    return nullptr;
  }
  auto s = std::make_unique<Import::State>(state_, detail::import_run_bytes());
  if (!s->writer_lock.acquire(state_->directory, error)) return nullptr;
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
  if (!detail::read_index_key_bits(txn, state_->dbs.meta, s->index_key_bits)) {
    error = "store " + state_->directory + ": meta/\"index_key_bits\" is damaged";
    return nullptr;
  }
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

}  // namespace plantview
