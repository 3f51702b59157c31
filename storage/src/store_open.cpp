// Opening a store: the environment, its checks (the data file's length, the format, the
// statistics) and the named databases.
#include "plantview/store.h"

#include <cerrno>
#include <cstring>
#include <filesystem>

#include <sys/stat.h>
#include <unistd.h>

#include "revisions.h"
#include "store_internal.h"
#include "writer_lock.h"

namespace plantview {

using detail::as_val;
using detail::lmdb_message;
using detail::read_statistics;
using detail::Databases;
using detail::kIndexFlags;
using detail::data_file_complete;

namespace {

constexpr size_t kMapSizeBytes = size_t(1) << 40;  // address space only; the file grows as used

}  // namespace

namespace detail {

namespace {

// The data file's length and the bytes its pages in use need (LMDB's last page number + 1
// pages); `fd` gets the file. An LMDB or system error code, or MDB_SUCCESS.
struct DataFileSize {
  uint64_t file_bytes = 0, needed_bytes = 0, last_page = 0, page_bytes = 0;
  mdb_filehandle_t fd{};
};
int measure_data_file(MDB_env* env, DataFileSize& out) {
  MDB_envinfo info;
  MDB_stat stat;
  struct stat file;
  int rc = mdb_env_info(env, &info);
  if (rc == MDB_SUCCESS) rc = mdb_env_stat(env, &stat);
  if (rc == MDB_SUCCESS) rc = mdb_env_get_fd(env, &out.fd);
  if (rc == MDB_SUCCESS && fstat(out.fd, &file) != 0) rc = errno;
  if (rc != MDB_SUCCESS) return rc;
  out.file_bytes = uint64_t(file.st_size);
  out.last_page = info.me_last_pgno;
  out.page_bytes = stat.ms_psize;
  out.needed_bytes = (out.last_page + 1) * out.page_bytes;
  return MDB_SUCCESS;
}

}  // namespace

bool data_file_complete(MDB_env* env, const std::string& directory, std::string& error) {
  DataFileSize size;
  if (const int rc = measure_data_file(env, size); rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "checking the size of data.mdb", rc);
    return false;
  }
  if (size.file_bytes >= size.needed_bytes) return true;
  error = "store " + directory + ": " +
          (std::filesystem::path(directory) / "data.mdb").string() + " is truncated: " +
          std::to_string(size.file_bytes) + " bytes, but its pages in use (0 to " +
          std::to_string(size.last_page) + ", " + std::to_string(size.page_bytes) +
          " bytes each) need " + std::to_string(size.needed_bytes) +
          " (a partial copy, or a disk that was full)";
  return false;
}

bool cover_free_tail(MDB_env* env, const std::string& directory, std::string& error) {
  DataFileSize size;
  int rc = measure_data_file(env, size);
  if (rc == MDB_SUCCESS && size.file_bytes < size.needed_bytes &&
      ftruncate(size.fd, off_t(size.needed_bytes)) != 0)
    rc = errno;
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "extending data.mdb over its free last pages", rc);
    return false;
  }
  return true;
}

}  // namespace detail

