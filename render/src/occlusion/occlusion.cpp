// Occlusion culling: occluder selection, rasterisation and the tests (rules in occlusion.h).
#include "occlusion/occlusion.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>

#include "decoded_objects.h"
#include "frame_plan.h"
#include "lod.h"
#include "plantview/store.h"
#include "worker_pool.h"

namespace plantview::detail {

namespace {

// The nearest and farthest view depths (along -z, metres) of an eye-relative box: those of
// its nearest and farthest corners.
std::pair<float, float> depth_range(const glm::mat3& rotation, const glm::vec3& lo, const glm::vec3& hi) {
  float nearest = std::numeric_limits<float>::infinity(), farthest = 0;
  for (int c = 0; c < 8; ++c) {
    const glm::vec3 p(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
    const float depth = -(rotation * p).z;
    nearest = std::min(nearest, depth);
    farthest = std::max(farthest, depth);
  }
  return {nearest, farthest};
}

// A box relative to the spatial origin, relative to the eye: {min, max}.
std::pair<glm::vec3, glm::vec3> eye_relative(const FrameView& frame_view, const float mn[3],
                                             const float mx[3]) {
  glm::vec3 lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] = mn[a] + frame_view.shift_m[a];
    hi[a] = mx[a] + frame_view.shift_m[a];
  }
  return {lo, hi};
}

// Whether the bounds of `v` reach within 2 x the near plane of the eye's plane (a view depth):
// its size on screen, taken at its nearest point, says nothing of what of it is in view.
bool reaches_eye_plane(const FrameView& frame_view, const VisibleObject& v) {
  const auto [lo, hi] = eye_relative(frame_view, v.min, v.max);
  return depth_range(glm::mat3(frame_view.rotation), lo, hi).first <= 2 * kNearPlaneM;
}

// Removes from `items` (order kept) those whose index `hidden` holds for; returns how many.
template <class T, class F>
size_t remove_hidden(std::vector<T>& items, const F& hidden) {
  size_t kept = 0;
  for (size_t i = 0; i < items.size(); ++i)
    if (!hidden(i)) items[kept++] = items[i];
  const size_t removed = items.size() - kept;
  items.resize(kept);
  return removed;
}

// Whether `k` (seen as `v`) has an occluder shape and is drawn as its solids this frame: not a
// pipe drawn as its centreline, nor a member of a run drawn merged.
bool drawn_as_solid(DecodedObjects& objects, const Known& k, const VisibleObject& v,
                    const FrameView& frame_view, const RenderOptions& options) {
  if (k.occluder.empty()) return false;
  if (drawn_as_centreline(k, options, v.distance_m, v.px_per_m)) return false;
  return k.run < 0 || !decide_run(objects.run(uint32_t(k.run)), frame_view, options).merged;
}

// Whether `k` (seen as `v`) is drawn as opaque triangles of its own this frame: not
// see-through, no lines, not a pipe drawn as its centreline, nor a member of a run drawn
// merged. Only such objects are drawn in the first phase: what is blended (see-through
// objects, centrelines, which blend their coverage) is drawn after every opaque surface behind
// it, as in a frame drawn at once.
bool drawn_opaque(DecodedObjects& objects, const Known& k, const VisibleObject& v,
                  const FrameView& frame_view, const RenderOptions& options) {
  if (k.colour.a < 255 || k.has_lines) return false;
  if (drawn_as_centreline(k, options, v.distance_m, v.px_per_m)) return false;
  return k.run < 0 || !decide_run(objects.run(uint32_t(k.run)), frame_view, options).merged;
}

}  // namespace

OcclusionCulling::OcclusionCulling(WorkerPool* pool) : pool_(pool) {}
OcclusionCulling::~OcclusionCulling() = default;

template <class F>
void OcclusionCulling::for_parts(size_t n, const F& f) const {
  const size_t parts = (n + kObjectsPerPart - 1) / kObjectsPerPart;
  const auto part = [&](size_t p, unsigned) { f(p * kObjectsPerPart, std::min(n, (p + 1) * kObjectsPerPart)); };
  if (pool_ && parts > 1) pool_->run(parts, part);
  else for (size_t p = 0; p < parts; ++p) part(p, 0);
}

