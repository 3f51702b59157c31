// Arena streaming: residency, tessellation into the arena, the object table and the index
// lists (rules in arena_streaming.h).
#include "streaming/arena_streaming.h"

#include <algorithm>
#include <bit>

#include "decoded_objects.h"
#include "frame_plan.h"

namespace plantview::detail {

namespace {

IndexList list_of(const Known& k, const Known::Part& part) {
  if (part.plan->topology == Topology::lines) return kLines;
  if (k.colour.a < 255) return kTransparent;
  return part.plan->closed ? kClosed : kOpen;
}

}  // namespace

// --- the object table ---------------------------------------------------------------------------

void ObjectTable::reset() {
  free_.clear();
  used_ = 0;
}

uint32_t ObjectTable::acquire() {
  if (!free_.empty()) {
    const uint32_t t = free_.back();
    free_.pop_back();
    return t;
  }
  if (used_ == entries_.size()) entries_.resize(std::max<size_t>(1024, entries_.size() * 2));
  return used_++;
}

void ObjectTable::set(uint32_t entry, const glm::dvec3& offset_m, const glm::vec3& scale,
                      Colour c, uint64_t id, uint32_t tie) {
  assert(tie < (1u << kTieBits));
  TableEntry& e = entries_[entry];
  e.offset_m[0] = float(offset_m.x);
  e.offset_m[1] = float(offset_m.y);
  e.offset_m[2] = float(offset_m.z);
  e.colour = uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | uint32_t(c.a) << 24;
  e.scale[0] = scale.x;
  e.scale[1] = scale.y;
  e.scale[2] = scale.z;
  pick_ids_.push_back(id);
  assert(pick_ids_.size() < kPickLimit);
  e.pick = uint32_t(pick_ids_.size()) | tie << (32 - kTieBits);
}

Colour ArenaStreaming::colour_of(const Known& k) const {
  return colouring_ ? colouring_->colour(k.style_value, k.colour) : k.colour;
}

// --- residency ----------------------------------------------------------------------------------

void ArenaStreaming::reset(uint64_t budget_vertices, bool drop_primitives) {
  drop_primitives_ = drop_primitives;
  pending_.clear();
  pending_vertices_.clear();
  table_.reset();
  proxy_tables_.clear();
  residency_ = Residency(budget_vertices);
}

const ArenaStreaming::Compaction& ArenaStreaming::compaction(const MeshPlan& plan, uint8_t base) {
  const CompactionKey key{plan.indices[0].data(), base, plan.flip_winding};
  if (const auto it = compactions_.find(key); it != compactions_.end()) return it->second;
  Compaction& c = compactions_[key];
  c.plan = plan;
  remap_.assign(plan.vertex_count, UINT32_MAX);
  for (uint32_t l = base; l < plan.level_count; ++l) {
    for (const uint32_t v : plan.indices[l]) {
      if (remap_[v] == UINT32_MAX) {
        remap_[v] = uint32_t(c.kept.size());
        c.kept.push_back(v);
      }
      c.indices[l].push_back(remap_[v]);
    }
  }
  for (uint32_t l = 0; l < kMaxLevels; ++l)
    c.plan.indices[l] = c.indices[std::max<uint32_t>(l, base)];  // finer levels are never asked
  c.plan.vertex_count = uint32_t(c.kept.size());
  return c;
}

bool ArenaStreaming::resident(const Known& k) { return k.table != UINT32_MAX; }

uint64_t ArenaStreaming::resident_vertices(const Known& k, uint8_t base) {
  base = uint8_t(std::min<uint32_t>(base, k.level_count - 1u));
  if (base == 0) return k.vertex_count;
  uint64_t n = 2 * k.centreline.size();
  for (const Known::Part& part : k.parts) {
    const uint8_t part_base = uint8_t(part.plan->clamp_level(base));
    n += part_base == 0 ? part.plan->vertex_count : compaction(*part.plan, part_base).kept.size();
  }
  return n;
}

void ArenaStreaming::tessellate(const std::vector<Primitive>& primitives, Known& k, uint8_t base,
                                std::vector<PackedVertex>& scratch,
                                std::vector<PackedVertex>& out) const {
  scratch.resize(k.vertex_count);
  for (const auto& part : k.parts) {
    write_vertices(primitives[part.primitive], *part.plan, glm::dvec3(0.0),
                   std::span<PackedVertex>(scratch.data() + part.first_vertex, part.plan->vertex_count));
  }
  for (size_t s = 0; s < k.centreline.size(); ++s) {
    // A centreline's normal word is its diameter (gl/backend.h).
    const uint32_t diameter = std::bit_cast<uint32_t>(k.centreline[s].diameter_m);
    scratch[k.centreline_first + 2 * s] = {k.centreline[s].start_m, diameter};
    scratch[k.centreline_first + 2 * s + 1] = {k.centreline[s].end_m, diameter};
  }
  k.resident_centreline_first = k.centreline_first;
  for (Known::Part& part : k.parts) {
    part.resident_first = part.first_vertex;
    part.resident_plan = nullptr;
  }
  if (base == 0) {
    out.swap(scratch);
    return;
  }
  // Keep only the vertices that levels >= base use (coarser levels use a subset of them).
  out.clear();
  for (Known::Part& part : k.parts) {
    const uint8_t part_base = uint8_t(part.plan->clamp_level(base));
    part.resident_first = uint32_t(out.size());
    if (part_base == 0) {  // a one-level part (facet groups among them): all of it
      out.insert(out.end(), scratch.begin() + part.first_vertex,
                 scratch.begin() + part.first_vertex + part.plan->vertex_count);
      continue;
    }
    const auto it = compactions_.find(CompactionKey{part.plan->indices[0].data(), part_base, part.plan->flip_winding});
    const Compaction& c = it->second;  // made by resident_vertices() before any tessellation
    part.resident_plan = &c.plan;
    for (const uint32_t v : c.kept) out.push_back(scratch[part.first_vertex + v]);
  }
  k.resident_centreline_first = uint32_t(out.size());
  out.insert(out.end(), scratch.begin() + k.centreline_first,
             scratch.begin() + k.centreline_first + 2 * k.centreline.size());
}

bool ArenaStreaming::make_resident(uint32_t key, Known& k, uint8_t base, DecodedObjects& objects,
                                   FrameStats& stats, std::string& error, bool& fits,
                                   const std::vector<PackedVertex>* prepared) {
  base = uint8_t(std::min<uint32_t>(base, k.level_count - 1u));
  const std::vector<PackedVertex>* upload = prepared;
  if (!upload) {
    const std::vector<Primitive>* primitives = objects.primitives(key, k, error);
    if (!primitives) return false;
    resident_vertices(k, base);  // makes the compactions it needs
    tessellate(*primitives, k, base, vertices_, compacted_);
    upload = &compacted_;
  }
  const uint32_t count = uint32_t(upload->size());

  evicted_.clear();
  const auto offset = residency_.admit(key, count, evicted_);
  for (const auto& [victim, units] : evicted_) {
    if (Known* v = objects.find(victim); v && v->table != UINT32_MAX) {
      table_.release(v->table);
      v->table = UINT32_MAX;
    }
    stats.objects_evicted += 1;
    stats.arena_bytes_evicted += units * kBytesPerVertex;
  }
  fits = offset.has_value();
  if (!fits) return true;
  if (!backend_.grow_arena(*offset + count, error)) {
    residency_.drop(key);  // resident exactly while it holds a table entry
    return false;
  }
  k.base = base;
  k.table = table_.acquire();
  k.arena_offset = uint32_t(*offset);
  if (deferring_) {
    pending_.push_back({*offset, k.table, pending_vertices_.size(), count});
    pending_vertices_.insert(pending_vertices_.end(), upload->begin(), upload->end());
  } else {
    vertex_objects_.assign(count, k.table);
    backend_.upload(*offset, *upload, vertex_objects_);
  }
  stats.objects_tessellated += 1;
  stats.arena_bytes_uploaded += uint64_t(count) * kBytesPerVertex;
  if (!k.keeps_primitives && drop_primitives_) {
    k.primitives.clear();
    k.primitives.shrink_to_fit();
  }
  return true;
}

void ArenaStreaming::flush_uploads() {
  for (const PendingUpload& u : pending_) {
    vertex_objects_.assign(u.count, u.table);
    backend_.upload(u.offset, std::span<const PackedVertex>(pending_vertices_.data() + u.first, u.count),
                    vertex_objects_);
  }
  pending_.clear();
  pending_vertices_.clear();
}

void ArenaStreaming::release(uint32_t key, Known& k) {
  residency_.drop(key);
  if (k.table != UINT32_MAX) table_.release(k.table);
  k.table = UINT32_MAX;
}

// --- a frame ------------------------------------------------------------------------------------

void ArenaStreaming::begin_frame(const FramePlan& plan, bool second_phase) {
  if (!second_phase) {
    residency_.begin_frame();
    for (const uint32_t t : proxy_tables_) table_.release(t);  // the last frame's boxes
    proxy_tables_.clear();
    table_.begin_frame();
  }
  phase_proxies_ = proxy_tables_.size();
  // Every visible object (merged runs' members and objects without geometry too), and the
  // merged runs.
  for (const VisibleObject& v : plan.visible()) residency_.mark_visible(v.slot);
  for (const Draw& d : plan.draws())
    if (d.key & kRunKeyBit) residency_.mark_visible(d.key);
  counts_.fill(0);
  segments_.clear();
}

bool ArenaStreaming::grow_for(std::span<const Draw> draws, LodPolicy policy, std::string& error) {
  const bool roomy = arena_roomy(residency_.used_units(), residency_.capacity_units());
  uint64_t needed = 0;
  for (const Draw& d : draws) {
    const Known& k = *d.known;
    if (resident(k) && d.level >= k.base) continue;
    needed += resident_vertices(k, resident_base(d.level, policy, roomy));
  }
  return !needed || backend_.grow_arena(residency_.used_units() + needed, error);
}

ArenaStreaming::Defer ArenaStreaming::spend_budget(const Known& k, uint8_t base) {
  if (!budget_bounded_) return Defer::none;
  if (budget_left_ == 0) {
    if (resident(k)) return Defer::keep_coarser;
    return base + 1u < k.level_count ? Defer::coarsest : Defer::none;
  }
  budget_left_ -= std::min(budget_left_, resident_vertices(k, base));  // the last one whole
  return Defer::none;
}

size_t ArenaStreaming::prepare(std::span<Draw> draws, LodPolicy policy) {
  // Which draws will be tessellated, at the base they will most likely get (the arena's
  // roominess as the frame starts); their compactions made here, on this thread.
  const bool roomy = arena_roomy(residency_.used_units(), residency_.capacity_units());
  job_of_draw_.assign(draws.size(), UINT32_MAX);
  defer_of_draw_.assign(draws.size(), Defer::none);
  size_t job_count = 0, batch_vertices = 0, covered = draws.size();
  for (size_t i = 0; i < draws.size(); ++i) {
    if (batch_vertices >= kPrepareBatchVertices) {
      covered = i;
      break;
    }
    Draw& d = draws[i];
    Known& k = *d.known;
    if (resident(k) && d.level >= k.base) continue;
    uint8_t base = uint8_t(std::min<uint32_t>(resident_base(d.level, policy, roomy), k.level_count - 1u));
    const Defer defer = spend_budget(k, base);
    defer_of_draw_[i] = defer;
    if (defer == Defer::keep_coarser) continue;  // nothing to tessellate
    if (defer == Defer::coarsest) base = uint8_t(k.level_count - 1);
    if (k.primitives.empty() && !k.parts.empty()) continue;  // decoded again on this thread
    batch_vertices += resident_vertices(k, base);
    if (jobs_.size() <= job_count) jobs_.emplace_back();
    Job& job = jobs_[job_count];
    job.draw = uint32_t(i);
    job.base = base;
    job_of_draw_[i] = uint32_t(job_count++);
  }
  // Tessellate them on the pool: each job writes only its own buffers and its own object.
  // What the buffers keep from the batches before is bounded: a huge object's buffer, and
  // those past kKeptJobBytes in all, are freed.
  size_t kept_bytes = 0;
  for (Job& job : jobs_) {
    const size_t bytes = job.vertices.capacity() * sizeof(PackedVertex);
    if (job.vertices.capacity() > kKeptJobVertices || kept_bytes + bytes > kKeptJobBytes)
      std::vector<PackedVertex>().swap(job.vertices);
    else
      kept_bytes += bytes;
  }
  if (scratch_.size() < pool_.size()) scratch_.resize(pool_.size());
  const auto tessellate_job = [&](size_t j, unsigned worker) {
    Job& job = jobs_[j];
    Known& k = *draws[job.draw].known;
    tessellate(k.primitives, k, job.base, scratch_[worker], job.vertices);
  };
  if (job_count < 2 * kJobsPerWorker) {
    for (size_t j = 0; j < job_count; ++j) tessellate_job(j, 0);
  } else {
    pool_.run(job_count, tessellate_job);
  }
  return covered;
}

bool ArenaStreaming::stream(FramePlan& plan, DecodedObjects& objects, const FrameView& view,
                            const RenderOptions& options, FrameStats& stats, std::string& error,
                            bool second_phase) {
  if (!second_phase) {
    budget_bounded_ = options.stream_budget_vertices > 0;
    budget_left_ = options.stream_budget_vertices;
  }
  begin_frame(plan, second_phase);
  if (!grow_for(plan.draws(), options.lod_policy, error)) return false;
  const std::span<Draw> draws = plan.draws();
  size_t batch_first = 0, batch_end = 0;
  for (size_t i = 0; i < draws.size(); ++i) {
    // Draws are tessellated ahead a batch at a time: what waits for upload stays bounded.
    if (i == batch_end) {
      batch_first = i;
      batch_end = i + prepare(draws.subspan(i, std::min(kPrepareBatch, draws.size() - i)), options.lod_policy);
    }
    const size_t batch = i - batch_first;
    Draw& d = draws[i];
    // The Knowns ahead; nearer, their parts and object-table entries; nearer still, their
    // first part's plan (place() reads them, and writes the entry).
    if (i + kPrefetchAhead < draws.size()) prefetch(draws[i + kPrefetchAhead].known);
    if (i + kPrefetchAhead / 2 < draws.size()) {
      const Known& ahead = *draws[i + kPrefetchAhead / 2].known;
      __builtin_prefetch(ahead.parts.data());
      if (ahead.table < table_.entries().size()) __builtin_prefetch(&table_.entries()[ahead.table], 1);
    }
    if (i + 2 < draws.size()) {
      const Known& ahead = *draws[i + 2].known;
      if (!ahead.parts.empty()) __builtin_prefetch(ahead.parts.front().plan);
    }
    bool resident = false;
    const Job* job = job_of_draw_[batch] == UINT32_MAX ? nullptr : &jobs_[job_of_draw_[batch]];
    if (!ensure_resident(d, objects, options.lod_policy, stats, error, resident, job, defer_of_draw_[batch]))
      return false;
    if (resident) {
      place(d, view, stats);
    } else if (d.visible) {
      // Over budget: the object's box, which costs no arena space (merged runs are skipped:
      // their members' boxes would be drawn one by one, and runs are small).
      const VisibleObject& v = *d.visible;
      stats.budget_proxies += 1;
      add_box(view.spatial_origin_m + glm::dvec3(v.min[0], v.min[1], v.min[2]) - view.eye_m,
              glm::vec3(v.max[0] - v.min[0], v.max[1] - v.min[1], v.max[2] - v.min[2]),
              colour_of(*d.known), d.known->id, stats);
    }
  }
  // Node boxes nearest first, as the objects are drawn: a far field of thousands of boxes
  // overlaps itself, and what a nearer box hides then fails the depth test before it is
  // shaded. Ties keep the cull's order (the sort is stable), which the camera alone fixes.
  const glm::vec3 eye = glm::vec3(view.eye_m - view.spatial_origin_m);
  box_keys_.clear();
  for (uint32_t i = 0; i < plan.node_boxes().size(); ++i) {
    const NodeBox& b = plan.node_boxes()[i];
    const glm::vec3 nearest = glm::clamp(eye, glm::vec3(b.min[0], b.min[1], b.min[2]),
                                         glm::vec3(b.max[0], b.max[1], b.max[2]));
    box_keys_.push_back({std::bit_cast<uint32_t>(glm::distance(nearest, eye)), i});
  }
  radix_sort(box_keys_, sort_scratch_);
  for (const auto& [key, i] : box_keys_) {
    const NodeBox& b = plan.node_boxes()[i];
    add_box(view.spatial_origin_m + glm::dvec3(b.min[0], b.min[1], b.min[2]) - view.eye_m,
            glm::vec3(b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]), b.colour, 0,
            stats);
  }
  residency_.end_frame();
  stats.objects_resident = residency_.resident_count();
  stats.arena_bytes_resident = residency_.used_units() * kBytesPerVertex;
  if (!second_phase) stats.draw_commands = 0;
  stats.draw_commands += proxy_tables().empty() ? 0 : 1;
  for (const size_t n : counts_) stats.draw_commands += n ? 1 : 0;
  return true;
}

