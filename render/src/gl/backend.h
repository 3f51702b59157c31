// GL backend: every OpenGL call of the renderer, a pass per unit of render/src/gl:
//   backend.cpp         init, the frame's order of passes (begin_frame, draw_phase, finish_frame)
//   arena.cpp           the vertex arena's buffers (grown or mapped), the index buffers
//   programs.{h,cpp}    compiling and linking, uniforms, stream buffers; the programs' sources
//                       in program_sources.h, the shaders in shaders/*.glsl
//   targets.cpp         the framebuffers, and how a look chooses them (Plan)
//   objects.cpp         surfaces, proxy boxes, centrelines, see-through triangles; highlight
//   ground.cpp          the ground
//   finish.cpp          multisampling resolved, ambient occlusion, the finishing pass
//   occlusion_test.cpp  the depth reduction and the box test (occlusion culling)
//   readback.cpp        the image and object ids read back
//   gpu_context.cpp     the EGL context (plantview/render.h: GpuContext)
//
// Rules
//   - The arena is two GPU buffers indexed alike: vertices (PackedVertex) and the object-table
//     index of each vertex (uint32). They hold at least what streaming asks for and never more
//     than the budget; growing at least doubles them (each growth allocates new buffers, which
//     the driver zeroes, and copies the old: about 1 ms a MB on llvmpipe). A centreline vertex's
//     normal word holds the pipe's diameter in metres (float bits), not a normal.
//   - On a software renderer that can draw from client memory (GL_AMD_pinned_memory), the
//     arena is instead the whole budget of address space mapped once (ArenaMemory::automatic):
//     memory is taken only where vertices are written, and it never grows (no zeroing, no
//     copy), and uploads are written straight into it (no driver copy: every frame's draws
//     are finished before the next streams, as for the index buffer below, and a second
//     phase streams after its first was waited for). A GPU driver keeps the grown buffers (its
//     own memory is faster to draw from), and so does a budget the driver cannot map
//     (llvmpipe: over 4 GB of vertices).
//   - The index buffer holds the frame's lists one after the other in IndexList order; it is
//     written through an unsynchronised mapping, which is safe because every frame is finished
//     (read back) before the next begins.
//   - Draw order: the ground first (seen from above only; its depth is written a little farther
//     than its plane, so that what stands on it is drawn over it and what is blended blends
//     over it), then closed opaque solids (back faces culled), open opaque meshes, proxy boxes
//     (one object-table entry each, the faces the eye sees drawn from it in one draw: no arena
//     vertices), centrelines (quads as wide as the pipe, blended), then the see-through
//     triangles blended without writing depth. Depth is reversed (greater wins).
//   - Highlight (Look::highlight_ids non-empty): the subject is drawn first, marking its pixels
//     in the stencil; the context (every other object, ghosted: lighter, desaturated, pick 0)
//     then where the subject is not, and once more, blended faintly and without depth, where it
//     lies in front of the subject: occluders are see-through. See-through subjects (a subject
//     colour with alpha, Look::subject_colours) are left out of the first draw: they mark their
//     pixels without drawing anything after it (the context in front of them is see-through
//     too), and are drawn last, blended at their alpha (more opaque along their outline:
//     u_rim), depth tested but not written, no ids: the subjects inside them show through.
//   - Framebuffers: the frame is drawn at `scale` x the output's size (2 when supersampled) with
//     `samples` per pixel (multisampled: resolved into textures by a blit; the depth is a
//     multisampled texture, which the depth reduction reads sample by sample, with a stencil
//     only once a frame highlights), then finished into the output size by one full-screen pass
//     when anything needs it (supersampling, the edge filter, ambient occlusion); object ids
//     follow one sample per output pixel.
//   - Object ids are written only when read back (with_ids).
//   - Sections (Look::section): its planes, then the faces of its box that cut the model, as
//     camera-relative half-spaces (offsets computed in double precision from the eye), are
//     clipped per vertex by gl_ClipDistance in every program that draws the model, never the
//     ground (section_clip.glsl; the closed solids of objects it does not cut, kClosed, are
//     drawn unclipped by the plain surface program): at most kMaxClipHalfSpaces, the rest of
//     a box's faces (three planes or more and a box cutting the model on every side) only
//     cull whole objects (frame_plan.h). Clipped fragments write neither colour, depth nor id. Capped
//     (Section::capped): the closed solids of the objects the section cuts (kClosedCut) are
//     drawn first in each phase, before the other closed solids (which would hide their back
//     faces where they lie inside them: a pipe through a vessel would show through its cap;
//     what an earlier phase drew inside a cut solid still does), with both sides, a front
//     face that passes the depth test clearing stencil bit kCapStencilBit and a back face
//     setting it: at the end it is
//     set where a back face is seen, which happens only where a solid is cut open. Their back
//     faces are then drawn again through the cap program where marked, each fragment moved
//     onto the cut (cap.frag.glsl), and the marks cleared. The cap's depth, colour and id are
//     written like a surface's. Where a non-convex solid's cut leaves air between the cut
//     plane and a face behind it, the cap covers that too (stencil capping by parity would
//     not). Cost: the cut objects' back faces rasterised, their vertices twice, the cap pass's
//     fragments tested late (it writes gl_FragDepth) where the stencil lets them.
// Units: arena offsets and sizes in vertices; buffer capacities in bytes; pixels; metres.
// Threads: the thread whose GL context was current at init(), which must stay current for
//   every call and for the destructor.
// Errors: false with "renderer: ..." naming what failed (shader log, sizes, the GL error code).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/image.h"
#include "plantview/primitives.h"
#include "plantview/render.h"

