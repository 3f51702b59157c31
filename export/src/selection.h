// Selection for glTF export: which objects (and, with a camera, which merged pipeline runs) go
// into which file, at which level. One pass over the store; the writer reads the objects
// again, group by group, in slot order.
//
// Rules: the filters of plantview/gltf.h ("Selection"); with a camera, only what the
// renderer's frame plan draws for that view, at its levels. Groups follow options.split: one
// group (named "") without it.
// Memory: 8 bytes per selected object; while the pass runs, 48 more per pipe or component that
//   waits for its pipeline's name (a --select whose pipeline comes later in the store).
// Threads: the calling thread, which owns `view`.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "plantview/gltf.h"
#include "plantview/model.h"

namespace plantview {
class ReadView;
}

namespace plantview::detail::gltf {

inline constexpr uint8_t kLevelByTolerance = 0xFF;  // the writer picks by options.tolerance_m

struct SelectedObject {
  uint32_t slot;
  uint8_t level;  // or kLevelByTolerance
};

// A pipeline run the renderer would draw as one cylinder (camera with hlod only).
struct SelectedRun {
  uint32_t first_member;  // slot: names the node
  uint64_t pipeline_id;
  uint8_t level;
  Primitive cylinder;     // relative to origin_m
  glm::dvec3 origin_m{0.0};
  Colour colour;
};

struct ExportGroup {
  std::string name;
  std::vector<SelectedObject> objects;  // ascending slots
  std::vector<SelectedRun> runs;
};

struct ExportPlan {
  std::vector<ExportGroup> groups;
  DAabb bounds;        // of the selected objects (and runs), model space
  uint64_t objects = 0;
};

// Fills `plan`. False with a message if the store cannot be read; an empty selection is a plan
// with no objects. `progress` gets the fraction of the pass done (may be empty).
bool plan_export(const ReadView& view, const GltfExportOptions& options, ExportPlan& plan,
                 const std::function<void(double)>& progress, std::string& error);

// The zone an object belongs to: its "Zone" attribute, else its "Area" (keys compared without
// case), else "".
std::string zone_of(const Object& object);

}  // namespace plantview::detail::gltf
