// Renderer: one frame as the data flows (render.h has the rules). The frontend (frame_plan.h:
// view, cull, occlusion, choose) and the decoded objects need no GL; arena streaming and the GL
// backend put what was chosen on the GPU, draw it and read it back. A drawn frame with
// occlusion runs choose, stream and draw twice, or three times (occlusion.h: phases).
#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "streaming/arena_streaming.h"
#include "change_set.h"
#include "decoded_objects.h"
#include "frame_plan.h"
#include "frame_stats.h"
#include "gl/backend.h"
#include "plantview/camera.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview {

using namespace detail;

struct Renderer::State {
  const Store* store = nullptr;  // outlives the renderer (render.h)
  // As set (options()), and as frames use them: hide and only (view_filters.h) turn pipeline
  // HLOD off, since a merged run would draw its members alike, hidden or not. (Colour by keeps
  // it: a run takes its deciding member's colour, the components it hides being under the
  // pixel error.)
  RenderOptions given;
  RenderOptions options;
  // A change image (RenderOptions::changes) turns HLOD off too, and replaces colour-by and the
  // highlight (its subject: the changed objects, set per frame by use_changes()).
  void use_options(const RenderOptions& o) {
    given = o;
    options = o;
    if (!o.style.hide.empty() || !o.style.only.empty()) options.hlod = false;
    // Subject colours replace colour-by, and turn HLOD off (a merged run would draw a coloured
    // pipe in its neighbours' colour).
    packed_subjects.clear();
    if (!o.subject_colours.empty() && !o.changes) {
      options.hlod = false;
      options.style.colour_by.clear();
      // A see-through subject's alpha marks it for the backend (gl/backend.h: Look); the
      // others' alpha is their own.
      for (const SubjectColour& c : o.subject_colours) {
        Colour packed = c.colour;
        packed.a = c.see_through ? uint8_t(std::lround(kSeeThroughSubjectAlpha * 255)) : 255;
        packed_subjects.emplace_back(c.id, packed_colour(packed));
      }
      std::sort(packed_subjects.begin(), packed_subjects.end());
    }
    if (o.changes) {
      options.hlod = false;
      options.style.colour_by.clear();
      options.highlight_ids.clear();
    }
    objects.set_style(options.style);
  }
  std::unique_ptr<ReadView> view;  // never null once created
  DAabb bounds;
  uint64_t frame_number = 0;

  // Declared in dependence order: streaming uses the backend and the pool, and destroys first.
  GlBackend backend;
  WorkerPool pool{WorkerPool::default_size()};
  DecodedObjects objects{&pool};
  FramePlan plan{&pool};
  ArenaStreaming streaming{backend, pool};
  FrameColouring colouring;  // colour_by: this frame's colours by value
  ChangeSet changes;         // RenderOptions::changes: read once per range and snapshot
  std::vector<std::pair<uint64_t, uint32_t>> packed_subjects;  // subject_colours, by id
  std::vector<uint64_t> frame_pick_ids;  // a change image's picks: the frame's, then its ghosts'

  std::vector<float> reduced_depth;  // occlusion's second phase: the first phase's depth grid
  std::vector<glm::vec4> test_boxes;  // and its exact test
  std::vector<uint32_t> boxes_seen;
  std::vector<uint32_t> blocks_ahead;  // the index blocks the cull will read, read ahead
  // expect(): the next frame's camera; look_ahead() then makes that frame's start (its cull
  // and occlusion's first phase, into `plan`, whose lists the frame drawn no longer needs; the
  // first phase streamed, into `streaming` and the backend's next index buffer) and notes for
  // which frame, view and options, with its statistics so far.
  std::optional<Camera> next_camera;
  struct MadeAhead {
    uint64_t frame = 0;
    Camera camera;
    uint32_t width = 0, height = 0;
    RenderOptions options;
    bool first_phase = false;  // occlusion's first phase made too (else the cull alone)
    bool streamed = false;     // and that phase chosen and streamed (its uploads deferred)
    FrameStats stats;
  };
  std::optional<MadeAhead> made_ahead;
  // This frame's first phase was chosen and streamed ahead (start() took it): it is drawn as
  // it stands. The pick ids of the frame drawn, kept for its read back while the next one is
  // made ahead (which starts a new object table).
  bool first_streamed = false;
  std::vector<uint64_t> drawn_pick_ids;
  // The frame's start: the cull, and, for a two-phase frame (occlusion.h), the first phase's
  // choice; taken from made_ahead if it was made for this frame, view and options.
  bool start(const Camera& camera, const FrameView& frame_view, bool first_phase, bool exact,
             FrameStats& stats, StageTimes& times, Stopwatch& clock, std::string& error);
  // expect()'s work, once a frame's drawing is sent: the next frame's start made (made_ahead):
  // its cull, and for a two-phase frame its first phase chosen, decoded, tessellated and
  // streamed, the uploads deferred until the next frame begins (the GPU still draws this one
  // from the arena). A read error is left for that frame to meet (it starts afresh) and report.
  void look_ahead(const Camera& next, uint32_t w, uint32_t h, bool exact);