#include "gl/program_sources.h"

namespace plantview::detail {

struct FrameView;
struct GhostMesh;

// One entry of the per-frame object table (std430: two vec4), read by the vertex shader.
struct TableEntry {
  float offset_m[3];  // the object's origin relative to the eye
  uint32_t colour;    // RGBA8
  float scale[3];     // 1 for objects; the box size for proxies
  // Low 32 - kTieBits bits: index into the frame's pick table + 1 (0: no object). High bits:
  // the object's tie-break t (tie_of): its depth is drawn t x kTieStep (relative) farther, so
  // that where two objects' surfaces coincide the same one shows whatever the order they are
  // drawn in (occlusion's phases draw an object earlier or later as the frames before it
  // differ). Farther only: what a test reads of drawn depth stays conservative. 1.5e-5 at
  // most: 1.5 mm at 100 m.
  uint32_t pick;
};
static_assert(sizeof(TableEntry) == 32);
// gl/shaders/tie_constants.glsl agrees (checked when compiled: gl/program_sources.cpp).
inline constexpr uint32_t kTieBits = 6;
inline constexpr uint32_t kTieStepInverse = 1u << 22;  // 1 / kTieStep
inline constexpr uint32_t kPickLimit = 1u << (32 - kTieBits);  // picks in a frame, at most
// The tie-break of an object from its order key (Known::order_key: from its id), spread.
inline uint32_t tie_of(uint32_t order_key) { return (order_key * 2654435761u) >> (32 - kTieBits); }

inline constexpr uint64_t kBytesPerVertex = sizeof(PackedVertex) + sizeof(uint32_t);
// With bounded drawing on a software renderer, triangles drawn at a time at most (see
// GlBackend::draw_triangles).
inline constexpr size_t kSoftwarePieceTriangles = size_t(1) << 17;

// Half-spaces a section clips on the GPU at most (GL_MAX_CLIP_DISTANCES is at least 8).
inline constexpr int kMaxClipHalfSpaces = 8;
// The stencil bit marking the pixels where a cut solid shows its inside (highlights use bit 0).
inline constexpr uint32_t kCapStencilBit = 2;
// A section's half-spaces relative to `eye_m` (x, y, z, w: removed where dot(xyz, p) + w > 0):
// its planes, then the faces of its box that cut `model_bounds`, at most kMaxClipHalfSpaces.
int section_half_spaces(const Section& section, const glm::dvec3& eye_m, const DAabb& model_bounds,
                        std::array<glm::vec4, 8>& out);

using GlName = uint32_t;  // a GLuint: the name of a GL object (0: none)

// The frame's index lists, in this order in the index buffer. kClosedCut: the closed solids of
// objects the section cuts (Draw::cut; capped, see the rules above).
enum IndexList : uint8_t { kClosed, kClosedCut, kOpen, kTransparent, kLines, kIndexListCount };
using IndexCounts = std::array<size_t, kIndexListCount>;

// How a frame looks: RenderOptions' look, and the model's bounds for the ground.
struct Look {
  bool antialias = true;
  AntialiasMethod method = AntialiasMethod::automatic;
  uint32_t samples = 0;  // multisampling (0: 4)
  bool ground = true;
  bool ambient_occlusion = true;
  std::span<const uint64_t> highlight_ids;  // any order; valid for the draw call
  // A change image's or a clash view's subject colours (RGBA8, sorted by id): a subject object
  // listed here is drawn in that colour (its alpha kept) instead of its own; with an alpha
  // under 255 it is a see-through subject, drawn at that alpha (see the highlight rule above).
  // Valid for the draw call.
  std::span<const std::pair<uint64_t, uint32_t>> subject_colours;
  const Section* section = nullptr;         // null or empty: none; valid for the frame
  DAabb model_bounds;                       // world metres (the ground lies at min.z)
};
Look look_of(const RenderOptions& options, const DAabb& model_bounds);

// How the arena's buffers are made (see the rules above).
enum class ArenaMemory {
  automatic,  // mapped where the renderer is software and can draw from client memory
  grown,      // GPU buffers grown on demand
};

class GlBackend {
 public:
  GlBackend() = default;
  ~GlBackend();
  GlBackend(const GlBackend&) = delete;
  GlBackend& operator=(const GlBackend&) = delete;

