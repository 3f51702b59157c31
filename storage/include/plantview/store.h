// plantview/store.h: the plant store. A plant model kept as parameters only, in one LMDB
// environment (a directory), read by renderers and services while imports write.
//
// Schema (LMDB named databases; integers in keys are big-endian so that keys sort numerically):
//   meta        "format"      -> u32 format version (kStoreFormatVersion); read before anything
//                                else, and a store of another version is refused
//               "statistics"  -> JSON: objects by class, primitives by kind and by class,
//                                full-resolution triangles by kind and class, model bounds
//               "next_slot"   -> u32, the slot the next object gets
//   objects     block (u32)   -> the object records of slots [block * 2048, block * 2048 + 2048),
//                                in chunks of 64 slots, each chunk one zstd frame: class, colour,
//                                origin, name, source, primitives, piping topology (layouts in
//                                chunks.h and record.h)
//   attributes  block (u32)   -> the same for the objects' key/value attributes: blocks of 4096
//                                slots, chunks of 256
//   indexes     "ids"         -> zstd: every (id, slot), sorted by id (tables.h)
//               "names"       -> zstd: every (32-bit hash of the name, slot), sorted by hash
//               "spatial"     -> zstd: the spatial origin and the objects' bounds on a grid of
//                                1/1024 m, in the order of the bounding volume hierarchy, whose
//                                shape follows from their count (spatial.h)
//   sources     source path   -> the slots of the objects it brought, as runs (tables.h)
// A slot is an object's place in the store: slots only grow, so that records append; an
// object's stable identity is its 64-bit id (model.h). Replacing or removing an object rewrites
// the chunk it is in; every import rewrites the indexes whole.
//
// Transactions and lifetimes
//   - An Import is one LMDB write transaction: until commit() nothing is visible, and a failed,
//     abandoned or killed import leaves the store exactly as it was. One import at a time per
//     store (LMDB serialises writers, across processes too).
//   - A ReadView is one LMDB read transaction: a consistent snapshot. Views may be used while an
//     import writes; they do not see it. A view belongs to the thread that made it.
//   - What views need of the indexes is decoded into memory once per committed state of the
//     store and shared by every view of that state; a view keeps its state's memory alive.
//     * The first view of a state (read()) decodes the id of every slot (8 bytes a slot, up to
//       the highest slot in use: for object() and for_each_object()) and the spatial hierarchy
//       (16 bytes an object with geometry and a 32-byte node per 4 or so): about 32 MB per
//       million objects, in about 0.4 s per million. It checks the id table on the way.
//     * The lookup tables wait for their first use, on whichever view of the state asks first
//       (another asking meanwhile waits for it): slot_of() builds the slots by id (4 bytes an
//       object), slots_named() the name hashes (8 bytes an object); about 80 ms per million
//       objects each. A renderer that never asks never pays.
//     * Decoding holds one index's inflated bytes at a time, besides what it keeps (10 to 12
//       bytes an object), and frees them before going on.
//     Spans a view returns point into that memory and are valid until the view is destroyed.
//   - Values are read in place from LMDB's mapping of the data file, and every page read counts
//     in the process's resident memory until the kernel reclaims it. So the environment reads
//     no more than is asked for (no readahead), index values are dropped from the resident set
//     once decoded, and a view drops the pages of the chunks it has decompressed every 256
//     chunks and when destroyed (the kernel's page cache keeps them all: reading them again
//     costs a minor fault). A view that has read the whole store holds about a twentieth of
//     the file (pages the kernel maps around those read), not all of it.
//   - object() decompresses the 64-slot chunk holding the slot and keeps the view's 32 most
//     recently used chunks: fetching neighbouring slots costs one decompression per chunk.
//
// Errors: every fallible call returns false (or an empty optional) and sets a message that
// names the store directory and the operation or slot (and the LMDB or zstd reason). slot_of()
// and slots_named() also have short forms without a message, for callers that treat "cannot
// tell" as "none".
//
// Read-only copies (several service replicas, or several hosts, reading one store): a store
// opened read_only never writes data.mdb. LMDB keeps its reader table in lock.mdb beside it; where
// that file cannot be created or opened for writing (a directory without write permission, a
// read-only mount), open() falls back to LMDB's MDB_NOLOCK and readers keep no table. Then no
// writer may change the store while those readers run (an import would reuse pages that a
// reader still sees): replace a shared store by writing a new directory and switching readers
// over, never by importing into it in place. Readers in a writable directory use lock.mdb as
// usual and may run alongside an import.
//
// Damaged stores: open() refuses, in either mode and without writing a byte to data.mdb, an
// empty data.mdb ("not a plantview store"), one too short for LMDB's meta pages, one shorter
// than the pages its newest meta page says are in use (a partial copy, a full disk: LMDB maps
// the file, and reading a page past its end would kill the process with SIGBUS), another format
// version, and meta/"statistics" that is not JSON of the form statistics_json() writes (the
// message names the key). read() checks the file's length again, so a file cut short while the
// store is open fails the next view instead of faulting; a cut during a view's life is not
// caught (the view's pages past the new end fault, as any mapped file's would).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/model.h"

