// Pump lines: the suction line of a pump pair (one branch to the far pump, a tee to the near
// one) and its discharge line (the two risers joined at a tee). Rule: both pumps of a pair get
// the same fittings, so that either can run while the other is isolated.
#include "pipelines.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace plantview::gen::pipelines {

// Pump suction: from the feeding vessel's bottom outlet down to a header in front of the pump
// pair, a tee for the near pump and an elbow into the far one; each pump gets a block valve, a
// strainer and an eccentric reducer (flat on top) before its suction flange.
bool Piping::build_pump_suction(int pair) {
  const int feeder = feeders_[size_t(pair)];
  int ia = -1;
  for (size_t i = 0; i < unit_.equipment.size(); ++i) {
    if (unit_.equipment[i].pump_pair == pair && unit_.equipment[i].pump_letter == 'A') ia = int(i);
  }
  if (ia < 0) return false;
  const EquipmentRecord& pa = unit_.equipment[size_t(ia)];
  const EquipmentRecord& pb = unit_.equipment[size_t(ia + 1)];
  const Nozzle& na = unit_.nozzles[pa.nozzles[0]];
  const Nozzle& nb = unit_.nozzles[pb.nozzles[0]];
  // The source: the feeding vessel's outlet, or else a battery-limit flange on the rack.
  Nozzle f;
  int lane_tier = -1;
  const int rack_index = pa.band >= 0 ? unit_.bands[size_t(pa.band)].rack : 0;
  Rack& rack = unit_.racks[size_t(rack_index)];
  if (feeder >= 0) {
    f = unit_.nozzles[size_t(feeder)];
  } else {
    f.bore = std::min(kPipeSizeCount - 1, na.bore + 1);
    const bool west = na.position.x < 0.5 * unit_.info.plan_x_m;
    const double x_bl = west ? 0.0 : unit_.info.plan_x_m;
    const int side = pa.band >= 0 ? unit_.bands[size_t(pa.band)].side : 1;
    for (int t = 0; t < int(rack.tiers.size()) && lane_tier < 0; ++t) {
      const double y = reserve_lane(rack, t, x_bl, na.position.x, pipe_size(f.bore).od_m, side);
      if (std::isnan(y)) continue;
      lane_tier = t;
      f.position = dvec3(x_bl, y, lane_z(t, rack, f.bore));
    }
    if (lane_tier < 0) return false;
    f.direction = dvec3(west ? 1.0 : -1.0, 0, 0);
  }
  const int bore = std::min(kPipeSizeCount - 1, std::max(f.bore, na.bore + 1));
  const double big_r = bend_radius(bore), c = tee_half(bore);
  const double dx = f.position.x <= 0.5 * (na.position.x + nb.position.x) ? 1.0 : -1.0;
  const bool a_far = (na.position.x - nb.position.x) * dx > 0;
  const Nozzle& far = a_far ? na : nb;
  const Nozzle& near = a_far ? nb : na;
  LineContext line = new_line(Service::process, bore);
  line.from = feeder >= 0 ? unit_.equipment[f.equipment].tag : std::string("Battery limit");
  line.to = pa.tag + "/B";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  // Pump end group, in flow order.
  std::vector<Item> end;
  {
    // A block valve: flanged, or butt-welded into the line.
    const Part valve = bore >= 8 && rng_.chance(500) ? Part::butterfly : Part::gate;
    const std::vector<Item> flanged{item(flange, bore, true), item(Part::gasket, bore),
                                    item(valve, bore), item(Part::gasket, bore),
                                    item(flange, bore, false)};
    const std::vector<Item> welded{item(Part::weld, bore), item(Part::ball_welded, bore),
                                   item(Part::weld, bore)};
    const Mix valve_options[] = {group_mix(flanged), group_mix(welded)};
    end = unit_.ledger.choose(valve_options) == 0 ? flanged : welded;
    const Mix strainer_options[] = {Mix{}, part_mix(Part::strainer)};
    if (unit_.ledger.choose(strainer_options) == 1) end.push_back(item(Part::strainer, bore));
    const Mix reducer_options[] = {part_mix(Part::reducer_conc), part_mix(Part::reducer_ecc)};
    const Part reducer =
        unit_.ledger.choose(reducer_options) == 1 ? Part::reducer_ecc : Part::reducer_conc;
    end.push_back({reducer, bore, far.bore, true});
    end.push_back(item(flange, far.bore, true));
    end.push_back(item(Part::gasket, far.bore));
  }
  const dvec3 arrive = -far.direction;
  const dvec3 e_far = far.position - group_span(end, arrive);
  const dvec3 e_near = near.position - group_span(end, arrive);
  const double leg = std::max(big_r, c) + kMinPipe + 0.3;
  const dvec3 corner = e_far - arrive * leg;
  const dvec3 tee_centre(e_near.x, corner.y, corner.z);
  // Vessel side.
  const Port head{f.position, f.direction, f.bore};
  const std::vector<Item> start = feeder >= 0 ? nozzle_group(line, f, bore, true, true)
                                              : std::vector<Item>{item(flange, bore, false)};
  const dvec3 s = head.position + group_span(start, f.direction);
  std::vector<dvec3> pts;
  const double run_in = std::abs(far.position.x - near.position.x) + c + 2 * big_r + 0.4;
  std::vector<Pattern> patterns = local_patterns(s, corner, big_r);
  if (feeder < 0) {
    // Along the lane to above the pumps, then down beside the rack.
    const double y_out = corner.y;
    patterns.insert(patterns.begin(),
                    Pattern{{kAxisX, corner.x - dx * run_in}, {kAxisY, y_out}, {kAxisZ, NAN}});
  }
  std::vector<std::vector<dvec3>> options;
  if (!route(s, f.direction, corner, dvec3(dx, 0, 0), big_r, 0.5 * pipe_size(bore).od_m + 0.1,
             {0.0, 0.4, 1.0, 2.0}, patterns, options, 3, 0.0, run_in) ||
      !pick_route(options, bore, pts)) {
    return false;
  }
  pts.push_back(e_far);
  if (!simplify(pts) || !long_enough(pts, big_r, 0.1)) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  if (!add_forced_tee(segs, pts, bore, tee_centre, arrive, bore, TeeUse::pump_suction, 0)) {
    return false;
  }
  // The near pump's branch: from the tee to its suction flange, with the far pump's end group.
  finish_branch(line, head, start, pts, segs, end, {feeder}, [&](const Slot&, const Port& port) {
    Run run(line, int(line.branches.size()) + 1, port);
    if (glm::dot(e_near - port.position, port.direction) > 1e-6) run.pipe_to(e_near);
    for (const Item& it : end) run.straight(it);
    run.finish();
  });
  return true;
}