bool ArenaStreaming::ensure_resident(Draw& d, DecodedObjects& objects, LodPolicy policy,
                                     FrameStats& stats, std::string& error, bool& resident,
                                     const Job* job, Defer defer) {
  Known& k = *d.known;
  if (ArenaStreaming::resident(k) && d.level < k.base) {
    if (defer == Defer::keep_coarser) {  // the budget is spent: drawn at its resident base
      stats.objects_deferred += 1;
      resident = true;
      return true;
    }
    release(d.key, k);  // nearer than its resident vertices serve: tessellate it again
    stats.objects_refined += 1;
  }
  resident = ArenaStreaming::resident(k);
  if (resident) return true;
  const bool roomy = arena_roomy(residency_.used_units(), residency_.capacity_units());
  uint8_t base = resident_base(d.level, policy, roomy);
  if (defer != Defer::none && base + 1u < k.level_count) {  // the budget is spent: coarsest
    base = uint8_t(k.level_count - 1);
    stats.objects_deferred += 1;
  }
  // The vertices tessellated ahead serve if they were made for this base.
  const bool prepared = job && job->base == uint8_t(std::min<uint32_t>(base, k.level_count - 1u));
  if (!make_resident(d.key, k, base, objects, stats, error, resident,
                     prepared ? &job->vertices : nullptr))
    return false;
  if (!resident && base + 1u < k.level_count) {
    // Over budget: the coarsest level's vertices may still fit.
    if (!make_resident(d.key, k, uint8_t(k.level_count - 1), objects, stats, error, resident))
      return false;
    if (resident) stats.budget_coarsened += 1;
  }
  return true;
}

