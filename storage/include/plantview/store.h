// plantview/store.h: the plant store. A plant model kept as parameters only, in one LMDB
// environment (a directory), read by renderers and services while imports write.
//
// Schema, format 6 (LMDB named databases; integers in keys are big-endian so that keys sort
// numerically):
//   meta        "format"      -> u32 format version (kStoreFormatVersion); read before anything
//                                else, and a store of another version is refused (a format 3 or
//                                4 store: "import or generate it again"). A format 5 store (the
//                                same less the three revision databases) opened read_write is
//                                upgraded in place, in one transaction, to revision 1 "upgraded
//                                from format 5" (no change list: later changes are against it);
//                                opened read_only it is refused with how to upgrade it
//               "statistics"  -> JSON: objects by class, primitives by kind and by class,
//                                full-resolution triangles by kind and class, model bounds
//               "next_slot"   -> u32, the slot the next object gets
//               "index_key_bits" -> u32, 8 to 24: the bits of an id or name hash that key the ids
//                                and names (below); absent until the first commit
//               "spatial_top" -> zstd: the top of the spatial hierarchy (spatial.h): the spatial
//                                origin, the entry and block counts, each block's count and grid
//                                bounds, and the far-field proxy of every top node
//   objects     first slot (u32) -> a chunk: the object records of consecutive slots from that
//                                one, as one zstd frame (id, class, colour, origin, name, source,
//                                primitives, piping topology; layouts in chunks.h and record.h).
//                                Chunks are cut by compressed bytes, so that each value fills
//                                two pages of the data file (about 150 generated objects): the
//                                slot of a record is found by the greatest key not above it.
//                                Format 4 cut a chunk every 64 slots, and LMDB's rounding of
//                                each value to whole pages made preset c half as big again;
//                                format 3 kept 32 chunks a value, which left an import's memory
//                                unbounded (below)
//   attributes  first slot (u32) -> the same for the objects' key/value attributes
//   ids         the top B bits of the id (B = meta/"index_key_bits", in (B + 7) / 8 bytes) ->
//                                sorted duplicates (MDB_DUPSORT | MDB_DUPFIXED, packed in pages):
//                                the other 64 - B bits of the id (in (71 - B) / 8 bytes), u32 slot.
//                                B follows the object count, about 32 objects a key (LMDB costs a
//                                key about 28 bytes; much beyond 200 it gives a key pages of its
//                                own): 10 bits at preset c (15 bytes an object on disk), 17 at
//                                its x100 (13 bytes); 16 bits for both took 20 and 14. An import
//                                that leaves the count outside 16 to 64 a key (it doubled or
//                                halved) writes the ids and names again with the width for it
//   names       the top B bits of the 32-bit name hash -> sorted duplicates: the other 32 - B
//                                bits, u32 slot (about 9 and 8 bytes an object)
//   spatial_a / spatial_b     -> u32 block -> zstd: the grid entries (bounds on a grid of
//                                1/1024 m, slot, colour) of kSpatialBlockObjects objects or fewer,
//                                consecutive in the Morton order of their centres; the top says
//                                which of the two databases holds the committed blocks
//   sources     source path   -> the slots of the objects it brought, as runs (tables.h)
//   revisions   u32 revision  -> JSON: the Revision (below) that commit made; kept for ever (a
//                                few hundred bytes each)
//   changes     u32 revision, u64 first id -> zstd: the changes that revision made, in id
//                                order, 256 objects a value: each u64 id, u8 kind, u8 class, u64
//                                content hash before (not for added), u64 after (not for
//                                removed), u32 length and name (after; removed: before),
//                                little-endian; kept for the last keep_revisions revisions
//   history     u32 revision, u64 first id -> zstd: the records and attribute records of the
//                                objects that revision removed or modified, as they were before
//                                (what a change image draws as a ghost), in id order, up to 256
//                                objects or 64 KB a value: each u64 id, u32 record bytes, u32
//                                attribute bytes, the two records; kept as the changes are
// A slot is an object's place in the store: slots only grow, so that records append; an
// object's stable identity is its 64-bit id (model.h). An object put again unchanged (the same
// content hash, "Revisions") keeps its slot, and nothing of it is written. Replacing or removing
// an object rewrites the chunks of its span (4096 object or 16384 attribute slots, which chunks
// never cross);
// every import writes the spatial blocks and the top again (the ids and names are updated key
// by key, or written again when their key width changes).
//
// Transactions and lifetimes
//   - An Import is one LMDB write transaction: until commit() nothing is visible, and a failed,
//     abandoned or killed import leaves the store exactly as it was. One import at a time per
//     store (LMDB serialises writers, across processes too). This holds however big the import,
//     because everything it writes (records, ids, names, blocks, top) goes through that one
//     transaction: LMDB keeps its dirty pages in memory up to a limit and spills some of them
//     into free pages of the data file beyond it, never over a page a committed state uses, and
//     the meta page that makes them the store's state is written only by the commit. The limit
//     counts values, not bytes (131071 dirty entries: a page, or one value of several pages):
//     so every value an import writes is a page or a few (a chunk of records of two pages, an
//     index page, a spatial block of about 20 KB), and the dirty pages stay under about 1 GB. A killed
//     process's pages are unreachable, and the next writer reuses them. (No MDB_WRITEMAP: the
//     guarantee does not need it, and it would write dirty pages in place through the map,
//     where they count in the process's memory until written back.)
//   - An import's memory is bounded whatever the plant's size: per object it appends to three
//     buffers (id and slot; name hash and slot; Morton key, slot, grid box and colour), and each
//     full buffer (64 MB) is sorted and written to a run file in the store directory
//     (import-<pid>-*.run, removed at commit or abort, and by the next import should the process
//     have been killed). commit() merges the runs into the ids and names databases (a commit
//     that changes their key width first moves their entries into the same runs) and, with the
//     committed blocks, into new blocks. For the revision, each object put and each committed
//     object removed goes the same way (id, content hash, slot, class: two buffers of 32 MB; the
//     names to a log file through 1 MB), merged by id at commit ("Revisions"). Besides the
//     buffers (about 260 MB at most) an import
//     keeps two bits per slot (removed, and removal pending: its only per-slot memory), a read
//     transaction on the state it began from with 16 inflated chunks, each touched
//     source's slots as runs, 700 bytes of block summary per 2048 objects at commit, and
//     LMDB's dirty pages (under 1 GB whatever the import's size; see chunks.h). `gen --preset c
//     --scale 1000` (40.75 million objects) peaked at 1.60 GB (format 4: 0.87 GB while putting
//     objects and 1.15 GB while committing; format 3: 3.7 GB).
//   - A ReadView is one LMDB read transaction: a consistent snapshot. Views may be used while an
//     import writes; they do not see it. A view is used by one thread at a time (it need not
//     be the thread that made it); threads that read one snapshot together each take a
//     sibling() view of it.
//   - Store::open(), Store::read() and info() read metadata only (a millisecond or so whatever
//     the store's size). The first spatial call on any view of a committed state decodes that
//     state's spatial top (about 10 MB at 40 million objects: 2 top nodes and up to 8 proxy
//     boxes of 28 bytes each per 2048 objects; tens of milliseconds), shared by every view of the
//     state; another view asking meanwhile waits for it. A view keeps its state's memory alive.
//     Spans a view returns are valid until the view is destroyed.
//   - Spatial blocks are decoded on demand (spatial_block()) into a cache shared by the views of
//     one committed state: at most kSpatialCacheBytes of blocks that nobody holds (least recently
//     used go first); a block somebody holds stays until released. About 50 KB a block.
//   - slot_of() and slots_named() look up the ids and names databases (an LMDB B-tree lookup,
//     a few microseconds): no table per object is ever built in memory.
//   - Values are read in place from LMDB's mapping of the data file, and every page read counts
//     in the process's resident memory until the kernel reclaims it. So the environment reads
//     no more than is asked for (no readahead), block and top values are dropped from the
//     resident set once decoded, and a view drops the pages of the chunks it has decompressed
//     every 256 chunks and when destroyed (the kernel's page cache keeps them all: reading them
//     again costs a minor fault).
//   - object() decompresses the chunk holding the slot (about 150 generated objects, found by a
//     cursor lookup) and keeps the view's 32 most recently used chunks: fetching neighbouring slots costs one decompression per chunk.
//     Decompressed chunks are also shared by the views of one committed state, up to
//     kChunkCacheBytes (least recently used go first; a chunk a view keeps stays alive with it):
//     a chunk another view, or an earlier one, decompressed is not decompressed again. (Preset c
//     holds 10 MB of them in all, so a walk decompresses each chunk once; out of core, at
//     --scale 100, a frame's new objects lie scattered over thousands of chunks, and 32 MB
//     spares a fifth of the decompressions for about 34 MB of peak memory.)
//
// Errors: every fallible call returns false (or an empty optional, or a null pointer) and sets a
// message that names the store directory and the operation, slot or block (and the LMDB or zstd
// reason). slot_of() and slots_named() also have short forms without a message, for callers that
// treat "cannot tell" as "none".
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
// Damaged stores: open() refuses, in either mode and without writing a byte to data.mdb, an empty
// data.mdb ("not a plantview store"), one too short for LMDB's meta pages, one shorter than the
// pages its newest meta page says are in use (a partial copy, a full disk: LMDB maps the file, and
// reading a page past its end would kill the process with SIGBUS), another format version,
// meta/"statistics" that is not JSON of the form statistics_json() writes, and
// meta/"index_key_bits" that is not a u32 from 8 to 24 (the message names the key). (LMDB may leave
// a commit's last pages free and unwritten; an import extends the file over them.) read() checks
// the file's length again, so a file cut short while the store is open fails the next view instead
// of faulting; a cut during a view's life is not caught (the view's pages past the new end fault,
// as any mapped file's would). A damaged spatial top fails spatial_ready(), spatial_block() and
// for_each_spatial_entry() (naming it; the other spatial calls answer as for an empty store); a
// damaged block fails spatial_block() (naming it) and nothing else. info(), objects and lookups
// read on.
#pragma once

