// Decoded objects: what the renderer knows of the store's objects and of the pipeline runs it
// merges (Su et al. section 5.3), decoded once and kept while they are resident and a while
// after. No GL: the frame plan chooses levels from it and arena streaming tessellates from it.
//
// Rules
//   - Objects are decoded from the renderer's read view, a frame's new ones in slot order (the
//     store compresses neighbouring slots together, so each chunk is decompressed once).
//   - A Known keeps its primitives until it is first resident; after that only while needed:
//     facet groups (their plans point into them) and merged runs (the store does not hold them)
//     always keep them, and others keep them unless the renderer drops them (models larger than
//     the arena budget), in which case they are decoded again when tessellated again.
//   - The cache is bounded: forget_old() keeps the resident objects and kKnownObjectsKept more.
//   - Runs are found stretch by stretch (hlod.h: a member that ends runs, such as an elbow or a
//     tee, parts a branch into stretches whose runs do not depend on each other). A pipe or
//     component that may lie in a run has its stretch analysed the first time it is decoded
//     (with HLOD on), as soon as it is read, through the view that read it: its pipeline and
//     the stretch's members lie in the slots about it, whose chunks that view still holds
//     decompressed (analysed once the frame's objects were all read, they were decompressed
//     again: x100 walk, 39% fewer chunk inflations). Only that stretch's members are decoded,
//     not the whole pipeline's (x100 walk's first 10 views: 90,506 records decoded for runs
//     against 629,407; most of a pipeline lies outside the view). A stretch that cannot be
//     read simply has no runs.
//   - The runs are bounded too: a pipeline none of whose members or runs is known any more is
//     forgotten (and its run indices reused) once more than kPipelinesKept pipelines, and twice
//     as many as the last time, are known. So a service that walks a whole site keeps the runs
//     of what it shows, not of all it has shown.
// Ownership: Known objects live in a pool (a deque: growing it moves none; forgotten entries
//   are emptied and reused, so the pool holds as many as were ever known at once), found
//   through a directory by slot (see KnownDirectory) or by run index: a Known* stays valid
//   until forget_old() or reset() (a frame's draws hold them for the frame). Part::plan points
//   into this cache's template plans (kept for the renderer's life) or into the Known's
//   own_plans.
// Keys: a Known is found by its residency key: the object's slot, or kRunKeyBit | run index.
// Threads: the renderer's thread. New objects are read and pipelines analysed on its worker
//   pool, each worker reading the store through a view of its own and writing only its own
//   parts' objects and the runs of the stretches it claimed (each claimed once, under a lock);
//   what is read is added on the renderer's thread, in slot order, and a stretch's runs when
//   its first member is added (so run indices do not depend on the thread count).
#pragma once

#include <algorithm>
#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "hlod.h"
#include "object_style.h"
#include "occlusion/occlusion_occluders.h"
#include "plantview/model.h"
#include "plantview/primitives.h"

namespace plantview {
class ReadView;
}

namespace plantview::detail {

class Residency;
class WorkerPool;
struct VisibleObject;

inline constexpr uint32_t kRunKeyBit = 0x80000000u;  // residency keys of merged runs: bit | run
inline constexpr size_t kKnownObjectsKept = 10000;   // decoded objects kept beyond the resident
inline constexpr size_t kPipelinesKept = 4096;       // analysed pipelines held before forgetting
inline constexpr size_t kNewObjectsPerPart = 256;       // new objects read per part on the pool
inline constexpr size_t kMinNewObjectsPerPart = 64;     // ... or fewer, to give every worker one
inline constexpr size_t kNewObjectsPerWave = 4096;      // new objects read before they are added
inline constexpr size_t kBlocksPerPart = 8;  // index blocks read ahead per part (read_blocks)
inline constexpr size_t kMaxTestBoxes = 32;  // Known::test_boxes

// A decoded object (or a merged pipeline run): what it takes to tessellate it and to write its
// indices at any level.
struct alignas(64) Known {
  struct Part {
    const MeshPlan* plan;   // shared per template (errors zeroed: see error_m), or own_plans
    uint32_t first_vertex;  // within the object's vertices
    uint32_t primitive;     // index into primitives
    // While resident: the part's first vertex within what the arena holds of the object, and
    // the plan whose indices address those vertices (the template's own at base 0, else its
    // compaction, shared by every object of that template; null: `plan` itself).
    uint32_t resident_first = 0;
    const MeshPlan* resident_plan = nullptr;
  };
  // What every frame reads, by cache line (a Known is aligned to one): line 0 is all that
  // occlusion's first phase and streaming's checks read of a visible object; choose adds
  // line 1; placing a drawn one adds line 2 (its parts).
  uint64_t last_seen = 0;           // frame
  uint32_t table = UINT32_MAX;      // object-table entry while resident (UINT32_MAX: not)
  uint32_t arena_offset = 0;        // while resident: its first vertex in the arena
  uint32_t vertex_count = 0;
  int32_t run = -1;                 // the pipeline run it belongs to, if any
  // Breaks ties in the draw order (and coincident surfaces' depth: gl/backend.h tie_of) the same
  // way whatever was decoded before and wherever the store put the object: a mix of its id, or
  // for a merged run of its pipeline's id and start (run indices depend on the order pipelines
  // were met; slots change when an import puts an object again, ids do not).
  uint32_t order_key = 0;
  uint32_t resident_centreline_first = 0;
  float pipe_diameter_m = 0;
  Colour colour;
  uint8_t level_count = 1;
  // While resident: the finest level whose vertices are in the arena. At base 0 every vertex
  // is there and the templates' indices serve every level; above 0 only the vertices of levels
  // >= base are, compacted part by part (see Part::resident_plan).
  uint8_t base = 0;
  bool has_lines = false, has_triangles = false;
  bool has_centreline = false;      // a pipe with its centreline (below)
  // RenderOptions::style (object_style.h), as of style_epoch: left out by hide/only; its
  // colour-by value (StyleValues index, -1: none).
  bool hidden = false;
  int32_t style_value = -1;
  alignas(64) std::array<float, kMaxLevels> error_m{};  // metres, largest over the triangle parts
  uint64_t id = 0;
  glm::dvec3 origin_m{0.0};
  alignas(64) std::vector<Part> parts;
  std::vector<CentrelineSegment> centreline;  // pipes: drawn as lines when thin on screen

