// plantview/store.h: the plant store. A plant model kept as parameters only, in one LMDB
// environment (a directory), read by renderers and services while imports write.
//
// Schema (LMDB named databases; integers in keys are big-endian so that keys sort numerically):
//   meta        "format"      -> u32 format version (kFormatVersion)
//               "statistics"  -> JSON: objects by class, primitives by kind and by class,
//                                full-resolution triangles by kind and class, model bounds
//               "dictionary"  -> the zstd dictionary records are compressed with (trained on
//                                the first import's records; fixed for the life of the store)
//               "next_slot"   -> u32, the slot the next object gets
//   objects     slot (u32)    -> zstd record: id, name, class, colour, origin, bounds, source,
//                                primitives, piping topology (see record.cpp for the layout)
//   attributes  slot (u32)    -> zstd record: the object's key/value attributes
//   ids         id (u64)      -> slot (u32)
//   names       FNV-1a 64 hash of the name (u64) -> slots (u32, sorted duplicates)
//   sources     source path   -> slots (u32, sorted duplicates)
//   spatial     "nodes"       -> SpatialNode[]: a bounding volume hierarchy over object bounds
//               "entries"     -> SpatialEntry[]: the leaves' objects with their bounds
//               "origin"      -> 3 doubles: the model-space point spatial bounds are relative to
// A slot is an object's place in the store: slots only grow, so that records append to full
// pages; an object's stable identity is its 64-bit id (model.h).
//
// Transactions and lifetimes
//   - An Import is one LMDB write transaction: until commit() nothing is visible, and a failed,
//     abandoned or killed import leaves the store exactly as it was. One import at a time per
//     store (LMDB serialises writers, across processes too).
//   - A ReadView is one LMDB read transaction: a consistent snapshot. Spans it returns point into
//     the memory map and are valid only until the view is destroyed. Views may be used while an
//     import writes; they do not see it. A view belongs to the thread that made it.
//
// Errors: every fallible call returns false (or an empty optional) and sets a message that
// names the store directory and the operation (and the LMDB or zstd reason).
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

inline constexpr uint32_t kStoreFormatVersion = 1;

// A node of the spatial hierarchy. Bounds are relative to the spatial origin, rounded outward.
// count > 0: a leaf over entries [first, first + count); count == 0: an inner node whose
// children are nodes `first` and `first + 1`. Node 0 is the root.
struct SpatialNode {
  float min[3], max[3];
  uint32_t first, count;
};
// An object in a leaf: its slot and its bounds (relative to the spatial origin, rounded outward).
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
  // Rebuilds the spatial index and statistics and commits. Afterwards the Import is spent.
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
  // The spatial hierarchy (empty for an empty store); valid while this view lives.
  std::span<const SpatialNode> spatial_nodes() const;
  std::span<const SpatialEntry> spatial_entries() const;
  glm::dvec3 spatial_origin() const;

  // Decodes the object in a slot (attributes included when asked). False if there is none or
  // its record is corrupt (error says which).
  bool object(uint32_t slot, Object& out, bool with_attributes, std::string& error) const;
  std::optional<uint32_t> slot_of(uint64_t id) const;
  // Slots of the objects with this exact name (usually one).
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
  // Starts a read snapshot. May be called from any thread; the view stays on that thread.
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