  // Compiles the shaders and makes the buffers and vertex arrays, the arena at its initial size
  // (at most budget_vertices, which bounds every later growth), or mapped whole. Needs a
  // current OpenGL 4.5 context.
  bool init(uint64_t budget_vertices, std::string& error,
            ArenaMemory memory = ArenaMemory::automatic);
  // Whether the arena is the budget mapped once (no growth ever), and its size in vertices.
  bool arena_mapped() const { return !mapped_vertices_.empty(); }
  uint64_t arena_vertices() const { return arena_vertices_; }

  // The arena buffers hold at least `vertices` (capped at the budget), keeping their contents.
  // A growth allocates the larger of twice the arena and half as much again as asked: the
  // frames after one that needed a large step (the first view) mostly need a little more,
  // and every growth zeroes a whole new buffer.
  bool grow_arena(uint64_t vertices, std::string& error);
  // Whether drawing holds memory down at some cost in speed (see draw_triangles): the
  // renderer asks it for models larger than the vertex budget.
  void set_bounded_drawing(bool bounded) { bounded_drawing_ = bounded; }
  // Milliseconds grow_arena() spent growing the buffers since the last call.
  double take_growth_ms() { return std::exchange(growth_ms_, 0.0); }
  // Writes vertices at arena offset `first` (and, unless `objects` is empty, their object-table
  // indices alike). The range must lie within the arena's current size.
  void upload(uint64_t first, std::span<const PackedVertex> vertices,
              std::span<const uint32_t> objects);

  // The index buffer, mapped for writing `count` indices; unmap_indices() before drawing. Null
  // with an error if it cannot be mapped. There are two: the one drawn from, which a frame's
  // phases write in turn (each waits for the one before), and the other (`next`), which the
  // look ahead writes the next frame's first phase into while the GPU still draws from the
  // first; use_next_indices() then makes it the one drawn from.
  uint32_t* map_indices(size_t count, std::string& error, bool next = false);
  void unmap_indices(bool next = false);
  void use_next_indices();