void ArenaStreaming::place(Draw& d, const FrameView& view, FrameStats& stats) {
  const Known& k = *d.known;
  const uint32_t level = std::max<uint32_t>(d.level, k.base);
  d.level = uint8_t(level);
  d.drawn = true;
  d.arena_first = k.arena_offset;
  d.segment_first = uint32_t(segments_.size());
  table_.set(k.table, k.origin_m - view.eye_m, glm::vec3(1.0f), colour_of(k), k.id,
             tie_of(k.order_key));
  if (d.centreline) {
    stats.centreline_pipes += 1;
    stats.lines += k.centreline.size();
    const uint32_t n = uint32_t(2 * k.centreline.size());
    counts_[kLines] += n;
    segments_.push_back({nullptr, d.arena_first + k.resident_centreline_first, n, 0, uint8_t(kLines)});
    d.segment_count = 1;
    return;
  }
  for (const Known::Part& part : k.parts) {
    const uint32_t l = part.plan->clamp_level(level);
    const uint32_t n = part.plan->index_count(l);
    IndexList list = list_of(k, part);
    if (list == kClosed && d.cut) list = kClosedCut;
    counts_[list] += n;
    const MeshPlan& plan = part.resident_plan ? *part.resident_plan : *part.plan;
    segments_.push_back({&plan, d.arena_first + part.resident_first, plan.index_count(level),
                         uint8_t(level), uint8_t(list)});
    if (part.plan->topology == Topology::lines) {
      stats.lines += n / 2;
    } else {
      stats.triangles += n / 3;
      stats.triangles_by_level[l] += n / 3;
    }
  }
  d.segment_count = uint32_t(k.parts.size());
}