  ObjectClass object_class = ObjectClass::other;
  uint64_t pipeline_id = 0;
  // The primitives, while needed (see the rules above).
  std::vector<Primitive> primitives;
  std::vector<MeshPlan> own_plans;  // facet groups' plans (others share the cache's)
  bool keeps_primitives = false;
  uint32_t centreline_first = 0;
  OccluderShape occluder;           // once built: empty unless it may occlude
  // Occlusion's exact test (occlusion.h), once built (DecodedObjects::test_boxes): the bounds
  // of up to kMaxTestBoxes groups of its primitives (metres, relative to origin_m), which hold
  // all it draws; empty for an object of one primitive (its own bounds serve).
  std::vector<Aabb> test_boxes;
  bool occluder_built = false;      // (occlusion_occluders.h; built when first asked for)
  bool test_boxes_built = false;
  uint32_t style_epoch = 0;         // DecodedObjects' style epoch when hidden/style_value were set
};
static_assert(offsetof(Known, has_centreline) < 64 && offsetof(Known, origin_m) + 24 <= 128 &&
              offsetof(Known, parts) == 128);

// Known objects by residency key, with no hashing: slots through a directory of pages of
// kSlotsPerPage pointers (a page exists while one of its slots is known: the store numbers
// neighbouring objects together, so a view's objects share few pages), merged runs through a
// vector by run index. Memory follows what is known, not the plant: 8 bytes a pointer of the
// pages in use, plus 8 bytes per kSlotsPerPage slots of the store for the directory itself.
class KnownDirectory {
 public:
  static constexpr uint32_t kSlotsPerPage = 1024;
  Known* find(uint32_t key) const {
    if (key & kRunKeyBit) {
      const uint32_t r = key & ~kRunKeyBit;
      return r < runs_.size() ? runs_[r] : nullptr;
    }
    const uint32_t page = key / kSlotsPerPage;
    return page < pages_.size() && pages_[page] ? pages_[page]->known[key % kSlotsPerPage]
                                                : nullptr;
  }
  // `key` must not be present; `k` must stay valid until erase(key) or clear().
  void insert(uint32_t key, Known* k);
  void erase(uint32_t key);
  void clear() {
    pages_.clear();
    runs_.clear();
  }
  // Pages held now (for memory bounds).
  size_t pages() const {
    return size_t(std::count_if(pages_.begin(), pages_.end(), [](const auto& p) { return p != nullptr; }));
  }