#include <cstddef>
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

inline constexpr uint32_t kStoreFormatVersion = 6;
// Objects in a spatial block (the last block of a store may hold fewer).
inline constexpr uint32_t kSpatialBlockObjects = 2048;
// Boxes in a top node's far-field proxy, at most.
inline constexpr uint32_t kProxyBoxes = 8;
// Decoded spatial blocks a committed state keeps that no view holds, at most (bytes).
inline constexpr size_t kSpatialCacheBytes = size_t(64) << 20;
// Decompressed object chunks a committed state keeps for its views, at most (bytes).
inline constexpr size_t kChunkCacheBytes = size_t(32) << 20;

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

// A block of the spatial hierarchy: kSpatialBlockObjects objects or fewer, consecutive in tree
// order, with its own subtree: nodes[0] is its root; count == 0 inner (children first, first + 1,
// block-local), count > 0 leaf over entries [first, first + count) of this block. Immutable.
struct SpatialBlock {
  std::vector<SpatialNode> nodes;
  std::vector<SpatialEntry> entries;
};

// A box of a far-field proxy: the bounds (metres, relative to the spatial origin, rounded
// outward) of a group of a top node's objects, with the colour of the largest (by volume) of
// them.
struct ProxyBox {
  float min[3], max[3];
  Colour colour;
};

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

