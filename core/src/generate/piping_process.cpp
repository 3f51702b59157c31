// Process lines: from one equipment nozzle to another (a local route when both stand in one band
// near each other, else over the rack), and from a nozzle to the battery limit over the rack.
// Rule: a line takes the size of its larger nozzle (or one up, with reducers at both ends).
#include "pipelines.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace plantview::gen::pipelines {

bool Piping::build_process(int ia, int ib) {
  const Nozzle& a = unit_.nozzles[size_t(ia)];
  const Nozzle& b = unit_.nozzles[size_t(ib)];
  int bore = std::max(a.bore, b.bore);
  {
    // One size up now and then (reducers at both ends).
    Mix same, up;
    up += part_mix(Part::reducer_conc);
    up += part_mix(Part::reducer_conc);
    const Mix options[] = {same, up};
    if (bore + 1 <= unit_.spec.line_bore_max + 1 && unit_.ledger.choose(options) == 1) ++bore;
  }
  LineContext line = new_line(Service::process, bore);
  line.from = unit_.equipment[a.equipment].tag;
  line.to = unit_.equipment[b.equipment].tag;
  const std::vector<Item> start =
      nozzle_group(line, a, bore, true, a.direction.z > -0.5 || a.position.z > 2.2);
  const std::vector<Item> end =
      nozzle_group(line, b, bore, false, b.direction.z > -0.5 || b.position.z > 2.2);
  const dvec3 s = a.position + group_span(start, a.direction);
  const dvec3 e = b.position - group_span(end, -b.direction);
  const double big_r = bend_radius(bore), min_z = 0.5 * pipe_size(bore).od_m + 0.1;
  const Band* band_a = band_of_nozzle(ia);
  const Band* band_b = band_of_nozzle(ib);
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  bool ok = false;
  const bool local = band_a == band_b && std::abs(a.position.x - b.position.x) < 25.0;
  if (local) {
    ok = route(s, a.direction, e, -b.direction, big_r, min_z, {0.0, 0.4, 1.0, 2.0},
               local_patterns(s, e, big_r), options, 3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    ok = rack_route(unit_, rng_, rack_of_nozzle(ia), band_a ? band_a->side : 1, s.x, e.x, bore,
                    big_r, s, a.direction, e, -b.direction, options) &&
         pick_route(options, bore, pts);
  }
  if (!ok && !local) {
    ok = route(s, a.direction, e, -b.direction, big_r, min_z, {0.0, 0.4, 1.0, 2.0},
               local_patterns(s, e, big_r), options, 3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  finish_branch(line, Port{a.position, a.direction, a.bore}, start, pts, segs, end, {ia, ib});
  return true;
}

bool Piping::build_battery_limit(int ia) {
  const Nozzle& a = unit_.nozzles[size_t(ia)];
  const int bore = a.bore;
  LineContext line = new_line(Service::process, bore);
  line.from = unit_.equipment[a.equipment].tag;
  line.to = "Battery limit";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  const std::vector<Item> start = nozzle_group(line, a, bore, true, true);
  const std::vector<Item> end{item(flange, bore, true),  item(Part::gasket, bore),
                              item(Part::gate, bore),    item(Part::gasket, bore),
                              item(flange, bore, false), item(Part::spectacle, bore),
                              item(flange, bore, true)};
  const dvec3 s = a.position + group_span(start, a.direction);
  const double x_bl = a.position.x < 0.5 * unit_.info.plan_x_m ? 0.02 : unit_.info.plan_x_m - 0.02;
  const dvec3 de(x_bl < 1.0 ? -1.0 : 1.0, 0, 0);
  const Band* band = band_of_nozzle(ia);
  Rack& rack = unit_.racks[size_t(rack_of_nozzle(ia))];
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  bool ok = false;
  for (int tier = 0; tier < int(rack.tiers.size()) && !ok; ++tier) {
    const double y =
        reserve_lane(rack, tier, s.x, x_bl, pipe_size(bore).od_m, band ? band->side : 1);
    if (std::isnan(y)) continue;
    const double z = lane_z(tier, rack, bore);
    const dvec3 e = dvec3(x_bl, y, z) - group_span(end, de);
    std::vector<Pattern> patterns;
    for (bool aside : {false, true}) {
      Pattern p;
      if (aside) p.push_back({kAxisY, s.y + (band ? band->side : 1) * 1.5});
      p.push_back({kAxisZ, z});
      p.push_back({kAxisY, y});
      p.push_back({kAxisX, NAN});
      patterns.push_back(p);
    }
    ok = route(s, a.direction, e, de, bend_radius(bore), 0.1, {0.0, 0.4, 1.0}, patterns, options,
               3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    // No lane left toward that end: to a battery limit at the nozzle's elevation.
    const dvec3 e = dvec3(x_bl, s.y, std::max(s.z, 1.0)) - group_span(end, de);
    ok = route(s, a.direction, e, de, bend_radius(bore), 0.1, {0.0, 0.4, 1.0},
               local_patterns(s, e, bend_radius(bore)), options, 3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  finish_branch(line, Port{a.position, a.direction, a.bore}, start, pts, segs, end, {ia});
  return true;
}

}  // namespace plantview::gen::pipelines
