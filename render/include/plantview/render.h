// plantview/render.h: the headless renderer. Turns a store and a camera into an image, an
// object-id buffer and the frame's LOD statistics, for models far larger than memory.
//
// Per frame (Zhou et al. 2012 section 4, Su et al. section 5.3):
//   1. cull     walk the store's paged spatial index (its resident top, then the blocks it
//               enters, read on demand) against the view frustum. Screen-space policy:
//               objects whose extent projects under the pixel error are left out, and a tree
//               node spanning under 3 x the pixel error is drawn whole: a top node as its
//               stored far-field proxy (a few boxes in its objects' colours), a node inside a
//               block as one box (that size doubles until at most 32,768 objects and boxes
//               remain in view), so a far view of a huge plant costs what the image holds,
//               not what the plant holds, and reads none of the far blocks;
//   1b. occlude (on by default) in two phases when the frame is drawn: first the objects
//               drawn in the previous frame that are still in view and the largest on screen
//               go through steps 2-4; the depth they drew is reduced on the GPU to a coarse
//               grid (each cell's farthest depth) and read back; tree leaves, objects and node
//               boxes hidden behind it are left out, the rest go through steps 2-4 into the
//               same image. statistics() rasterises the largest objects on the CPU instead.
//               What is left out is neither decoded, tessellated, uploaded nor drawn, and its
//               visibility counter ages like a culled object's. Nothing visible is dropped;
//   2. choose   a level per visible object by LodPolicy (screen-space error by default); pipes
//               whose diameter projects under a pixel, and under the pixel error where that is
//               finer, are drawn as their centreline.
//               Pipeline HLOD: a straight run of pipes and inline components is drawn as one
//               cylinder where the components' relief projects under the pixel error;
//   3. stream   vertices of newly visible objects are tessellated from their parameters into one
//               GPU vertex arena of fixed size (20 bytes a vertex: position, packed normal and
//               the object-table index). The GPU buffer grows to what each frame needs,
//               doubling, up to the budget; a model larger than the budget at full resolution
//               gets the whole budget at once (growing copies the buffer, and old plus new would
//               exceed it), and its resident objects keep only what drawing needs (their
//               primitives are decoded again from the store if they must be tessellated again). An
//               object is made resident from one level below its chosen one (from the chosen
//               one once the arena is half full): the vertices of a level serve every coarser
//               level, so coarsening, and refining within that slack, only changes the index
//               range drawn; refining beyond it tessellates the object again. Every resident
//               object has a visibility counter, reset when it is visible and incremented each
//               frame it is not; when the arena is full, the largest counters are evicted first.
//               The arena never exceeds its budget: a visible object that does not fit is made
//               resident at its coarsest level (`budget_coarsened`), else drawn as its box
//               (`budget_proxies`);
//   4. draw     one draw call per kind of geometry (closed solids with back faces culled, open
//               meshes, see-through, lines, boxes): every vertex carries the index of its object
//               in a per-frame object table that holds the object's origin relative to the eye
//               (computed in double precision), its colour and its pick id; so plants
//               kilometres from the origin do not jitter, and the draw-call count does not grow
//               with the object count;
//               Nearest objects are drawn first, so that hidden fragments fail the depth test
//               before they are shaded; object ids are drawn only when asked for.
//               Surfaces are lit by a hemisphere light (sky above, ground below), a key light
//               from above behind the eye's left shoulder and a fill from the eye. Centrelines
//               are quads as wide as the pipe's projected diameter (at least a pixel, its
//               coverage the diameter below one), in the pipe's colour, lit like its side.
//               Then the ground (RenderOptions::ground) where nothing else is; with a highlight,
//               the subject first, then the ghosted rest, see-through where it hides the subject;
//   5. finish   antialiasing (supersampled frames averaged down, multisampling resolved, or the
//               edge filter) and ambient occlusion, in one full-screen pass;
//   6. read back colour (RGBA8, sRGB values) and object ids (one sample per pixel).
//
// Inside, the renderer is a frontend and a backend (as Filament separates them): the frame plan
// (camera -> view, cull, choose; no GL), the decoded objects, arena streaming and the GL backend
// (GL resources, draw, read back), one file each under render/src.
//
// Units: lengths in metres, angles in degrees where the name says _deg, times in milliseconds.
// Threads: a GpuContext and every Renderer made with it belong to the thread that made them;
//          so does the store snapshot a Renderer reads (read_view()).
// Lifetimes: the GpuContext and the Store must outlive every Renderer made with them.
// Errors: fallible calls return false (or null) and fill `error` with what and where.
//
// Cameras (camera.h) and images (image.h) have headers of their own; this one includes both.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/camera.h"
#include "plantview/image.h"
#include "plantview/model.h"
#include "plantview/view_filters.h"

