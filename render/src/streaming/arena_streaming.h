// Arena streaming (Zhou et al. section 4): makes the frame's draws resident in the GPU vertex
// arena, tessellating objects from their parameters, evicting by visibility counter
// (residency.h), and hands each draw an object-table entry; then writes the frame's index
// lists.
//
// Rules
//   - The arena never exceeds its budget (Residency's capacity, in vertices).
//   - An object is made resident from resident_base() of its chosen level (frame_plan.h): the
//     vertices of that level serve every coarser one. Refining below the resident base
//     tessellates it again (objects_refined). Over budget, it is made resident at its coarsest
//     level (budget_coarsened), else drawn as its box (budget_proxies; merged runs are then
//     skipped, their members' boxes would be drawn one by one).
//   - Progressive refinement (RenderOptions::stream_budget_vertices > 0): the frame's draws,
//     largest on screen first, spend the budget in vertices tessellated, across the frame's
//     phases; once it is spent, a resident object that would be tessellated again for a finer
//     level keeps its resident base (drawn coarser), and one not resident is made resident
//     from its coarsest level (objects_deferred). The decision is made once per draw, in
//     prepare(), so that what is tessellated ahead is what is placed.
//   - The GPU buffers grow once a frame, before streaming, for what the frame may need (and
//     again only if a placement lands beyond them).
//   - Object-table entries: resident objects hold one while resident; proxy boxes hold one
//     until the next frame streams. Entry offsets are relative to the eye (double
//     precision until the final subtraction).
//   - Index lists: each drawn object's indices at its level, nearest first (hidden fragments
//     then fail the depth test before they are shaded), into the list of its kind.
// Units: arena offsets and sizes in vertices (kBytesPerVertex bytes each); metres.
// Ownership: owns the residency, the object table, the templates' compactions (kept for the
//   renderer's life: Known::Part::resident_plan points into them) and its scratch buffers
//   (reused: no allocation per frame once warm). Uses the GlBackend it is given, which must
//   outlive it.
// Threads: the renderer's thread (it calls GL through the backend), with the renderer's worker
//   pool (worker_pool.h) for two parts: newly resident objects are tessellated on it first,
//   up to kPrepareBatch draws or kPrepareBatchVertices vertices at a time (so that what waits
//   for upload stays bounded; the jobs' buffers keep at most kKeptJobBytes between batches;
//   each job writes only its own object and buffers), then placed and uploaded on the
//   renderer's thread; and the index lists are written on it, each worker a run of the draw
//   order into its own ranges.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "gl/backend.h"
#include "plantview/render.h"
#include "radix_sort.h"
#include "streaming/residency.h"
#include "worker_pool.h"

namespace plantview::detail {

struct Draw;
struct FrameView;
struct Known;
class DecodedObjects;
class FramePlan;
class FrameColouring;

// The per-frame object table the vertex shader reads, and the frame's pick ids (the value a
// pixel's pick p stands for is pick_ids[p - 1]).
class ObjectTable {
 public:
  void reset();
  uint32_t acquire();
  void release(uint32_t entry) { free_.push_back(entry); }
  // Fills `entry` for this frame and gives it the next pick id; `tie` is its depth tie-break
  // (TableEntry::pick).
  void set(uint32_t entry, const glm::dvec3& offset_m, const glm::vec3& scale, Colour colour,
           uint64_t id, uint32_t tie = 0);
  void begin_frame() { pick_ids_.clear(); }
  std::span<const TableEntry> entries() const { return {entries_.data(), used_}; }
  std::span<const uint64_t> pick_ids() const { return pick_ids_; }

 private:
  std::vector<TableEntry> entries_;
  std::vector<uint32_t> free_;
  uint32_t used_ = 0;  // high-water mark
  std::vector<uint64_t> pick_ids_;
};

class ArenaStreaming {
 public:
  // `backend` and `pool` must outlive it.
  ArenaStreaming(GlBackend& backend, WorkerPool& pool) : backend_(backend), pool_(pool) {}

  // Forgets everything resident (a new snapshot): an empty arena of budget_vertices.
  // drop_primitives: resident objects give up their primitives (models larger than the budget).
  void reset(uint64_t budget_vertices, bool drop_primitives);