// ---------------------------------------------------------------------------------------------
// Revisions (format 6). Every committed import (import, generate, ingest_objects) makes one
// revision: 1 for the first commit, then 2, 3, ... An object's change between two revisions is
// found by its id and its content hash: a 64-bit XXH3 of its stored record and its stored
// attributes (geometry, colour, name, class, topology, source, attributes), so putting an object
// again unchanged changes nothing, and re-importing an unchanged file makes a revision with no
// changes. Objects whose id is new are added, ids that went are removed, ids whose hash differs
// are modified (a slot that moved alone is not a change). The previous record of every removed
// or modified object is kept for the last keep_revisions revisions (Import::set_keep_revisions,
// default kDefaultKeepRevisions), with each revision's change list; older ones are pruned at a
// later commit, and their Revision says changes_kept = false. Revisions themselves are kept for
// ever.

inline constexpr uint32_t kDefaultKeepRevisions = 10;

struct Revision {
  uint32_t number = 0;            // 1, 2, ... in commit order; 0: nothing committed yet
  // When it was committed (UTC, milliseconds since 1970); SOURCE_DATE_EPOCH (seconds) in the
  // environment fixes it, so that the same imports make the same bytes.
  int64_t time_unix_ms = 0;
  std::vector<std::string> sources;  // the sources the import touched, sorted (store.h sources)
  std::string note;               // Import::set_note(); may be empty
  uint64_t added = 0, removed = 0, modified = 0;  // objects, by the content hash rule above
  uint64_t objects = 0;           // objects in the store after it
  bool changes_kept = true;       // its change list and previous records are still kept
  // The --keep-revisions of the commit that made it (the last one's is the store's: what
  // pruning messages quote).
  uint32_t keep_revisions = kDefaultKeepRevisions;
};

