// Revisions: content hashes, the values of revisions/, changes/ and history/, and the name log
// of an import's changes (revisions.h).
#include "revisions.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "store_internal.h"

namespace plantview {

std::string_view change_kind_name(ChangeKind kind) {
  switch (kind) {
    case ChangeKind::added: return "added";
    case ChangeKind::removed: return "removed";
    case ChangeKind::modified: return "modified";
  }
  return "?";
}

namespace detail {

uint64_t content_hash(std::span<const uint8_t> record, std::span<const uint8_t> attributes) {
  ContentHasher hasher;
  hasher.record(record);
  return hasher.attributes(attributes);
}

NameLog::~NameLog() {
  if (fd_ < 0) return;
  ::close(fd_);
  std::error_code ec;
  std::filesystem::remove(path_, ec);
}

bool NameLog::flush(std::string& error) {
  if (buffer_.empty()) return true;
  if (fd_ < 0) {
    path_ = directory_ + "/import-" + std::to_string(::getpid()) + "-changenames.run";
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd_ < 0) {
      error = "creating " + path_ + ": " + std::strerror(errno);
      return false;
    }
  }
  const char* p = buffer_.data();
  size_t left = buffer_.size();
  while (left > 0) {
    const ssize_t wrote = ::pwrite(fd_, p, left, off_t(flushed_ + uint64_t(p - buffer_.data())));
    if (wrote < 0 && errno == EINTR) continue;
    if (wrote <= 0) {
      error = "writing " + path_ + ": " + std::strerror(errno);
      return false;
    }
    p += wrote;
    left -= size_t(wrote);
  }
  flushed_ += buffer_.size();
  buffer_.clear();
  return true;
}

bool NameLog::add(std::string_view name, uint64_t& at, std::string& error) {
  constexpr size_t kBufferBytes = size_t(1) << 20;
  at = flushed_ + buffer_.size();
  buffer_.append(name);
  return buffer_.size() < kBufferBytes || flush(error);
}

bool NameLog::get(uint64_t at, uint32_t bytes, std::string& out, std::string& error) {
  out.resize(bytes);
  if (at >= flushed_) {
    std::memcpy(out.data(), buffer_.data() + (at - flushed_), bytes);
    return true;
  }
  if (at + bytes > flushed_ && !flush(error)) return false;  // straddles the buffer: write it
  size_t done = 0;
  while (done < bytes) {
    const ssize_t got = ::pread(fd_, out.data() + done, bytes - done, off_t(at + done));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      error = "reading " + path_ + ": " + (got < 0 ? std::strerror(errno) : "cut short");
      return false;
    }
    done += size_t(got);
  }
  return true;
}

ChangeKey::ChangeKey(uint32_t revision, uint64_t id) {
  for (int i = 0; i < 4; ++i) bytes[i] = static_cast<unsigned char>(revision >> (24 - 8 * i));
  for (int i = 0; i < 8; ++i) bytes[4 + i] = static_cast<unsigned char>(id >> (56 - 8 * i));
}

bool ChangeKey::decode(const MDB_val& k, uint32_t& revision, uint64_t& id) {
  if (k.mv_size != 12) return false;
  const auto* b = static_cast<const unsigned char*>(k.mv_data);
  revision = read_be32(b);
  id = 0;
  for (int i = 0; i < 8; ++i) id = id << 8 | b[4 + i];
  return true;
}

void append_change(uint64_t id, ChangeKind kind, uint8_t object_class, uint64_t hash_before,
                   uint64_t hash_after, std::string_view name, std::vector<uint8_t>& block) {
  const auto put = [&](const void* data, size_t bytes) {
    const auto* p = static_cast<const uint8_t*>(data);
    block.insert(block.end(), p, p + bytes);
  };
  put(&id, 8);
  block.push_back(uint8_t(kind));
  block.push_back(object_class);
  if (kind != ChangeKind::added) put(&hash_before, 8);
  if (kind != ChangeKind::removed) put(&hash_after, 8);
  const uint32_t name_bytes = uint32_t(name.size());
  put(&name_bytes, 4);
  put(name.data(), name.size());
}

bool decode_change_block(const std::vector<uint8_t>& block, std::vector<ChangeEntry>& out,
                         std::string& why) {
  out.clear();
  size_t at = 0;
  const auto get = [&](void* data, size_t bytes) {
    if (block.size() - at < bytes) return false;
    std::memcpy(data, block.data() + at, bytes);
    at += bytes;
    return true;
  };
  while (at < block.size()) {
    ChangeEntry e;
    uint8_t kind = 0;
    uint32_t name_bytes = 0;
    bool ok = get(&e.id, 8) && get(&kind, 1) && get(&e.object_class, 1) &&
              kind <= uint8_t(ChangeKind::modified) && e.object_class < kObjectClassCount;
    e.kind = ChangeKind(kind);
    if (ok && e.kind != ChangeKind::added) ok = get(&e.hash_before, 8);
    if (ok && e.kind != ChangeKind::removed) ok = get(&e.hash_after, 8);
    ok = ok && get(&name_bytes, 4) && block.size() - at >= name_bytes;
    if (!ok) {
      why = "a malformed change entry at byte " + std::to_string(at);
      return false;
    }
    e.name.assign(reinterpret_cast<const char*>(block.data() + at), name_bytes);
    at += name_bytes;
    out.push_back(std::move(e));
  }
  return true;
}