  // Colour by an attribute: the frame's colours and legend (object_style.h) from the values of
  // the objects the cull found (plan.visible(), decoded here where new), before any phase is
  // drawn; else the objects' own colours.
  bool colour_view(FrameStats& stats, std::string& error);
  // A change image: its range read (once per range and snapshot), its subject made the
  // highlight (its summary and legend go into the frame's statistics at its end).
  bool use_changes(std::string& error);
  bool open_view(std::string& error);
  bool frame(const Camera& camera, uint32_t w, uint32_t h, bool draw, bool with_ids, Image* out,
             FrameStats& stats, std::string& error);
  // Occlusion's exact test of what a coarse test left (FramePlan::box_test_inputs): the boxes
  // drawn against the depth drawn so far.
  bool exact_test(const FrameView& frame_view, FrameStats& stats, StageTimes& times,
                  Stopwatch& clock, std::string& error);
  // One phase of a frame (the whole frame without two-phase occlusion): the plan's visible
  // objects decoded where new, a level chosen for each, made resident; with a look (drawing),
  // their index lists written and drawn (the first phase begins the frame's image; `wait`:
  // until the GPU has drawn them).
  bool phase(const FrameView& frame_view, const Look* look, bool with_ids, bool second_phase,
             bool wait, FrameStats& stats, StageTimes& times, Stopwatch& clock,
             std::string& error);
  // A phase's objects (plan.visible()) ordered, decoded where new, chosen for frame `frame` and
  // streamed; with `indices`, their index lists written (`next`: into the index buffer the next
  // frame draws from). The frame's phases and the look ahead both stream through it, so that a
  // first phase streamed ahead is the one the frame would have streamed.
  bool stream_phase(const FrameView& frame_view, uint64_t frame, bool second_phase, bool indices,
                    bool next, FrameStats& stats, StageTimes& times, Stopwatch& clock,
                    std::string& error);
  // Appends the phase's draws and node boxes to stats (RenderOptions::record_drawn).
  void record_drawn(FrameStats& stats) const;
};

void Renderer::State::look_ahead(const Camera& next, uint32_t w, uint32_t h, bool exact) {
  const FrameView next_view = make_frame_view(next, w, h, view->spatial_origin());
  MadeAhead made{frame_number + 1, next, w, h, options, FramePlan::two_phase(options), false, {}};
  std::string ignored;
  if (!plan.find_visible(*view, next_view, options, made.stats, ignored) ||
      !colour_view(made.stats, ignored))
    return;
  if (made.first_phase && !plan.first_phase(objects, next_view, options, made.frame, exact,
                                            made.stats, ignored))
    return;
  if (made.first_phase) {
    // Its index lists into the index buffer that frame draws from (this one draws from the
    // other); a read error leaves the frame to start afresh.
    StageTimes unused;
    Stopwatch clock;
    streaming.defer_uploads(true);
    made.streamed = stream_phase(next_view, made.frame, false, true, true, made.stats, unused,
                                 clock, ignored);
    streaming.defer_uploads(false);
    if (!made.streamed) return;
  }
  made_ahead = std::move(made);
}

bool Renderer::State::start(const Camera& camera, const FrameView& frame_view, bool first_phase,
                            bool exact, FrameStats& stats, StageTimes& times, Stopwatch& clock,
                            std::string& error) {
  const std::optional<MadeAhead> made = std::exchange(made_ahead, std::nullopt);
  first_streamed = false;
  if (made && made->frame == frame_number && made->camera == camera &&
      made->width == frame_view.width && made->height == frame_view.height &&
      made->options == options && made->first_phase == first_phase) {
    // What the cull and the first phase counted (made from fresh statistics, as this frame's).
    const uint64_t budget_bytes = stats.arena_bytes_budget;
    stats = made->stats;
    stats.arena_bytes_budget = budget_bytes;
    stats.made_ahead = true;
    first_streamed = made->streamed;
    times.cull = clock.lap();
    return true;
  }
  plan.blocks_ahead(*view, frame_view, options, blocks_ahead);
  objects.read_blocks(blocks_ahead);
  if (!plan.find_visible(*view, frame_view, options, stats, error)) return false;
  times.cull = clock.lap();
  if (!colour_view(stats, error)) return false;
  times.decode = clock.lap();
  if (first_phase &&
      !plan.first_phase(objects, frame_view, options, frame_number, exact, stats, error))
    return false;
  times.occlusion = clock.lap();
  return true;
}

