// Change images: a range's changes and ghosts read once (change_set.h has the rules).
#include "change_set.h"

#include <algorithm>

#include "plantview/store.h"

namespace plantview {

std::string change_caption(const FrameStats::Changes& c) {
  return "Changes since revision " + std::to_string(c.from) + " (to " + std::to_string(c.to) +
         "): " + std::to_string(c.added) + " added, " + std::to_string(c.modified) +
         " modified, " + std::to_string(c.removed) + " removed";
}

}  // namespace plantview

namespace plantview::detail {

namespace {

FrameLegend::Entry legend_entry(std::string_view kind, Colour colour, uint64_t objects) {
  FrameLegend::Entry e;
  e.value = std::string(kind);
  e.colour = colour;
  e.objects = objects;
  return e;
}

bool same_shape(const Object& a, const Object& b) {
  return a.origin_m == b.origin_m && a.primitives == b.primitives;
}

}  // namespace

bool ChangeSet::load(const ReadView& view, const ChangeRange& range, std::string& error) {
  if (loaded_ && range_ == range) return true;
  loaded_ = false;
  const uint32_t revision = view.info().revision;
  const std::string named = "changes " + change_range_text(range);
  if (range.to != 0 && range.to != revision) {
    error = named + ": the store is at revision " + std::to_string(revision) +
            "; a change image draws the store as it is, so its range ends there (give " +
            std::to_string(range.from) + ".." + std::to_string(revision) + ")";
    return false;
  }
  if (range.from >= revision) {
    error = named + ": revision " + std::to_string(range.from) + " is not before the store's (" +
            std::to_string(revision) + ")";
    return false;
  }
  std::vector<ObjectChange> changes;
  if (!view.changes(range.from, revision, changes, error)) {
    error = named + ": " + error;
    return false;
  }

  subject_ids_.clear();
  subject_colours_.clear();
  ghosts_ = GhostMesh{};
  ghosts_left_out_ = 0;
  summary_ = FrameStats::Changes{true, range.from, revision, 0, 0, 0};
  Object previous, current;
  for (const ObjectChange& c : changes) {
    if (c.kind == ChangeKind::added) ++summary_.added;
    if (c.kind == ChangeKind::modified) ++summary_.modified;
    if (c.kind == ChangeKind::removed) ++summary_.removed;
    if (c.kind != ChangeKind::removed) {
      subject_ids_.push_back(c.id);
      subject_colours_.emplace_back(
          c.id, packed_colour(c.kind == ChangeKind::added ? kAddedColour : kModifiedColour));
    }
    if (c.kind == ChangeKind::added) continue;
    bool found = false;
    if (!view.object_at(range.from, c.id, previous, found, false, error)) return false;
    if (!found) continue;  // (the store's changes say it was there: nothing to draw if not)
    if (c.kind == ChangeKind::modified && c.slot) {
      if (!view.object(*c.slot, current, false, error)) return false;
      if (same_shape(previous, current)) continue;
    }
    if (!add_ghost(previous, c.kind == ChangeKind::removed ? kRemovedColour : kPreviousColour))
      ++ghosts_left_out_;
  }
  std::sort(subject_ids_.begin(), subject_ids_.end());
  std::sort(subject_colours_.begin(), subject_colours_.end());
  if (subject_ids_.empty()) subject_ids_.push_back(0);

  legend_ = FrameLegend{};
  legend_.key = "changes";
  legend_.entries = {legend_entry("added", kAddedColour, summary_.added),
                     legend_entry("modified", kModifiedColour, summary_.modified),
                     legend_entry("removed", kRemovedColour, summary_.removed)};
  range_ = range;
  loaded_ = true;
  return true;
}

bool ChangeSet::add_ghost(const Object& previous, Colour colour) {
  size_t vertices = 0;
  for (const Primitive& primitive : previous.primitives) {
    const MeshPlan plan = plan_mesh(primitive);
    if (plan.topology == Topology::triangles) vertices += plan.vertex_count;
  }
  if (ghosts_.vertices.size() + vertices > kMaxGhostVertices) return false;
  const uint32_t ghost = uint32_t(ghosts_.ghosts.size());
  ghosts_.ghosts.push_back({previous.id, previous.origin_m, colour});
  for (const Primitive& primitive : previous.primitives) {
    const MeshPlan plan = plan_mesh(primitive);
    if (plan.topology != Topology::triangles || plan.vertex_count == 0) continue;
    const uint32_t level = plan.coarsest_level_within(kGhostErrorM);
    scratch_.resize(plan.vertex_count);
    // Placements are relative to the object's origin: the ghost's origin is that origin.
    write_vertices(primitive, plan, glm::dvec3(0.0), scratch_);
    const uint32_t base = uint32_t(ghosts_.vertices.size());
    ghosts_.vertices.insert(ghosts_.vertices.end(), scratch_.begin(), scratch_.end());
    ghosts_.vertex_ghosts.resize(ghosts_.vertices.size(), ghost);
    const size_t at = ghosts_.indices.size();
    ghosts_.indices.resize(at + plan.index_count(level));
    write_indices(plan, level, base, std::span<uint32_t>(ghosts_.indices).subspan(at));
  }
  return true;
}

}  // namespace plantview::detail
