// Equipment layout: where each item stands. Rule: plot items fill the bands' shelves deepest first,
// each in the least filled band; stacked exchangers stand on the one below; pump pairs stand in
// the pump row beside the vessel that feeds them; air coolers sit on the first rack's top.
#include "equipment.h"

#include <algorithm>
#include <vector>

namespace plantview::gen::items {

using T = EquipmentType;

bool place_all(Unit& unit, bool overflow) {
  clear_band_places(unit);
  std::vector<uint32_t> order;
  for (uint32_t i = 0; i < unit.equipment.size(); ++i) {
    const EquipmentRecord& e = unit.equipment[i];
    if (e.type != T::pump && e.type != T::air_cooler && e.stacked_on < 0) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return unit.equipment[a].size_y > unit.equipment[b].size_y;
  });
  std::vector<double> used(unit.bands.size(), 0.0);
  for (uint32_t i : order) {
    EquipmentRecord& e = unit.equipment[i];
    std::vector<int> bands(unit.bands.size());
    for (size_t k = 0; k < bands.size(); ++k) bands[k] = int(k);
    std::stable_sort(bands.begin(), bands.end(),
                     [&](int a, int b) { return used[size_t(a)] < used[size_t(b)]; });
    bool placed = false;
    for (int pass = 0; pass < (overflow ? 2 : 1) && !placed; ++pass) {
      for (int band : bands) {
        if (place_in_band(unit, band, e.size_x, e.size_y, i, pass == 1, e.centre)) {
          e.band = band;
          used[size_t(band)] += e.size_x * e.size_y;
          placed = true;
          break;
        }
      }
    }
    if (!placed) return false;
  }
  spread_shelves(unit);

  // Stacked exchangers stand on the one below.
  for (EquipmentRecord& e : unit.equipment) {
    if (e.stacked_on < 0) continue;
    const EquipmentRecord& below = unit.equipment[size_t(e.stacked_on)];
    e.centre = below.centre;
    e.band = below.band;
  }
  // Pumps: pairs beside their feeding vessel.
  std::vector<uint32_t> feeders;
  for (uint32_t i = 0; i < unit.equipment.size(); ++i) {
    const T t = unit.equipment[i].type;
    if (t == T::column || t == T::vertical_drum || t == T::horizontal_drum) feeders.push_back(i);
  }
  int pair = 0;
  for (uint32_t i = 0; i + 1 < unit.equipment.size(); ++i) {
    EquipmentRecord& a = unit.equipment[i];
    if (a.type != T::pump || a.pump_letter != 'A') continue;
    EquipmentRecord& b = unit.equipment[i + 1];
    const EquipmentRecord* feeder =
        feeders.empty() ? nullptr : &unit.equipment[feeders[size_t(pair) % feeders.size()]];
    int band = feeder ? feeder->band : pair % int(unit.bands.size());
    double x_wanted = feeder ? feeder->centre.x : unit.racks[0].x_begin + 5.0 * pair;
    double x = 0;
    bool ok = false;
    for (size_t k = 0; k < unit.bands.size() && !ok; ++k) {
      const int bnd = (band + int(k)) % int(unit.bands.size());
      ok = place_in_pump_row(unit, bnd, x_wanted, 3.2, x);
      if (ok) band = bnd;
    }
    if (!ok) return false;
    const Band& bd = unit.bands[size_t(band)];
    a.band = b.band = band;
    a.centre = dvec3(x - 0.8, bd.pump_row_y, 0);
    b.centre = dvec3(x + 0.8, bd.pump_row_y, 0);
    if (feeder && feeder->feeds_pair < 0) {
      unit.equipment[feeders[size_t(pair) % feeders.size()]].feeds_pair = a.pump_pair;
    }
    ++pair;
  }
  // Air coolers: bays on top of the first rack, spread along it.
  std::vector<uint32_t> coolers;
  for (uint32_t i = 0; i < unit.equipment.size(); ++i) {
    if (unit.equipment[i].type == T::air_cooler) coolers.push_back(i);
  }
  const Rack& rack = unit.racks[0];
  const int bays = int((rack.x_end - rack.x_begin) / rack.bent_pitch);
  for (size_t k = 0; k < coolers.size(); ++k) {
    const int bay = int(double(bays) * (double(k) + 0.5) / double(coolers.size()));
    EquipmentRecord& e = unit.equipment[coolers[k]];
    e.centre = dvec3(rack.x_begin + rack.bent_pitch * (bay + 0.5), rack.y_centre, 0);
    e.band = -1;
  }
  return true;
}

}  // namespace plantview::gen::items
