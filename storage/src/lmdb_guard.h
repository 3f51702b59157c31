// Internal: RAII for LMDB handles and error messages that name the store and the operation.
#pragma once

#include <lmdb.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace plantview::detail {

inline std::string lmdb_message(std::string_view directory, std::string_view what, int rc) {
  return "store " + std::string(directory) + ": " + std::string(what) + ": " + mdb_strerror(rc);
}

// Owns an MDB_env; closes it on destruction (after every transaction is gone).
class LmdbEnv {
 public:
  LmdbEnv() = default;
  ~LmdbEnv() {
    if (env_) mdb_env_close(env_);
  }
  LmdbEnv(const LmdbEnv&) = delete;
  LmdbEnv& operator=(const LmdbEnv&) = delete;
  MDB_env** out() { return &env_; }
  MDB_env* get() const { return env_; }
  void reset() {
    if (env_) mdb_env_close(env_);
    env_ = nullptr;
  }

 private:
  MDB_env* env_ = nullptr;
};

// A transaction that aborts unless committed.
class LmdbTxn {
 public:
  LmdbTxn() = default;
  ~LmdbTxn() { abort(); }
  LmdbTxn(const LmdbTxn&) = delete;
  LmdbTxn& operator=(const LmdbTxn&) = delete;
  int begin(MDB_env* env, unsigned flags) {
    abort();
    return mdb_txn_begin(env, nullptr, flags, &txn_);
  }
  int commit() {
    const int rc = mdb_txn_commit(txn_);
    txn_ = nullptr;  // committed or, on failure, freed by LMDB
    return rc;
  }
  void abort() {
    if (txn_) mdb_txn_abort(txn_);
    txn_ = nullptr;
  }
  MDB_txn* get() const { return txn_; }

 private:
  MDB_txn* txn_ = nullptr;
};

class LmdbCursor {
 public:
  LmdbCursor() = default;
  ~LmdbCursor() {
    if (cursor_) mdb_cursor_close(cursor_);
  }
  LmdbCursor(const LmdbCursor&) = delete;
  LmdbCursor& operator=(const LmdbCursor&) = delete;
  int open(MDB_txn* txn, MDB_dbi dbi) { return mdb_cursor_open(txn, dbi, &cursor_); }
  MDB_cursor* get() const { return cursor_; }

 private:
  MDB_cursor* cursor_ = nullptr;
};

// Pages of LMDB's file mapping. LMDB hands out values in place in its read-only mapping of the
// data file; every page read stays counted in the process's memory (RSS) until the kernel wants
// it back, and with MDB_NORDAHEAD the kernel reads only the pages touched, one fault at a time.
// Both calls are advice (failures are harmless) and work on whole pages, so neighbouring values
// on the edge pages are affected too. Only for values read in a read transaction: a write
// transaction may hand out its own copies of pages, which live in ordinary memory.

// Starts reading [data, data + size) from the file at once (a value about to be read whole).
inline void prefetch_map_pages(const void* data, size_t size) {
  static const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
  const uintptr_t begin = uintptr_t(data) & ~(page - 1);
  madvise(reinterpret_cast<void*>(begin), uintptr_t(data) + size - begin, MADV_WILLNEED);
}

// Takes the pages under [data, data + size) out of this process's resident set (a value read
// once: an index decoded, a chunk inflated into a cache). The page cache keeps them: reading
// them again maps them back in (a minor fault), for this or any other view.
// The range is widened to whole 64 KB windows: on a read fault the kernel also maps the pages
// around the one read that it has cached (fault-around, 64 KB by default), and those stayed
// counted in the resident set too (hundreds of MB over a walk of a 40 M-object store).
inline void release_map_pages(const void* data, size_t size) {
  constexpr uintptr_t kWindow = 64 * 1024;
  if (size == 0) return;
  const uintptr_t begin = uintptr_t(data) & ~(kWindow - 1);
  const uintptr_t end = (uintptr_t(data) + size + kWindow - 1) & ~(kWindow - 1);
  madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
}

inline MDB_val as_val(const void* data, size_t size) {
  return MDB_val{size, const_cast<void*>(data)};
}
inline MDB_val as_val(std::string_view s) { return as_val(s.data(), s.size()); }

// Big-endian keys sort numerically under LMDB's default memcmp order.
struct Key32 {
  unsigned char bytes[4];
  explicit Key32(uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes[i] = static_cast<unsigned char>(v >> (24 - 8 * i));
  }
  MDB_val val() const { return as_val(bytes, 4); }
};
struct Key64 {
  unsigned char bytes[8];
  explicit Key64(uint64_t v) {
    for (int i = 0; i < 8; ++i) bytes[i] = static_cast<unsigned char>(v >> (56 - 8 * i));
  }
  MDB_val val() const { return as_val(bytes, 8); }
};
inline uint32_t read_be32(const void* p) {
  const auto* b = static_cast<const unsigned char*>(p);
  return uint32_t(b[0]) << 24 | uint32_t(b[1]) << 16 | uint32_t(b[2]) << 8 | uint32_t(b[3]);
}

}  // namespace plantview::detail