namespace plantview {

class ReadView;
class Store;

// ---------------------------------------------------------------------------------------------
// Options and statistics.

enum class LodPolicy {
  screen_space,  // the coarsest level whose error projects under pixel_error (default)
  distance,      // the papers' rules: level by distance over object size (Zhou), pipes as
                 // centrelines beyond a distance proportional to their radius (Su's d2)
  none,          // full resolution (level 0) everywhere
};
std::string_view lod_policy_name(LodPolicy policy);
bool parse_lod_policy(std::string_view name, LodPolicy& policy);

// Antialiasing of stills (RenderOptions::antialias). What each costs, as the frame time of a
// warm view (arena filled) over an aliased one's with no ground and no occlusion, measured by
// bench/bench_stills on llvmpipe (2 cores shared with other work: +-20%) with preset c at
// 1280x720, the default and an interior view (0.93 s aliased):
//   multisampling x4   2.3 x   llvmpipe shades and stores every sample, and resolves by a blit
//   multisampling x2   2.5 x   (no cheaper than x4 there)
//   supersampling 2x2  1.5 x   4 x the fragments, but vertices and binning (most of a plant's
//                              frame on llvmpipe) are paid once; thin pipes and far edges smooth
//   edge filter        1.05 x  one full-screen pass; smooths high-contrast edges only, not
//                              sub-pixel detail (thin triangles stay broken)
// and ambient occlusion 1.2 x, the ground under 1.05 x; a still with every default 1.7 x, with a
// highlight 2.6 x (the model is drawn three times). A cold still (a `render` run, which also
// streams the model and compiles the shaders) took 1.7 x the aliased renderer's before these
// (3.8 s against 2.2 s, medians of 3). On a GPU multisampling x4 costs little.
enum class AntialiasMethod {
  automatic,      // multisampling on a GPU, supersampling on a software renderer; with
                  // `samples` given, multisampling with that many (1: none)
  multisampling,  // `samples` per pixel (0: 4) by GL multisampling
  supersampling,  // drawn at 2x2 the size and averaged down
  edge_filter,    // an FXAA-like post-process filter along edges
};
std::string_view antialias_method_name(AntialiasMethod method);

// How occlusion culling (RenderOptions::occlusion) tests what its first phase did not draw
// (render/src/occlusion.h). Measured with bench_render (preset c, 1280x720, 4 samples, 30-view
// walkthrough and 12 interior views, llvmpipe), screen-space 1 px: interior views draw 1.97x
// fewer triangles than without occlusion with `exact`, 1.58x with `coarse`; but on llvmpipe
// drawing the boxes costs 56-96 ms of a frame, more than the triangles it saves with LOD (the
// out-of-core walk: 581 -> 794 ms; README, occlusion culling), where on a GPU drawing boxes
// against the depth costs next to nothing.
enum class OcclusionTest {
  automatic,  // exact on a GPU, coarse on a software renderer
  coarse,     // bounds against a grid of the first phase's depth (a cell per 4 x 4 pixels)
  exact,      // then what passes: bounds (of groups of an object's primitives) drawn against
              // the depth itself, and a third phase where the second is large
};
std::string_view occlusion_test_name(OcclusionTest test);

// Default pixel errors, chosen from bench_render (preset c, 1280x720, 4 samples, llvmpipe, a
// 30-view walkthrough and 12 interior views, occlusion on; PSNR against policy none):
//   1 px:    PSNR 31.4 dB mean, 26.8 worst; 3.5% of none's walkthrough triangles
//   0.5 px:  PSNR 35.2 dB mean, 29.8 worst; 5.2% of them, frames ~15% slower
//   0.25 px: PSNR 39.1 dB mean, 32.5 worst; 7.9% of them, frames ~45% slower
// Stills (`plantview render`, review images, farms) are read closely and drawn once: 0.5 px,
// +4 dB for ~1.5x the triangles. Interactive frames (the service) pay per frame and degrade
// further under load (X-Plantview-Degraded): 1 px.
inline constexpr double kStillPixelError = 0.5;
inline constexpr double kInteractivePixelError = 1.0;

// Change images (RenderOptions::changes, view_filters.h: ChangeRange): added objects in
// kAddedColour, modified ones in kModifiedColour with their shape at `from` as a see-through
// ghost in kPreviousColour, removed ones as see-through ghosts in kRemovedColour from their
// records at `from` (ReadView::object_at); the rest is ghosted as a highlight's context, and
// picks on the image return the changed objects' ids (a ghost's pixels, where it lies in front,
// the id of the object it was), 0 elsewhere. docs/changes.md.
inline constexpr Colour kAddedColour{40, 170, 60, 255};      // green
inline constexpr Colour kModifiedColour{245, 160, 20, 255};  // amber
inline constexpr Colour kPreviousColour{185, 140, 80, 255};  // amber-grey: a modified object's
                                                              // shape at `from`, see-through
inline constexpr Colour kRemovedColour{215, 40, 40, 255};    // red, see-through

struct RenderOptions {
  LodPolicy lod_policy = LodPolicy::screen_space;
  double pixel_error = kInteractivePixelError;     // screen_space: allowed error in pixels
  uint64_t vertex_budget_bytes = 512ull << 20;     // the GPU vertex arena's fixed size
  bool centrelines = true;                         // thin pipes as lines (screen_space, distance)
  bool hlod = true;                                // merge straight pipeline runs when allowed
  bool subpixel_culling = true;                    // screen_space: leave out objects under the
                                                   // pixel error on screen