namespace {

// A box relative to the spatial origin, in view space: its centre turned, its half extents.
struct TurnedBox {
  glm::mat3 rotation;
  glm::vec3 centre, half;
};

TurnedBox turn(const FrameView& frame_view, const float mn[3], const float mx[3]) {
  TurnedBox box{glm::mat3(frame_view.rotation), {}, {}};
  glm::vec3 centre;
  for (int a = 0; a < 3; ++a) {
    centre[a] = 0.5f * (mn[a] + mx[a]) + frame_view.shift_m[a];
    box.half[a] = 0.5f * (mx[a] - mn[a]);
  }
  box.centre = box.rotation * centre;
  return box;
}

ProjectedBounds project(const TurnedBox& box) {
  const glm::mat3& r = box.rotation;
  const glm::vec3 &c = box.centre, &half = box.half;
  const glm::vec3 ax = r[0] * half.x, ay = r[1] * half.y, az = r[2] * half.z;
  constexpr float kFar = std::numeric_limits<float>::infinity();
  constexpr ProjectedBounds kEverywhere{-kFar, kFar, -kFar, kFar, 0.0f};
  // Rounding (of the rotation, the corners, the quotients): each true corner lies within a
  // hair of its computed one in each axis, which moves its x / d by at most
  // hair (1 + |x / d|) / (d - hair), and d - hair >= d (nearest - hair) / nearest.
  const float hair = 1e-5f * (std::abs(c.x) + std::abs(c.y) + std::abs(c.z) + half.x + half.y + half.z) + 1e-5f;
  std::array<glm::vec3, 8> corners;
  float nearest_d = kFar;
  for (int corner = 0; corner < 8; ++corner) {
    corners[corner] = c + (corner & 1 ? ax : -ax) + (corner & 2 ? ay : -ay) + (corner & 4 ? az : -az);
    nearest_d = std::min(nearest_d, -corners[corner].z);
  }
  if (!(nearest_d > 2 * hair)) return kEverywhere;  // reaching the eye's plane
  const float grow = hair * nearest_d / (nearest_d - hair);
  ProjectedBounds b{kFar, -kFar, kFar, -kFar, nearest_d - hair};
  for (const glm::vec3& p : corners) {
    const float inverse = 1.0f / -p.z;
    const float x = p.x * inverse, y = p.y * inverse;
    // (and a float's rounding of the quotients)
    const float sx = grow * (1.0f + std::abs(x)) * inverse + 1e-6f * (1.0f + std::abs(x));
    const float sy = grow * (1.0f + std::abs(y)) * inverse + 1e-6f * (1.0f + std::abs(y));
    b.x0 = std::min(b.x0, x - sx);
    b.x1 = std::max(b.x1, x + sx);
    b.y0 = std::min(b.y0, y - sy);
    b.y1 = std::max(b.y1, y + sy);
  }
  return b;
}

}  // namespace

ProjectedBounds project_box(const FrameView& frame_view, const float mn[3], const float mx[3]) {
  return project(turn(frame_view, mn, mx));
}

bool OcclusionCulling::hidden(const FrameView& frame_view, const float mn[3], const float mx[3]) const {
  // Most boxes that are not hidden are seen at their centre: the cell there is not nearer than
  // the centre, so not nearer than the box's nearest point either.
  const TurnedBox box = turn(frame_view, mn, mx);
  if (!(-box.centre.z > 0.0f) || !buffer_.nearer_at(box.centre)) return false;
  return buffer_.hidden(project(box));
}

