// plantview/generate.h: synthetic process plants sized like the papers' models.
//
// generate_plant() builds a plausible plant unit of parametric primitives: steel pipe racks and
// structures, equipment (columns, drums, heat exchangers, pumps, compressors, air coolers,
// furnaces, tanks) with nozzles, and pipelines routed orthogonally between nozzles, along the racks
// and from utility headers. Its presets 'a', 'b' and 'c' reproduce the statistics of the three
// models of Su et al. (Tables 1-3: objects, primitives and triangles by class) and the primitive
// mix of Zhou et al. (Table 1), within 10 % per category (15 % for triangles); plan sizes follow
// Su et al. Fig. 1. `preset_info()` gives the paper figures the tests compare against.
//
// Objects follow model.h. In addition, the generator guarantees:
//   - Classes: equipment, pipeline (no primitives, only branches), pipe (exactly one cylinder),
//     component (fittings, valves, flanges, gaskets, welds, supports...), structure (racks and
//     steel; outside Su's categories, its boxes and wedges count toward Zhou's kinds).
//   - Piping topology. A pipeline lists branches; a branch lists its pipes and components in flow
//     order. For every branch member, connections[0] is the flow inlet and connections[1] the
//     outlet (a tee adds its branch port as connections[2]); a member's outlet coincides with the
//     next member's inlet and the two point in opposite directions. Only elbows (Type "ELBO")
//     change the flow direction; all other members are straight (inlet and outlet directions
//     opposite), and inline ones (flanges, gaskets, welds, valves, concentric reducers) have
//     their connection points on the run's centreline. A branch starts and ends at an equipment
//     nozzle (listed as a connection of the equipment object), a tee's branch port, a battery
//     limit, or a closed end (blind flange, cap, plug). Members carry pipeline_id.
//   - Pipe supports are components of their pipeline (pipeline_id set) but not branch members:
//     one connection point where they carry the pipe (on its centreline, pointing toward the
//     support), no centreline.
//   - Names read like a PDMS model: "/P-01-0203" (pipeline), "/P-01-0203-B1" (branch),
//     "/P-01-0203-B1/ELBO-3", "/C-01-004" (equipment), "/RACK-01-1/COL-12" (steel). The two
//     digits after the service code are the plant unit's area (unit index + 1, wider past 99).
//   - Ids: object_id("gen:<preset>:<seed>:<unit>", name); Object::source is "gen:<preset>".
//   - Origins: a pipe's or component's origin is its inlet connection point; equipment and
//     structure objects have theirs at their footprint centre on grade; pipelines at their first
//     branch's start. Model space: x along the units' length, y across, z up, grade at z = 0.
//
// Determinism: the output is a pure function of (preset, scale, seed): the generator uses its own
// integer PRNG, integer bookkeeping for its choices, and no transcendental function of generated
// values (FP contraction differences between compilers could still move a coordinate by an ulp).
//
// Threads: generate_plant() may run on any thread; concurrent calls are independent. The sink and
// progress callbacks are called on the calling thread.
#pragma once

#include <cstdint>
#include <functional>
#include <string_view>

#include "plantview/model.h"

namespace plantview {

struct GenerateOptions {
  char preset = 'c';    // 'a', 'b' or 'c' (Su et al. Fig. 1)
  uint32_t scale = 1;   // plant units laid out in a grid, 1..kMaxGenerateScale
  uint64_t seed = 1;    // every unit derives its own variation from (preset, seed, unit index)
};
inline constexpr uint32_t kMaxGenerateScale = 1000;

// What was generated, counted as it streamed out.
struct GenerateSummary {
  uint32_t units = 0;
  uint64_t objects = 0;
  uint64_t objects_by_class[kObjectClassCount] = {};
  uint64_t primitives = 0;
  DAabb bounds;  // model space, metres
  // Planned pipelines for which the router found no path (a unit has that many fewer; typically
  // none to a few per unit).
  uint64_t pipelines_skipped = 0;
};

// Streams the plant to `sink`, one object at a time, unit after unit (objects move out; the sink
// owns them). At most one plant unit is held in memory (a few MB), so any scale runs in bounded
// memory. Within a unit, equipment and structure come first, then each pipeline's members followed
// by the pipeline object itself. `progress`, if given, is called with the fraction done (0..1],
// at least once per unit and last with 1. Options out of range (unknown preset, scale 0 or above
// kMaxGenerateScale) are a caller bug: check them with parse_preset() and the constant above.
GenerateSummary generate_plant(const GenerateOptions& options,
                               const std::function<void(Object&&)>& sink,
                               const std::function<void(double fraction)>& progress = {});

// Convenience for tests and small plants: the whole plant in memory.
PlantModel generate_model(const GenerateOptions& options);

// Accepts "a", "b", "c" (either case). Returns false for anything else.
bool parse_preset(std::string_view text, char& preset);

// Paper figures of one preset, per plant unit (scale multiplies every count).
struct PresetInfo {
  char preset = 0;
  std::string_view description;
  double plan_x_m = 0, plan_y_m = 0, height_m = 0;  // Su et al. Fig. 1
  // Su et al. Table 1 (objects) and Table 2 (primitives, "voxels"); Table 3 (triangles).
  uint32_t equipment = 0, pipes = 0, components = 0, pipelines = 0;
  uint32_t equipment_primitives = 0, pipe_primitives = 0, component_primitives = 0;
  uint32_t su_primitives = 0;  // Table 2 total: equipment + pipes + components
  uint64_t triangles = 0;      // Table 3 total, full resolution
  // Zhou et al. Table 1 kinds, scaled to this preset (c: Zhou's counts; a, b: Zhou's proportions
  // scaled by Su total / Su total of c). Index: PrimitiveKind. Snouts split as Zhou does.
  uint32_t kind_primitives[kPrimitiveKindCount] = {};
  uint32_t sheared_cylinders = 0, eccentric_cones = 0, concentric_cones = 0;  // snout subkinds
  uint32_t zhou_primitives = 0;  // sum of kind_primitives (includes structure)
};
// The figures of 'a', 'b' or 'c'; nullptr for another character.
const PresetInfo* preset_info(char preset);

// Zhou's snout subkinds, as the generator uses them: sheared cylinder (equal radii, some shear),
// eccentric cone (an offset), concentric cone (otherwise).
enum class SnoutVariant : uint8_t { sheared_cylinder, eccentric_cone, concentric_cone };
SnoutVariant snout_variant(const Snout& snout);

}  // namespace plantview