namespace plantview {

inline constexpr uint32_t kStoreFormatVersion = 2;

// A node of the spatial hierarchy. Bounds (metres) are relative to the spatial origin, rounded
// outward: the union of what the node holds.
// count > 0: a leaf over entries [first, first + count); count == 0: an inner node whose
// children are nodes `first` and `first + 1`. Node 0 is the root.
struct SpatialNode {
  float min[3], max[3];
  uint32_t first, count;
};
// An object in a leaf: its slot and its bounds, quantised within the bounds of the leaf that
// holds it (16 bytes an object: at 4 million objects that is what a view keeps most of). On
// each axis 0 stands for the leaf's min and 65535 for its max; entry_bounds() turns them into
// metres relative to the spatial origin, and those contain the object's bounds (rounded outward
// to the store's 1/1024 m grid, then to float, then to the leaf's 1/65535 steps).
struct SpatialEntry {
  uint16_t min[3], max[3];
  uint32_t slot;
};
static_assert(sizeof(SpatialNode) == 32 && sizeof(SpatialEntry) == 16);

// The bounds of `entry`, held by `leaf` (metres, relative to the spatial origin). Each end is
// measured from the leaf's nearer side, so 0 and 65535 give the leaf's bounds exactly.
inline void entry_bounds(const SpatialNode& leaf, const SpatialEntry& entry, float min[3],
                         float max[3]) {
  for (int a = 0; a < 3; ++a) {
    const float step = (leaf.max[a] - leaf.min[a]) * (1.0f / 65535.0f);
    min[a] = leaf.min[a] + step * float(entry.min[a]);
    max[a] = leaf.max[a] - step * float(65535 - entry.max[a]);
  }
}

// What `plantview info` shows.
struct StoreInfo {
  uint32_t format_version = 0;
  uint64_t objects = 0;
  ModelStatistics statistics;  // bounds included
  uint64_t store_bytes = 0;    // size of the data file on disk
};

// The statistics as one JSON object: objects, primitives and triangles (full resolution), each
// by class and by kind, and bounds_m {min, max} when there is geometry. This is the form kept in
// meta/"statistics" and printed by `plantview info --json`.
std::string statistics_json(const ModelStatistics& statistics);

// Threads for the imports of this process (0, the default: the machine's hardware threads): an
// import compresses its records on that many threads beside the importing one, and ingest
// (ingest.h) generates a plant on a thread of its own; 1 does everything on the importing
// thread. Speed only: the store written is the same, byte for byte, whatever the count. Any
// thread may call; imports begun afterwards follow it.
void set_import_threads(unsigned threads);
unsigned import_threads();  // the count in effect (0 resolved)

class Store;

// Adds and replaces objects in one transaction. Not thread-safe; one per store at a time.
class Import {
 public:
  ~Import();  // aborts unless committed
  Import(const Import&) = delete;
  Import& operator=(const Import&) = delete;