bool OcclusionCulling::rasterise_occluders(DecodedObjects& objects, const FrameView& frame_view,
                                           const RenderOptions& options,
                                           std::span<const VisibleObject> visible, bool& any,
                                           FrameStats& stats, std::string& error) {
  buffer_.begin(frame_view.width, frame_view.height, frame_view.focal, frame_view.aspect,
                float(kNearPlaneM));
  any = false;
  smallest_candidate_px_ = kOccluderMinPixels;

  // 1. Occluders: the largest on screen, decoded (new ones) to know their shapes.
  candidates_.clear();
  for (const VisibleObject& v : visible)
    if (v.px_per_m * v.extent_m() >= kOccluderMinPixels) candidates_.push_back(v);
  const auto larger = [](const VisibleObject& a, const VisibleObject& b) {
    return a.px_per_m * a.extent_m() > b.px_per_m * b.extent_m();
  };
  if (candidates_.size() > kMaxOccluders) {
    std::nth_element(candidates_.begin(), candidates_.begin() + (kMaxOccluders - 1), candidates_.end(), larger);
    candidates_.resize(kMaxOccluders);
    const VisibleObject& last = candidates_.back();
    smallest_candidate_px_ = last.px_per_m * last.extent_m();
  }
  if (candidates_.empty()) return true;
  if (!objects.decode(candidates_, options.hlod, error)) return false;

  // 2. Which of them occlude (shapes built here, on this thread), then their pieces rasterised
  //    in parts on the pool, each worker into a buffer of its own, merged by the nearest depth
  //    (the same cells whatever the split).
  stats.occluders = 0;
  occluding_.clear();
  for (const VisibleObject& v : candidates_) {
    Known& k = objects.at(v.slot);
    if (!may_occlude(k.object_class, k.colour)) continue;
    if (!objects.occluder(v.slot, k, error)) return false;
    if (!drawn_as_solid(objects, k, v, frame_view, options)) continue;
    stats.occluders += 1;
    occluding_.push_back(&k);
  }
  const glm::mat3 rotation(frame_view.rotation);
  const unsigned workers = pool_ ? pool_->size() : 1;
  if (worker_buffers_.size() < workers) worker_buffers_.resize(workers);
  const auto rasterise = [&](size_t part, unsigned worker) {
    WorkerBuffer& wb = worker_buffers_[worker];
    OcclusionBuffer& into = worker == 0 ? buffer_ : wb.buffer;
    if (worker != 0 && !wb.used)
      into.begin(frame_view.width, frame_view.height, frame_view.focal, frame_view.aspect,
                 float(kNearPlaneM));
    wb.used = true;
    for (size_t o = part * kOccludersPerPart; o < std::min(occluding_.size(), (part + 1) * kOccludersPerPart); ++o) {
      const Known& k = *occluding_[o];
      const glm::vec3 offset(k.origin_m - frame_view.eye_m);
      uint32_t first = 0;
      for (size_t piece = 0; piece < k.occluder.ends.size(); ++piece) {
        const uint32_t end = k.occluder.ends[piece];
        // The piece's bounds wholly beyond the near plane (see occlusion_occluders.h), and
        // holding a whole cell of the buffer on screen: else the piece covers none (most
        // pieces: small on screen or off it), and its points are not even transformed.
        const glm::vec3 lo = offset + k.occluder.bounds[2 * piece], hi = offset + k.occluder.bounds[2 * piece + 1];
        // A piece the section cuts hides less than its shape: not used (conservative).
        if (!options.section.empty() &&
            !section_keeps_all(options.section,
                               DAabb{k.origin_m + glm::dvec3(k.occluder.bounds[2 * piece]),
                                     k.origin_m + glm::dvec3(k.occluder.bounds[2 * piece + 1])})) {
          first = end;
          continue;
        }
        std::array<glm::vec3, 8> corners;
        float nearest_m = std::numeric_limits<float>::infinity();
        for (int c = 0; c < 8; ++c) {
          corners[c] = rotation * glm::vec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
          nearest_m = std::min(nearest_m, -corners[c].z);
        }
        if (nearest_m <= 2 * kNearPlaneM || !into.may_cover(corners)) {
          first = end;
          continue;
        }
        wb.piece.clear();
        for (uint32_t p = first; p < end; ++p) wb.piece.push_back(rotation * (offset + k.occluder.points[p]));
        first = end;
        wb.any |= into.add_convex(wb.piece);
      }
    }
  };
  for (WorkerBuffer& wb : worker_buffers_) wb.any = wb.used = false;
  const size_t parts = (occluding_.size() + kOccludersPerPart - 1) / kOccludersPerPart;
  if (pool_ && parts > 1) pool_->run(parts, rasterise);
  else for (size_t p = 0; p < parts; ++p) rasterise(p, 0);
  for (unsigned w = 0; w < workers; ++w) {
    any |= worker_buffers_[w].any;
    if (w != 0 && worker_buffers_[w].used) buffer_.merge_nearest(worker_buffers_[w].buffer);
  }
  return true;
}