void ArenaStreaming::add_box(const glm::dvec3& offset_m, const glm::vec3& size_m, Colour colour,
                             uint64_t id, FrameStats& stats) {
  const uint32_t t = table_.acquire();
  proxy_tables_.push_back(t);
  table_.set(t, offset_m, size_m, colour, id);
  stats.triangles += 12;
}

bool ArenaStreaming::write_index_lists(std::span<const Draw> draws, std::string& error, bool next) {
  size_t total = 0;
  std::array<size_t, kIndexListCount> first{};
  for (int list = 0; list < kIndexListCount; ++list) {
    first[list] = total;
    total += counts_[list];
  }
  uint32_t* indices = backend_.map_indices(total, error, next);
  if (!indices) return false;
  // Nearest first: hidden fragments then fail the depth test before they are shaded. Ties
  // broken by a key of the object's own (Known::order_key), so that the order of two objects
  // depends neither on what else is drawn nor on the frames before (coincident surfaces then
  // resolve the same way fresh or after a path; within a phase, occlusion.h: an object drawn
  // in the first phase wins ties against the second's). Sorted as packed
  // keys: the distance's float bits (non-negative floats order as their bits), the order key.
  sort_keys_.clear();
  for (uint32_t i = 0; i < draws.size(); ++i) {
    if (!draws[i].drawn) continue;
    const uint64_t distance_bits = std::bit_cast<uint32_t>(float(std::max(draws[i].distance_m, 0.0)));
    sort_keys_.push_back({distance_bits << 32 | draws[i].order_key, i});
  }
  radix_sort(sort_keys_, sort_scratch_);
  draw_order_.clear();
  for (const auto& [key, i] : sort_keys_) draw_order_.push_back(i);
  // The draw order cut into runs of about equal indices, one per worker; each run starts
  // writing each list where the runs before it end.
  const size_t runs = std::clamp<size_t>(total / kIndicesPerRun, 1, pool_.size());
  std::vector<size_t>& run_first = run_first_;
  run_first.assign(1, 0);
  run_cursors_.assign(1, first);
  std::array<size_t, kIndexListCount> at = first;
  size_t written = 0;
  for (size_t o = 0; o < draw_order_.size(); ++o) {
    if (run_first.size() < runs && written * runs >= total * run_first.size()) {
      run_first.push_back(o);
      run_cursors_.push_back(at);
    }
    const Draw& d = draws[draw_order_[o]];
    for (uint32_t g = d.segment_first; g < d.segment_first + d.segment_count; ++g) {
      at[segments_[g].list] += segments_[g].count;
      written += segments_[g].count;
    }
  }
  run_first.push_back(draw_order_.size());
  pool_.run(run_cursors_.size(), [&](size_t run, unsigned) {
    std::array<uint32_t*, kIndexListCount> cursor;
    for (int list = 0; list < kIndexListCount; ++list) cursor[list] = indices + run_cursors_[run][list];
    for (size_t o = run_first[run]; o < run_first[run + 1]; ++o) {
      const Draw& d = draws[draw_order_[o]];
      for (uint32_t g = d.segment_first; g < d.segment_first + d.segment_count; ++g) {
        const Segment& seg = segments_[g];
        uint32_t*& to = cursor[seg.list];
        if (!seg.plan) {
          for (uint32_t c = 0; c < seg.count; ++c) *to++ = seg.base_vertex + c;
          continue;
        }
        to += write_indices(*seg.plan, seg.level, seg.base_vertex, std::span<uint32_t>(to, seg.count));
      }
    }
  });
  backend_.unmap_indices(next);
  return true;
}

}  // namespace plantview::detail
