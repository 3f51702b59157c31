// The broad phase (plantview/clash.h): block pairs from the spatial top, candidate pairs of
// entries within a block pair, the pool that works through them, and the clashes they make.
#include <algorithm>
#include <atomic>
#include <cassert>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_map>

#include "clash/clash_internal.h"
#include "plantview/store.h"

namespace plantview {

namespace {

using clash_detail::PairClash;

struct BlockBounds {
  uint32_t block = 0;
  float min[3], max[3];
};

bool near(const float amin[3], const float amax[3], const float bmin[3], const float bmax[3], float reach) {
  for (int i = 0; i < 3; ++i)
    if (amin[i] > bmax[i] + reach || bmin[i] > amax[i] + reach) return false;
  return true;
}

struct Entry {
  float min[3], max[3];
  uint32_t slot;
  bool second;  // from the task's second block
};

void block_entries(const SpatialBlock& block, bool second, std::vector<Entry>& out) {
  for (const SpatialNode& node : block.nodes) {
    if (node.count == 0) continue;
    for (uint32_t e = node.first; e < node.first + node.count; ++e) {
      Entry entry;
      entry_bounds(node, block.entries[e], entry.min, entry.max);
      entry.slot = block.entries[e].slot;
      entry.second = second;
      out.push_back(entry);
    }
  }
}

// One worker's reading of the store: its view, the objects and shapes of its current task, the
// pipelines' tags it has looked up.
struct Worker {
  std::unique_ptr<ReadView> own;
  const ReadView* view = nullptr;
  const ClashSettings* settings = nullptr;
  glm::dvec3 frame_origin{0.0};
  std::unordered_map<uint32_t, Object> objects;
  std::unordered_map<uint32_t, std::unique_ptr<MeasureShapes>> shapes;
  // Texts shared by this worker's clashes (clash.h: ClashText): pipelines' tags for the run,
  // objects' tags and groups for the task (the objects of one task recur in its clashes).
  std::unordered_map<uint64_t, ClashText> owner_tags, tags;
  struct PairHash {
    size_t operator()(const std::pair<uint64_t, uint64_t>& p) const { return std::hash<uint64_t>()(p.first * 31 + p.second); }
  };
  std::unordered_map<std::pair<uint64_t, uint64_t>, ClashText, PairHash> groups;
  std::vector<Clash> clashes;  // the current task's, handed to the report when it is done
  ClashCounts counts;

  const Object* object(uint32_t slot, std::string& error) {
    auto it = objects.find(slot);
    if (it == objects.end()) {
      Object o;
      if (!view->object(slot, o, true, error)) return nullptr;
      it = objects.emplace(slot, std::move(o)).first;
    }
    return &it->second;
  }
  const MeasureShapes& shape(uint32_t slot, const Object& o) {
    auto& s = shapes[slot];
    if (!s) s = std::make_unique<MeasureShapes>(o.primitives, o.origin_m, frame_origin, settings->mesh_error_m,
                                               !(settings->clearance_m > 0));
    return *s;
  }
  const ClashText& tag(const Object& o) {
    auto it = tags.find(o.id);
    if (it == tags.end()) it = tags.emplace(o.id, ClashText(o.name)).first;
    return it->second;
  }
  // The tag of the object's owner: its pipeline's, else its own (clash.h, groups).
  ClashText owner(const Object& o) {
    if (o.pipeline_id == 0) return o.name.empty() ? ClashText(std::to_string(o.id)) : tag(o);
    auto it = owner_tags.find(o.pipeline_id);
    if (it == owner_tags.end()) {
      std::string name = std::to_string(o.pipeline_id);
      std::string error;
      Object line;
      if (const auto slot = view->slot_of(o.pipeline_id); slot && view->object(*slot, line, false, error) &&
                                                           !line.name.empty())
        name = line.name;
      it = owner_tags.emplace(o.pipeline_id, ClashText(name)).first;
    }
    return it->second;
  }
  // The group of two objects (clash.h): their owners' tags, sorted, joined by " x ".
  const ClashText& group(const Object& a, const Object& b) {
    const auto key = std::minmax(a.pipeline_id ? a.pipeline_id : a.id, b.pipeline_id ? b.pipeline_id : b.id);
    auto it = groups.find(key);
    if (it == groups.end()) {
      const ClashText oa = owner(a), ob = owner(b);
      const bool swap = ob.view() < oa.view();
      it = groups.emplace(key, ClashText((swap ? ob : oa).str() + " x " + (swap ? oa : ob).str())).first;
    }
    return it->second;
  }