bool OcclusionCulling::apply(const ReadView& /*view*/, const FrameBlocks& blocks,
                             DecodedObjects& objects, const FrameView& frame_view,
                             const RenderOptions& options, std::vector<VisibleObject>& visible,
                             std::vector<NodeBox>& node_boxes, FrameStats& stats,
                             std::string& error) {
  bool any = false;
  if (!rasterise_occluders(objects, frame_view, options, visible, any, stats, error)) return false;
  if (!any) return true;

  // 3. Test leaves, objects and node boxes.
  drop_hidden(blocks, frame_view, visible, node_boxes, stats);
  return true;
}

bool OcclusionCulling::split(DecodedObjects& objects, const FrameView& frame_view,
                             const RenderOptions& options, uint64_t frame, bool exact,
                             std::vector<VisibleObject>& visible, std::vector<VisibleObject>& rest,
                             FrameStats& stats, std::string& error) {
  // The CPU occluders choose: what they hide is left to the second phase's test, where the
  // depth actually drawn most likely hides it too.
  bool any = false;
  if (!rasterise_occluders(objects, frame_view, options, visible, any, stats, error)) return false;
  // Of the largest, with the exact test, the nearer half is drawn first (the farther are left
  // to the tests, where the nearer most likely hide them), and none reaching the eye's plane
  // (the exact test can drop what of it is out of view or hidden); none with the eye within its
  // bounds (its size on screen says nothing: it may well draw nothing, seen from inside).
  double near_cut_m = std::numeric_limits<double>::infinity();
  if (exact && !candidates_.empty()) {
    distances_.clear();
    for (const VisibleObject& v : candidates_) distances_.push_back(v.distance_m);
    const size_t cut = size_t(kFirstPhaseNearShare * double(distances_.size() - 1));
    std::nth_element(distances_.begin(), distances_.begin() + ptrdiff_t(cut), distances_.end());
    near_cut_m = distances_[cut];
  }
  // Which objects the first phase draws: tested in parts on the pool (reading only), then
  // split in order here.
  flags_.resize(visible.size());
  for_parts(visible.size(), [&](size_t first, size_t end) {
    for (size_t i = first; i < end; ++i) {
      const VisibleObject& v = visible[i];
      if (i + kPrefetchAhead < end)
        if (const Known* ahead = objects.find(visible[i + kPrefetchAhead].slot)) prefetch(ahead);
      const Known* k = objects.find(v.slot);
      // Drawn last frame (frames count from 1: 0 is never), and not found hidden behind what
      // that frame drew first.
      const bool drawn_last = k && k->last_seen != 0 && k->last_seen + 1 == frame &&
                              !(hidden_drawn_frame_ + 1 == frame &&
                                std::binary_search(hidden_drawn_.begin(), hidden_drawn_.end(), v.slot));
      const bool largest = v.px_per_m * v.extent_m() >= smallest_candidate_px_ &&
                           v.distance_m <= near_cut_m && v.distance_m > 2 * kNearPlaneM &&
                           !(exact && reaches_eye_plane(frame_view, v));
      flags_[i] = (drawn_last || largest) && k && drawn_opaque(objects, *k, v, frame_view, options) &&
                  !(any && hidden(frame_view, v.min, v.max));
    }
  });
  rest.clear();
  size_t kept = 0;
  for (size_t i = 0; i < visible.size(); ++i) {
    if (flags_[i]) visible[kept++] = visible[i];
    else rest.push_back(visible[i]);
  }
  visible.resize(kept);
  stats.occluders = kept;
  return true;
}

