// Internal: the generator's recipe for each preset (what the papers do not say, chosen so that
// the statistics land on theirs). Not part of the public API; see plantview/generate.h.
#pragma once

#include <array>
#include <cstdint>

#include "generator.h"

namespace plantview::gen {

struct PresetSpec {
  char preset;
  // Layout.
  int racks;  // pipe racks along x, spread evenly across y
  double rack_width_m;
  std::array<double, 4> tiers_m;  // beam top elevations; 0 ends the list
  // Equipment: how many of each EquipmentType, per unit.
  std::array<uint16_t, kEquipmentTypeCount> equipment_mix;
  int exchangers_on_saddles;   // the rest stand on concrete piers
  double column_height_max_m;  // tallest column (below the plant height)
  double equipment_scale;      // plan sizes of equipment (dense plots take smaller items)
  // Piping.
  int utility_headers;               // headers along the racks, each feeding utility drops
  int line_bore_min, line_bore_max;  // process line bores (indices into kPipeSizes)
  int header_bore_min, header_bore_max;
  // Triangles: lines (per mille) whose elbows are 3D or 5D bends (more sweep segments).
  uint32_t bends_3d_per_mille, bends_5d_per_mille;
  // Equipment nozzles (per mille) with butt-weld ends instead of flanges (welded plants).
  uint32_t welded_nozzles_per_mille;
  // Process lines (per mille) that join a nozzle farther along the rack than its neighbour.
  uint32_t far_partner_per_mille;
};

const PresetSpec& preset_spec(char preset);

}  // namespace plantview::gen
