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
//   - The indexes are decoded into memory once per committed state of the store, by the first
//     view that reads that state, and shared by the later views of it (read() is then cheap).
//     Spans a view returns point into that memory and are valid until the view is destroyed.
//   - object() decompresses the 64-slot chunk holding the slot and keeps the view's 32 most
//     recently used chunks: fetching neighbouring slots costs one decompression per chunk.
//
// Errors: every fallible call returns false (or an empty optional) and sets a message that
// names the store directory and the operation or slot (and the LMDB or zstd reason).
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
// An object in a leaf: its slot and its bounds (metres, relative to the spatial origin, rounded
// outward to the store's 1/1024 m grid and then to float, so they contain the object's bounds).
struct SpatialEntry {
  float min[3], max[3];
  uint32_t slot;
};
static_assert(sizeof(SpatialNode) == 32 && sizeof(SpatialEntry) == 28);

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
  std::optional<uint32_t> slot_of(uint64_t id) const;
  // Slots of the objects with this exact name (usually one). Binary search, then each candidate
  // is confirmed by its record.
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
  // read_only fails if there is no store there.
  static std::unique_ptr<Store> open(const std::string& directory, Mode mode, std::string& error);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  // Starts the (only) write transaction. Fails on a read-only store.
  std::unique_ptr<Import> begin_import(std::string& error);
  // Starts a read snapshot. May be called from any thread; the view stays on that thread. The
  // first view of a newly committed state decodes its indexes (about 30 ms for preset c).
  std::unique_ptr<ReadView> read(std::string& error) const;

  const std::string& directory() const;

 private:
  friend class Import;
  friend class ReadView;
  struct State;
  explicit Store(std::unique_ptr<State> state);
  std::shared_ptr<State> state_;
};

}  // namespace plantview