  // The connection points of the first and last members of the pipeline's branches (model
  // space), looked up once per pipeline.
  std::unordered_map<uint64_t, std::vector<glm::dvec3>> line_ends;
  const std::vector<glm::dvec3>& ends(uint64_t pipeline_id) {
    auto it = line_ends.find(pipeline_id);
    if (it != line_ends.end()) return it->second;
    std::vector<glm::dvec3> points;
    std::string error;
    Object line;
    if (const auto slot = view->slot_of(pipeline_id); slot && view->object(*slot, line, false, error)) {
      for (const Branch& branch : line.branches) {
        if (branch.members.empty()) continue;
        for (const uint64_t id : {branch.members.front(), branch.members.back()}) {
          Object member;
          if (const auto s = view->slot_of(id); s && view->object(*s, member, false, error))
            for (const ConnectionPoint& c : member.connections)
              points.push_back(member.origin_m + glm::dvec3(c.position_m));
        }
      }
    }
    return line_ends.emplace(pipeline_id, std::move(points)).first->second;
  }
  // The nozzle rule (clash.h) for a clash between `piece` and `item` at `points`.
  bool at_own_nozzle(const Object& piece, const Object& item, const std::vector<glm::dvec3>& points) {
    if (piece.pipeline_id == 0 || item.object_class != ObjectClass::equipment) return false;
    std::vector<std::pair<glm::dvec3, double>> nozzles;  // position, reach
    for (const ConnectionPoint& c : item.connections) {
      const glm::dvec3 p = item.origin_m + glm::dvec3(c.position_m);
      for (const glm::dvec3& e : ends(piece.pipeline_id))
        if (glm::length(e - p) <= 0.002) {
          nozzles.emplace_back(p, 0.5 + 2.0 * double(c.diameter_m));
          break;
        }
    }
    if (nozzles.empty()) return false;
    for (const glm::dvec3& point : points) {
      bool near_one = false;
      for (const auto& [p, reach] : nozzles) near_one = near_one || glm::length(point - p) <= reach;
      if (!near_one) return false;
    }
    return true;
  }

