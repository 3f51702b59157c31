// An import's commit: the runs merged into the ids, names and spatial blocks, the sources,
// the top and the meta keys, then one LMDB commit.
#include "plantview/store.h"

#include <algorithm>
#include <cassert>

#include "import_state.h"

namespace plantview {

using detail::as_val;
using detail::lmdb_message;
using detail::mix_digest;
using detail::read_commit_id;
using detail::Databases;
using detail::read_top;
using detail::IdEntry;
using detail::NameEntry;
using detail::IndexAppender;
using detail::IdSlot;
using detail::HashSlot;
using detail::SpatialItem;
using detail::SpatialItemLess;

bool Import::State::rekey_indexes(std::string& error) {
  const Databases& dbs = store->dbs;
  bool ids_empty, names_empty;
  if (!database_empty(dbs.ids, ids_empty, error) ||
      !database_empty(dbs.names, names_empty, error)) {
    return false;
  }
  const bool empty = ids_empty && names_empty;
  const unsigned bits = detail::index_key_bits(totals.objects, empty ? 0 : index_key_bits);
  if (bits == index_key_bits) return true;
  if (empty) {
    index_key_bits = bits;
    return true;
  }
  // Entries are read in place from the map (clean file pages, which the kernel may drop) or
  // from the pages this transaction changed. (LMDB names its map's address only for a fixed
  // map, so which is which cannot be told here: no page is given back early.)
  const auto move = [&](MDB_dbi dbi, const char* what, auto decode_add) {
    detail::LmdbCursor cursor;
    int rc = cursor.open(txn.get(), dbi);
    MDB_val k, v;
    if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_FIRST);
    while (rc == MDB_SUCCESS) {
      std::string why;
      if (!decode_add(k, v, why)) {
        error = message(std::string("re-keying the ") + what + ": " + why);
        return false;
      }
      rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_NEXT);
    }
    if (rc == MDB_NOTFOUND) rc = mdb_drop(txn.get(), dbi, 0);
    if (rc != MDB_SUCCESS) error = fail(std::string("re-keying the ") + what, rc);
    return rc == MDB_SUCCESS;
  };
  const unsigned old_bits = index_key_bits;
  const auto malformed = [&](std::string& why) {
    why = "an entry of another size than keys of " + std::to_string(old_bits) + " bits make";
    return false;
  };
  const bool moved =
      move(dbs.ids, "ids",
           [&](const MDB_val& k, const MDB_val& v, std::string& why) {
             IdSlot e{};
             if (!IdEntry::decode(k, v, old_bits, e.id, e.slot)) return malformed(why);
             return new_ids.add(e, why);
           }) &&
      move(dbs.names, "names", [&](const MDB_val& k, const MDB_val& v, std::string& why) {
        HashSlot e{};
        uint64_t hash;
        if (!NameEntry::decode(k, v, old_bits, hash, e.slot)) return malformed(why);
        e.hash = uint32_t(hash);
        return new_names.add(e, why);
      });
  if (moved) index_key_bits = bits;
  return moved;
}

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
    const int rc = out.put(IdEntry(e.id, e.slot, index_key_bits));
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
    const int rc = out.put(NameEntry(e.hash, e.slot, index_key_bits));
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

bool Import::commit(std::string& error) {
  assert(state_->txn.get() && "commit() on a spent Import");
  // Spent either way: a failed commit leaves the store as it was.
  const bool ok = state_->commit(error);
  state_->txn.abort();
  state_->writer_lock.release();
  return ok;
}

bool Import::State::commit(std::string& error) {
  State& s = *this;
  const Databases& dbs = s.store->dbs;
  // The pending removals first (the statistics and the ids as they stand, for rekey_indexes),
  // then the ids: resolving an id put twice removes slots, which the other merges then leave out.
  if (!s.remove_pending(error)) return false;
  s.committed.abort();
  if (!s.rekey_indexes(error) || !s.merge_ids(error)) return false;
  detail::import_stage("ids merged");
  if (!s.write_revision(error)) return false;
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
  const uint32_t key_bits = s.index_key_bits;
  const uint64_t commit_id = mix_digest(read_commit_id(s.txn.get(), dbs.meta), s.changes_digest);
  if (!put_meta("statistics", stats.data(), stats.size()) ||
      !put_meta("next_slot", &s.next_slot, sizeof s.next_slot) ||
      !put_meta("index_key_bits", &key_bits, sizeof key_bits) ||
      !put_meta("format", &version, sizeof version) ||
      !put_meta("commit_id", &commit_id, sizeof commit_id)) {
    return false;
  }
  const int rc = s.txn.commit();
  if (rc != MDB_SUCCESS) {
    error = s.fail("committing the import", rc);
    return false;
  }
  // The commit stands whatever this says (Import::commit() is false only for a store left as it
  // was): a file it could not extend is refused by the next open(), naming the size it needs.
  std::string ignored;
  detail::cover_free_tail(s.store->env.get(), s.store->directory, ignored);
  return true;
}

}  // namespace plantview