bool Renderer::State::colour_view(FrameStats& stats, std::string& error) {
  if (options.style.colour_by.empty()) {
    streaming.colour_by(nullptr);
    return true;
  }
  if (!objects.decode(plan.visible(), options.hlod, error) ||
      !colouring.make(options.style.colour_by, objects.decoded(), objects.style_values(),
                      stats.legend, error))
    return false;
  streaming.colour_by(&colouring);
  return true;
}

bool Renderer::State::use_changes(std::string& error) {
  if (!given.changes) return true;
  if (!changes.load(*view, *given.changes, error)) return false;
  options.highlight_ids = changes.subject_ids();
  return true;
}

bool Renderer::State::exact_test(const FrameView& frame_view, FrameStats& stats,
                                 StageTimes& times, Stopwatch& clock, std::string& error) {
  times.occlusion += clock.lap();
  if (!plan.box_test_inputs(objects, frame_view, options, test_boxes, error)) return false;
  times.occlusion += clock.lap();
  if (!backend.test_boxes(frame_view, test_boxes, boxes_seen, error)) return false;
  times.depth_reduction += clock.lap();
  plan.drop_unseen(boxes_seen, stats);
  times.occlusion += clock.lap();
  return true;
}

// Starts a new snapshot of the store and forgets everything decoded and resident. If the store
// cannot be read, the current snapshot (if any) stays.
bool Renderer::State::open_view(std::string& error) {
  std::unique_ptr<ReadView> next = store->read(error);
  // A damaged spatial top would read as an empty plant: refuse it instead.
  if (!next || !next->spatial_ready(error)) return false;
  view = std::move(next);
  const ModelStatistics statistics = view->info().statistics;
  bounds = statistics.bounds;
  objects.reset(*view);
  plan.reset_view();
  changes.reset();
  made_ahead.reset();
  // A model larger than the budget at full resolution (one that will fill it) gets the whole
  // arena now: growing it later copies it, and the old and new buffers together would exceed
  // the budget for a moment. Smaller ones grow as they need (a new buffer costs zeroing it).
  // Such a model also drops the primitives of what is resident (decoding them again when they
  // must be tessellated again), and is drawn in bounded pieces (GlBackend::draw_triangles); a
  // smaller one keeps them and is drawn at once, for speed.
  const uint64_t budget_vertices = options.vertex_budget_bytes / kBytesPerVertex;
  const bool larger_than_budget = statistics.triangles > budget_vertices;
  streaming.reset(budget_vertices, larger_than_budget);
  backend.set_bounded_drawing(larger_than_budget);
  return !larger_than_budget || backend.grow_arena(budget_vertices, error);
}