  // How the image looks. Stills (every command, the service's still frames) keep the defaults;
  // interactive frames set antialias = false.
  bool antialias = true;          // smooth edges, by antialias_method (costs measured on
                                  // llvmpipe, preset c at 1280x720: see AntialiasMethod)
  AntialiasMethod antialias_method = AntialiasMethod::automatic;
  uint32_t samples = 0;           // multisampling: samples per pixel (0: 4, or automatic's
                                  // choice); at most what GL allows
  bool ground = true;             // ground cue: a grid at the plant's lowest level (model bounds
                                  // min z), fading with distance; drawn only where nothing else is
  bool ambient_occlusion = true;  // screen-space ambient occlusion from the depth buffer: creases
                                  // and dense piping darken, the ground darkens under the plant
  // Non-empty: these objects (store ids) in their colours and the rest ghosted (desaturated,
  // lighter, id 0 in the id buffer); whatever lies between the eye and them is drawn
  // see-through, so a subject deep in a rack is still seen.
  std::vector<uint64_t> highlight_ids;
  // Non-empty (with highlight_ids naming them): these subjects in these colours instead of
  // their own (alpha kept), and the frame's legend (key "subjects") one entry a label, in this
  // order, objects 1. Replaces style.colour_by; a change image ignores it. A see-through one
  // (SubjectColour::see_through) is drawn last, blended at kSeeThroughSubjectAlpha (more
  // opaque where its surface turns away from the eye: its outline), without depth or ids:
  // the other subjects show through it, tinted, and the context in front of it is drawn
  // see-through as in front of any subject.
  std::vector<SubjectColour> subject_colours;  // (view_filters.h)
  // Clip planes and a section box (view_filters.h): what they remove is neither decoded,
  // tessellated, drawn nor picked (culled whole where its bounds are removed, else clipped on
  // the GPU); cut closed solids are capped (docs/sections.md).
  Section section;
  // Colour by an attribute, hide, show only (view_filters.h).
  ObjectStyle style;
  bool occlusion = true;                           // leave out objects hidden behind what
                                                   // is drawn first (conservative: nothing
                                                   // visible is ever left out; step 1b)
  OcclusionTest occlusion_test = OcclusionTest::automatic;
  // Progressive refinement (interactive frames; 0: unbounded, every frame streams all it
  // chooses, as stills and batch renders do): the vertices a frame tessellates into the arena,
  // about at most. Once a frame has streamed this many, a resident object that its chosen level
  // would tessellate again is drawn at the coarser level it is resident at, and an object not
  // resident is made resident at its coarsest level (FrameStats::objects_deferred); the
  // following frames refine them within their own budgets. So a view whose levels all turn
  // finer at once (degradation lifting in the service) costs a few ordinary frames, not one
  // long one. The object that crosses the budget is streamed whole: every frame makes progress.
  uint64_t stream_budget_vertices = 0;
  // Set: a change image of this range (see ChangeRange). It replaces highlight_ids and
  // style.colour_by (its legend is the changes'), and turns pipeline HLOD off (a merged run
  // would draw a changed pipe in its neighbours' colour). A range the store cannot draw (a
  // revision pruned, never made, or not the snapshot's) fails the frame with the store's message.
  std::optional<ChangeRange> changes;
  // Fill FrameStats::drawn_slots and drawn_regions (what the image was drawn from: the farm's
  // incremental re-render, docs/farm.md). Off for interactive frames: it costs a pass over the
  // frame's draws.
  bool record_drawn = false;