  // Makes the plan's draws resident (or boxes), fills each drawn one's arena_first and level,
  // the object table, the proxy boxes (over-budget objects and the plan's node boxes) and the
  // index counts; counts triangles, lines and the arena statistics. False on a GL or store
  // error. second_phase: the plan is the second phase of the frame streamed last (occlusion.h):
  // what the first made visible stays visible (not evicted), its boxes and pick ids stay (its
  // pixels are drawn), and index_counts() and proxy_tables() are this phase's alone; the
  // counts add to the first phase's.
  bool stream(FramePlan& plan, DecodedObjects& objects, const FrameView& view,
              const RenderOptions& options, FrameStats& stats, std::string& error,
              bool second_phase = false);
  // Writes the index lists of the draws streamed into the backend's index buffer (`next`: the
  // one the next frame draws from, GlBackend::map_indices).
  bool write_index_lists(std::span<const Draw> draws, std::string& error, bool next = false);

  // While deferring (a frame streamed ahead, while the GPU still draws the one before from the
  // arena), the vertices of objects made resident are kept here instead of written into the
  // arena, where they could overwrite what an evicted object is still drawn with; they are
  // written by flush_uploads(), which the renderer calls before it draws again. The residency,
  // the object table and the Knowns change as if written.
  void defer_uploads(bool on) { deferring_ = on; }
  // The colours stream() writes into the object table: by colour-by value (object_style.h),
  // or (null) the objects' own. It must outlive the stream() calls it is set for.
  void colour_by(const FrameColouring* colouring) { colouring_ = colouring; }
  void flush_uploads();

  const Residency& residency() const { return residency_; }
  const IndexCounts& index_counts() const { return counts_; }
  const ObjectTable& table() const { return table_; }
  // This phase's proxy boxes (the frame's, drawn in one phase).
  std::span<const uint32_t> proxy_tables() const {
    return std::span<const uint32_t>(proxy_tables_).subspan(phase_proxies_);
  }

 private:
  // A template's levels from `base` on, over only the vertices they use: what an object
  // resident from a coarser base draws with. Depends on the template alone (its index spans,
  // the base and the winding), so it is built once and shared by every object of that template.
  struct Compaction {
    std::vector<uint32_t> kept;  // template vertex numbers, in the compacted order
    std::array<std::vector<uint32_t>, kMaxLevels> indices;  // levels >= base, into `kept`
    MeshPlan plan;  // the template's plan with these indices; vertex_count = kept.size()
  };
  struct CompactionKey {
    const uint32_t* finest;  // the template's level-0 indices: unique per template
    uint8_t base;
    bool flip;
    bool operator==(const CompactionKey&) const = default;
  };
  struct CompactionKeyHash {
    size_t operator()(const CompactionKey& k) const {
      return std::hash<const void*>()(k.finest) ^ (size_t(k.base) << 1) ^ (size_t(k.flip) << 5);
    }
  };

  const Compaction& compaction(const MeshPlan& plan, uint8_t base);
  // Whether `k` is resident, without a residency lookup: a known object or run holds an
  // object-table entry exactly while it is resident (make_resident, release and eviction keep
  // the two together; forget_old() never drops a resident Known).
  static bool resident(const Known& k);
  // Vertices an object takes in the arena when resident from level `base` on.
  uint64_t resident_vertices(const Known& k, uint8_t base);
  // A draw's vertices tessellated ahead of streaming, at the base it will most likely get.
  struct Job {
    uint32_t draw = 0;
    uint8_t base = 0;
    std::vector<PackedVertex> vertices;
  };
  // The vertices `k` takes in the arena from level `base` on, into `out` (scratch: level 0's),
  // and its parts' resident layout. The compactions it needs must exist (resident_vertices).
  // Safe on several threads at once for different objects.
  void tessellate(const std::vector<Primitive>& primitives, Known& k, uint8_t base,
                  std::vector<PackedVertex>& scratch, std::vector<PackedVertex>& out) const;
  // What the frame's streaming budget leaves a draw that needs vertices (see the rules).
  enum class Defer : uint8_t { none, keep_coarser, coarsest };
  // Decides it for a draw that needs vertices and spends the budget for it.
  Defer spend_budget(const Known& k, uint8_t base);
  // Tessellates the newly resident objects of the first draws of `draws` on every core
  // (jobs_, job_of_draw_ and defer_of_draw_ by index in the batch), as many draws as fit
  // kPrepareBatchVertices (at least one): returns how many.
  size_t prepare(std::span<Draw> draws, LodPolicy policy);
  // Makes `k` resident in the arena from level `base` on (tessellating it unless `prepared`
  // holds its vertices for that base), evicting if needed. fits = false when it cannot be
  // placed without evicting what this frame shows.
  bool make_resident(uint32_t key, Known& k, uint8_t base, DecodedObjects& objects,
                     FrameStats& stats, std::string& error, bool& fits,
                     const std::vector<PackedVertex>* prepared = nullptr);
  void release(uint32_t key, Known& k);
  // Makes a draw's object resident at the level chosen (or coarser, over budget) unless its
  // resident vertices serve it. resident = false: it cannot be, even at its coarsest level.
  bool ensure_resident(Draw& d, DecodedObjects& objects, LodPolicy policy, FrameStats& stats,
                       std::string& error, bool& resident, const Job* job, Defer defer);
  // A resident draw: its level (no finer than the resident base), arena offset, table entry,
  // and its indices counted into their lists.
  void place(Draw& d, const FrameView& view, FrameStats& stats);
  // A proxy box for this frame: `offset_m` (its min corner, eye-relative) and `size_m`.
  void add_box(const glm::dvec3& offset_m, const glm::vec3& size_m, Colour colour, uint64_t id,
               FrameStats& stats);
  // Marks what the frame shows visible, so that nothing it shows is evicted; a second phase
  // adds to the first (see stream()).
  void begin_frame(const FramePlan& plan, bool second_phase);
  // Grows the GPU buffers once for what the frame may stream (with the level slack), rather
  // than object by object: every new buffer is zeroed and the old one copied into it.
  bool grow_for(std::span<const Draw> draws, LodPolicy policy, std::string& error);

