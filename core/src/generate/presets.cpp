// Presets: the papers' figures (PresetInfo) and the recipes that reproduce them (PresetSpec).
#include "presets.h"

#include <cassert>
#include <cmath>

namespace plantview {
namespace {

// Zhou et al. Table 1, in PrimitiveKind order (snouts: sheared + eccentric + concentric).
constexpr uint32_t kZhouKinds[kPrimitiveKindCount] = {
    9269,                 // box
    1547,                 // pyramid (Zhou's wedges; Squcone 0)
    134,                  // prism
    30354,                // cylinder
    12638 + 3624 + 6030,  // snout: Scylinder + Econe + Concone
    0,                    // square_to_round (Sqcir 0)
    7881,                 // circular_torus
    528,                  // rectangular_torus
    2904,                 // sphere
    389,                  // elliptical_dish (Oval)
    0,                    // spherical_dish
    32,                   // saddle
    0,                    // line
    0,                    // facet_group
};
constexpr uint32_t kZhouSheared = 12638, kZhouEccentric = 3624, kZhouConcentric = 6030;
constexpr uint32_t kSuTotalC = 73054;

PresetInfo make_info(char preset, std::string_view description, double x, double y, double z,
                     uint32_t equipment, uint32_t pipes, uint32_t components, uint32_t pipelines,
                     uint32_t eq_prims, uint32_t comp_prims, uint32_t su_total,
                     uint64_t triangles) {
  PresetInfo info;
  info.preset = preset;
  info.description = description;
  info.plan_x_m = x;
  info.plan_y_m = y;
  info.height_m = z;
  info.equipment = equipment;
  info.pipes = pipes;
  info.components = components;
  info.pipelines = pipelines;
  info.equipment_primitives = eq_prims;
  info.pipe_primitives = pipes;
  info.component_primitives = comp_prims;
  info.su_primitives = su_total;
  info.triangles = triangles;
  // Zhou's model is Su's c (same plant, 3 % apart); a and b keep its proportions.
  auto scaled = [&](uint32_t n) {
    return uint32_t(std::llround(double(n) * double(su_total) / double(kSuTotalC)));
  };
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    info.kind_primitives[k] = preset == 'c' ? kZhouKinds[k] : scaled(kZhouKinds[k]);
    info.zhou_primitives += info.kind_primitives[k];
  }
  info.sheared_cylinders = preset == 'c' ? kZhouSheared : scaled(kZhouSheared);
  info.eccentric_cones = preset == 'c' ? kZhouEccentric : scaled(kZhouEccentric);
  info.concentric_cones = preset == 'c' ? kZhouConcentric : scaled(kZhouConcentric);
  return info;
}

const PresetInfo kInfo[3] = {
    make_info('a', "Su et al. Fig. 1(a): long process unit", 213.96, 36.05, 19.14, 201, 3491, 12372,
              841, 7919, 10762, 22172, 5692556),
    make_info('b', "Su et al. Fig. 1(b): tall unit, many utility lines", 149.37, 82.96, 65.97, 108,
              8509, 28959, 1101, 2148, 32751, 43408, 11579044),
    make_info('c', "Su et al. Fig. 1(c) and Zhou et al. Fig. 1: ethylene plant section", 119.40,
              33.66, 31.32, 232, 7787, 31059, 1543, 9382, 55885, 73054, 21619272),
};

}  // namespace

const PresetInfo* preset_info(char preset) {
  for (const PresetInfo& info : kInfo) {
    if (info.preset == preset) return &info;
  }
  return nullptr;
}

bool parse_preset(std::string_view text, char& preset) {
  if (text.size() != 1) return false;
  const char c = char(text[0] | 0x20);  // lower case for letters
  if (preset_info(c) == nullptr) return false;
  preset = c;
  return true;
}

SnoutVariant snout_variant(const Snout& s) {
  if (s.offset_x_m != 0.0f || s.offset_y_m != 0.0f) return SnoutVariant::eccentric_cone;
  const bool sheared = s.bottom_shear_x_rad != 0.0f || s.bottom_shear_y_rad != 0.0f ||
                       s.top_shear_x_rad != 0.0f || s.top_shear_y_rad != 0.0f;
  if (sheared && s.radius_bottom_m == s.radius_top_m) return SnoutVariant::sheared_cylinder;
  return SnoutVariant::concentric_cone;
}