  // Removes every object that `source` brought before (importing a file again replaces them).
  bool remove_source(std::string_view source, std::string& error);
  // Adds an object (its `source` field says where it came from). An object whose id is already
  // in the store replaces it.
  bool put(const Object& object, std::string& error);
  // Rebuilds the indexes and statistics and commits. Afterwards the Import is spent, whether
  // the commit succeeded or not (a failed commit leaves the store as it was).
  bool commit(std::string& error);

  uint64_t objects_put() const;

 private:
  friend class Store;
  struct State;
  explicit Import(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// A consistent read-only snapshot of the store (one LMDB read transaction).
class ReadView {
 public:
  ~ReadView();
  ReadView(const ReadView&) = delete;
  ReadView& operator=(const ReadView&) = delete;

  StoreInfo info() const;
  // The spatial hierarchy (empty for an empty store); valid while this view lives. No work per
  // call: the arrays are decoded once per committed state.
  std::span<const SpatialNode> spatial_nodes() const;
  std::span<const SpatialEntry> spatial_entries() const;
  glm::dvec3 spatial_origin() const;

  // Decodes the object in a slot (attributes included when asked). False if there is none or
  // its record is corrupt (error says which). Cost: decompressing the slot's chunk of 64 slots
  // (about 10 microseconds) unless it is one of the view's 32 most recently used; so fetch a
  // batch of slots in ascending order (a renderer's newly visible objects, sorted), and each
  // chunk is decompressed once. Slots follow import order, which keeps a pipe run's parts
  // together but is only loosely spatial: a leaf of the hierarchy spans 2 to 3 chunks.
  bool object(uint32_t slot, Object& out, bool with_attributes, std::string& error) const;

  // The slot of the object with this id: `slot` empty if there is none. Binary search (1 to 2
  // microseconds at 4 million objects). The first call on any view of a committed state builds
  // the lookup table (see "Transactions and lifetimes"); false with a message naming the store
  // if the stored id table cannot be read then (and on every later call on views of that state).
  bool slot_of(uint64_t id, std::optional<uint32_t>& slot, std::string& error) const;
  // The same, empty also when the id table cannot be read.
  std::optional<uint32_t> slot_of(uint64_t id) const;
  // Slots of the objects with this exact name (usually one), in slot order. Binary search, then
  // each candidate is confirmed by its record. The first call on any view of a committed state
  // builds the lookup table; false with a message naming the store if the stored name table,
  // or a candidate's record, cannot be read.
  bool slots_named(std::string_view name, std::vector<uint32_t>& slots, std::string& error) const;
  // The same, empty when the name table cannot be read; a candidate whose record cannot be read
  // is left out.
  std::vector<uint32_t> slots_named(std::string_view name) const;
  // Calls fn for every object in slot order until it returns false.
  bool for_each_object(const std::function<bool(uint32_t slot, Object&&)>& fn, bool with_attributes,
                       std::string& error) const;

 private:
  friend class Store;
  struct State;
  explicit ReadView(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

class Store {
 public:
  enum class Mode { read_only, read_write };
  // Opens (read_write: creating the directory and store if needed) the store in `directory`.
  // read_only fails if there is no store there; it writes nothing, and opens a store in a
  // directory or file system it may not write to (see "Read-only copies").
  static std::unique_ptr<Store> open(const std::string& directory, Mode mode, std::string& error);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  // Starts the (only) write transaction. Fails on a read-only store.
  std::unique_ptr<Import> begin_import(std::string& error);
  // Starts a read snapshot. May be called from any thread; the view stays on that thread. The
  // first view of a newly committed state decodes its indexes (see "Transactions and
  // lifetimes"); a failure there (a corrupt id table or spatial index) fails read().
  std::unique_ptr<ReadView> read(std::string& error) const;

  const std::string& directory() const;
  // True when a read-only store was opened without LMDB's lock file (see "Read-only copies").
  bool without_lock_file() const;

 private:
  friend class Import;
  friend class ReadView;
  struct State;
  explicit Store(std::unique_ptr<State> state);
  std::shared_ptr<State> state_;
};

}  // namespace plantview