 private:
  struct Page {
    std::array<Known*, kSlotsPerPage> known{};
    uint32_t count = 0;
  };
  std::vector<std::unique_ptr<Page>> pages_;
  std::vector<Known*> runs_;
};

// Asks for the cache lines of a Known that a frame reads (see Known), ahead of reading them:
// loops over a frame's objects ask kPrefetchAhead objects ahead (their Knowns are scattered).
inline constexpr size_t kPrefetchAhead = 8;
inline void prefetch(const Known* k) {
  const char* p = reinterpret_cast<const char*>(k);
  __builtin_prefetch(p);
  __builtin_prefetch(p + 64);
  __builtin_prefetch(p + 128);
}

// Whether a pipeline run is drawn merged, decided once per frame by its first visible member.
struct RunDecision {
  uint64_t frame = 0;
  bool merged = false;
};

class DecodedObjects {
 public:
  // New objects are read and pipelines analysed on `pool` (null: on the calling thread), each
  // worker reading from a sibling view of its own (ReadView::sibling), made the first time a
  // frame has work enough to share out (kMinNewObjectsPerPart).
  explicit DecodedObjects(WorkerPool* pool = nullptr) : workers_(pool) {}
  // Forgets every object and run: `view` is a new snapshot (it must outlive its use here).
  void reset(const ReadView& view);
  // The style objects are evaluated by (object_style.h). A change keeps every Known (nothing is
  // tessellated again) and evaluates each again, its record read again with its attributes
  // where the style needs them, the next time decode() meets it. Objects are read with their
  // attributes while the style needs them.
  void set_style(const ObjectStyle& style);
  const CompiledStyle& style() const { return style_; }
  const StyleValues& style_values() const { return style_values_; }

  // Decodes the visible objects not known yet, in slot order. hlod: also find the runs of the
  // pipelines their pipes and components belong to. False if an object cannot be decoded
  // (error names the store and slot; the objects before it in slot order are known).
  // Afterwards decoded()[i] is the Known of visible[i] (one lookup per object and frame).
  bool decode(std::span<const VisibleObject> visible, bool hlod, std::string& error);
  // The Known of each object of the last decode() call's span, in its order; valid until the
  // next decode(), forget_old() or reset().
  std::span<Known* const> decoded() const { return decoded_; }
  // A known object or run (null if not known).
  Known* find(uint32_t key);
  // Objects and runs known now; pipelines analysed and their runs held now.
  size_t known_count() const { return pool_.size() - free_known_.size(); }
  size_t pipelines_count() const { return pipeline_runs_.size(); }
  size_t runs_count() const { return runs_.size() - free_runs_.size(); }
  // Views pipelines are read through at once: 1 until a decode() had pipelines enough to share
  // out among the workers, then the workers that got a view of their own.
  size_t reading_views() const { return std::max<size_t>(views_.size(), 1); }
  // A known object; it must be known (decoded this frame or before).
  Known& at(uint32_t slot) {
    Known* k = directory_.find(slot);
    assert(k);
    return *k;
  }
  // The merged cylinder of run `run`, made the first time it is asked for.
  Known& know_run(uint32_t run);

  const PipelineRun& run(uint32_t r) const { return runs_[r]; }
  RunDecision& decision(uint32_t r) { return decisions_[r]; }

  // The primitives to tessellate `k` (the object or run of residency key `key`) from: its own,
  // or, where they were dropped, decoded again (valid until the next call). Null on a read
  // error.
  const std::vector<Primitive>* primitives(uint32_t key, const Known& k, std::string& error);

  // The occluder shape of the object in `slot` (known), built the first time it is asked for
  // (from its primitives, decoded again if dropped). Null on a read error.
  const OccluderShape* occluder(uint32_t slot, Known& k, std::string& error);

  // The exact test's boxes of the object in `slot` (known; Known::test_boxes), built the first
  // time they are asked for (from its primitives, decoded again if dropped): only objects the
  // exact test meets pay for them. Null on a read error. Threads: for different objects at
  // once where each is built already or keeps its primitives (no read; the reads share one
  // buffer).
  const std::vector<Aabb>* test_boxes(uint32_t slot, Known& k, std::string& error);

  // Reads the spatial index's `blocks` into the store's shared cache of decoded blocks, on the
  // workers (each through its sibling view) and this thread, so that the cull finds them
  // there. A block that cannot be read is left for the cull, which reports it.
  void read_blocks(std::span<const uint32_t> blocks);

  // Keeps the cache bounded (kKnownObjectsKept beyond the resident): objects neither resident
  // nor seen in frame `frame` go first, those looked at longest ago first, only as many as the
  // bound needs; those seen (drawn as boxes because the arena was full) only if that is not
  // enough. Costs about what it forgets, not the number known.
  void forget_old(uint64_t frame, const Residency& residency);

