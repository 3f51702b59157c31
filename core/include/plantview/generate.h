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
//     component (fittings, valves, flanges, gaskets, welds, supports...), structure (rack bents
//     and bays; outside Su's categories, its primitives count toward Zhou's kinds).
//   - Piping topology. A pipeline lists branches; a branch lists its pipes and components in flow
//     order. For every branch member, connections[0] is the flow inlet and connections[1] the
//     outlet (a tee or olet adds its branch port as connections[2]; a closing blind flange, cap
//     or plug, always a branch's last member, has only its inlet); a member's outlet coincides
//     with the next member's inlet and the two point in opposite directions. Only elbows (Type
//     "ELBO", 90 degrees) change the flow direction; every other member is straight (inlet and
//     outlet directions opposite), and concentric inline ones (flanges, gaskets, welds, valves,
//     concentric reducers, orifice plates) have their connection points and centreline on the
//     run's centreline. Welds and olets have no length along the run. A branch starts and ends
//     at an equipment nozzle (listed among the equipment object's connections), a tee's or
//     olet's branch port, a battery limit at the unit's edge (x = 0 or the plan length), or a
//     closure. Members carry pipeline_id.
//   - Pipe supports (Type "SUPP": shoes, guides, brackets, struts, clamps, hangers, stanchions,
//     dummy legs, trunnions) are components of their pipeline (pipeline_id set) but not branch
//     members: one connection point where they carry the pipe, pointing toward the support, and
//     no centreline.
//   - Names read like a PDMS model: "/P-01-0203" (pipeline: service code, area, line number),
//     "/P-01-0203-B1" (branch), "/P-01-0203-B1/ELBO-3" (member), "/P-01-0203/SUPP-4" (support),
//     "/C-01-004" (equipment), "/RACK-01-1/BENT-03" (steel). The area is the plant unit's index
//     + 1, two digits (three or four from scale 100 or 1000 on). Attributes carry Type, Stype,
//     Bore, Spec, Rating, Material, Tag (valves, instruments), Pipeline, Branch...
//   - Ids: object_id("gen:<preset>:<seed>:<unit index>", name); Object::source is "gen:<preset>".
//   - Origins: a pipe's or component's origin is its inlet connection point (a support's: its
//     connection point); equipment and structure objects have theirs at their footprint centre on
//     grade; a pipeline at its first branch's head. Model space: x along the units' length, y
//     across, z up, grade at z = 0; unit u lies in a grid cell of the plan size plus a 20 m road.
//   - A unit is a pure function of (preset, seed, unit index): below scale 100 (same area width)
//     the first unit of any scale is the scale-1 plant of the same seed, object for object.
//
// Determinism: the output is a pure function of (preset, scale, seed) on every machine: the
// generator draws from its own integer PRNG (xoshiro256**), keeps its bookkeeping in exact
// integers (its choices compare correctly rounded divisions summed in a fixed order), and calls
// no transcendental function on generated values (angles are tabulated constants). Compilers that
// fuse multiply-adds by default (GCC for AArch64, or any -march with FMA) may round differently:
// build the generator with -ffp-contract=off there for bit-identical output.
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
  char preset = 'c';   // 'a', 'b' or 'c' (Su et al. Fig. 1)
  uint32_t scale = 1;  // plant units laid out in a grid, 1..kMaxGenerateScale
  uint64_t seed = 1;   // every unit derives its own variation from (preset, seed, unit index)
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
// owns them). At most one plant unit's layout is held in memory (a few MB whatever the scale).
// Within a unit, equipment and structure come first, then each pipeline's members and supports
// followed by the pipeline object itself. `progress`, if given, is called with the fraction done
// (0..1], non-decreasing, at least once per unit and last with 1. An exception thrown by `sink`
// or `progress` propagates (the generator holds nothing that needs cleaning up). Options out of
// range (unknown preset, scale 0 or above kMaxGenerateScale) are a caller bug: check them with
// parse_preset() and the constant above.
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