void OcclusionCulling::test_rest(const FrameBlocks& blocks, const FrameView& frame_view,
                                 uint64_t frame, std::span<const VisibleObject> first,
                                 std::span<const float> reversed_depth,
                                 std::vector<VisibleObject>& rest, std::vector<NodeBox>& node_boxes,
                                 FrameStats& stats) {
  buffer_.load_device_depth(reversed_depth);
  // The first phase's objects that the others of it hide (never itself: an object's own depth
  // is no nearer than its bounds): drawn in vain, and not to be drawn first next frame.
  flags_.resize(first.size());
  for_parts(first.size(), [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) flags_[i] = hidden(frame_view, first[i].min, first[i].max);
  });
  hidden_drawn_.clear();
  for (size_t i = 0; i < first.size(); ++i)
    if (flags_[i]) hidden_drawn_.push_back(first[i].slot);
  std::sort(hidden_drawn_.begin(), hidden_drawn_.end());
  hidden_drawn_frame_ = frame;
  drop_hidden(blocks, frame_view, rest, node_boxes, stats);
}

bool OcclusionCulling::defer_smaller(DecodedObjects& objects, const FrameView& frame_view,
                                 const RenderOptions& options, std::vector<VisibleObject>& rest,
                                 std::vector<VisibleObject>& later, bool& deferred,
                                 std::string& error) {
  later.clear();
  deferred = rest.size() >= kThirdPhaseObjects;
  if (!deferred) return true;
  // The key above which the largest share lies (ties at it drawn now too): pixels spanned
  // over distance (measured on preset c's 12 interior views at screen-space 1 px: 1.6% fewer
  // triangles drawn than by pixels alone with the exact test, 0.5% with the coarse one).
  const auto pixels = [](const VisibleObject& v) {
    return v.px_per_m * v.extent_m() / std::max(v.distance_m, 1.0);
  };
  distances_.resize(rest.size());
  for (size_t i = 0; i < rest.size(); ++i) distances_[i] = -pixels(rest[i]);
  const size_t cut = size_t(kThirdPhaseLargestShare * double(rest.size() - 1));
  std::nth_element(distances_.begin(), distances_.begin() + ptrdiff_t(cut), distances_.end());
  const double smallest_px = -distances_[cut];
  candidates_.clear();
  for (const VisibleObject& v : rest)
    if (pixels(v) >= smallest_px) candidates_.push_back(v);
  if (!objects.decode(candidates_, options.hlod, error)) return false;
  size_t kept = 0;
  for (size_t i = 0; i < rest.size(); ++i) {
    const VisibleObject& v = rest[i];
    const Known* k = pixels(v) >= smallest_px ? objects.find(v.slot) : nullptr;
    if (k && drawn_opaque(objects, *k, v, frame_view, options)) rest[kept++] = v;
    else later.push_back(v);
  }
  rest.resize(kept);
  return true;
}

void OcclusionCulling::test_later(const FrameBlocks& blocks, const FrameView& frame_view,
                                  std::span<const float> reversed_depth,
                                  std::vector<VisibleObject>& later,
                                  std::vector<NodeBox>& node_boxes, FrameStats& stats) {
  buffer_.load_device_depth(reversed_depth);
  drop_hidden(blocks, frame_view, later, node_boxes, stats);
}

namespace {

// Adds the box (relative to the spatial origin) of rest[index] to `out`, eye-relative and grown
// by `spill_px` image pixels of drawing that may reach past it (occlusion_buffer.h) and a hair
// for rounding (of the shift, of the drawn vertices and depths). False (nothing added) for a
// box that holds the eye, or comes within the near plane's distance of it: no face of it faces
// the eye, so its object is kept. (One reaching past the near plane, or the eye's plane,
// elsewhere is tested as any other: GlBackend::test_boxes draws without clipping at the near
// plane.)
bool add_box(const FrameView& frame_view, const glm::mat3& rotation, const float mn[3],
             const float mx[3], uint32_t index, double spill_px, TestBoxes& out) {
  auto [lo, hi] = eye_relative(frame_view, mn, mx);
  const float farthest_m = depth_range(rotation, lo, hi).second;
  // The spill in metres where the box is farthest (a pixel spans the most metres there).
  const float spill_m = float(spill_px * std::max(farthest_m, 0.0f) / frame_view.focal_px);
  for (int a = 0; a < 3; ++a) {
    const float grow = spill_m + 1e-5f * std::max(std::abs(lo[a]), std::abs(hi[a])) + 1e-4f;
    lo[a] -= grow;
    hi[a] += grow;
  }
  const glm::vec3 near_m = glm::vec3(float(kNearPlaneM));
  if (glm::all(glm::lessThanEqual(lo, near_m)) && glm::all(glm::greaterThanEqual(hi, -near_m)))
    return false;
  out.boxes.emplace_back(lo, 0.0f);
  out.boxes.emplace_back(hi, 0.0f);
  out.tested.push_back(index);
  return true;
}

}  // namespace