  bool operator==(const RenderOptions&) const = default;
};

// The legend of a frame coloured by an attribute (RenderOptions::style.colour_by; rules in
// render/src/object_style.h): the values drawn, as categories (a colour each) or a ramp.
struct FrameLegend {
  enum class Kind { categories, ramp };
  std::string key;                // "": no legend (colour_by empty)
  Kind kind = Kind::categories;
  struct Entry {
    std::string value;
    Colour colour;
    uint64_t objects = 0;
  };
  std::vector<Entry> entries;     // categories, by value text
  uint64_t other_objects = 0;     // categories beyond the palette, drawn in one colour
  std::string unit;               // ramp: the values' unit ("" none)
  double min = 0, max = 0;        // ramp: the values' range
  std::vector<Colour> colours;    // ramp: its stops, min to max
  uint64_t objects = 0;           // ramp: objects with a value
  uint64_t missing_objects = 0;   // objects drawn without the key (neutral grey)
  static constexpr Colour kMissingColour{200, 200, 200, 255};  // objects without the key
  static constexpr Colour kOtherColour{96, 96, 96, 255};       // values beyond the palette
  // {"key": ..., "kind": "categories", "entries": [{"value", "colour": "#rrggbb", "objects"}],
  //  "other_objects": N, "missing_objects": N} or {"key", "kind": "ramp", "unit", "min",
  //  "max", "colours": [5 stops], "objects", "missing_objects"}; one line.
  std::string to_json() const;
  // Reads what to_json wrote (other fields are ignored). False with a message naming the field.
  static bool from_json(std::string_view json, FrameLegend& out, std::string& error);
  // The colour the frame gives an object whose colour_by attribute is `value`: its category's
  // entry; on a ramp its place between min and max (clamped). Nothing for a category the legend
  // does not list (in no drawn object, or beyond the palette) or, on a ramp, a value that is not
  // a number in the ramp's unit.
  std::optional<Colour> colour_of(std::string_view value) const;
};

struct FrameStats {
  uint64_t objects_visible = 0, objects_culled = 0;  // culled: outside the frustum
  uint64_t objects_occluded = 0;  // in the frustum but hidden behind occluders (not drawn)
  uint64_t objects_clipped = 0;   // in the frustum but wholly removed by the section
                                  // (RenderOptions::section): neither decoded nor drawn
  uint64_t nodes_occluded = 0;    // tree leaves and node boxes found hidden as a whole
  uint64_t occluders = 0;         // drawn frames: objects drawn in occlusion's first phase
                                  // (last frame's and the largest); statistics(): objects
                                  // rasterised as occluders on the CPU
  uint64_t triangles = 0, lines = 0;
  std::array<uint64_t, 8> triangles_by_level{};
  uint64_t centreline_pipes = 0;  // pipes (and merged runs) drawn as their centreline
  uint64_t hlod_merges = 0;       // pipeline runs drawn as one cylinder (or line)
  uint64_t hlod_members = 0;      // visible pipes and inline components those runs replaced
  uint64_t budget_proxies = 0;    // visible objects drawn as boxes because the arena was full
  uint64_t budget_coarsened = 0;  // objects made resident at their coarsest level to fit
  uint64_t objects_refined = 0;   // resident objects tessellated again for a finer level
  uint64_t objects_deferred = 0;  // drawn coarser than chosen: the frame's streaming budget
                                  // (RenderOptions::stream_budget_vertices) was spent
  uint64_t objects_subpixel = 0;  // in the frustum but under the pixel error on screen
  uint64_t node_proxies = 0;      // tree nodes of a few pixels drawn as one box each
  double node_proxy_pixels = 0;   // the node size (px) under which they were: 3 x the pixel
                                  // error, more when the view holds over 32,768 objects
                                  // and boxes
  uint64_t objects_in_node_proxies = 0;
  uint64_t draw_commands = 0;
  uint64_t arena_bytes_budget = 0, arena_bytes_resident = 0;
  uint64_t arena_bytes_uploaded = 0, arena_bytes_evicted = 0;
  uint64_t objects_resident = 0, objects_tessellated = 0, objects_evicted = 0;
  // Out-of-core memory after the frame: what the renderer keeps per object and per node
  // follows what the frames touched, never the plant. Blocks of the spatial index cull walked
  // this frame, and held (those of this frame's visible objects; the store's block cache is
  // apart); decoded objects kept; bytes of the
  // residency bookkeeping. (Not in to_json: for tests and benches.)
  uint64_t spatial_blocks_walked = 0, spatial_blocks_held = 0;
  uint64_t objects_known = 0;
  uint64_t residency_bytes = 0;
  bool made_ahead = false;  // this frame's start was made while the one before drew (expect)
  // cpu: the frame's CPU work, cull + occlusion + choose + stream (each part as measured, all
  // phases together; choose includes writing the index lists, stream decoding new objects;
  // occlusion is choosing the first phase and testing the rest). depth_reduction: occlusion's
  // GPU part, the drawn depth reduced and read back, and the exact test's boxes drawn and
  // their flags read back (the CPU waits for the GPU there, so it is not in cpu); draw
  // includes the earlier phases' drawing. arena_growth: the part of
  // stream spent growing the GPU vertex arena (a buffer twice the size, the old one copied
  // in): rare, and on a software renderer mostly the first touch of the new memory, which
  // the operating system pays page by page. ahead: Renderer::expect()'s work for the next view
  // (its cull and occlusion's first phase, chosen and streamed), done once this frame's drawing
  // is sent, while the GPU draws it: in total (the image is read back after it), not in cpu
  // (this frame's path to the GPU). The next frame, which takes it, then reports cull near 0,
  // and occlusion, choose and stream without its first phase (stream: that phase's vertices
  // written into the arena).
  struct Times {
    double cull = 0, occlusion = 0, depth_reduction = 0, choose = 0, stream = 0,
           arena_growth = 0, cpu = 0, draw = 0, ahead = 0, read_back = 0,
           encode = 0, total = 0;
  } ms;
  // RenderOptions::style: objects in view left out by hide/only (neither tessellated nor
  // drawn), and the legend when colour_by is set (key empty otherwise).
  uint64_t objects_hidden = 0;
  FrameLegend legend;
  // RenderOptions::changes: the range drawn and what changed in it, in the whole store (not
  // only in view); the legend (key "changes") has an entry per kind with the same counts.
  // shown false: no change image.
  struct Changes {
    bool shown = false;
    uint32_t from = 0, to = 0;
    uint64_t added = 0, modified = 0, removed = 0;
  } changes;
  // RenderOptions::record_drawn (else empty): every object that gave the image pixels, as its
  // slot in the renderer's snapshot (read_view()): drawn one by one at any level, as its
  // centreline or as a box for the arena's budget, or as a member of a merged pipeline run
  // (every member, in view or not: the run's cylinder spans them); unordered, possibly
  // repeated. Objects culled, under the pixel error, hidden by their style or left out by
  // occlusion (which leaves out nothing visible) gave none. And the nodes drawn whole (far-field
  // proxies, node boxes), as model-space bounds: any object beneath one gave it pixels. Not in
  // to_json.
  std::vector<uint32_t> drawn_slots;
  std::vector<DAabb> drawn_regions;
  // One JSON object (one line): the fields above, times under "ms"; "legend" only when set;
  // "changes": {"from", "to", "added", "modified", "removed"} only when shown.
  std::string to_json() const;
};
// A change image's caption: "Changes since revision 3 (to 5): 2 added, 1 modified, 4 removed".
std::string change_caption(const FrameStats::Changes& changes);

// ---------------------------------------------------------------------------------------------
// The GPU context and the renderer.

// An OpenGL 4.5 core context with no display: EGL_EXT_platform_device first (hardware devices
// before software ones), then Mesa's surfaceless platform (llvmpipe on machines without a GPU).
// One device of EGL_EXT_platform_device's list, as GpuContext::create(index) finds it.
struct GpuDeviceInfo {
  int index = 0;             // for create(index), and the programs' --device
  std::string name;          // its DRM node, "CUDA device N", "software" or "unnamed"
  bool software = false;     // EGL_MESA_device_software (llvmpipe)
  bool usable = false;       // an OpenGL 4.5 core context was made on it
  std::string description;   // what description() says of a context on it, or why none was made
};

class GpuContext {
 public:
  // device_index < 0: the first hardware device, else the first that works; >= 0: that device
  // of EGL_EXT_platform_device's list (error if there is none such).
  static std::unique_ptr<GpuContext> create(int device_index, std::string& error);
  // Every device EGL_EXT_platform_device lists, in its order, each opened and closed once (tens
  // of milliseconds each; a device that a context of this process holds stays open). Empty
  // where EGL lists none: then create(-1) tries Mesa's surfaceless platform alone. create(-1)
  // takes the first usable device that is not software, else the first usable one.
  static std::vector<GpuDeviceInfo> list_devices();
  ~GpuContext();
  GpuContext(const GpuContext&) = delete;
  GpuContext& operator=(const GpuContext&) = delete;