namespace gen {
namespace {

using T = EquipmentType;
constexpr std::array<uint16_t, kEquipmentTypeCount> mix(
    std::initializer_list<std::pair<EquipmentType, uint16_t>> counts) {
  std::array<uint16_t, kEquipmentTypeCount> m{};
  for (auto [type, n] : counts) m[size_t(type)] = n;
  return m;
}

// Bore indices: see kPipeSizes (2: 1", 4: 2", 6: 4", 7: 6", 8: 8", 10: 12", 12: 16").
const PresetSpec kSpecs[3] = {
    // a: a long unit (214 m), one rack of four tiers, many pumps and filters; a welded plant
    // (butt-welded nozzles and valves), so its components carry few primitives each.
    {.preset = 'a',
     .racks = 1,
     .rack_width_m = 8.0,
     .tiers_m = {5.0, 7.0, 9.0, 11.0},
     .equipment_mix = mix({{T::column, 6}, {T::vertical_drum, 20}, {T::horizontal_drum, 4},
                           {T::exchanger, 32}, {T::pump, 60}, {T::compressor, 3},
                           {T::air_cooler, 8}, {T::furnace, 2}, {T::filter, 40}, {T::tank, 2},
                           {T::package, 24}}),
     .exchangers_on_saddles = 1,
     .column_height_max_m = 18.0,
     .equipment_scale = 1.0,
     .utility_headers = 8,
     .line_bore_min = 4,
     .line_bore_max = 9,
     .header_bore_min = 6,
     .header_bore_max = 11,
     .bends_3d_per_mille = 0,
     .bends_5d_per_mille = 0,
     .welded_nozzles_per_mille = 850,
     .far_partner_per_mille = 100},
    // b: a wide, tall unit (149 x 83 m, 63 m columns) with two racks, few items of equipment
    // and many utility lines.
    {.preset = 'b',
     .racks = 2,
     .rack_width_m = 8.0,
     .tiers_m = {5.0, 7.5, 10.0, 12.5},
     .equipment_mix = mix({{T::column, 4}, {T::vertical_drum, 28}, {T::horizontal_drum, 7},
                           {T::exchanger, 56}, {T::pump, 8}, {T::filter, 5}}),
     .exchangers_on_saddles = 2,
     .column_height_max_m = 63.0,
     .equipment_scale = 1.0,
     .utility_headers = 16,
     .line_bore_min = 4,
     .line_bore_max = 9,
     .header_bore_min = 6,
     .header_bore_max = 11,
     .bends_3d_per_mille = 0,
     .bends_5d_per_mille = 0,
     .welded_nozzles_per_mille = 300,
     .far_partner_per_mille = 330},
    // c: a dense ethylene plant section (119 x 34 m, 232 items): smaller items, exchangers in
    // stacks of three, larger lines, and pulled 3D/5D bends on a third of the lines (Zhou's
    // tori average more triangles than long-radius elbows).
    {.preset = 'c',
     .racks = 1,
     .rack_width_m = 6.4,
     .tiers_m = {5.5, 7.5, 9.5, 0.0},
     .equipment_mix = mix({{T::column, 12}, {T::vertical_drum, 54}, {T::horizontal_drum, 12},
                           {T::exchanger, 80}, {T::pump, 40}, {T::compressor, 4},
                           {T::air_cooler, 10}, {T::furnace, 4}, {T::filter, 10},
                           {T::package, 6}}),
     .exchangers_on_saddles = 4,
     .column_height_max_m = 29.0,
     .equipment_scale = 0.58,
     .utility_headers = 12,
     .line_bore_min = 5,
     .line_bore_max = 10,
     .header_bore_min = 7,
     .header_bore_max = 12,
     .bends_3d_per_mille = 200,
     .bends_5d_per_mille = 150,
     .welded_nozzles_per_mille = 200,
     .far_partner_per_mille = 330},
};

}  // namespace

const PresetSpec& preset_spec(char preset) {
  for (const PresetSpec& s : kSpecs) {
    if (s.preset == preset) return s;
  }
  assert(false && "unknown preset");
  return kSpecs[2];
}

}  // namespace gen
}  // namespace plantview