bool OcclusionCulling::object_boxes(DecodedObjects& objects, const FrameView& frame_view,
                                    const glm::mat3& rotation, const RenderOptions& options,
                                    const VisibleObject& v, uint32_t index, bool may_read,
                                    TestBoxes& out, std::string& error) {
  Known* k = objects.find(v.slot);
  // Not decoded yet (nor to be, if hidden), drawn as a centreline, with lines, or a member of
  // a merged run: its own bounds, grown by what is drawn of it past them.
  if (!k || k->has_lines || drawn_as_centreline(*k, options, v.distance_m, v.px_per_m) ||
      (k->run >= 0 && decide_run(objects.run(uint32_t(k->run)), frame_view, options).merged)) {
    add_box(frame_view, rotation, v.min, v.max, index, OcclusionBuffer::kSpillPixels, out);
    return true;
  }
  // A solid of its own: tested only where drawing it costs more triangles than testing its
  // boxes (the bounds of groups of its primitives, else its own).
  const uint32_t level = chosen_level(*k, options, v.distance_m, v.px_per_m, v.extent_m());
  size_t triangles = 0;
  for (const Known::Part& part : k->parts)
    triangles += part.plan->index_count(part.plan->clamp_level(level)) / 3;
  if (triangles <= kBoxTestTriangles) return true;  // (whatever its boxes: none built for it)
  // Its groups are built from its primitives the first time, which reads the store where they
  // were dropped: that only where `may_read`.
  if (!k->test_boxes_built && !may_read && k->primitives.empty() && !k->parts.empty()) {
    out.waiting.push_back(index);
    return true;
  }
  const std::vector<Aabb>* test_boxes = objects.test_boxes(v.slot, *k, error);
  if (!test_boxes) return false;
  if (triangles <= kBoxTestTriangles * std::max<size_t>(1, test_boxes->size())) return true;
  if (test_boxes->empty()) {
    add_box(frame_view, rotation, v.min, v.max, index, 0, out);
    return true;
  }
  // Each clipped to the object's bounds, which hold all it draws too. One reaching the near
  // plane keeps the object: none of its boxes is tested.
  const glm::vec3 origin(k->origin_m - frame_view.spatial_origin_m);
  const size_t boxes_before = out.boxes.size(), tested_before = out.tested.size();
  for (const Aabb& b : *test_boxes) {
    float mn[3], mx[3];
    for (int a = 0; a < 3; ++a) {
      mn[a] = std::max(v.min[a], origin[a] + b.min[a]);
      mx[a] = std::min(v.max[a], origin[a] + b.max[a]);
    }
    if (mn[0] <= mx[0] && mn[1] <= mx[1] && mn[2] <= mx[2] &&
        !add_box(frame_view, rotation, mn, mx, index, 0, out)) {
      out.boxes.resize(boxes_before);
      out.tested.resize(tested_before);
      break;
    }
  }
  return true;
}