enum class ChangeKind : uint8_t { added, removed, modified };
// "added", "removed", "modified".
std::string_view change_kind_name(ChangeKind kind);

// An object's net change between two revisions (ReadView::changes()).
struct ObjectChange {
  uint64_t id = 0;
  ChangeKind kind = ChangeKind::added;
  std::string name;                     // as at the later revision (removed: as it was)
  ObjectClass object_class = ObjectClass::other;  // the same
  std::optional<uint32_t> slot;         // its slot in this view's snapshot; none when removed
  uint64_t hash_before = 0, hash_after = 0;  // content hashes (0 where it did not exist)
  uint32_t revision = 0;                // the last revision in the range that changed it
};

// What `plantview info` shows.
struct StoreInfo {
  uint32_t format_version = 0;
  uint64_t objects = 0;
  ModelStatistics statistics;  // bounds included
  uint64_t store_bytes = 0;    // size of the data file on disk
  // Changes with every committed import: a digest of what the import changed (each object put,
  // its attributes, each slot removed) chained onto the previous commit's id. The same imports
  // in the same order give the same id; any other change another one, whatever the statistics
  // say (an object recoloured or moved within the bounds). 0: nothing committed yet.
  uint64_t commit_id = 0;
  // The snapshot's revision (Revision::number; 0 when nothing is committed) and when it was
  // committed.
  uint32_t revision = 0;
  int64_t revision_time_unix_ms = 0;
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

// Two writers at once. LMDB lets one write transaction run at a time (across processes); the
// writer (begin_import(), and open() read_write when it must create or upgrade databases) also
// holds an advisory lock on `import.lock` in the store directory and says who it is in
// `import.writer` (pid, command line, start time) until it commits or aborts (a killed writer's
// lock goes with its process; its file is overwritten by the next). A second writer that finds
// the lock taken prints "store DIR: waiting for the import by pid N (plantview import X.rvm,
// started 10:02:11)" to stderr and waits (true, the default), or fails with that message (false:
// `--no-wait`). Process-wide; any thread.
void set_import_lock_wait(bool wait);

class Store;

// Adds and replaces objects in one transaction. Not thread-safe; one per store at a time.
class Import {
 public:
  ~Import();  // aborts unless committed
  Import(const Import&) = delete;
  Import& operator=(const Import&) = delete;

  // Removes every object that `source` brought before (importing a file again replaces them):
  // at commit, for those not put again unchanged meanwhile.
  bool remove_source(std::string_view source, std::string& error);
  // Adds an object (its `source` field says where it came from). An object whose id is already
  // in the store stays in its slot, untouched, when its content hash is the same (and is then no
  // longer removed by remove_source()), and is replaced otherwise, at a new slot; one put twice
  // in this import is resolved at commit (the later wins). Fails, naming the slot, for bounds that are not finite or lie beyond the spatial
  // grid (about 2000 km from the spatial origin, which the first object with geometry ever
  // put fixes: whole metres at its centre; it never moves).
  bool put(const Object& object, std::string& error);
  // Merges this import's runs into the ids, names and spatial blocks, writes the top and the
  // statistics, and commits. Afterwards the Import is spent, whether
  // the commit succeeded or not (a failed commit leaves the store as it was).
  bool commit(std::string& error);

  // A note recorded with this commit's revision (Revision::note): what the revision is, e.g.
  // "E3D export 2026-12-06". Any time before commit().
  void set_note(std::string note);
  // How many revisions (this one included) keep their change lists and previous records; older
  // ones are pruned by this commit. At least 1 (0 is a caller bug and asserts).
  void set_keep_revisions(uint32_t revisions);

  uint64_t objects_put() const;
  // The statistics of the objects put so far, bounds included (what they replaced or removed is
  // not subtracted): what the caller would count from them, counted once.
  const ModelStatistics& put_statistics() const;

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

  // Metadata only (meta/"format" and "statistics", the file's size): nothing spatial is read.
  StoreInfo info() const;