// Pump discharge: each pump rises through a check valve and a block valve; the second pump's
// riser joins the first one's line at a tee, which then runs to its destination over the rack.
bool Piping::build_pump_discharge(int pair) {
  int ia = -1;
  for (size_t i = 0; i < unit_.equipment.size(); ++i) {
    if (unit_.equipment[i].pump_pair == pair && unit_.equipment[i].pump_letter == 'A') ia = int(i);
  }
  if (ia < 0) {
    return false;
  }
  const EquipmentRecord& pa = unit_.equipment[size_t(ia)];
  const EquipmentRecord& pb = unit_.equipment[size_t(ia + 1)];
  const Nozzle& na = unit_.nozzles[pa.nozzles[1]];
  const Nozzle& nb = unit_.nozzles[pb.nozzles[1]];
  const int target = discharge_targets_[size_t(pair)];
  const int bore = std::min(unit_.spec.line_bore_max + 1, na.bore + 1);
  const double big_r = bend_radius(bore), c = tee_half(bore);
  const int rack_index = pa.band >= 0 ? unit_.bands[size_t(pa.band)].rack : 0;
  const Rack& rack = unit_.racks[size_t(rack_index)];
  const int side = pa.band >= 0 ? unit_.bands[size_t(pa.band)].side : 1;
  const double x_dest =
      target >= 0 ? unit_.nozzles[size_t(target)].position.x
                  : (na.position.x < 0.5 * unit_.info.plan_x_m ? 0.0 : unit_.info.plan_x_m);
  const double dx = x_dest >= 0.5 * (na.position.x + nb.position.x) ? 1.0 : -1.0;
  const bool a_first = (nb.position.x - na.position.x) * dx > 0;
  const Nozzle& first = a_first ? na : nb;
  const Nozzle& second = a_first ? nb : na;
  LineContext line = new_line(Service::process, bore);
  line.from = pa.tag + "/B";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  // Each riser: the pump's flange, a reducer, then a check valve and a block valve (bolted
  // together between flanges, or butt-welded).
  const std::vector<Item> flanged{item(Part::gasket, na.bore),
                                  item(flange, na.bore, false),
                                  {Part::reducer_conc, na.bore, bore, true},
                                  item(flange, bore, true),
                                  item(Part::gasket, bore),
                                  item(Part::check, bore),
                                  item(Part::gasket, bore),
                                  item(Part::gate, bore),
                                  item(Part::gasket, bore),
                                  item(flange, bore, false)};
  const std::vector<Item> welded{item(Part::gasket, na.bore),
                                 item(flange, na.bore, false),
                                 {Part::reducer_conc, na.bore, bore, true},
                                 item(Part::weld, bore),
                                 item(Part::check, bore),
                                 item(Part::weld, bore),
                                 item(Part::ball_welded, bore),
                                 item(Part::weld, bore)};
  const std::vector<Item> check_only{item(Part::gasket, na.bore),
                                     item(flange, na.bore, false),
                                     {Part::reducer_conc, na.bore, bore, true},
                                     item(Part::weld, bore),
                                     item(Part::check, bore),
                                     item(Part::weld, bore)};
  const Mix riser_options[] = {group_mix(flanged), group_mix(welded), group_mix(check_only)};
  const size_t riser = unit_.ledger.choose(riser_options);
  const std::vector<Item> start = riser == 0 ? flanged : riser == 1 ? welded : check_only;
  const dvec3 s_first = first.position + group_span(start, kUp);
  const dvec3 s_second = second.position + group_span(start, kUp);
  const dvec3 corner(s_first.x, s_first.y, s_first.z + big_r + kMinPipe + 0.3 + c);
  const dvec3 tee_centre(s_second.x, corner.y, corner.z);
  // Destination.
  std::vector<Item> end;
  dvec3 e, de;
  if (target >= 0) {
    const Nozzle& t = unit_.nozzles[size_t(target)];
    end = nozzle_group(line, t, bore, false, false);
    e = t.position - group_span(end, -t.direction);
    de = -t.direction;
    line.to = unit_.equipment[t.equipment].tag;
  } else {
    end = {item(flange, bore, true), item(Part::gasket, bore),  item(Part::gate, bore),
           item(Part::gasket, bore), item(flange, bore, false), item(flange, bore, true)};
    de = dvec3(dx, 0, 0);
    line.to = "Battery limit";
  }
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  const double run_out = std::abs(second.position.x - first.position.x) + c + 2 * big_r + 0.4;
  bool ok = false;
  if (target >= 0) {
    for (int attempt = 0; attempt < 3 && !ok; ++attempt) {
      const int tier = int(rng_.below(uint32_t(rack.tiers.size())));
      Rack& rk = unit_.racks[size_t(rack_index)];
      const double y = reserve_lane(rk, tier, corner.x, e.x, pipe_size(bore).od_m, side);
      if (std::isnan(y)) continue;
      const double z = lane_z(tier, rk, bore);
      std::vector<Pattern> patterns = rack_patterns(y, z, corner.y);
      for (const Pattern& p : local_patterns(corner, e, big_r)) patterns.push_back(p);
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.5 * pipe_size(bore).od_m + 0.1,
                 {0.0, 0.5, 1.2}, patterns, options, 3, run_out) &&
           pick_route(options, bore, pts);
    }
    if (!ok) {
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.5 * pipe_size(bore).od_m + 0.1,
                 {0.0, 0.5, 1.2}, local_patterns(corner, e, big_r), options, 3, run_out) &&
           pick_route(options, bore, pts);
    }
  } else {
    Rack& rk = unit_.racks[size_t(rack_index)];
    for (int tier = 0; tier < int(rk.tiers.size()) && !ok; ++tier) {
      const double y = reserve_lane(rk, tier, corner.x, x_dest, pipe_size(bore).od_m, side);
      if (std::isnan(y)) continue;
      const double z = lane_z(tier, rk, bore);
      const dvec3 q(dx > 0 ? unit_.info.plan_x_m - 0.02 : 0.02, y, z);
      e = q - group_span(end, de);
      const std::vector<Pattern> patterns{{{kAxisZ, z}, {kAxisY, y}, {kAxisX, NAN}}};
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.1, {0.0, 0.5, 1.2}, patterns, options, 3,
                 run_out) &&
           pick_route(options, bore, pts);
    }
    if (!ok) {
      // No lane left toward that end: along the pump row to a battery limit at grade level.
      const dvec3 q(dx > 0 ? unit_.info.plan_x_m - 0.02 : 0.02, corner.y, corner.z);
      e = q - group_span(end, de);
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.1, {0.0, 0.5, 1.2},
                 local_patterns(corner, e, big_r), options, 3, run_out) &&
           pick_route(options, bore, pts);
    }
  }
  if (!ok) {
    return false;
  }
  pts.insert(pts.begin(), s_first);
  if (!simplify(pts) || !long_enough(pts, big_r, 0.1)) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  if (!add_forced_tee(segs, pts, bore, tee_centre, kDown, bore, TeeUse::pump_discharge, 0)) {
    return false;
  }
  const Port head{first.position, kUp, first.bore};
  // The second pump's riser flows up into the tee.
  finish_branch(line, head, start, pts, segs, end, {target}, [&](const Slot&, const Port& port) {
    Run run(line, int(line.branches.size()) + 1, Port{second.position, kUp, second.bore});
    for (const Item& it : start) run.straight(it);
    if (glm::dot(port.position - run.position(), kUp) > 1e-6) {
      run.pipe_to(port.position);
    }
    run.finish();
  });
  return true;
}

}  // namespace plantview::gen::pipelines
