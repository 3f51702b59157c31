// Equipment sizes: the per-type table (tag prefix, name, primitive budget, colour) and each item's
// main dimensions. Rule: dimensions are drawn on a millimetre grid within the type's usual range,
// scaled by `shrink` where the plot is tight, and never deeper than the shallowest band can take.
#include "equipment.h"

#include <algorithm>
#include <cmath>

namespace plantview::gen::items {

using T = EquipmentType;

constexpr TypeInfo kTypes[kEquipmentTypeCount] = {
    {"C", "Column", 22, 10, {178, 190, 170, 255}},
    {"V", "Vertical drum", 14, 4, {172, 188, 176, 255}},
    {"V", "Horizontal drum", 14, 4, {172, 188, 176, 255}},
    {"E", "Shell and tube exchanger", 15, 4, {150, 172, 200, 255}},
    {"P", "Centrifugal pump", 12, 0, {60, 110, 190, 255}},
    {"K", "Compressor", 14, 3, {205, 125, 60, 255}},
    {"EA", "Air cooler", 16, 4, {190, 192, 205, 255}},
    {"F", "Cracking furnace", 16, 10, {176, 92, 70, 255}},
    {"S", "Filter", 10, 2, {160, 160, 120, 255}},
    {"TK", "Storage tank", 10, 4, {222, 222, 212, 255}},
    {"TK", "Spherical tank", 14, 3, {222, 222, 212, 255}},
    {"PK", "Package unit", 10, 3, {120, 162, 120, 255}},
};

void size_item(Unit& unit, EquipmentRecord& e, double shrink) {
  Rng& rng = unit.rng;
  const double top = unit.info.height_m;
  switch (e.type) {
    case T::column:
      e.diameter = rng.metres(1600, 4200) * shrink;
      e.height = std::min(unit.spec.column_height_max_m, top - 1.0) * (0.55 + 0.45 * rng.unit());
      e.size_x = e.size_y = e.diameter + 2.8;
      break;
    case T::vertical_drum:
      e.diameter = rng.metres(1000, 2600) * shrink;
      e.height = std::min(rng.metres(2500, 7000), top - 4.5);
      e.size_x = e.size_y = e.diameter + 1.6;
      break;
    case T::horizontal_drum:
      e.diameter = rng.metres(1400, 3000) * shrink;
      e.length = rng.metres(4000, 9000) * shrink;
      e.size_x = e.length + e.diameter * 0.5 + 1.2;
      e.size_y = e.diameter + 1.6;
      break;
    case T::exchanger:
      e.diameter = rng.metres(450, 1200) * shrink;
      e.length = rng.metres(3000, 6500) * shrink;
      e.size_x = e.length + 1.6 + e.diameter * 0.5;
      e.size_y = e.diameter + 1.4;
      break;
    case T::pump:
      e.diameter = rng.metres(440, 700);
      e.size_x = 1.2;
      e.size_y = 2.8;
      break;
    case T::compressor:
      e.diameter = rng.metres(1000, 1600) * shrink;
      e.length = rng.metres(1500, 2500);
      e.size_x = e.length + 4.5;
      e.size_y = e.diameter + 2.6;
      break;
    case T::air_cooler:
      e.length = 6.0;
      e.size_x = 6.0;
      break;
    case T::furnace:
      e.length = rng.metres(6000, 9000) * shrink;
      e.diameter = rng.metres(1400, 2000);
      e.height = std::min(top - 1.0, rng.metres(18000, 30000));
      e.size_x = e.length + 1.5;
      e.size_y = rng.metres(3500, 5000) * shrink + 1.5;
      break;
    case T::filter:
      e.diameter = rng.metres(450, 800);
      e.height = rng.metres(1200, 1800);
      e.size_x = e.size_y = e.diameter + 1.2;
      break;
    case T::tank:
      e.diameter = rng.metres(6000, 10000) * shrink;
      e.height = std::min(top - 2.0, rng.metres(6000, 11000));
      e.size_x = e.size_y = e.diameter + 2.0;
      break;
    case T::sphere_tank:
      e.diameter = rng.metres(7000, 10000) * shrink;
      e.size_x = e.size_y = e.diameter + 2.0;
      break;
    case T::package:
      e.length = rng.metres(3000, 4500) * shrink;
      e.size_x = e.length;
      e.size_y = rng.metres(2000, 3000) * shrink;
      break;
  }
  // Nothing may be deeper than the shallowest band can take.
  double band_depth = 1e9;
  for (const Band& b : unit.bands) band_depth = std::min(band_depth, std::abs(b.y_far - b.y_near));
  const double max_y = std::max(2.0, band_depth - 4.2);
  if (e.size_y > max_y) {
    const double f = max_y / e.size_y;
    e.size_y = max_y;
    if (e.type == T::column || e.type == T::vertical_drum || e.type == T::tank ||
        e.type == T::sphere_tank || e.type == T::filter) {
      e.diameter *= f;
      e.size_x = e.size_y;
    } else if (e.type == T::horizontal_drum || e.type == T::exchanger || e.type == T::compressor) {
      e.diameter = std::min(e.diameter, max_y - 1.4);
    }
  }
}

}  // namespace plantview::gen::items