Store::Store(std::unique_ptr<State> state) : state_(std::move(state)) {}
Store::~Store() = default;
const std::string& Store::directory() const { return state_->directory; }
bool Store::without_lock_file() const { return state_->without_lock; }

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
  // An empty data file is refused before LMDB sees it: opened for writing, LMDB would take it
  // for a new environment and write to it.
  const std::filesystem::path data_file = std::filesystem::path(directory) / "data.mdb";
  if (std::filesystem::is_regular_file(data_file, ec) &&
      std::filesystem::file_size(data_file, ec) == 0 && !ec) {
    error = "store " + directory + ": " + data_file.string() +
            " is empty: not a plantview store (or a truncated copy)";
    return nullptr;
  }
  // No readahead: readers fetch chunks of a few kilobytes at random, and readahead would bring
  // (and count in the process's memory) most of the file around them.
  const auto open_env = [&](unsigned extra_flags) {
    state->env.reset();
    int rc = mdb_env_create(state->env.out());
    if (rc == MDB_SUCCESS) rc = mdb_env_set_maxdbs(state->env.get(), 12);
    if (rc == MDB_SUCCESS) rc = mdb_env_set_mapsize(state->env.get(), kMapSizeBytes);
    if (rc == MDB_SUCCESS) rc = mdb_env_set_maxreaders(state->env.get(), 254);
    const unsigned flags = MDB_NOTLS | MDB_NORDAHEAD | (mode == Mode::read_only ? MDB_RDONLY : 0u) | extra_flags;
    if (rc == MDB_SUCCESS) rc = mdb_env_open(state->env.get(), directory.c_str(), flags, 0644);
    return rc;
  };
  int rc = open_env(0);
  // A read-only directory or file system (a shared copy, a read-only volume): LMDB cannot
  // create or open lock.mdb for writing. Read without the lock table then; the manual says what
  // that requires (no writer while readers run).
  if ((rc == EACCES || rc == EROFS) && mode == Mode::read_only) {
    rc = open_env(MDB_NOLOCK);
    state->without_lock = rc == MDB_SUCCESS;
  }
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    // LMDB reads its two meta pages with read(): a file too short to hold them is "not an LMDB
    // file"; say how short.
    const auto size = std::filesystem::file_size(data_file, ec);
    if (rc == MDB_INVALID && !ec) {
      error += " (" + data_file.string() + " is " + std::to_string(size) +
               " bytes: not a plantview store, or a truncated copy)";
    }
    return nullptr;
  }
  // Before anything reads a page through the mapping.
  if (!data_file_complete(state->env.get(), directory, error)) return nullptr;
  // Open (or create) the named databases once; their handles serve every later transaction.
  // A writer first takes the store's writer lock, so that waiting for another import says whose.
  detail::WriterLock writer_lock;
  if (mode == Mode::read_write && !writer_lock.acquire(directory, error)) return nullptr;
  detail::LmdbTxn txn;
  rc = txn.begin(state->env.get(), mode == Mode::read_only ? MDB_RDONLY : 0u);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening", rc);
    return nullptr;
  }
  const unsigned create = mode == Mode::read_only ? 0u : MDB_CREATE;
  Databases& d = state->dbs;
  rc = mdb_dbi_open(txn.get(), "meta", create, &d.meta);
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, "opening database 'meta'", rc);
    return nullptr;
  }
  // The format comes first: another version's databases are not to be opened, let alone read.
  MDB_val k = as_val("format"), v;
  bool upgrade = false;  // a format 5 store, opened read_write
  if (mdb_get(txn.get(), d.meta, &k, &v) == MDB_SUCCESS) {
    uint32_t version = 0;
    if (v.mv_size == 4) std::memcpy(&version, v.mv_data, 4);
    if (version == 5 && mode == Mode::read_only) {
      error = "store " + directory + ": format 5, run `plantview upgrade --store " + directory +
              "` (or any import) to upgrade it in place";
      return nullptr;
    }
    upgrade = version == 5;
    if (version != kStoreFormatVersion && !upgrade) {
      error = "store " + directory + " has format " + std::to_string(version) +
              "; this build reads format " + std::to_string(kStoreFormatVersion) +
              (version < kStoreFormatVersion ? ": import or generate it again"
                                             : " (a newer plantview wrote it)");
      return nullptr;
    }
  }
  // Statistics that cannot be read would leave `info` without counts and an import without its
  // totals: refuse the store now, naming the key, rather than misreport it later.
  ModelStatistics statistics;
  if (!read_statistics(txn.get(), d.meta, directory, statistics, error)) return nullptr;
  // So is a key width the ids and names cannot be read with.
  unsigned index_key_bits;
  if (!detail::read_index_key_bits(txn.get(), d.meta, index_key_bits)) {
    error = "store " + directory + ": meta/\"index_key_bits\" is damaged (not a u32 from " +
            std::to_string(detail::kMinIndexKeyBits) + " to " +
            std::to_string(detail::kMaxIndexKeyBits) + ")";
    return nullptr;
  }
  struct Named {
    const char* name;
    MDB_dbi* dbi;
    unsigned flags;
  };
  const Named named[] = {
      {"objects", &d.objects, 0},
      {"attributes", &d.attributes, 0},
      {"sources", &d.sources, 0},
      {"ids", &d.ids, kIndexFlags},
      {"names", &d.names, kIndexFlags},
      {"spatial_a", &d.spatial[0], 0},
      {"spatial_b", &d.spatial[1], 0},
      {"revisions", &d.revisions, 0},
      {"changes", &d.changes, 0},
      {"history", &d.history, 0},
  };
  for (const Named& n : named) {
    rc = mdb_dbi_open(txn.get(), n.name, create | n.flags, n.dbi);
    if (rc != MDB_SUCCESS) {
      error = lmdb_message(directory, std::string("opening database '") + n.name + "'", rc);
      return nullptr;
    }
  }
  if (upgrade && !detail::upgrade_from_format_5(txn.get(), d, directory, statistics.objects, error)) {
    return nullptr;
  }
  rc = txn.commit();
  if (rc != MDB_SUCCESS) {
    error = lmdb_message(directory, upgrade ? "upgrading from format 5" : "opening", rc);
    return nullptr;
  }
  return std::unique_ptr<Store>(new Store(std::move(state)));
}

}  // namespace plantview