  // "EGL device 0 (EGL_EXT_device_drm /dev/dri/card0): NVIDIA H200 ..., OpenGL 4.5 ..." or
  // "Mesa surfaceless: llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 ...".
  const std::string& description() const;
  // Makes the context current on the calling thread.
  bool make_current(std::string& error);

 private:
  struct State;
  explicit GpuContext(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Renders frames of one store. Holds one read snapshot of the store (a ReadView) for its life
// (refresh() starts a new one, to see later imports), what it has decoded of the store's
// objects, and the GPU resources of its arena.
// Lifetimes: keeps a pointer to the Store, which must outlive the Renderer; uses the
// GpuContext current on its thread when created, which must stay current on that thread and
// outlive it.
// Threads: every call on the thread that created it; one frame at a time.
// Memory: the vertex arena never exceeds options.vertex_budget_bytes of GPU memory; the
// decoded-object cache keeps the resident objects and 10,000 more. On a software device
// (llvmpipe) the first renderer sets the process's malloc thresholds (glibc: up to 64 MB of
// free heap kept instead of given back, blocks up to 32 MB from the heap), so that what the
// driver frees draw by draw is not faulted in again at the next.
class Renderer {
 public:
  // Errors: a budget outside 1 MB .. 64 GB, a pixel error that is not a positive number, no
  // current OpenGL 4.5 context, or a store that cannot be read.
  static std::unique_ptr<Renderer> create(const Store& store, const RenderOptions& options,
                                          std::string& error);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Renders one frame of width x height (1..kMaxImageSide) through `camera` (valid: see
  // validate_camera). with_ids: also read back the object-id buffer. Fills `stats` (ms.encode
  // is left to the caller).
  bool render(const Camera& camera, uint32_t width, uint32_t height, bool with_ids, Image& out,
              FrameStats& stats, std::string& error);
  // The camera of the render() after the next one, where it is known (a path, a batch of
  // views): the next render(), once its drawing is sent, makes the start of that view's frame
  // while the GPU draws (FrameStats::ms.ahead): its cull, and with occlusion its first phase
  // chosen, decoded, tessellated, made resident and its index lists written (the vertices
  // written into the arena only when the render() after begins: the GPU may still draw from
  // what they replace). The render() after takes it if it is for the same camera, size and
  // options, else it starts afresh. Images are the same with or without it, and so are the
  // counts while the views expected come; after one that did not, the arena also holds what
  // its first phase needed. Applies to the next render() alone; an invalid camera is ignored.
  // (The second phase's new objects are not made ahead: which of them are hidden is known only
  // once the first is drawn; decoding and tessellating all the view's new objects ahead was
  // measured and not kept, two fifths to five sixths of them went unused.)
  void expect(const Camera& next);
  // Culls and chooses levels without drawing (LOD statistics for a view). It streams like a
  // frame, so the arena is left as render() would leave it.
  bool statistics(const Camera& camera, uint32_t width, uint32_t height, FrameStats& stats,
                  std::string& error);

  // Starts a new read snapshot and forgets everything decoded and resident. If the store cannot
  // be read, the renderer keeps its current snapshot (and what it holds) and stays usable.
  bool refresh(std::string& error);
  void set_options(const RenderOptions& options);  // the vertex budget is fixed at creation
  const RenderOptions& options() const;
  const DAabb& model_bounds() const;  // of the current snapshot
  // The snapshot every frame is drawn from: picking or reading attributes through it sees the
  // same commit as the frames. Valid until a refresh() reads a new snapshot or the renderer is
  // destroyed; like the renderer, it belongs to the renderer's thread.
  const ReadView& read_view() const;

 private:
  struct State;
  explicit Renderer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// What a renderer draws for a view, planned without GL: the frustum cull, the level choice and
// the pipeline runs merged into one cylinder (hlod), exactly as render() chooses them for the
// same camera, size and options (occlusion is not applied: nothing is drawn to test against).
// glTF export writes what a view shows from it.
struct PlannedObject {
  uint32_t slot = 0;
  uint8_t level = 0;         // chosen level
  uint8_t level_count = 1;   // of the object's mesh plan
  bool centreline = false;   // drawn as its centreline
};
struct PlannedRun {          // a straight pipeline run drawn as one cylinder
  uint32_t first_member = 0;  // slot of its first member, in flow order
  uint64_t pipeline_id = 0;
  uint8_t level = 0, level_count = 1;
  bool centreline = false;
  Primitive cylinder;         // relative to origin_m
  glm::dvec3 origin_m{0.0};
  Colour colour;
  DAabb bounds;               // of the members, model space
};
struct ViewPlan {
  std::vector<PlannedObject> objects;  // in draw order
  std::vector<PlannedRun> runs;
};
// Reads through `view` on the calling thread. False with a message if the store cannot be
// read. Preconditions as for Renderer::render (a valid camera, sizes 1..kMaxImageSide).
bool plan_view(const ReadView& view, const Camera& camera, uint32_t width, uint32_t height,
               const RenderOptions& options, ViewPlan& out, std::string& error);

}  // namespace plantview