  // A frame, drawn in one phase or more (occlusion culling's two phases, occlusion.h):
  // begin_frame() makes the targets for the view's size, clears them and draws the ground (as
  // `look` says); each draw_phase()
  // draws its lists (counts per list, as written) and its proxy boxes, one per entry of
  // `proxy_tables`, with the object table `table` (its pick values index `pick_ids`), as `look`
  // says, into the same framebuffer without clearing (`wait`: returns once the GPU has drawn
  // them); reduce_depth() reads what has been drawn back as a coarse depth grid;
  // finish_frame() finishes the image into the output's size and waits for the GPU (`wait` false: sends it all to the GPU and returns; wait() then waits).
  bool begin_frame(const FrameView& view, const Look& look, bool with_ids, std::string& error);
  void draw_phase(const FrameView& view, const IndexCounts& counts,
                  std::span<const TableEntry> table, std::span<const uint32_t> proxy_tables,
                  std::span<const uint64_t> pick_ids, const Look& look, bool with_ids, bool wait);
  void finish_frame(const FrameView& view, bool with_ids, bool wait = true);
  // A change image's ghosts (change_set.h: GhostMesh), after the frame's objects and before
  // finish_frame(): blended, writing no depth; where in front of what was drawn at
  // kGhostFrontAlpha (writing their pick values, first_pick + ghost index + 1, when with_ids),
  // where behind it fainter (kGhostBehindAlpha, colour only), so that a removed object deep in
  // a rack still shows. Clipped by the frame's section like the objects. Its own small
  // buffers (gl/ghosts.cpp), grown to the largest mesh drawn.
  void draw_ghosts(const FrameView& view, const GhostMesh& ghosts, uint32_t first_pick,
                   bool with_ids);
  void wait();
  // The depth drawn so far in the frame, reduced to cells_width x cells_height cells over the
  // image (rows bottom-up): each cell the farthest reversed depth (the least; 0 where nothing
  // was drawn) over every sample of every framebuffer pixel it overlaps. Between
  // begin_frame() and finish_frame(); waits for the GPU. `depth` is resized to the cells.
  // Occlusion's exact test: which of `boxes` (eye-relative {min, max} pairs, metres; none
  // holding the eye) have a sample of their front faces that is not behind what has been
  // drawn so far in the frame (reversed depth greater or equal). seen[i] is non-zero for
  // those. The faces are not clipped at the near plane: their depth is clamped to it (depth
  // clamping), so that a box reaching past it, or past the eye's plane, is seen wherever a
  // ray of the view meets it (where it enters the box, at the near plane or beyond). Nothing
  // is drawn. Between begin_frame() and finish_frame(); waits for the GPU.
  bool test_boxes(const FrameView& view, std::span<const glm::vec4> boxes,
                  std::vector<uint32_t>& seen, std::string& error);
  // A software renderer (llvmpipe and the like: fragments are the cost).
  bool software() const { return software_; }
  bool reduce_depth(uint32_t cells_width, uint32_t cells_height, std::vector<float>& depth,
                    std::string& error);
  // Reads the frame drawn back into `out` (top row first). with_ids: also the object ids, each
  // pixel's pick value p mapped to pick_ids[p - 1] (0 where nothing was drawn).
  bool read_back(uint32_t width, uint32_t height, bool with_ids,
                 std::span<const uint64_t> pick_ids, Image& out, std::string& error);