bool find_history(const std::vector<uint8_t>& block, uint64_t id, std::span<const uint8_t>& record,
                  std::span<const uint8_t>& attributes, bool& found, std::string& why) {
  found = false;
  size_t at = 0;
  while (at < block.size()) {
    uint64_t entry_id;
    uint32_t record_bytes, attribute_bytes;
    if (block.size() - at < 16) break;
    std::memcpy(&entry_id, block.data() + at, 8);
    std::memcpy(&record_bytes, block.data() + at + 8, 4);
    std::memcpy(&attribute_bytes, block.data() + at + 12, 4);
    at += 16;
    if (block.size() - at < uint64_t(record_bytes) + attribute_bytes) break;
    if (entry_id == id) {
      record = std::span(block.data() + at, record_bytes);
      attributes = std::span(block.data() + at + record_bytes, attribute_bytes);
      found = true;
      return true;
    }
    at += uint64_t(record_bytes) + attribute_bytes;
  }
  if (at == block.size()) return true;
  why = "a malformed entry at byte " + std::to_string(at);
  return false;
}

std::string revision_json(const Revision& r, bool changes_unknown) {
  nlohmann::json j;
  j["number"] = r.number;
  j["time_unix_ms"] = r.time_unix_ms;
  j["sources"] = r.sources;
  j["note"] = r.note;
  j["added"] = r.added;
  j["removed"] = r.removed;
  j["modified"] = r.modified;
  j["objects"] = r.objects;
  j["changes_kept"] = r.changes_kept;
  j["keep_revisions"] = r.keep_revisions;
  if (changes_unknown) j["changes_unknown"] = true;
  return j.dump();
}

bool revision_from_json(std::string_view text, Revision& r, bool& changes_unknown,
                        std::string& why) {
  r = Revision{};
  changes_unknown = false;
  const auto j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    why = "not a JSON object";
    return false;
  }
  try {
    r.number = j.at("number").get<uint32_t>();
    r.time_unix_ms = j.at("time_unix_ms").get<int64_t>();
    r.sources = j.at("sources").get<std::vector<std::string>>();
    r.note = j.at("note").get<std::string>();
    r.added = j.at("added").get<uint64_t>();
    r.removed = j.at("removed").get<uint64_t>();
    r.modified = j.at("modified").get<uint64_t>();
    r.objects = j.at("objects").get<uint64_t>();
    r.changes_kept = j.at("changes_kept").get<bool>();
    r.keep_revisions = j.value("keep_revisions", kDefaultKeepRevisions);
    changes_unknown = j.value("changes_unknown", false);
  } catch (const nlohmann::json::exception& e) {
    why = e.what();
    return false;
  }
  return true;
}

namespace {
bool decode_revision_value(const MDB_val& v, Revision& out, bool& changes_unknown,
                           std::string& why) {
  return revision_from_json(std::string_view(static_cast<const char*>(v.mv_data), v.mv_size),
                            out, changes_unknown, why);
}
}  // namespace

bool read_last_revision(MDB_txn* txn, MDB_dbi dbi, Revision& out, bool& found, std::string& why) {
  found = false;
  LmdbCursor cursor;
  int rc = cursor.open(txn, dbi);
  MDB_val k, v;
  if (rc == MDB_SUCCESS) rc = mdb_cursor_get(cursor.get(), &k, &v, MDB_LAST);
  if (rc == MDB_NOTFOUND) return true;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return false;
  }
  bool unknown;
  if (!decode_revision_value(v, out, unknown, why)) {
    why = "revision " + std::to_string(k.mv_size == 4 ? read_be32(k.mv_data) : 0) + ": " + why;
    return false;
  }
  found = true;
  return true;
}

bool read_revision(MDB_txn* txn, MDB_dbi dbi, uint32_t number, Revision& out,
                   bool& changes_unknown, bool& found, std::string& why) {
  const Key32 key(number);
  MDB_val k = key.val(), v;
  const int rc = mdb_get(txn, dbi, &k, &v);
  found = rc == MDB_SUCCESS;
  if (rc == MDB_NOTFOUND) return true;
  if (rc != MDB_SUCCESS) {
    why = mdb_strerror(rc);
    return false;
  }
  if (!decode_revision_value(v, out, changes_unknown, why)) {
    why = "revision " + std::to_string(number) + ": " + why;
    return false;
  }
  return true;
}

int64_t now_unix_ms() {
  // Reproducible stores (the reproducible-builds convention): a fixed time, in seconds.
  if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH"); epoch && *epoch) {
    char* end = nullptr;
    const long long seconds = std::strtoll(epoch, &end, 10);
    if (end && *end == '\0') return int64_t(seconds) * 1000;
  }
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool upgrade_from_format_5(MDB_txn* txn, const Databases& dbs, const std::string& directory,
                           uint64_t objects, std::string& error) {
  Revision revision;
  revision.number = 1;
  revision.time_unix_ms = now_unix_ms();
  revision.note = "upgraded from format 5";
  revision.objects = objects;
  revision.changes_kept = false;
  const std::string json = revision_json(revision, true);
  const Key32 key(1);
  MDB_val k = key.val(), v = as_val(json);
  int rc = mdb_put(txn, dbs.revisions, &k, &v, 0);
  const uint32_t version = kStoreFormatVersion;
  MDB_val fk = as_val("format"), fv = as_val(&version, sizeof version);
  if (rc == MDB_SUCCESS) rc = mdb_put(txn, dbs.meta, &fk, &fv, 0);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "upgrading from format 5", rc);
    return false;
  }
  return true;
}

}  // namespace detail
}  // namespace plantview