bool Renderer::State::frame(const Camera& camera, uint32_t w, uint32_t h, bool draw,
                            bool with_ids, Image* out, FrameStats& stats, std::string& error) {
  Stopwatch clock;
  StageTimes times;
  // expect()'s camera is for this frame's look ahead alone, drawn or not, failed or not.
  const std::optional<Camera> next = std::exchange(next_camera, std::nullopt);
  stats = FrameStats{};
  stats.arena_bytes_budget = options.vertex_budget_bytes;
  if (w == 0 || h == 0 || w > kMaxImageSide || h > kMaxImageSide) {
    error = "renderer: image size " + std::to_string(w) + "x" + std::to_string(h) +
            " is outside 1.." + std::to_string(kMaxImageSide);
    return false;
  }
  if (!use_changes(error)) return false;
  ++frame_number;
  backend.take_growth_ms();  // (growth outside a frame: opening a view or a look ahead)
  const FrameView frame_view = make_frame_view(camera, w, h, view->spatial_origin());
  Look look = look_of(options, bounds);
  if (given.changes) look.subject_colours = changes.subject_colours();
  else if (!packed_subjects.empty()) look.subject_colours = packed_subjects;
  const Look* drawn = draw ? &look : nullptr;
  clock.lap();
  // What a look ahead streamed is written into the arena now, whether its frame came or not
  // (the residency holds it resident).
  streaming.flush_uploads();
  times.stream = clock.lap();

  // Frontend: what is in the frustum, then what of it is hidden (occlusion.h), decoded where
  // new, at which level; streamed; drawn.
  // The exact test (render.h: OcclusionTest) where it pays: on a GPU unless told.
  const bool exact = options.occlusion_test == OcclusionTest::exact ||
                     (options.occlusion_test == OcclusionTest::automatic && !backend.software());
  const bool two_phase = draw && FramePlan::two_phase(options);
  if (!start(camera, frame_view, two_phase, exact, stats, times, clock, error)) return false;
  if (two_phase) {
    // What will mostly be visible drawn first (start(): the first phase's choice); its depth
    // reduced and read back; the rest tested against it and drawn into the same image.
    if (!phase(frame_view, drawn, with_ids, false, true, stats, times, clock, error)) return false;
    const auto [cells_width, cells_height] = plan.occlusion_cells();
    if (!backend.reduce_depth(cells_width, cells_height, reduced_depth, error)) return false;
    times.depth_reduction = clock.lap();
    plan.second_phase(frame_view, frame_number, reduced_depth, stats);
    if (exact && !exact_test(frame_view, stats, times, clock, error)) return false;
    // A large second phase (a view cut to: little drawn last frame to draw first) draws its
    // largest on screen for their distance first, and the rest is tested against both.
    bool third = false;
    if (!plan.defer_smaller(objects, frame_view, options, third, error)) return false;
    times.occlusion += clock.lap();
    if (!phase(frame_view, drawn, with_ids, true, third, stats, times, clock, error)) return false;
    if (third) {
      if (!backend.reduce_depth(cells_width, cells_height, reduced_depth, error)) return false;
      times.depth_reduction += clock.lap();
      plan.third_phase(frame_view, reduced_depth, stats);
      if (exact && !exact_test(frame_view, stats, times, clock, error)) return false;
      times.occlusion += clock.lap();
      if (!phase(frame_view, drawn, with_ids, true, false, stats, times, clock, error)) return false;
    }
  } else {
    // Statistics alone: occluders rasterised on the CPU. (A highlight hides nothing: its
    // occluders are drawn see-through; FramePlan::occlude knows.)
    if (!draw && !plan.occlude(*view, objects, frame_view, options, stats, error)) return false;
    times.occlusion = clock.lap();
    if (!phase(frame_view, drawn, with_ids, false, false, stats, times, clock, error)) return false;
  }
  objects.forget_old(frame_number, streaming.residency());
  stats.objects_known = objects.known_count();
  stats.residency_bytes = streaming.residency().bookkeeping_bytes();
  times.stream += clock.lap();
  times.arena_growth = backend.take_growth_ms();

  // Backend: the ground, finishing and read back (render() only).
  if (draw) {
    std::span<const uint64_t> pick_ids = streaming.table().pick_ids();
    if (given.changes && !changes.ghosts().empty()) {
      // The shapes the snapshot does not hold, over the frame; their picks after its own.
      backend.draw_ghosts(frame_view, changes.ghosts(), uint32_t(pick_ids.size()), with_ids);
      frame_pick_ids.assign(pick_ids.begin(), pick_ids.end());
      for (const GhostMesh::Ghost& g : changes.ghosts().ghosts) frame_pick_ids.push_back(g.id);
      pick_ids = frame_pick_ids;
    }
    // With the next view expected, its start is made while the GPU draws this one.
    backend.finish_frame(frame_view, with_ids, !next);
    times.draw += clock.lap();
    if (next) {
      // (The look ahead may begin the next frame's object table, whatever comes of it.)
      drawn_pick_ids.assign(pick_ids.begin(), pick_ids.end());  // (ghosts' included)
      pick_ids = drawn_pick_ids;
      look_ahead(*next, w, h, exact);
      times.ahead = clock.lap();
      backend.wait();
      times.draw += clock.lap();
    }
    if (!backend.read_back(w, h, with_ids, pick_ids, *out, error)) return false;
    times.read_back = clock.lap();
  }
  if (given.changes) {
    stats.changes = changes.summary();
    stats.legend = changes.legend();
  } else if (!packed_subjects.empty()) {
    stats.legend = FrameLegend{};
    stats.legend.key = "subjects";
    for (const SubjectColour& c : given.subject_colours)
      stats.legend.entries.push_back({c.label, c.colour, 1});
  }
  report_times(times, clock.total(), stats.ms);
  return true;
}

