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

void encode_change(const ChangeValue& change, std::string& out) {
  out.resize(18);
  out[0] = char(change.kind);
  out[1] = char(change.object_class);
  std::memcpy(out.data() + 2, &change.hash_before, 8);
  std::memcpy(out.data() + 10, &change.hash_after, 8);
  out.append(change.name);
}

bool decode_change(const MDB_val& v, ChangeValue& out) {
  if (v.mv_size < 18) return false;
  const auto* b = static_cast<const unsigned char*>(v.mv_data);
  if (b[0] > uint8_t(ChangeKind::modified) || b[1] >= kObjectClassCount) return false;
  out.kind = ChangeKind(b[0]);
  out.object_class = b[1];
  std::memcpy(&out.hash_before, b + 2, 8);
  std::memcpy(&out.hash_after, b + 10, 8);
  out.name = std::string_view(reinterpret_cast<const char*>(b + 18), v.mv_size - 18);
  return true;
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