  GlBackend& backend_;
  WorkerPool& pool_;
  Residency residency_{0};
  ObjectTable table_;
  const FrameColouring* colouring_ = nullptr;
  Colour colour_of(const Known& k) const;
  bool drop_primitives_ = false;
  std::unordered_map<CompactionKey, Compaction, CompactionKeyHash> compactions_;  // few
  IndexCounts counts_{};
  // Scratch, reused.
  std::vector<uint32_t> proxy_tables_;  // the frame's boxes, both phases
  size_t phase_proxies_ = 0;            // where this phase's begin
  std::vector<PackedVertex> vertices_, compacted_;
  std::vector<uint32_t> vertex_objects_, remap_, draw_order_;
  std::vector<SortPair> sort_keys_, sort_scratch_;  // (distance, order key), draw
  std::vector<SortPair> box_keys_;  // (nearest distance, index), node box
  // This frame's index ranges to write, drawn objects' parts in draw order (Draw::segment_*):
  // a plan's level at a base vertex, into a list; lines: `plan` null, `count` line vertices.
  struct Segment {
    const MeshPlan* plan;
    uint32_t base_vertex;
    uint32_t count;  // indices
    uint8_t level;
    uint8_t list;
  };
  std::vector<Segment> segments_;
  // Deferred uploads (defer_uploads()): where each goes in the arena, its object-table entry,
  // and its vertices' range in pending_vertices_.
  struct PendingUpload {
    uint64_t offset;
    uint32_t table;
    size_t first, count;
  };
  bool deferring_ = false;
  std::vector<PendingUpload> pending_;
  std::vector<PackedVertex> pending_vertices_;
  std::vector<std::pair<uint32_t, uint64_t>> evicted_;
  std::vector<Job> jobs_;
  std::vector<uint32_t> job_of_draw_;
  std::vector<Defer> defer_of_draw_;
  // The frame's streaming budget (RenderOptions::stream_budget_vertices): whether it is
  // bounded, and the vertices left; set when a frame's first phase streams.
  bool budget_bounded_ = false;
  uint64_t budget_left_ = 0;
  std::vector<std::vector<PackedVertex>> scratch_;  // one per worker
  // write_index_lists(): where each run of the draw order starts writing, per list.
  std::vector<std::array<size_t, kIndexListCount>> run_cursors_;
  std::vector<size_t> run_first_;  // and the first draw (in draw order) of each run
};

inline constexpr size_t kJobsPerWorker = 16;     // fewer new objects are not worth a thread
inline constexpr size_t kIndicesPerRun = 1u << 16;  // fewer indices are not worth a worker
inline constexpr size_t kPrepareBatch = 256;     // draws tessellated ahead at a time, at most
inline constexpr size_t kPrepareBatchVertices = 1u << 19;  // and their vertices (8 MB), at most
inline constexpr size_t kKeptJobVertices = 1u << 16;  // a job buffer larger is freed
inline constexpr size_t kKeptJobBytes = size_t(8) << 20;  // all the jobs' buffers keep at most

}  // namespace plantview::detail