 private:
  Known& add(uint32_t key, Object& object, bool keeps_primitives);
  // Sets k.hidden and k.style_value from `o` (its attributes read where the style needs them).
  void evaluate_style(Known& k, const Object& o);
  // Evaluates again the objects of restyle_ (known, evaluated under an older style): their
  // records read again (with attributes) where the style needs them. False on a read error.
  bool restyle(std::string& error);
  // A fresh Known for `key` (not known), from the pool.
  Known& insert(uint32_t key);
  // A stretch of one branch analysed this decode(): its members' slots (sorted) and its runs.
  struct Stretch {
    uint64_t pipeline_id = 0;
    std::vector<uint32_t> slots;
    std::vector<PipelineRun> runs;
    bool added = false;
  };
  // Adds a stretch's runs, marks its members analysed and tells the known ones their run.
  void add_stretch(Stretch& stretch);
  // Whether the stretch of the member in `slot` of `pipeline_id` was analysed before.
  bool analysed(uint64_t pipeline_id, uint32_t slot) const;
  // The worker views (views_[0] is the renderer's own); fewer than the pool's workers when
  // siblings cannot be had (the store moved on, or no reader slot left).
  void make_sibling_views();
  // Calls f(part, view) for every part in [0, parts), on the workers that have a view (made
  // here the first time there are parts enough to share) and this thread.
  template <class F>
  void on_views(size_t parts, const F& f);
  // Reads the objects of new_slots_[first..] (up to kNewObjectsPerWave) into wave_objects_,
  // setting wave_read_ for each read (a part's first failure: its wave_errors_ entry, and the
  // rest of that part left unread).
  // hlod: also analyses the stretches of the pipes and components read that may lie in a run
  // and were not analysed yet, each once, through the view that read it (into stretches_).
  void read_wave(size_t first, bool hlod);
  // A run index for a new run: a freed one, or a new one at the end.
  uint32_t new_run(PipelineRun&& run);
  // forget_old()'s parts: the objects, then the pipelines that no known object or run refers to.
  void forget_known(uint64_t frame, const Residency& residency);
  void forget_pipelines();

  // Template plans are shared by every primitive of the template and winding; their errors are
  // zeroed (they differ with the placement's scale: Known::error_m holds the object's).
  struct PlanKey {
    const uint32_t* finest;  // the template's level-0 indices: unique per template
    bool flip;
    bool operator==(const PlanKey&) const = default;
  };
  struct PlanKeyHash {
    size_t operator()(const PlanKey& k) const {
      return std::hash<const void*>()(k.finest) ^ size_t(k.flip);
    }
  };

  const ReadView* view_ = nullptr;
  WorkerPool* workers_ = nullptr;
  std::vector<std::unique_ptr<ReadView>> siblings_;  // views_[1..]
  std::vector<const ReadView*> views_;  // per worker; empty until first needed
  // Known objects and runs: the pool (an entry is in use while keys_[i] != kFreeKey), the free
  // entries, and the directory that finds them by key.
  static constexpr uint32_t kFreeKey = UINT32_MAX - 1;  // no slot or run has it
  std::deque<Known> pool_;
  std::vector<uint32_t> keys_;
  std::vector<uint32_t> free_known_;
  size_t forget_hand_ = 0;  // forget_known()'s next entry to look at
  KnownDirectory directory_;
  std::unordered_map<PlanKey, MeshPlan, PlanKeyHash> plans_;  // few: per template and winding
  // Pipeline HLOD: the runs (a deque: growing it copies nothing; a forgotten pipeline's run
  // indices go to free_runs_ and are reused), this frame's decision per run, and per pipeline
  // the runs' indices and the members whose stretch was analysed (a member finds its run
  // there: a pipeline has few runs, and a map by member would cost 40 bytes a member).
  struct PipelineKnown {
    std::vector<uint32_t> runs;
    std::vector<uint32_t> analysed;  // slots, sorted
  };
  std::deque<PipelineRun> runs_;
  std::vector<RunDecision> decisions_;
  std::vector<uint32_t> free_runs_;
  std::unordered_map<uint64_t, PipelineKnown> pipeline_runs_;
  size_t pipelines_referenced_ = 0;  // at the last forget_pipelines()
  // The stretches this decode() analysed, and the stretch of each of their members (read_wave;
  // added by decode() in the order their first members are added).
  std::deque<Stretch> stretches_;
  std::unordered_map<uint32_t, Stretch*> stretch_of_;
  std::vector<uint32_t> new_slots_;
  size_t part_size_ = kNewObjectsPerPart;  // read_wave()'s, for decode() to find a part's error
  std::vector<Object> wave_objects_;
  std::vector<uint8_t> wave_read_;
  std::vector<std::string> wave_errors_;  // per part of a wave
  std::vector<Known*> decoded_;
  CompiledStyle style_;
  StyleValues style_values_;
  uint32_t style_epoch_ = 0;
  std::vector<uint32_t> restyle_;  // decode(): known slots to evaluate again
  Object object_;  // decode target
  std::vector<PackedVertex> occluder_scratch_;
};

}  // namespace plantview::detail
