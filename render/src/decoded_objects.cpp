// Decoded objects: decoding, pipeline analysis and the bounded cache (rules in decoded_objects.h).
#include "decoded_objects.h"

#include <algorithm>
#include <atomic>
#include <deque>
#include <cassert>
#include <cstring>
#include <mutex>
#include <optional>
#include <unordered_set>

#include "frame_plan.h"
#include "plantview/store.h"
#include "streaming/residency.h"
#include "worker_pool.h"

namespace plantview::detail {

void KnownDirectory::insert(uint32_t key, Known* k) {
  assert(!find(key));
  if (key & kRunKeyBit) {
    const uint32_t r = key & ~kRunKeyBit;
    if (r >= runs_.size()) runs_.resize(r + 1, nullptr);
    runs_[r] = k;
    return;
  }
  const uint32_t page = key / kSlotsPerPage;
  if (page >= pages_.size()) pages_.resize(page + 1);
  if (!pages_[page]) pages_[page] = std::make_unique<Page>();
  pages_[page]->known[key % kSlotsPerPage] = k;
  pages_[page]->count += 1;
}

void KnownDirectory::erase(uint32_t key) {
  if (key & kRunKeyBit) {
    const uint32_t r = key & ~kRunKeyBit;
    if (r < runs_.size()) runs_[r] = nullptr;
    return;
  }
  const uint32_t page = key / kSlotsPerPage;
  if (page >= pages_.size() || !pages_[page] || !pages_[page]->known[key % kSlotsPerPage]) return;
  pages_[page]->known[key % kSlotsPerPage] = nullptr;
  if (--pages_[page]->count == 0) pages_[page].reset();
}

void DecodedObjects::reset(const ReadView& view) {
  view_ = &view;
  views_.clear();
  siblings_.clear();
  pool_.clear();
  keys_.clear();
  free_known_.clear();
  directory_.clear();
  decoded_.clear();
  runs_.clear();
  decisions_.clear();
  free_runs_.clear();
  pipeline_runs_.clear();
  pipelines_referenced_ = 0;
  style_values_.clear();
}

void DecodedObjects::set_style(const ObjectStyle& style) {
  if (style == style_.style()) return;
  style_ = CompiledStyle(style);
  style_values_.clear();
  ++style_epoch_;
}

void DecodedObjects::evaluate_style(Known& k, const Object& o) {
  const bool was_hidden = k.hidden;
  k.style_epoch = style_epoch_;
  k.hidden = style_.active() && style_.hides(o);
  k.style_value = -1;
  if (!style_.style().colour_by.empty()) {
    style_values_.note_keys(o);
    if (const std::string* v = style_.value(o)) k.style_value = style_values_.intern(*v);
  }
  if (k.hidden != was_hidden) {
    // A hidden object occludes nothing: its occluder is built again when asked for.
    k.occluder = {};
    k.occluder_built = false;
  }
}

bool DecodedObjects::restyle(std::string& error) {
  if (!style_.needs_record()) {
    Object o;
    for (const uint32_t slot : restyle_) {
      Known& k = at(slot);
      o.object_class = k.object_class;
      evaluate_style(k, o);
    }
    restyle_.clear();
    return true;
  }
  // The records read again in waves, in slot order (each chunk decompressed once per part), in
  // parts on the workers as new objects are (read_wave); evaluated here, in slot order.
  std::sort(restyle_.begin(), restyle_.end());
  for (size_t first = 0; first < restyle_.size(); first += kNewObjectsPerWave) {
    const size_t count = std::min(kNewObjectsPerWave, restyle_.size() - first);
    if (wave_objects_.size() < count) wave_objects_.resize(count);
    wave_read_.assign(count, 0);
    const size_t workers = workers_ ? workers_->size() : 1;
    const size_t per_part = std::clamp<size_t>((count + workers - 1) / workers,
                                               kMinNewObjectsPerPart, kNewObjectsPerPart);
    const size_t parts = (count + per_part - 1) / per_part;
    wave_errors_.assign(parts, std::string());
    on_views(parts, [&](size_t part, const ReadView& view) {
      for (size_t i = part * per_part; i < std::min(count, (part + 1) * per_part); ++i) {
        if (!view.object(restyle_[first + i], wave_objects_[i], true, wave_errors_[part])) break;
        wave_read_[i] = 1;
      }
    });
    for (size_t i = 0; i < count; ++i) {
      if (!wave_read_[i]) {
        error = wave_errors_[i / per_part];
        return false;
      }
      evaluate_style(at(restyle_[first + i]), wave_objects_[i]);
    }
  }
  restyle_.clear();
  return true;
}

namespace {

// Whether an object of this class and pipeline is analysed for runs (pipes and components).
bool in_pipeline(ObjectClass object_class, uint64_t pipeline_id) {
  return pipeline_id != 0 &&
         (object_class == ObjectClass::pipe || object_class == ObjectClass::component);
}

}  // namespace

Known* DecodedObjects::find(uint32_t key) { return directory_.find(key); }

Known& DecodedObjects::insert(uint32_t key) {
  uint32_t i;
  if (!free_known_.empty()) {
    i = free_known_.back();
    free_known_.pop_back();
    pool_[i] = Known{};
    keys_[i] = key;
  } else {
    i = uint32_t(pool_.size());
    pool_.emplace_back();
    keys_.push_back(key);
  }
  directory_.insert(key, &pool_[i]);
  return pool_[i];
}

bool DecodedObjects::decode(std::span<const VisibleObject> visible, bool hlod,
                            std::string& error) {
  new_slots_.clear();
  restyle_.clear();
  decoded_.resize(visible.size());
  for (size_t i = 0; i < visible.size(); ++i) {
    decoded_[i] = directory_.find(visible[i].slot);
    if (!decoded_[i])
      new_slots_.push_back(visible[i].slot);
    else if (decoded_[i]->style_epoch != style_epoch_)
      restyle_.push_back(visible[i].slot);
  }
  if (!restyle_.empty() && !restyle(error)) return false;
  std::sort(new_slots_.begin(), new_slots_.end());
  stretches_.clear();
  stretch_of_.clear();
  for (size_t i = 0; i < new_slots_.size(); ++i) {
    // Read in waves, on the workers, with the pipelines they meet analysed (read_wave).
    const size_t in_wave = i % kNewObjectsPerWave;
    if (in_wave == 0) read_wave(i, hlod);
    if (!wave_read_[in_wave]) {
      error = wave_errors_[in_wave / part_size_];
      return false;
    }
    const uint32_t slot = new_slots_[i];
    Known& k = add(slot, wave_objects_[in_wave], false);
    if (!hlod || !in_pipeline(k.object_class, k.pipeline_id)) continue;
    if (analysed(k.pipeline_id, slot)) {
      for (const uint32_t r : pipeline_runs_.find(k.pipeline_id)->second.runs) {
        const auto& members = runs_[r].members;
        if (std::find(members.begin(), members.end(), slot) != members.end()) {
          k.run = int32_t(r);
          break;
        }
      }
      continue;
    }
    // Its stretch met first now: its runs added now, in the order stretches are met (so run
    // indices do not depend on the thread count), and the members known told theirs (this
    // one too); those added after find theirs above. (None: it ends runs, an elbow or a tee.)
    const auto stretch = stretch_of_.find(slot);
    if (stretch != stretch_of_.end() && !stretch->second->added) add_stretch(*stretch->second);
  }
  // The new ones' Known (the pool's growth moves none).
  if (!new_slots_.empty())
    for (size_t i = 0; i < visible.size(); ++i)
      if (!decoded_[i]) decoded_[i] = directory_.find(visible[i].slot);
  return true;
}

namespace {

// Known::test_boxes of `primitives`: each one's bounds, or where there are more than
// kMaxTestBoxes, those of groups of neighbours: the set split in halves at the median of their
// centres along its widest spread, and each half again, down to kMaxTestBoxes groups (a tower's
// shell, its platforms and its ladders part early).
void group_bounds(const std::vector<Primitive>& primitives, std::vector<Aabb>& boxes) {
  boxes.clear();
  if (primitives.size() < 2) return;
  std::vector<Aabb> each;
  each.reserve(primitives.size());
  for (const Primitive& p : primitives) {
    const Aabb b = model_bounds(p);
    if (!b.empty()) each.push_back(b);
  }
  if (each.size() < 2) return;
  if (each.size() <= kMaxTestBoxes) {
    boxes = std::move(each);
    return;
  }
  const auto split = [&](auto& self, size_t first, size_t end, size_t groups) -> void {
    if (groups <= 1 || end - first <= 1) {
      Aabb g = each[first];
      for (size_t i = first + 1; i < end; ++i) {
        g.min = glm::min(g.min, each[i].min);
        g.max = glm::max(g.max, each[i].max);
      }
      boxes.push_back(g);
      return;
    }
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (size_t i = first; i < end; ++i) {
      const glm::vec3 c = each[i].min + each[i].max;
      lo = glm::min(lo, c);
      hi = glm::max(hi, c);
    }
    const glm::vec3 spread = hi - lo;
    const int axis = spread.x >= spread.y && spread.x >= spread.z ? 0 : spread.y >= spread.z ? 1 : 2;
    const size_t middle = first + (end - first) / 2;
    std::nth_element(each.begin() + ptrdiff_t(first), each.begin() + ptrdiff_t(middle),
                     each.begin() + ptrdiff_t(end), [axis](const Aabb& a, const Aabb& b) {
                       return a.min[axis] + a.max[axis] < b.min[axis] + b.max[axis];
                     });
    self(self, first, middle, groups / 2);
    self(self, middle, end, groups - groups / 2);
  };
  split(split, 0, each.size(), kMaxTestBoxes);
}

// Known::order_key: 32 well-mixed bits of an object's id (splitmix64's finaliser), or of a
// merged run's pipeline id and start point.
uint32_t order_key_of(uint64_t id, const PipelineRun* run) {
  uint64_t x = id;
  if (run) {
    for (const double c : {run->start_m.x, run->start_m.y, run->start_m.z}) {
      uint64_t bits;
      std::memcpy(&bits, &c, sizeof bits);
      x = (x ^ bits) * 0x9e3779b97f4a7c15ull;
    }
  }
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return uint32_t(x ^ (x >> 31));
}

}  // namespace

// Makes the Known of `key` from an object (its primitives moved out of it): its parts, their
// shared plans, its levels and their errors, its centreline.
Known& DecodedObjects::add(uint32_t key, Object& o, bool keeps_primitives) {
  Known* existing = directory_.find(key);
  Known& k = existing ? *existing : insert(key);
  k.id = o.id;
  k.order_key = order_key_of(key & kRunKeyBit ? runs_[key & ~kRunKeyBit].pipeline_id : o.id,
                             key & kRunKeyBit ? &runs_[key & ~kRunKeyBit] : nullptr);
  k.object_class = o.object_class;
  k.colour = o.colour;
  k.origin_m = o.origin_m;
  k.pipeline_id = o.pipeline_id;
  k.primitives = std::move(o.primitives);
  o.primitives.clear();
  k.keeps_primitives = keeps_primitives;
  evaluate_style(k, o);
  k.parts.clear();
  k.parts.reserve(k.primitives.size());
  k.own_plans.clear();
  size_t facet_groups = 0;
  for (const Primitive& p : k.primitives) facet_groups += std::holds_alternative<FacetGroup>(p.shape);
  k.own_plans.reserve(facet_groups);  // never reallocated: parts point into it
  k.keeps_primitives |= facet_groups > 0;
  uint32_t vertex_count = 0;
  for (uint32_t i = 0; i < k.primitives.size(); ++i) {
    MeshPlan plan = plan_mesh(k.primitives[i]);
    if (plan.vertex_count == 0) continue;
    vertex_count += plan.vertex_count;
    if (plan.topology == Topology::lines) {
      k.has_lines = true;
    } else {
      k.has_triangles = true;
      k.level_count = std::max(k.level_count, plan.level_count);
      for (uint32_t l = 0; l < kMaxLevels; ++l)
        k.error_m[l] = std::max(k.error_m[l], plan.error_m[plan.clamp_level(l)]);
    }
    const MeshPlan* shared;
    if (std::holds_alternative<FacetGroup>(k.primitives[i].shape)) {
      shared = &k.own_plans.emplace_back(plan);
    } else {
      plan.error_m = {};
      const auto [it, added] = plans_.try_emplace(PlanKey{plan.indices[0].data(), plan.flip_winding}, plan);
      assert(it->second.vertex_count == plan.vertex_count && it->second.closed == plan.closed &&
             it->second.topology == plan.topology && it->second.level_count == plan.level_count);
      shared = &it->second;
    }
    k.parts.push_back({shared, vertex_count - plan.vertex_count, i});
  }
  if (o.object_class == ObjectClass::pipe && !o.centreline.empty()) {
    k.centreline = o.centreline;
    k.has_centreline = true;
    k.centreline_first = vertex_count;
    vertex_count += uint32_t(2 * o.centreline.size());
    for (const auto& s : o.centreline) k.pipe_diameter_m = std::max(k.pipe_diameter_m, s.diameter_m);
  }
  k.vertex_count = vertex_count;
  k.occluder = {};
  k.occluder_built = false;
  k.test_boxes.clear();
  k.test_boxes_built = false;
  return k;
}

namespace {

// A pipeline's members lie together in slot order, in branch order, and the pipeline beside
// them (importers write them so; a generated plant puts the pipeline 1 to 18 slots after its
// last member). So the pipeline is looked for in the slots about a member, by their records'
// keys (ReadView::object_key: their chunks are decompressed already, or soon read anyway),
// forward until it is found or kPipelineGapSlots slots in a row are neither it nor one of its
// members, then back the same way, noting the members met; a stretch's member not met so is
// looked for in the slot beside its neighbour's, and only then in the ids table, which costs a
// page fault or more (x100 walk, first 10 views: 643,559 keys read and no id looked up; 2.1
// million keys when the search went on both ways until every member was found).
inline constexpr uint32_t kPipelineGapSlots = 24;

// The slot of member `id`: from `near` (sorted (id, slot) pairs found about the member), else
// `guess` if that slot holds it (a branch's members lie in consecutive slots), else looked up
// in the ids table.
std::optional<uint32_t> member_slot_of(const ReadView& view,
                                       const std::vector<std::pair<uint64_t, uint32_t>>& near,
                                       uint64_t id, int64_t guess) {
  const auto it = std::lower_bound(near.begin(), near.end(), std::pair<uint64_t, uint32_t>{id, 0});
  if (it != near.end() && it->first == id) return it->second;
  uint64_t guessed_id = 0, pipeline_of = 0;
  std::string ignored;
  if (guess >= 0 && guess < int64_t(view.slot_count()) &&
      view.object_key(uint32_t(guess), guessed_id, pipeline_of, ignored) && guessed_id == id)
    return uint32_t(guess);
  return view.slot_of(id);
}

// Scratch of find_stretch_runs, kept by the caller across calls (its vectors keep their room),
// with the last pipeline it read: a part of a frame's new objects (consecutive slots) meets a
// pipeline's stretches one after another, and reads the pipeline once (preset c's 100-view
// walk and 12 interior views: pipelines read 17,111 -> 2,972 for as many stretches).
struct StretchScratch {
  uint64_t pipeline_id = 0;  // of `pipeline` and `near` (0: none)
  Object pipeline;
  std::vector<std::pair<uint64_t, uint32_t>> near;
  std::deque<Object> before, after;  // the stretch's members before and after the one met
  std::vector<uint32_t> slots_before, slots_after;
  std::vector<std::pair<uint32_t, const Object*>> branch;
};

// Reads pipeline `pipeline_id` into scratch.pipeline, and the slots of its members found about
// `member_slot` into scratch.near (sorted). False if it cannot be read.
bool find_pipeline(const ReadView& view, uint64_t pipeline_id, uint32_t member_slot,
                   StretchScratch& scratch) {
  scratch.pipeline_id = 0;
  std::string ignored;  // (a slot that cannot be read is left to the lookups)
  Object& pipeline = scratch.pipeline;
  std::optional<uint32_t> pipeline_slot;
  auto& near = scratch.near;
  near.clear();
  const int64_t end = view.slot_count();
  for (const int step : {1, -1}) {
    uint32_t gap = 0;
    for (int64_t s = step > 0 ? member_slot : int64_t(member_slot) - 1;
         s >= 0 && s < end && gap < kPipelineGapSlots && !pipeline_slot; s += step) {
      uint64_t id = 0, pipeline_of = 0;
      if (!view.object_key(uint32_t(s), id, pipeline_of, ignored)) {
        ++gap;
      } else if (id == pipeline_id) {
        if (!view.object(uint32_t(s), pipeline, false, ignored)) return false;
        pipeline_slot = uint32_t(s);
      } else if (pipeline_of == pipeline_id) {
        near.emplace_back(id, uint32_t(s));
        gap = 0;
      } else {
        ++gap;
      }
    }
  }
  if (!pipeline_slot) {
    const auto slot = view.slot_of(pipeline_id);
    if (!slot || !view.object(*slot, pipeline, false, ignored)) return false;
  }
  std::sort(near.begin(), near.end());
  scratch.pipeline_id = pipeline_id;
  return true;
}

// The stretch of `member` (in `member_slot`, of pipeline `pipeline_id`, not ending runs: see
// ends_runs) and its runs, read through `view`: its members from the one met back and forth
// along its branch to the members that end runs (or the branch's ends), skipping those that
// cannot be read. Without the pipeline, or with the member in none of its branches, the
// stretch is the member alone, with no runs (such a pipeline is simply not merged).
void find_stretch_runs(const ReadView& view, uint64_t pipeline_id, const Object& member,
                       uint32_t member_slot, StretchScratch& scratch, std::vector<uint32_t>& slots,
                       std::vector<PipelineRun>& runs) {
  slots.assign(1, member_slot);
  runs.clear();
  std::string ignored;  // (a slot that cannot be read is left to the lookups)
  Object& pipeline = scratch.pipeline;
  auto& near = scratch.near;  // (id, slot) of its members found, sorted
  if (scratch.pipeline_id != pipeline_id && !find_pipeline(view, pipeline_id, member_slot, scratch))
    return;
  // The member's place: the first branch that lists it.
  const Branch* branch = nullptr;
  size_t at = 0;
  for (const Branch& b : pipeline.branches) {
    const auto it = std::find(b.members.begin(), b.members.end(), member.id);
    if (it == b.members.end()) continue;
    branch = &b;
    at = size_t(it - b.members.begin());
    break;
  }
  if (!branch) return;
  // Each way from it, up to a member that ends runs.
  const auto walk = [&](std::deque<Object>& objects, std::vector<uint32_t>& object_slots, int step) {
    objects.clear();
    object_slots.clear();
    int64_t previous = member_slot;
    for (int64_t j = int64_t(at) + step; j >= 0 && j < int64_t(branch->members.size()); j += step) {
      const auto s = member_slot_of(view, near, branch->members[size_t(j)], previous + step);
      if (!s) continue;
      previous = *s;
      Object& o = objects.emplace_back();
      if (!view.object(*s, o, false, ignored)) {
        objects.pop_back();
        continue;
      }
      if (ends_runs(o)) {
        objects.pop_back();
        break;
      }
      object_slots.push_back(*s);
    }
  };
  walk(scratch.before, scratch.slots_before, -1);
  walk(scratch.after, scratch.slots_after, 1);
  auto& members = scratch.branch;
  members.clear();
  for (size_t i = scratch.before.size(); i-- > 0;)
    members.emplace_back(scratch.slots_before[i], &scratch.before[i]);
  members.emplace_back(member_slot, &member);
  for (size_t i = 0; i < scratch.after.size(); ++i)
    members.emplace_back(scratch.slots_after[i], &scratch.after[i]);
  find_runs(members, runs);
  slots.clear();
  for (const auto& [s, o] : members) slots.push_back(s);
  std::sort(slots.begin(), slots.end());
  slots.erase(std::unique(slots.begin(), slots.end()), slots.end());
}

}  // namespace

template <class F>
void DecodedObjects::on_views(size_t parts, const F& f) {
  if (workers_ && parts > 1 && views_.empty()) make_sibling_views();
  // Parts taken in turn by the workers that have a view, then by this thread (every part may
  // have gone to workers without one).
  std::atomic<size_t> next{0};
  const auto take_parts = [&](const ReadView& view) {
    for (size_t p; (p = next.fetch_add(1)) < parts;) f(p, view);
  };
  if (workers_ && parts > 1 && views_.size() > 1)
    workers_->run(views_.size(), [&](size_t, unsigned worker) {
      if (worker < views_.size()) take_parts(*views_[worker]);
    });
  take_parts(*view_);
}

void DecodedObjects::read_wave(size_t first, bool hlod) {
  const size_t count = std::min(kNewObjectsPerWave, new_slots_.size() - first);
  if (wave_objects_.size() < count) wave_objects_.resize(count);
  wave_read_.assign(count, 0);
  // Parts of kNewObjectsPerPart, or fewer, down to kMinNewObjectsPerPart, where that gives
  // every worker one: a walk's frame meets a few hundred new objects, which one part left to
  // one thread. (A part reads through a view of its own: each part boundary may inflate a
  // chunk twice.)
  const size_t workers = workers_ ? workers_->size() : 1;
  const size_t per_part = std::clamp<size_t>((count + workers - 1) / workers, kMinNewObjectsPerPart,
                                             kNewObjectsPerPart);
  part_size_ = per_part;
  const size_t parts = (count + per_part - 1) / per_part;
  wave_errors_.resize(parts);
  std::mutex claims;
  on_views(parts, [&](size_t part, const ReadView& view) {
    StretchScratch scratch;
    std::vector<uint32_t> slots;
    std::vector<PipelineRun> runs;
    // A part stops at its first object that cannot be read (decode() stops there).
    for (size_t i = part * per_part; i < std::min(count, (part + 1) * per_part); ++i) {
      const Object& o = wave_objects_[i];
      if (!view.object(new_slots_[first + i], wave_objects_[i], style_.needs_record(),
                       wave_errors_[part]))
        break;
      wave_read_[i] = 1;
      // Its stretch analysed now, through the view that just read it, if it may lie in a run and
      // no part has taken it yet: its pipeline and neighbours lie in the slots about this one,
      // whose chunks that view holds decompressed (analysed after the whole wave, they were
      // decompressed again). (pipeline_runs_ is only read while the parts run; stretches_
      // and stretch_of_ are written under the lock.)
      const uint32_t slot = new_slots_[first + i];
      if (!hlod || !in_pipeline(o.object_class, o.pipeline_id) || analysed(o.pipeline_id, slot) ||
          ends_runs(o))
        continue;
      {
        std::lock_guard<std::mutex> lock(claims);
        if (stretch_of_.count(slot)) continue;  // a neighbour's stretch, found already
      }
      find_stretch_runs(view, o.pipeline_id, o, slot, scratch, slots, runs);
      std::lock_guard<std::mutex> lock(claims);
      if (stretch_of_.count(slot)) continue;  // found meanwhile by another part
      Stretch& stretch = stretches_.emplace_back();
      stretch.pipeline_id = o.pipeline_id;
      stretch.slots = slots;
      stretch.runs = std::move(runs);
      for (const uint32_t s : stretch.slots) stretch_of_.try_emplace(s, &stretch);
    }
  });
}

void DecodedObjects::read_blocks(std::span<const uint32_t> blocks) {
  const size_t parts = (blocks.size() + kBlocksPerPart - 1) / kBlocksPerPart;
  on_views(parts, [&](size_t part, const ReadView& view) {
    std::string ignored;
    for (size_t i = part * kBlocksPerPart; i < std::min(blocks.size(), (part + 1) * kBlocksPerPart); ++i)
      (void)view.spatial_block(blocks[i], ignored);
  });
}

void DecodedObjects::make_sibling_views() {
  views_.assign(1, view_);
  const unsigned workers = workers_ ? workers_->size() : 1;
  while (views_.size() < workers) {
    std::string why;  // without a sibling, fewer workers read
    std::unique_ptr<ReadView> sibling = view_->sibling(why);
    if (!sibling) break;
    views_.push_back(sibling.get());
    siblings_.push_back(std::move(sibling));
  }
}

void DecodedObjects::add_stretch(Stretch& stretch) {
  PipelineKnown& pipeline = pipeline_runs_[stretch.pipeline_id];
  for (PipelineRun& run : stretch.runs) {
    run.pipeline_id = stretch.pipeline_id;
    const uint32_t r = new_run(std::move(run));
    pipeline.runs.push_back(r);
    for (const uint32_t m : runs_[r].members)
      if (Known* k = directory_.find(m)) k->run = int32_t(r);
  }
  stretch.runs.clear();
  const size_t before = pipeline.analysed.size();
  pipeline.analysed.insert(pipeline.analysed.end(), stretch.slots.begin(), stretch.slots.end());
  std::inplace_merge(pipeline.analysed.begin(), pipeline.analysed.begin() + ptrdiff_t(before),
                     pipeline.analysed.end());
  stretch.added = true;
}

bool DecodedObjects::analysed(uint64_t pipeline_id, uint32_t slot) const {
  const auto it = pipeline_runs_.find(pipeline_id);
  return it != pipeline_runs_.end() &&
         std::binary_search(it->second.analysed.begin(), it->second.analysed.end(), slot);
}

uint32_t DecodedObjects::new_run(PipelineRun&& run) {
  if (free_runs_.empty()) {
    runs_.push_back(std::move(run));
    decisions_.emplace_back();
    return uint32_t(runs_.size() - 1);
  }
  const uint32_t r = free_runs_.back();
  free_runs_.pop_back();
  runs_[r] = std::move(run);
  decisions_[r] = {};
  return r;
}

void DecodedObjects::forget_pipelines() {
  if (pipeline_runs_.size() <= std::max(kPipelinesKept, 2 * pipelines_referenced_)) return;
  // What the known objects and runs refer to (their keys and runs survive only with it).
  std::unordered_set<uint64_t> referenced;
  for (size_t i = 0; i < pool_.size(); ++i) {
    const uint32_t key = keys_[i];
    if (key == kFreeKey) continue;
    if (key & kRunKeyBit) referenced.insert(runs_[key & ~kRunKeyBit].pipeline_id);
    else if (pool_[i].run >= 0) referenced.insert(pool_[i].pipeline_id);
  }
  for (auto it = pipeline_runs_.begin(); it != pipeline_runs_.end();) {
    if (referenced.count(it->first)) {
      ++it;
      continue;
    }
    for (const uint32_t r : it->second.runs) {
      runs_[r] = PipelineRun{};
      free_runs_.push_back(r);
    }
    it = pipeline_runs_.erase(it);
  }
  pipelines_referenced_ = pipeline_runs_.size();
}

Known& DecodedObjects::know_run(uint32_t run) {
  const uint32_t key = kRunKeyBit | run;
  if (Known* k = directory_.find(key)) return *k;
  const PipelineRun& r = runs_[run];
  Object o;
  // The pipeline's id, known from the run itself: not from whichever member happens to be
  // decoded (that depends on the frames before, and the picture must not).
  o.id = r.pipeline_id;
  o.object_class = ObjectClass::pipe;
  o.colour = r.colour;
  o.origin_m = r.start_m;
  o.primitives.push_back(merged_cylinder(r, r.start_m));
  o.centreline.push_back({glm::vec3(0.0f), glm::vec3(r.end_m - r.start_m), r.diameter_m});
  return add(key, o, true);
}

const OccluderShape* DecodedObjects::occluder(uint32_t slot, Known& k, std::string& error) {
  if (!k.occluder_built) {
    if (may_occlude(k.object_class, k.colour) && !k.hidden) {
      const std::vector<Primitive>* p = primitives(slot, k, error);
      if (!p) return nullptr;
      build_occluder_shape(*p, occluder_scratch_, k.occluder);
    }
    k.occluder_built = true;
  }
  return &k.occluder;
}

const std::vector<Aabb>* DecodedObjects::test_boxes(uint32_t slot, Known& k, std::string& error) {
  if (!k.test_boxes_built) {
    const std::vector<Primitive>* p = primitives(slot, k, error);
    if (!p) return nullptr;
    group_bounds(*p, k.test_boxes);
    k.test_boxes_built = true;
  }
  return &k.test_boxes;
}

const std::vector<Primitive>* DecodedObjects::primitives(uint32_t key, const Known& k,
                                                         std::string& error) {
  if (!k.primitives.empty() || k.parts.empty()) return &k.primitives;
  // Dropped after an earlier upload (never for runs, which keep theirs).
  if (!view_->object(key, object_, false, error)) return nullptr;
  return &object_.primitives;
}

void DecodedObjects::forget_old(uint64_t frame, const Residency& residency) {
  forget_known(frame, residency);
  forget_pipelines();
}

void DecodedObjects::forget_known(uint64_t frame, const Residency& residency) {
  const size_t limit = kKnownObjectsKept + residency.resident_count();
  if (known_count() <= limit) return;
  decoded_.clear();
  // A clock hand over the pool: each call goes on from where the last stopped and stops as soon
  // as the count is back at the limit, so a frame looks at about as many entries as it forgets
  // (and the resident and just-seen ones it passes), never the whole pool; the entries looked at
  // longest ago go first. A freed entry is reused by the next insert, just behind the hand.
  for (int pass = 0; pass < 2 && known_count() > limit; ++pass) {
    for (size_t n = pool_.size(); n > 0 && known_count() > limit; --n) {
      if (forget_hand_ >= pool_.size()) forget_hand_ = 0;
      const size_t i = forget_hand_++;
      const uint32_t key = keys_[i];
      if (key == kFreeKey) continue;
      const bool old = pass == 1 || pool_[i].last_seen < frame;
      if (!old || residency.resident(key)) continue;
      directory_.erase(key);
      pool_[i] = Known{};  // its memory goes now, not when the entry is reused
      keys_[i] = kFreeKey;
      free_known_.push_back(uint32_t(i));
    }
  }
}

}  // namespace plantview::detail
