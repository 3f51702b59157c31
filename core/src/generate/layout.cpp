// Layout of one plant unit: pipe racks along x, equipment bands beside them (a pump row next to
// the rack, then shelves of equipment), and the rack lanes that pipe runs reserve.
#include <algorithm>
#include <cmath>

#include "presets.h"

namespace plantview::gen {

namespace {
constexpr double kEdgeMargin_m = 1.5;     // plot edge to the first equipment
constexpr double kRackClearance_m = 0.5;  // rack edge to the pump row
constexpr double kPumpRowDepth_m = 3.2;   // pumps stand across this strip
constexpr double kShelfGap_m = 1.2;       // access way between shelves
constexpr double kItemGap_m = 1.0;        // between neighbours on a shelf
}  // namespace

void lay_out_unit(Unit& unit) {
  const PresetSpec& spec = unit.spec;
  const double length = unit.info.plan_x_m, depth = unit.info.plan_y_m;
  for (int r = 0; r < spec.racks; ++r) {
    Rack rack;
    rack.y_centre = depth * double(2 * r + 1) / double(2 * spec.racks);
    rack.width = spec.rack_width_m;
    rack.x_begin = 2.0;
    rack.x_end = length - 2.0;
    // Bents on a grid of about 6 m spanning the rack exactly.
    const int bays = std::max(1, int((rack.x_end - rack.x_begin) / 6.0 + 0.5));
    rack.bent_pitch = (rack.x_end - rack.x_begin) / double(bays);
    for (double z : spec.tiers_m) {
      if (z > 0.0) rack.tiers.push_back(z);
    }
    const int lane_count = int((rack.width - 0.6) / rack.lane_pitch) + 1;
    rack.lanes.assign(rack.tiers.size(),
                      std::vector<std::vector<std::pair<double, double>>>(size_t(lane_count)));
    unit.racks.push_back(std::move(rack));
  }
  for (int r = 0; r < spec.racks; ++r) {
    const Rack& rack = unit.racks[size_t(r)];
    const double lo =
        r == 0 ? kEdgeMargin_m : 0.5 * (unit.racks[size_t(r - 1)].y_centre + rack.y_centre);
    const double hi = r + 1 == spec.racks
                          ? depth - kEdgeMargin_m
                          : 0.5 * (unit.racks[size_t(r + 1)].y_centre + rack.y_centre);
    for (int side : {-1, 1}) {
      Band band;
      band.rack = r;
      band.side = side;
      band.y_near = rack.y_centre + side * (0.5 * rack.width + kRackClearance_m);
      band.y_far = side < 0 ? lo : hi;
      band.pump_row_y = band.y_near + side * (0.5 * kPumpRowDepth_m);
      unit.bands.push_back(std::move(band));
    }
  }
}

// Shelves run along x at growing distance from the rack; an item goes on the first shelf with
// room, a new shelf opens beyond the deepest item of the last one.
bool place_in_band(Unit& unit, int band_index, double size_x, double size_y, uint32_t item,
                   bool overflow, dvec3& centre) {
  Band& band = unit.bands[size_t(band_index)];
  const Rack& rack = unit.racks[size_t(band.rack)];
  const double depth = std::abs(band.y_far - band.y_near) - kPumpRowDepth_m;
  auto put = [&](Band::Shelf& shelf, Band::Column& column) {
    const double y0 = column.used == 0.0 ? 0.0 : column.used + kItemGap_m;
    const double y = band.y_near + band.side * (kPumpRowDepth_m + shelf.start + y0 + 0.5 * size_y);
    centre = dvec3(column.x0 + 0.5 * size_x, y, 0.0);
    column.used = y0 + size_y;
    shelf.items.push_back(item);
  };
  for (Band::Shelf& shelf : band.shelves) {
    // Behind an item already in a column, or in a new column.
    for (Band::Column& column : shelf.columns) {
      const double y0 = column.used + kItemGap_m;
      if (size_x <= column.width + 1e-9 && y0 + size_y <= shelf.depth + 1e-9) {
        put(shelf, column);
        return true;
      }
    }
    if (size_y <= shelf.depth + 1e-9 && shelf.next_x + size_x <= rack.x_end) {
      shelf.columns.push_back({shelf.next_x, size_x, 0.0});
      shelf.next_x += size_x + kItemGap_m;
      put(shelf, shelf.columns.back());
      return true;
    }
  }
  const double start = band.shelves.empty()
                           ? 0.5
                           : band.shelves.back().start + band.shelves.back().depth + kShelfGap_m;
  if ((!overflow && start + size_y > depth) || rack.x_begin + size_x > rack.x_end) return false;
  band.shelves.push_back({rack.x_begin + size_x + kItemGap_m, start, size_y, {}, {}});
  band.shelves.back().columns.push_back({rack.x_begin, size_x, 0.0});
  put(band.shelves.back(), band.shelves.back().columns.back());
  return true;
}

void spread_shelves(Unit& unit) {
  for (const Band& band : unit.bands) {
    const Rack& rack = unit.racks[size_t(band.rack)];
    for (const Band::Shelf& shelf : band.shelves) {
      const double slack = rack.x_end - (shelf.next_x - kItemGap_m);
      if (shelf.columns.empty() || slack <= 0) continue;
      const double n = double(shelf.columns.size());
      for (uint32_t i : shelf.items) {
        EquipmentRecord& e = unit.equipment[i];
        // The item's column: the last one starting at or before its left edge.
        size_t k = 0;
        for (size_t c = 0; c < shelf.columns.size(); ++c) {
          if (shelf.columns[c].x0 <= e.centre.x - 0.5 * e.size_x + 1e-9) k = c;
        }
        e.centre.x += slack * (double(k) + 0.5) / n;
      }
    }
  }
}

bool place_in_pump_row(Unit& unit, int band_index, double x_wanted, double size_x,
                       double& x_centre) {
  Band& band = unit.bands[size_t(band_index)];
  const Rack& rack = unit.racks[size_t(band.rack)];
  const double lo = rack.x_begin + 0.5 * size_x, hi = rack.x_end - 0.5 * size_x;
  auto fits = [&](double x) {
    if (x < lo || x > hi) return false;
    for (const auto& [a, b] : band.pump_slots) {
      if (a < x + 0.5 * size_x + 0.6 && x - 0.5 * size_x - 0.6 < b) return false;
    }
    return true;
  };
  // Candidates: the wanted place, and either side of every pump already placed.
  std::vector<double> candidates{std::clamp(x_wanted, lo, hi)};
  for (const auto& [a, b] : band.pump_slots) {
    candidates.push_back(b + 0.6 + 0.5 * size_x + 1e-6);
    candidates.push_back(a - 0.6 - 0.5 * size_x - 1e-6);
  }
  bool found = false;
  for (double x : candidates) {
    if (fits(x) && (!found || std::abs(x - x_wanted) < std::abs(x_centre - x_wanted))) {
      x_centre = x;
      found = true;
    }
  }
  if (found) band.pump_slots.push_back({x_centre - 0.5 * size_x, x_centre + 0.5 * size_x});
  return found;
}

void clear_band_places(Unit& unit) {
  for (Band& band : unit.bands) {
    band.shelves.clear();
    band.pump_slots.clear();
  }
}

double reserve_lane(Rack& rack, int tier, double x0, double x1, double od_m, int from_side) {
  if (tier < 0 || size_t(tier) >= rack.lanes.size()) return NAN;
  if (x0 > x1) std::swap(x0, x1);
  x0 -= 1.0;
  x1 += 1.0;
  auto& lanes = rack.lanes[size_t(tier)];
  const int need = std::max(1, int(std::ceil((od_m + 0.2) / rack.lane_pitch)));
  auto free = [&](size_t lane) {
    for (const auto& [a, b] : lanes[lane]) {
      if (a < x1 && x0 < b) return false;
    }
    return true;
  };
  for (size_t k = 0; k + size_t(need) <= lanes.size(); ++k) {
    const size_t first = from_side > 0 ? lanes.size() - size_t(need) - k : k;
    bool ok = true;
    for (size_t l = first; l < first + size_t(need) && ok; ++l) ok = free(l);
    if (!ok) continue;
    for (size_t l = first; l < first + size_t(need); ++l) lanes[l].push_back({x0, x1});
    const double centre_lane = double(first) + 0.5 * double(need - 1);
    return rack.y_centre - 0.5 * rack.width + 0.3 + centre_lane * rack.lane_pitch;
  }
  return NAN;
}

}  // namespace plantview::gen
