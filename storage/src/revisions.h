// Internal: revisions (store.h, "Revisions"): content hashes, the values of the revisions,
// changes and history databases, and what an import gathers for them in bounded memory.
#pragma once

#include <lmdb.h>
// XXH3_state_t as a complete type (a member, not a heap allocation per hasher).
#define XXH_STATIC_LINKING_ONLY
#include <xxhash.h>

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lmdb_guard.h"
#include "plantview/store.h"

namespace plantview::detail {

// The content hash of an object: XXH3-64 of its encoded record then its encoded attributes.
uint64_t content_hash(std::span<const uint8_t> record, std::span<const uint8_t> attributes);
// The same in two steps (the record, then its attributes), without keeping the record.
class ContentHasher {
 public:
  void record(std::span<const uint8_t> bytes) {
    XXH3_64bits_reset(&state_);
    XXH3_64bits_update(&state_, bytes.data(), bytes.size());
  }
  uint64_t attributes(std::span<const uint8_t> bytes) {
    XXH3_64bits_update(&state_, bytes.data(), bytes.size());
    return XXH3_64bits_digest(&state_);
  }

 private:
  XXH3_state_t state_{};
};

// An object an import put, or a committed object it removed: what the change list needs of it.
// The name lies in the import's NameLog at [name_at, name_at + name_bytes).
struct ChangeItem {
  uint64_t id = 0, hash = 0, name_at = 0;
  uint32_t slot = 0, name_bytes = 0;
  uint8_t object_class = 0;
  uint8_t unused[7] = {};
};
struct ChangeItemLess {
  bool operator()(const ChangeItem& a, const ChangeItem& b) const {
    return a.id != b.id ? a.id < b.id : a.slot < b.slot;
  }
};

// The names of an import's ChangeItems, appended to a file in the store directory
// (import-<pid>-changenames.run: removed with the other runs) through a buffer of 1 MB.
class NameLog {
 public:
  explicit NameLog(std::string directory) : directory_(std::move(directory)) {}
  ~NameLog();
  NameLog(const NameLog&) = delete;
  NameLog& operator=(const NameLog&) = delete;
  // Where `name` went; false with a message naming the file on a write error.
  bool add(std::string_view name, uint64_t& at, std::string& error);
  bool get(uint64_t at, uint32_t bytes, std::string& out, std::string& error);

 private:
  bool flush(std::string& error);
  std::string directory_, path_;
  int fd_ = -1;
  uint64_t flushed_ = 0;  // bytes in the file
  std::string buffer_;
};

// Keys of changes/ and history/: u32 revision, u64 id (big-endian).
struct ChangeKey {
  unsigned char bytes[12];
  ChangeKey(uint32_t revision, uint64_t id);
  MDB_val val() const { return as_val(bytes, sizeof bytes); }
  static bool decode(const MDB_val& k, uint32_t& revision, uint64_t& id);
};

// changes/ holds each revision's changes in id order, in blocks of up to kChangesPerBlock
// entries keyed by (revision, first id): a zstd frame of entries, each u64 id, u8 kind, u8
// class, u64 hash before (not for added), u64 hash after (not for removed), u32 name bytes, the
// name (little-endian). Ids and hashes do not compress; blocks spare LMDB's 20-odd bytes a key.
inline constexpr size_t kChangesPerBlock = 256;
struct ChangeEntry {
  uint64_t id = 0;
  ChangeKind kind = ChangeKind::added;
  uint8_t object_class = 0;
  uint64_t hash_before = 0, hash_after = 0;
  std::string name;
};
void append_change(uint64_t id, ChangeKind kind, uint8_t object_class, uint64_t hash_before,
                   uint64_t hash_after, std::string_view name, std::vector<uint8_t>& block);
// The entries of an inflated block; false with `why` when it is malformed.
bool decode_change_block(const std::vector<uint8_t>& block, std::vector<ChangeEntry>& out,
                         std::string& why);

// history/ holds the previous records of a revision's removed and modified objects in id order,
// in blocks keyed by (revision, first id): a zstd frame of up to kHistoryPerBlock entries (cut
// after kHistoryBlockBytes), each u64 id, u32 record bytes, u32 attribute bytes, the record,
// the attribute record. Compressed together, about as small as the objects' own chunks.
inline constexpr size_t kHistoryPerBlock = 256;
inline constexpr size_t kHistoryBlockBytes = size_t(64) << 10;
// The record and attribute record of `id` in an inflated history block (`found` false when it
// is not there); false with `why` when the block is malformed.
bool find_history(const std::vector<uint8_t>& block, uint64_t id, std::span<const uint8_t>& record,
                  std::span<const uint8_t>& attributes, bool& found, std::string& why);

// A revisions/ value. `changes_unknown`: a revision made by upgrading a format 5 store, whose
// changes were never recorded.
std::string revision_json(const Revision& revision, bool changes_unknown);
bool revision_from_json(std::string_view text, Revision& out, bool& changes_unknown,
                        std::string& why);

// The newest revision in `dbi` (revisions/): `found` false when there is none. False with
// `why` on an LMDB error or a damaged value.
bool read_last_revision(MDB_txn* txn, MDB_dbi dbi, Revision& out, bool& found, std::string& why);
// Revision `number`: `found` false when there is none.
bool read_revision(MDB_txn* txn, MDB_dbi dbi, uint32_t number, Revision& out,
                   bool& changes_unknown, bool& found, std::string& why);

int64_t now_unix_ms();

struct Databases;
// Makes a format 5 store format 6 in `txn` (its databases open): revision 1, "upgraded from
// format 5", whose changes are unknown, and meta/"format". False with a message naming the store.
bool upgrade_from_format_5(MDB_txn* txn, const Databases& dbs, const std::string& directory,
                           uint64_t objects, std::string& error);

}  // namespace plantview::detail