  bool pair(uint32_t slot_a, uint32_t slot_b, std::string& error);
  bool task(uint32_t block_a, uint32_t block_b, std::string& error);
};

ClashObject clash_object(const Object& o, const ClashText& tag) {
  ClashObject c;
  c.id = o.id;
  c.tag = tag;
  c.object_class = o.object_class;
  c.pipeline_id = o.pipeline_id;
  return c;
}

bool Worker::pair(uint32_t slot_a, uint32_t slot_b, std::string& error) {
  ++counts.candidate_pairs;
  const bool rules = !settings->include_connected;
  if (rules) {  // the same pipeline, from the records' first bytes, before decoding anything
    uint64_t id_a, id_b, line_a, line_b;
    if (!view->object_key(slot_a, id_a, line_a, error) || !view->object_key(slot_b, id_b, line_b, error))
      return false;
    if (line_a != 0 && line_a == line_b) {
      ++counts.skipped_by_rule[int(ClashRule::same_pipeline)];
      return true;
    }
  }
  const Object* a = object(slot_a, error);
  if (!a) return false;
  const Object* b = object(slot_b, error);
  if (!b) return false;
  if (a->id == b->id || a->primitives.empty() || b->primitives.empty()) return true;
  const ClashSet &x = settings->between, &y = settings->with;
  if (!x.empty() || !y.empty()) {
    if (!((x.contains(*a) && y.contains(*b)) || (x.contains(*b) && y.contains(*a)))) return true;
  }
  if (rules) {
    if (const auto rule = clash_detail::exempting_rule(*a, *b)) {
      ++counts.skipped_by_rule[int(*rule)];
      return true;
    }
  }
  const MeasureShapes& sa = shape(slot_a, *a);
  const MeasureShapes& sb = shape(slot_b, *b);
  if (sa.empty() || sb.empty()) return true;
  ++counts.narrow_pairs;
  std::optional<PairClash> found = clash_detail::narrow_phase(sa, sb, settings->tolerance_m, settings->clearance_m);
  if (!found) return true;
  if (rules && (at_own_nozzle(*a, *b, found->points_m) || at_own_nozzle(*b, *a, found->points_m))) {
    ++counts.skipped_by_rule[int(ClashRule::nozzle)];
    return true;
  }
  Clash c;
  const bool swap = b->id < a->id;
  const Object& lo = swap ? *b : *a;
  const Object& hi = swap ? *a : *b;
  c.a = clash_object(lo, tag(lo));
  c.b = clash_object(hi, tag(hi));
  c.kind = found->kind;
  c.depth_m = found->depth_m;
  c.distance_m = found->distance_m;
  c.error_m = found->error_m;
  c.points_m = std::move(found->points_m);
  c.id = clash_detail::clash_id(c.a.id, c.b.id, c.points_m.front());
  c.group = group(lo, hi);
  clashes.push_back(std::move(c));
  return true;
}

bool Worker::task(uint32_t block_a, uint32_t block_b, std::string& error) {
  objects.clear();
  shapes.clear();
  tags.clear();
  groups.clear();
  const auto first = view->spatial_block(block_a, error);
  if (!first) return false;
  std::shared_ptr<const SpatialBlock> second;
  if (block_b != block_a && !(second = view->spatial_block(block_b, error))) return false;
  std::vector<Entry> entries;
  block_entries(*first, false, entries);
  if (second) block_entries(*second, true, entries);
  std::sort(entries.begin(), entries.end(), [](const Entry& p, const Entry& q) {
    return p.min[0] != q.min[0] ? p.min[0] < q.min[0] : p.slot < q.slot;
  });
  // Sweep along x: candidates overlap (within the clearance) on every axis.
  const float reach = float(settings->clearance_m) + 0.001f;
  std::vector<std::pair<uint32_t, uint32_t>> candidates;
  for (size_t i = 0; i < entries.size(); ++i) {
    const Entry& p = entries[i];
    for (size_t j = i + 1; j < entries.size() && entries[j].min[0] <= p.max[0] + reach; ++j) {
      const Entry& q = entries[j];
      if (second && p.second == q.second) continue;
      if (!near(p.min, p.max, q.min, q.max, reach)) continue;
      candidates.emplace_back(std::min(p.slot, q.slot), std::max(p.slot, q.slot));
    }
  }
  // Slot order: neighbouring records share chunks (store.h).
  std::sort(candidates.begin(), candidates.end());
  for (const auto& [sa, sb] : candidates)
    if (!pair(sa, sb, error)) return false;
  objects.clear();
  shapes.clear();
  return true;
}

}  // namespace

void sort_clashes(std::deque<Clash>& clashes) {
  std::sort(clashes.begin(), clashes.end(), [](const Clash& x, const Clash& y) {
    if (x.status == ClashStatus::resolved) {
      if (y.status != ClashStatus::resolved) return false;
    } else if (y.status == ClashStatus::resolved) {
      return true;
    }
    if (x.group != y.group) return x.group < y.group;
    if (x.a.id != y.a.id) return x.a.id < y.a.id;
    if (x.b.id != y.b.id) return x.b.id < y.b.id;
    return x.id < y.id;
  });
}

bool find_clashes(const ReadView& view, const std::string& directory, const ClashSettings& settings,
                  ClashReport& out, std::string& error) {
  assert(settings.tolerance_m >= 0 && settings.tolerance_m <= kClashMaxDistanceM);
  assert(settings.clearance_m >= 0 && settings.clearance_m <= kClashMaxDistanceM);
  assert(settings.shard.count >= 1 && settings.shard.index < settings.shard.count);
  if (!view.spatial_ready(error)) return false;
  out = ClashReport();
  std::error_code ec;
  const auto canonical = std::filesystem::weakly_canonical(directory, ec);
  out.store_directory = ec ? directory : canonical.string();
  const StoreInfo info = view.info();
  out.spatial_origin_m = view.spatial_origin();
  out.commit_id = info.commit_id;
  out.revision = info.revision;
  out.objects = info.objects;
  out.tolerance_m = settings.tolerance_m;
  out.clearance_m = settings.clearance_m;
  out.between = settings.between.word;
  out.with = settings.with.word;
  out.include_connected = settings.include_connected;
  out.shard = settings.shard;

  // The blocks and their bounds, in block order; the shard's run of them.
  std::vector<BlockBounds> blocks;
  for (const SpatialNode& node : view.spatial_top()) {
    if (node.count == 0) continue;
    BlockBounds b;
    b.block = node.first;
    std::copy(node.min, node.min + 3, b.min);
    std::copy(node.max, node.max + 3, b.max);
    blocks.push_back(b);
  }
  std::sort(blocks.begin(), blocks.end(), [](const BlockBounds& p, const BlockBounds& q) { return p.block < q.block; });
  const size_t n = blocks.size();
  const size_t from = n * settings.shard.index / settings.shard.count;
  const size_t to = n * (settings.shard.index + 1) / settings.shard.count;
  const float reach = float(settings.clearance_m) + 0.001f;
  std::vector<std::pair<uint32_t, uint32_t>> tasks;
  for (size_t i = from; i < to; ++i)
    for (size_t j = i; j < n; ++j)
      if (j == i || near(blocks[i].min, blocks[i].max, blocks[j].min, blocks[j].max, reach))
        tasks.emplace_back(blocks[i].block, blocks[j].block);
  out.counts.block_pairs = tasks.size();

  unsigned threads = settings.threads ? settings.threads : std::max(1u, std::thread::hardware_concurrency());
  threads = unsigned(std::min<size_t>(threads, std::max<size_t>(1, tasks.size())));
  std::vector<Worker> workers(threads);
  for (unsigned t = 0; t < threads; ++t) {
    Worker& w = workers[t];
    if (t == 0) {
      w.view = &view;
    } else {
      w.own = view.sibling(error);
      if (!w.own) return false;
      w.view = w.own.get();
    }
    w.settings = &settings;
    w.frame_origin = view.spatial_origin();
  }
  std::atomic<size_t> next{0}, done{0};
  std::atomic<uint64_t> found{0};
  std::atomic<bool> failed{false};
  std::mutex mutex;  // the first error, the progress callback, out.clashes
  std::string first_error;
  const auto work = [&](Worker& w) {
    for (size_t k; !failed && (k = next.fetch_add(1)) < tasks.size();) {
      std::string e;
      if (!w.task(tasks[k].first, tasks[k].second, e)) {
        std::lock_guard lock(mutex);
        if (!failed.exchange(true)) first_error = e;
        return;
      }
      found += w.clashes.size();
      {  // the task's clashes join the report's (held once: no gathering at the end)
        std::lock_guard lock(mutex);
        for (Clash& c : w.clashes) out.clashes.push_back(std::move(c));
      }
      w.clashes.clear();
      const size_t d = ++done;
      if (settings.progress) {
        std::lock_guard lock(mutex);
        settings.progress(double(d) / double(tasks.size()), found);
      }
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, std::ref(workers[t]));
  work(workers[0]);
  for (std::thread& t : pool) t.join();
  if (failed) {
    error = first_error;
    return false;
  }
  for (Worker& w : workers) {
    out.counts.candidate_pairs += w.counts.candidate_pairs;
    out.counts.narrow_pairs += w.counts.narrow_pairs;
    for (int r = 0; r < kClashRuleCount; ++r) out.counts.skipped_by_rule[r] += w.counts.skipped_by_rule[r];
  }
  sort_clashes(out.clashes);
  return true;
}

}  // namespace plantview
