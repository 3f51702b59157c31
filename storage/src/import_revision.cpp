// An import's revision (store.h, "Revisions"): the change list, found by merging what the
// import put with what it removed by id; the previous records of what it removed or modified;
// pruning the change lists of old revisions; the revision itself.
#include <cstring>

#include "import_state.h"

namespace plantview {

using detail::ChangeItem;
using detail::ChangeKey;

namespace {
// Chunks of the previous state a commit keeps decompressed while it copies previous records.
constexpr size_t kBeforeChunks = 8;
constexpr size_t kBeforeChunkBytes = size_t(16) << 20;
}  // namespace

bool Import::State::write_revision(std::string& error) {
  const detail::Databases& dbs = store->dbs;
  MDB_txn* t = txn.get();
  std::string why;
  Revision last, revision;
  bool found;
  if (!detail::read_last_revision(t, dbs.revisions, last, found, why)) {
    error = message("revisions: " + why);
    return false;
  }
  revision.number = found ? last.number + 1 : 1;
  revision.note = note;
  revision.keep_revisions = keep_revisions;

  // The previous records come from a read transaction on the state this import began from (no
  // commit can come between: this transaction holds the writer lock). Begun when first needed,
  // ended with this function.
  detail::LmdbTxn before;
  detail::ChunkCache before_objects(dbs.objects, kBeforeChunks, kBeforeChunkBytes);
  detail::ChunkCache before_attributes(dbs.attributes, kBeforeChunks, kBeforeChunkBytes);
  detail::ZstdDCtx before_dctx(ZSTD_createDCtx());
  std::vector<uint8_t> history;
  std::string after_name, before_name;

  // The change list, a block of kChangesPerBlock entries at a time (revisions.h).
  std::vector<uint8_t> block;
  uint64_t block_first = 0;
  size_t block_entries = 0;
  const auto flush_block = [&]() {
    if (block_entries == 0) return true;
    const ChangeKey key(revision.number, block_first);
    block_entries = 0;
    return put_frame(dbs.changes, key.val(), block, MDB_APPEND,
                     "the changes of revision " + std::to_string(revision.number), error);
  };
  // The previous records, in blocks too (revisions.h).
  uint64_t history_first = 0;
  size_t history_entries = 0;
  const auto flush_history = [&]() {
    if (history_entries == 0) return true;
    const ChangeKey key(revision.number, history_first);
    history_entries = 0;
    return put_frame(dbs.history, key.val(), history, MDB_APPEND,
                     "the previous records of revision " + std::to_string(revision.number), error);
  };
  const auto emit = [&](ChangeKind kind, const ChangeItem* was, const ChangeItem* now) {
    const ChangeItem& named = now ? *now : *was;
    std::string& name = now ? after_name : before_name;
    if (!change_names.get(named.name_at, named.name_bytes, name, why)) {
      error = message(why);
      return false;
    }
    if (block_entries == 0) {
      block.clear();
      block_first = named.id;
    }
    detail::append_change(named.id, kind, named.object_class, was ? was->hash : 0,
                          now ? now->hash : 0, name, block);
    if (++block_entries == detail::kChangesPerBlock && !flush_block()) return false;
    if (kind == ChangeKind::added) return true;
    // The previous record and attributes, as committed.
    if (!before.get()) {
      const int rc = before.begin(store->env.get(), MDB_RDONLY);
      if (rc != MDB_SUCCESS) {
        error = fail("starting a read of the previous revision", rc);
        return false;
      }
    }
    std::span<const uint8_t> record, old_attributes;
    bool ok = before_objects.record(before.get(), before_dctx.get(), was->slot, record, why);
    if (ok && record.empty()) ok = false, why = "no record";
    if (history_entries == 0) {
      history.clear();
      history_first = was->id;
    }
    const size_t at = history.size();
    history.resize(at + 16);
    const uint32_t record_bytes = uint32_t(record.size());
    std::memcpy(history.data() + at, &was->id, 8);
    std::memcpy(history.data() + at + 8, &record_bytes, 4);
    history.insert(history.end(), record.begin(), record.end());
    if (ok) ok = before_attributes.record(before.get(), before_dctx.get(), was->slot, old_attributes, why);
    if (!ok) {
      error = message("the previous record of object " + std::to_string(was->id) + " (slot " +
                      std::to_string(was->slot) + "): " + why);
      return false;
    }
    const uint32_t attribute_bytes = uint32_t(old_attributes.size());
    std::memcpy(history.data() + at + 12, &attribute_bytes, 4);
    history.insert(history.end(), old_attributes.begin(), old_attributes.end());
    ++history_entries;
    return (history_entries < detail::kHistoryPerBlock &&
            history.size() < detail::kHistoryBlockBytes) ||
           flush_history();
  };

  // Both lists in id order: an id is removed at most once (a slot is), and of the puts only the
  // last of an id stands (merge_ids removed the others).
  decltype(put_items)::Merger puts(put_items);
  decltype(removed_items)::Merger removals(removed_items);
  if (!puts.start(why) || !removals.start(why)) {
    error = message("merging the changes: " + why);
    return false;
  }
  ChangeItem p{}, r{};
  bool done_p = false, done_r = false;
  const auto next_put = [&]() {
    while (puts.next(p, done_p, why)) {
      if (!is_removed(p.slot)) return true;
    }
    return false;
  };
  bool have_p = next_put(), have_r = removals.next(r, done_r, why);
  for (;;) {
    if ((!have_p && !done_p) || (!have_r && !done_r)) {
      error = message("merging the changes: " + why);
      return false;
    }
    if (!have_p && !have_r) break;
    if (have_p && have_r && p.id == r.id) {
      if (p.hash != r.hash) {
        if (!emit(ChangeKind::modified, &r, &p)) return false;
        ++revision.modified;
      }
      have_p = next_put();
      have_r = removals.next(r, done_r, why);
    } else if (have_r && (!have_p || r.id < p.id)) {
      if (!emit(ChangeKind::removed, &r, nullptr)) return false;
      ++revision.removed;
      have_r = removals.next(r, done_r, why);
    } else {
      if (!emit(ChangeKind::added, nullptr, &p)) return false;
      ++revision.added;
      have_p = next_put();
    }
  }
  if (!flush_block() || !flush_history()) return false;
  before.abort();

  // Pruning: revisions up to `limit` keep no changes any more.
  if (revision.number > keep_revisions) {
    const uint32_t limit = revision.number - keep_revisions;
    for (MDB_dbi dbi : {dbs.changes, dbs.history}) {
      detail::LmdbCursor cursor;
      int rc = cursor.open(t, dbi);
      MDB_val k, v;
      uint32_t number;
      uint64_t id;
      while (rc == MDB_SUCCESS) {
        rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_FIRST);
        if (rc != MDB_SUCCESS) break;
        if (!ChangeKey::decode(k, number, id) || number > limit) break;
        rc = mdb_cursor_del(cursor.get(), 0);
      }
      if (rc != MDB_SUCCESS && rc != MDB_NOTFOUND) {
        error = fail("pruning the changes of revisions up to " + std::to_string(limit), rc);
        return false;
      }
    }
    for (uint32_t n = limit; n >= 1; --n) {
      Revision old;
      bool unknown, exists;
      if (!detail::read_revision(t, dbs.revisions, n, old, unknown, exists, why)) {
        error = message("revisions: " + why);
        return false;
      }
      if (!exists || !old.changes_kept) break;
      old.changes_kept = false;
      const std::string json = detail::revision_json(old, unknown);
      const detail::Key32 key(n);
      MDB_val k = key.val(), v = detail::as_val(json);
      const int rc = mdb_put(t, dbs.revisions, &k, &v, 0);
      if (rc != MDB_SUCCESS) {
        error = fail("writing revision " + std::to_string(n), rc);
        return false;
      }
    }
  }

  for (const auto& [source, runs] : sources) revision.sources.push_back(source);
  revision.objects = totals.objects;
  revision.time_unix_ms = detail::now_unix_ms();
  const std::string json = detail::revision_json(revision, false);
  const detail::Key32 key(revision.number);
  MDB_val k = key.val(), v = detail::as_val(json);
  const int rc = mdb_put(t, dbs.revisions, &k, &v, MDB_APPEND);
  if (rc != MDB_SUCCESS) {
    error = fail("writing revision " + std::to_string(revision.number), rc);
    return false;
  }
  return true;
}

}  // namespace plantview
