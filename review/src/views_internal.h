// Private parts of review views (review.h: make_review_views): the subjects a store's model
// offers, and where a fitted eye may stand among the other objects.
//
// Units: metres, model space. Threads: a ReadView and what is made from it stay on its thread.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "plantview/review.h"
#include "plantview/store.h"

namespace plantview::views {

// Something a review view frames: an equipment item, a pipeline (the pipeline object and every
// object that names it), an area (objects sharing an RVM zone, a generated plant's unit, ...) or
// the whole plant.
struct Subject {
  std::string key;    // as the model names it: the tag or path ("C-01-004", "/PS/WD1/0001")
  std::string kind;   // equipment|pipeline|area|overview
  std::string title;  // "Pump P-01-002", "Pipeline LS-01-0001", "Zone /PS/WD1/0001"
  std::vector<uint64_t> ids;    // object ids; empty for the overview (everything)
  std::vector<uint32_t> slots;  // the same objects' store slots, ascending
  DAabb bounds;                 // of their geometry; never empty
  std::vector<DAabb> boxes;     // what cameras are fitted to: the objects' bounds, merged on a
                                // grid when there are many (merge_boxes_on_grid)
  std::vector<std::pair<std::string, std::string>> attributes;  // caption lines, in order
};

// The subjects of kind `per` in `view`, sorted by key (then by first id), each with geometry.
// An empty list is no error (a plant without pipelines); false only when the store cannot be
// read. `progress` (may be empty) gets the fraction of objects read.
bool read_subjects(const ReadView& view, std::string_view per, std::vector<Subject>& out,
                   std::string& error, const std::function<void(double)>& progress);

// The subjects of change views (review.h: per "change"): what changed between range.from and
// range.to (0: the snapshot's revision), grouped by `group`: "object" (each changed object),
// "equipment" (each changed equipment object; others left out) or "pipeline" (each pipeline
// holding a changed object, or changed itself; objects of no pipeline left out). Each is
// fitted on its objects' bounds now and at range.from; its ids and slots are those the
// snapshot holds (none for a removed object). Sorted by key. False with the store's message
// when the range cannot be read (a revision pruned or never made), or a message naming --from
// when it does not start before the snapshot's revision.
bool read_change_subjects(const ReadView& view, const ChangeRange& range, std::string_view group,
                          std::vector<Subject>& out, std::string& error);

// `key` made safe as a view name (review.h: is_safe_view_name): every run of other characters
// becomes one '-' (none at either end), leading '.' go, the key's own '-' stay; at most
// `max_chars`; "view" if nothing is left.
std::string safe_name(std::string_view key, size_t max_chars);

// Other objects' bounds near a camera, from the store's spatial index (the top, then the blocks
// a query reaches, read for the query and dropped after it). A block that cannot be read hides
// nothing; error() then says which (the first such failure).
class Occluders {
 public:
  explicit Occluders(const ReadView& view) : view_(view) {}
  const std::string& error() const { return error_; }
  // True if `eye_m` lies inside (or within `margin_m` of) the bounds of an object whose slot is
  // not in `excluded` (ascending).
  bool eye_inside(const glm::dvec3& eye_m, double margin_m, std::span<const uint32_t> excluded) const;
  // True if the segment from `from_m` to `to_m` crosses the bounds of an object not in
  // `excluded` whose second-largest side is at least `min_side_m` (a wall, a column, a vessel:
  // not a pipe). `first_hit_m` gets the distance from `from_m` to where the first such box is
  // entered (from `from_m`'s side).
  bool segment_blocked(const glm::dvec3& from_m, const glm::dvec3& to_m, double min_side_m,
                       std::span<const uint32_t> excluded, double& first_hit_m) const;

 private:
  const ReadView& view_;
  mutable std::string error_;
};

// The camera for one subject seen along `direction` (from eye to target), placed as
// make_review_views promises: fitted; if the eye would stand inside another object or a large
// one hides the subject, another quadrant (alternatives), or closer along the ray with a wider
// field of view. `moved` says whether it left the first fit; `clear` whether the chosen eye is
// outside others' bounds with an open line to the subject.
struct Placement {
  Camera camera;
  bool moved = false, clear = true;
};
Placement place_camera(const Occluders& occluders, const Subject& subject,
                       const std::vector<glm::dvec3>& directions, double aspect, double fov_deg,
                       double fill);

}  // namespace plantview::views