bool Renderer::State::phase(const FrameView& frame_view, const Look* look, bool with_ids,
                            bool second_phase, bool wait, FrameStats& stats, StageTimes& times,
                            Stopwatch& clock, std::string& error) {
  // A first phase streamed ahead is drawn as it stands, from the index buffer it was written
  // into.
  if (!second_phase && first_streamed) {
    if (look) backend.use_next_indices();
  } else if (!stream_phase(frame_view, frame_number, second_phase, look != nullptr, false, stats,
                           times, clock, error)) {
    return false;
  }
  if (options.record_drawn) record_drawn(stats);
  if (!look) return true;
  if (!second_phase && !backend.begin_frame(frame_view, *look, with_ids, error)) return false;
  backend.draw_phase(frame_view, streaming.index_counts(), streaming.table().entries(),
                     streaming.proxy_tables(), streaming.table().pick_ids(), *look, with_ids,
                     wait);
  times.draw += clock.lap();
  return true;
}

void Renderer::State::record_drawn(FrameStats& stats) const {
  for (const Draw& d : plan.draws()) {
    if (d.key & kRunKeyBit) {
      const PipelineRun& run = objects.run(d.key & ~kRunKeyBit);
      stats.drawn_slots.insert(stats.drawn_slots.end(), run.members.begin(), run.members.end());
    } else {
      stats.drawn_slots.push_back(d.key);
    }
  }
  const glm::dvec3 origin = view->spatial_origin();
  for (const NodeBox& b : plan.node_boxes()) {
    DAabb region;
    region.min = origin + glm::dvec3(b.min[0], b.min[1], b.min[2]);
    region.max = origin + glm::dvec3(b.max[0], b.max[1], b.max[2]);
    stats.drawn_regions.push_back(region);
  }
}

bool Renderer::State::stream_phase(const FrameView& frame_view, uint64_t frame,
                                   bool second_phase, bool indices, bool next, FrameStats& stats,
                                   StageTimes& times, Stopwatch& clock, std::string& error) {
  plan.order();
  times.cull += clock.lap();
  if (!objects.decode(plan.visible(), options.hlod, error)) return false;
  times.decode += clock.lap();
  plan.choose(objects, frame_view, options, frame, stats);
  times.choose += clock.lap();
  // The chosen levels resident in the arena (or boxes), the object table filled.
  if (!streaming.stream(plan, objects, frame_view, options, stats, error, second_phase))
    return false;
  times.stream += clock.lap();
  if (!indices) return true;
  if (!streaming.write_index_lists(plan.draws(), error, next)) return false;
  times.index_lists += clock.lap();
  return true;
}

Renderer::Renderer(std::unique_ptr<State> state) : state_(std::move(state)) {}
Renderer::~Renderer() = default;

std::unique_ptr<Renderer> Renderer::create(const Store& store, const RenderOptions& options,
                                           std::string& error) {
  if (options.vertex_budget_bytes < (1u << 20) || options.vertex_budget_bytes > (64ull << 30)) {
    error = "renderer: the vertex budget must be 1 MB .. 64 GB";
    return nullptr;
  }
  if (!(options.pixel_error > 0.0) || !std::isfinite(options.pixel_error)) {
    error = "renderer: the pixel error must be a positive number";
    return nullptr;
  }
  auto state = std::make_unique<State>();
  state->store = &store;
  state->use_options(options);
  if (!state->backend.init(options.vertex_budget_bytes / kBytesPerVertex, error) ||
      !state->open_view(error))
    return nullptr;
  return std::unique_ptr<Renderer>(new Renderer(std::move(state)));
}

bool Renderer::render(const Camera& camera, uint32_t width, uint32_t height, bool with_ids,
                      Image& out, FrameStats& stats, std::string& error) {
  return state_->frame(camera, width, height, true, with_ids, &out, stats, error);
}

void Renderer::expect(const Camera& next) {
  std::string ignored;
  if (validate_camera(next, ignored)) state_->next_camera = next;
}

bool Renderer::statistics(const Camera& camera, uint32_t width, uint32_t height,
                          FrameStats& stats, std::string& error) {
  return state_->frame(camera, width, height, false, false, nullptr, stats, error);
}

bool Renderer::refresh(std::string& error) { return state_->open_view(error); }

void Renderer::set_options(const RenderOptions& options) {
  const uint64_t budget = state_->options.vertex_budget_bytes;
  RenderOptions o = options;
  o.vertex_budget_bytes = budget;
  state_->use_options(o);
}

const RenderOptions& Renderer::options() const { return state_->given; }
const DAabb& Renderer::model_bounds() const { return state_->bounds; }
const ReadView& Renderer::read_view() const { return *state_->view; }

}  // namespace plantview