 private:
  // A framebuffer with colour (RGBA8), pick (R32UI) and, optionally, depth (DEPTH_COMPONENT32F,
  // or DEPTH32F_STENCIL8 once a frame highlights) attachments: textures when single-sampled,
  // else renderbuffers.
  struct Target {
    GlName framebuffer = 0, colour = 0, pick = 0, depth = 0;
    uint32_t width = 0, height = 0, samples = 0;
    bool has_depth = false;
    bool has_pick = false;  // an id attachment: made the first time a frame asks for ids
    bool has_stencil = false;  // depth with stencil (else depth alone): see ensure_target()
  };
  // What a frame is drawn with, from the look and the device.
  struct Plan {
    uint32_t scale = 1, samples = 1;
    bool edge_filter = false, occlusion = false;
    bool finish() const { return scale > 1 || edge_filter || occlusion; }
  };
  Plan plan_for(const Look& look) const;
  bool ensure_target(Target& t, uint32_t w, uint32_t h, uint32_t samples, bool depth, bool pick,
                     bool stencil, std::string& error);
  static void release_target(Target& t);
  void bind_arena();
  // Binds the drawing framebuffer and sets the depth state and the programs' uniforms for the
  // view.
  void begin_pass(const FrameView& view, const Plan& plan, bool with_ids);
  // One draw call per non-empty list, and the proxy boxes (instanced), in the order of the
  // rules, in highlight mode `mode` (gl/shaders/object_table.glsl). see_through: every list blended at
  // `alpha`, depth not written, ids not written.
  void draw_lists(const IndexCounts& counts, size_t proxies, int mode, float alpha,
                  bool with_ids);
  void draw_ground(const FrameView& view, const DAabb& bounds, bool with_ids);
  // Draws `count` indices of the index buffer from index `first` as triangles. A software
  // renderer keeps a draw's triangles, binned, in memory until it has rasterised them, and its
  // setup runs several scenes ahead of rasterisation (llvmpipe: about 130 MB for a frame of a
  // million triangles). With bounded drawing there the list is drawn in pieces of
  // kSoftwarePieceTriangles, the next binned while the last is rasterised and no further
  // ahead, so that at most two are held. Measured (llvmpipe, 2 cores, render --path): peak
  // resident memory about 100 MB lower, drawing 5-9% slower, images identical.
  void draw_triangles(size_t first, size_t count) const;
  // The cut closed solids (`count` indices from `first`) with their caps, in highlight mode
  // `mode` (see the rules above).
  void draw_cut_capped(size_t first, size_t count, int mode);
  // Enables the section's clip distances (begin_pass) or disables them (passes that do not
  // write them).
  void set_clipping(bool on) const;
  // Resolves multisampling and runs the finishing pass into output_.
  void finish(const FrameView& view, const Plan& plan, bool with_ids);
  // The table with the context ghosted for a highlight: colours lightened and desaturated,
  // picks 0. Sets see_through_subjects_.
  std::span<const TableEntry> highlighted(
      std::span<const TableEntry> table, std::span<const uint64_t> pick_ids,
      std::span<const uint64_t> highlight_ids,
      std::span<const std::pair<uint64_t, uint32_t>> subject_colours);

  // A single-texture framebuffer that a pass renders into, sized on demand.
  struct Grid {
    GlName framebuffer = 0, texture = 0;
    uint32_t width = 0, height = 0;
  };
  // Makes `g` w x h of GL internal format `gl_format` (anew only when its size changed).
  static void ensure_grid(Grid& g, uint32_t gl_format, uint32_t w, uint32_t h);
  static void release_grid(Grid& g);

  // The frame's section as camera-relative half-spaces (section_clip.glsl), from
  // begin_frame().
  std::array<glm::vec4, 8> clip_{};
  int clip_count_ = 0;
  bool caps_ = false;