  // Another view of this view's snapshot, for another thread (a renderer's workers reading
  // objects beside it): it shares the state's caches and answers every call as this one does.
  // Null with a message naming the store when the store has committed since this view began
  // (LMDB starts a read at the latest commit, so the snapshot cannot be had again), or when no
  // read can start (every reader slot of the store taken). Costs a read transaction.
  std::unique_ptr<ReadView> sibling(std::string& error) const;
  // LMDB's number of the commit this snapshot reads (its transaction id): equal to
  // Store::last_commit() while no import has committed since the view began. Not a revision
  // (info().revision): any commit counts, and the numbers are the environment's, not the plant's.
  uint64_t commit() const;

  // The spatial hierarchy, split in two: the top, resident while the view lives, and blocks,
  // decoded on demand. Spans are valid while this view lives; no work per call once the top is
  // decoded (the first spatial call on any view of the state decodes it).
  //
  // Whether the top could be decoded: false with a message naming the store when it is damaged
  // (then the calls below answer as for an empty store, and spatial_block() fails). Call it
  // once after read() where an empty answer would hide the damage (a renderer).
  bool spatial_ready(std::string& error) const;
  //
  // The top: a binary tree whose leaves are blocks. count == 0: inner node, children `first`
  // and `first + 1` (top indices); count > 0: a block leaf: block index `first`, whose root
  // bounds equal this node's. Node 0 is the root. Empty for a store without geometry. A node is
  // identified across frames and views of one state by its index; a block's node by (block,
  // block-local index).
  std::span<const SpatialNode> spatial_top() const;
  // Objects (with geometry) beneath each top node, parallel to spatial_top().
  std::span<const uint32_t> spatial_top_objects() const;
  uint64_t spatial_objects() const;  // entries in the whole hierarchy
  uint32_t spatial_block_count() const;
  // What spatial bounds are relative to (whole metres, fixed by the first objects with geometry
  // ever imported; it never moves).
  glm::dvec3 spatial_origin() const;
  // The block, decoded on demand and kept in the cache of this committed state (see
  // "Transactions and lifetimes"). The pointer keeps the block alive: hold the blocks of a frame
  // for the frame. Thread-safe across the views of a state (each view on its own thread). Null
  // with a message naming the store and block on a read or decode error (and for a block past
  // spatial_block_count(), a caller bug that also asserts).
  std::shared_ptr<const SpatialBlock> spatial_block(uint32_t block, std::string& error) const;
  // Far-field proxy of a top node: 1 to kProxyBoxes boxes, generated at import and stored, whose
  // union has exactly the node's bounds (each box the bounds of a group of the node's objects;
  // together they cover every object beneath it). Empty only for an empty store (or a node past
  // the top, a caller bug that also asserts).
  std::span<const ProxyBox> spatial_proxy(uint32_t top_node) const;
  // Every entry in tree order, block after block (each dropped after its turn unless cached):
  // for whole-plant passes (views, benches). fn returns false to stop. False with a message on
  // a read error.
  bool for_each_spatial_entry(
      const std::function<bool(const SpatialNode& leaf, const SpatialEntry& entry)>& fn,
      std::string& error) const;
  // Bytes of decoded blocks the cache of this view's state holds now (held ones included).
  size_t spatial_cache_bytes() const;
  // Bytes of decompressed object chunks the views of this view's state share now.
  size_t chunk_cache_bytes() const;
  // Object chunks this view has decompressed (found neither among its own nor among the shared
  // ones): what reading objects cost it, for benches and tests.
  uint64_t chunks_decompressed() const;

  // Revisions (see "Revisions" above). The snapshot's own revision is info().revision.
  // Every revision ever committed, oldest first. False with a message naming the store on a
  // read error.
  bool revisions(std::vector<Revision>& out, std::string& error) const;
  // The net change of every object that differs between the state at revision `from` and the
  // state at `to` (from < to <= info().revision; from may be 0, the empty store), in id order:
  // an object added then removed within the range is left out; removed then added again with
  // the same hash is left out; otherwise the kind compares the two ends. False with a message
  // naming the revision when one in (from, to] is not kept any more ("revision 3's changes were
  // pruned: the store keeps the last 10 (--keep-revisions)") or never existed.
  bool changes(uint32_t from, uint32_t to, std::vector<ObjectChange>& out,
               std::string& error) const;
  // The object with this id as it was at revision `revision` (< info().revision): from the
  // previous records of the first revision after it that changed the object, or its current
  // record if none did. `found` false when it did not exist then. False with a message on a
  // read error or when the records needed were pruned.
  bool object_at(uint32_t revision, uint64_t id, Object& out, bool& found, bool with_attributes,
                 std::string& error) const;
  // The content hash of the object in a slot (the rule above). False as object() is.
  bool content_hash(uint32_t slot, uint64_t& hash, std::string& error) const;