bool OcclusionCulling::box_test_inputs(DecodedObjects& objects, const FrameView& frame_view,
                                       const RenderOptions& options,
                                       std::span<const VisibleObject> rest,
                                       std::vector<glm::vec4>& boxes, std::string& error) {
  candidates_.clear();
  for (const VisibleObject& v : rest)
    if (v.px_per_m * v.extent_m() >= kBoxTestDecodePixels && !objects.find(v.slot)) candidates_.push_back(v);
  if (!candidates_.empty() && !objects.decode(candidates_, options.hlod, error)) return false;
  // In parts on the pool, each into lists of its own, joined in order; an object whose groups
  // must be built from primitives read again from the store waits for this thread, after.
  const glm::mat3 rotation(frame_view.rotation);
  const size_t parts = (rest.size() + kObjectsPerPart - 1) / kObjectsPerPart;
  if (part_boxes_.size() < parts) part_boxes_.resize(parts);
  for_parts(rest.size(), [&](size_t first, size_t end) {
    TestBoxes& out = part_boxes_[first / kObjectsPerPart];
    out.boxes.clear();
    out.tested.clear();
    out.waiting.clear();
    std::string unused;  // (no read: nothing to fail)
    for (size_t i = first; i < end; ++i) {
      if (i + kPrefetchAhead < end)
        if (const Known* ahead = objects.find(rest[i + kPrefetchAhead].slot)) prefetch(ahead);
      object_boxes(objects, frame_view, rotation, options, rest[i], uint32_t(i), false, out, unused);
    }
  });
  boxes.clear();
  tested_.clear();
  for (size_t p = 0; p < parts; ++p) {
    TestBoxes& part = part_boxes_[p];
    for (const uint32_t i : part.waiting)
      if (!object_boxes(objects, frame_view, rotation, options, rest[i], i, true, part, error))
        return false;
    boxes.insert(boxes.end(), part.boxes.begin(), part.boxes.end());
    tested_.insert(tested_.end(), part.tested.begin(), part.tested.end());
  }
  return true;
}

void OcclusionCulling::drop_unseen(std::span<const uint32_t> seen, std::vector<VisibleObject>& rest,
                                   FrameStats& stats) {
  assert(seen.size() == tested_.size());
  // Hidden: tested, and none of its boxes seen.
  flags_.assign(rest.size(), 0);
  for (size_t t = 0; t < tested_.size(); ++t) flags_[tested_[t]] = 1;
  for (size_t t = 0; t < tested_.size(); ++t)
    if (seen[t]) flags_[tested_[t]] = 0;
  stats.objects_occluded += remove_hidden(rest, [&](size_t i) { return flags_[i] != 0; });
}

void OcclusionCulling::drop_hidden(const FrameBlocks& blocks, const FrameView& frame_view,
                                   std::vector<VisibleObject>& visible,
                                   std::vector<NodeBox>& node_boxes, FrameStats& stats) const {
  // Leaves once each (a leaf's objects are consecutive), then objects; in parts on the pool
  // (a leaf cut by a part's start is tested by both parts, and counted where it starts); then
  // the hidden dropped in order here; then node boxes.
  constexpr uint8_t kHidden = 1, kLeafHidden = 2;  // flags: the object; a hidden leaf starts here
  flags_.resize(visible.size());
  for_parts(visible.size(), [&](size_t first, size_t end) {
    bool leaf_hidden = false;
    for (size_t i = first; i < end; ++i) {
      const VisibleObject& v = visible[i];
      const bool leaf_starts = i == 0 || v.block != visible[i - 1].block || v.node != visible[i - 1].node;
      uint8_t flag = 0;
      if (leaf_starts || i == first) {
        const SpatialNode& leaf = blocks.at(v.block).nodes[v.node];
        leaf_hidden = hidden(frame_view, leaf.min, leaf.max);
        if (leaf_hidden && leaf_starts) flag |= kLeafHidden;
      }
      if (leaf_hidden || hidden(frame_view, v.min, v.max)) flag |= kHidden;
      flags_[i] = flag;
    }
  });
  for (size_t i = 0; i < visible.size(); ++i) stats.nodes_occluded += (flags_[i] & kLeafHidden) != 0;
  stats.objects_occluded += remove_hidden(visible, [&](size_t i) { return (flags_[i] & kHidden) != 0; });
  stats.nodes_occluded += remove_hidden(node_boxes, [&](size_t i) {
    return hidden(frame_view, node_boxes[i].min, node_boxes[i].max);
  });
}

}  // namespace plantview::detail