  uint64_t budget_vertices_ = 0;
  bool software_ = false;  // llvmpipe and the like: fragments are the cost
  bool bounded_drawing_ = false;
  std::array<GlName, kProgramCount> programs_{};  // linked at init(), by ProgramId
  GlName gl_program(ProgramId id) const { return programs_[size_t(id)]; }
  // Surface, proxy or centreline as this frame draws with it: the section variant
  // when the frame has a section.
  GlName drawing_program(ProgramId id) const {
    return gl_program(clip_count_ > 0 ? sections_variant(id) : id);
  }
  GlName box_buffer_ = 0, seen_buffer_ = 0;
  size_t box_capacity_ = 0, seen_capacity_ = 0;  // bytes
  GlName vao_ = 0, empty_vao_ = 0, arena_ = 0, arena_objects_ = 0, table_buffer_ = 0,
         proxy_buffer_ = 0;
  std::array<GlName, 2> index_buffers_{};  // [drawn_indices_] is drawn from
  std::array<size_t, 2> index_capacities_{};  // bytes
  unsigned drawn_indices_ = 0;
  GlName linear_sampler_ = 0, nearest_sampler_ = 0;
  // Client memory mapped for the arena (see the rules above): unmapped on destruction, after
  // the buffers that draw from it are deleted.
  class Mapping {
   public:
    Mapping() = default;
    ~Mapping();
    Mapping(const Mapping&) = delete;
    Mapping& operator=(const Mapping&) = delete;
    // Reserves `bytes` of zeroed address space, backed only where written (and up to
    // kCommitStep beyond: commit_to); false if refused.
    bool map(size_t bytes);
    void reset();  // unmaps
    void* data() const { return data_; }
    bool empty() const { return data_ == nullptr; }
    // Before writing below `end_bytes`: backs the pages up to it at once, kCommitStep at a time
    // (one call, not a page fault a page: on this VM 0.4 ms a MB against 0.6-1.1). The arena
    // is allocated from its start up (residency.h: best fit, the lowest first), so what lies
    // below the highest write is written too. Where the kernel cannot, the writes fault the
    // pages in as before.
    void commit_to(size_t end_bytes);
    static constexpr size_t kCommitStep = size_t(2) << 20;

   private:
    void* data_ = nullptr;
    size_t bytes_ = 0;
    size_t committed_ = 0;  // [0, committed_) backed
    bool can_commit_ = true;
  };
  // Makes the arena's buffers from client memory, the whole budget at once: false (nothing
  // changed) where the driver or the system refuses.
  bool map_arena();

  uint64_t arena_vertices_ = 0;  // size of the arena's buffers, in vertices (<= the budget)
  double growth_ms_ = 0;
  Mapping mapped_vertices_, mapped_objects_;  // unmapped after ~GlBackend deleted the buffers
  // Drawing goes to scene_ (scale x the output's size, multisampled or not); multisampled, it
  // is resolved into resolved_; finished, into output_; read back from the last of these used.
  Target scene_, resolved_, output_;
  // Ambient occlusion and depth per 2x2 output pixels (RG32F), before the finishing pass
  // blurs it.
  Grid occlusion_grid_;
  // The depth reduction's grid (R32F).
  Grid reduce_grid_;
  // Reduction programs for whole pixels per cell, by (pixels across, pixels up, samples).
  std::vector<std::pair<std::array<uint32_t, 3>, GlName>> reduce_fixed_;
  Plan frame_plan_;  // the frame's, from begin_frame()
  const Target* final_ = nullptr;
  size_t table_capacity_ = 0, proxy_capacity_ = 0;  // bytes
  std::vector<uint32_t> pick_pixels_;  // read-back scratch
  std::vector<uint8_t> row_;  // read-back scratch: one row of the image
  // draw_ghosts(): its vertex array, vertices, their ghost indices, indices and table.
  struct GhostBuffers {
    GlName vao = 0, vertices = 0, objects = 0, indices = 0, table = 0;
    size_t vertex_capacity = 0, object_capacity = 0, index_capacity = 0, table_capacity = 0;
    std::vector<TableEntry> entries;
  } ghost_;
  void release_ghost_buffers();
  std::vector<TableEntry> highlight_table_;
  std::vector<uint64_t> highlight_sorted_;
  bool see_through_subjects_ = false;  // highlighted(): the table holds see-through subjects
};

}  // namespace plantview::detail