  // Decodes the object in a slot (attributes included when asked). False if there is none or
  // its record is corrupt (error says which). Cost: decompressing the slot's chunk (two
  // pages compressed, a few hundred slots: tens of microseconds) unless it is one of the view's 32 most recently used; so fetch a
  // batch of slots in ascending order (a renderer's newly visible objects, sorted), and each
  // chunk is decompressed once. Slots follow import order, which keeps a pipe run's parts
  // together but is only loosely spatial: a leaf of the hierarchy spans one to a few chunks.
  bool object(uint32_t slot, Object& out, bool with_attributes, std::string& error) const;
  // The id and pipeline id of the object in a slot, from the first bytes of its record: the
  // same chunk as object() (so as cheap once a neighbour was read) without decoding the rest,
  // to look through the slots about one (a pipeline's members lie together). False if there is
  // none or the record is corrupt (error says which, as object()).
  bool object_key(uint32_t slot, uint64_t& id, uint64_t& pipeline_id, std::string& error) const;

  // The slot of the object with this id: `slot` empty if there is none. One lookup in the ids
  // database; false with a message naming the store on an LMDB error or a malformed value.
  bool slot_of(uint64_t id, std::optional<uint32_t>& slot, std::string& error) const;
  // The same, empty also when the lookup fails.
  std::optional<uint32_t> slot_of(uint64_t id) const;
  // Slots of the objects with this exact name (usually one), in slot order. A range of the names
  // database (by hash), then each candidate is confirmed by its record. False with a message
  // naming the store if the names database, or a candidate's record, cannot be read.
  bool slots_named(std::string_view name, std::vector<uint32_t>& slots, std::string& error) const;
  // The same, empty when the names cannot be read; a candidate whose record cannot be read is
  // left out.
  std::vector<uint32_t> slots_named(std::string_view name) const;
  // Calls fn for every object in slot order until it returns false (slots of removed objects are
  // skipped: each chunk is decompressed once).
  bool for_each_object(const std::function<bool(uint32_t slot, Object&&)>& fn, bool with_attributes,
                       std::string& error) const;
  // The same for the objects of one class only: a record of another class is passed over by its
  // class byte, without decoding it (each chunk is still decompressed once), so a pass for a
  // rare class costs little more than decompressing the store. A record too short to hold a
  // class fails as a corrupt record would.
  bool for_each_object_of_class(ObjectClass object_class,
                                const std::function<bool(uint32_t slot, Object&&)>& fn,
                                bool with_attributes, std::string& error) const;
  // One past the highest slot any object of this snapshot has had (removed ones included): the
  // slots a pass in slot order goes through, for its progress.
  uint32_t slot_count() const;

 private:
  friend class Store;
  struct State;
  explicit ReadView(std::unique_ptr<State> state);
  // The pass of both for_each_object forms: every object, or (only != null) those of one class.
  bool visit_objects(const ObjectClass* only,
                     const std::function<bool(uint32_t slot, Object&&)>& fn,
                     bool with_attributes, std::string& error) const;
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
  // Starts a read snapshot. May be called from any thread; the view stays on that thread. Reads
  // metadata only (see "Transactions and lifetimes").
  std::unique_ptr<ReadView> read(std::string& error) const;
  // LMDB's number of the newest commit (ReadView::commit() of a view begun now), read from the
  // environment's meta pages without a transaction, a lock or a system call: cheap enough to ask
  // before every frame, so that a reader notices an import's commit and moves to it (a view
  // held open keeps every page its snapshot uses, and the file grows while imports repeat).
  // Any thread. LMDB writes the meta page a moment (microseconds) before it lets readers begin
  // at it, so a view begun just after this changed may still read the commit before: compare
  // its commit() and look again later. A store opened without the lock file (see "Read-only
  // copies") answers too, but must not be written while it is read.
  uint64_t last_commit() const;

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
