// Utility headers and their drops. A header runs the length of a rack lane from a battery-limit
// flange to a closed end, with a take-off tee (or olet) for each of its drops; a drop runs from
// its take-off to a utility nozzle or, failing a route, to a hose station beside the rack. Rule:
// a header's take-offs are placed before its drops are built; a drop whose header had no room
// for its take-off is not built.
#include "pipelines.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace plantview::gen::pipelines {

namespace {

constexpr Service kHeaderServices[] = {
    Service::lp_steam,
    Service::cooling_water_supply,
    Service::cooling_water_return,
    Service::nitrogen,
    Service::instrument_air,
    Service::mp_steam,
    Service::plant_air,
    Service::fuel_gas,
    Service::condensate,
    Service::flare,
};
constexpr int kHeaderServiceCount = int(sizeof kHeaderServices / sizeof kHeaderServices[0]);

}  // namespace

bool Piping::build_header(int h) {
  const Service service = kHeaderServices[h % kHeaderServiceCount];
  const int rack_index = h % int(unit_.racks.size());
  Rack& rack = unit_.racks[size_t(rack_index)];
  const int tiers = int(rack.tiers.size());
  int bore = rng_.range(unit_.spec.header_bore_min, unit_.spec.header_bore_max);
  if (service == Service::flare) bore = std::min(kPipeSizeCount - 1, bore + 3);
  const double length = unit_.info.plan_x_m;
  double y = NAN;
  int tier = tiers - 1 - (h / int(unit_.racks.size())) % tiers;
  for (int t = 0; t < tiers && std::isnan(y); ++t) {
    tier = (tier + tiers - (t > 0 ? 1 : 0)) % tiers;
    y = reserve_lane(rack, tier, 0.0, length, pipe_size(bore).od_m, (h % 2) ? 1 : -1);
  }
  if (std::isnan(y)) return false;
  const double z = lane_z(tier, rack, bore);
  LineContext line = new_line(service, bore);
  line.from = "Battery limit";
  line.to = "Header end";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  const Port head{dvec3(0.0, y, z), kX, bore};
  const std::vector<Item> start{item(flange, bore, false)};
  const std::vector<Item> end = closure_group(line, bore, false);
  const dvec3 s = head.position + group_span(start, kX);
  const dvec3 e = dvec3(rack.x_end + 0.8, y, z) - group_span(end, kX);
  const std::vector<dvec3> pts{s, e};
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  // Take-offs for the drops, in x order, spaced apart.
  std::vector<int>& drops = header_drops_[size_t(h)];
  std::stable_sort(drops.begin(), drops.end(),
                   [&](int a, int b) { return drops_[size_t(a)].x < drops_[size_t(b)].x; });
  // Spaced apart: pushed forward from the start, then back from the end.
  const double c = tee_half(bore), spacing = 2 * c + 2 * kMinPipe + 0.2;
  const double first = s.x + c + kMinPipe + 1.0, last = e.x - c - kMinPipe - 0.5;
  double next = first;
  for (int d : drops) {
    Drop& drop = drops_[size_t(d)];
    drop.x = std::max(drop.x, next);
    next = drop.x + spacing;
  }
  next = last;
  for (auto it = drops.rbegin(); it != drops.rend(); ++it) {
    Drop& drop = drops_[size_t(*it)];
    drop.x = std::min(drop.x, next);
    next = drop.x - spacing;
  }
  for (int d : drops) {
    Drop& drop = drops_[size_t(d)];
    if (drop.x < first) continue;  // no room left: the drop will fail
    // Small take-offs from large headers are olets; the rest tees. Stations beside the rack
    // take off the header's top (up, across, down) or its side (across, down).
    bool olet = false;
    if (drop.bore <= 5 && bore - drop.bore >= 2) {
      const Mix options[] = {part_mix(Part::tee), part_mix(Part::olet)};
      olet = unit_.ledger.choose(options) == 1;
    }
    if (drop.nozzle < 0) {
      Mix top, side;  // the top take-off's first elbow can sit right on the tee (no pipe)
      top += part_mix(Part::elbow);
      top += part_mix(Part::elbow);
      side += part_mix(Part::elbow);
      const Mix options[] = {top, side};
      drop.side_takeoff = unit_.ledger.choose(options) == 1;
    }
    const dvec3 takeoff = drop.side_takeoff ? dvec3(0, drop.side, 0) : kUp;
    add_forced_tee(segs, pts, bore, dvec3(drop.x, y, z), takeoff, drop.bore, TeeUse::takeoff, d,
                   olet);
  }
  // The take-off ports wait for their drops.
  finish_branch(line, head, start, pts, segs, end, {},
                [&](const Slot& slot, const Port& port) { drops_[size_t(slot.tag)].port = port; });
  return true;
}

bool Piping::build_drop(Drop& d) {
  if (!d.port) return false;  // its header had no room left for the take-off
  const Service service = kHeaderServices[d.header % kHeaderServiceCount];
  const Rack& rack = unit_.racks[size_t(d.header % int(unit_.racks.size()))];
  const int bore = d.bore;
  const double r = 0.5 * pipe_size(bore).od_m;
  LineContext line = new_line(service, bore);
  const Port head = *d.port;
  // A block valve at the take-off, or straight on.
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  std::vector<Item> start;
  {
    const std::vector<Item> valve_set{item(flange, bore, true), item(Part::gasket, bore),
                                      item(Part::gate, bore), item(Part::gasket, bore),
                                      item(flange, bore, false)};
    const Mix options[] = {Mix{}, group_mix(valve_set)};
    if (unit_.ledger.choose(options) == 1) start = valve_set;
  }
  const dvec3 s = head.position + group_span(start, head.direction);
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  std::vector<Item> end;
  bool ok = false;
  int joined = -1;  // the nozzle the drop ends at, if it does
  line.from = "Header take-off";
  if (d.nozzle >= 0) {
    const Nozzle& n = unit_.nozzles[size_t(d.nozzle)];
    end = nozzle_group(line, n, bore, false, true);
    const dvec3 e = n.position - group_span(end, -n.direction);
    const Band* band = band_of_nozzle(d.nozzle);
    const int side = band ? band->side : 1;
    const double y_exit = rack.y_centre + side * (0.5 * rack.width + 0.6);
    std::vector<Pattern> patterns = permutations({{kAxisY, y_exit}});
    for (const Pattern& p : permutations({})) patterns.push_back(p);
    ok = route(s, head.direction, e, -n.direction, bend_radius(bore), r + 0.1, {0.0, 0.5, 1.0, 1.8},
               patterns, options, 4) &&
         pick_route(options, bore, pts);
    if (ok) {
      joined = d.nozzle;
      line.to = unit_.equipment[n.equipment].tag;
    }
  }
  if (!ok) {
    // A utility station beside the rack: a hose connection 1 m above grade, below the take-off
    // or a few metres along the rack; steam stations drain through a trap first.
    end = closure_group(line, bore, true);
    if (service == Service::lp_steam || service == Service::mp_steam ||
        service == Service::condensate) {
      const Mix trap_options[] = {Mix{}, part_mix(Part::trap)};
      if (unit_.ledger.choose(trap_options) == 1) end.insert(end.begin(), item(Part::trap, bore));
    }
    const double y_station = rack.y_centre + d.side * (0.5 * rack.width + 0.6);
    // The hose connection points down, or along the rack from an elbow at the drop's foot.
    std::vector<std::vector<dvec3>> all;
    for (double shift : {0.0, 2.5, -2.5}) {
      for (const dvec3& de : {kDown, kX, -kX}) {
        const dvec3 q(head.position.x + shift, y_station, 1.0);
        const dvec3 e = q - group_span(end, de);
        const std::vector<Pattern> patterns{{{kAxisY, y_station}, {kAxisX, NAN}, {kAxisZ, NAN}},
                                            {{kAxisY, y_station}, {kAxisZ, NAN}, {kAxisX, NAN}}};
        if (route(s, head.direction, e, de, bend_radius(bore), r + 0.1, {0.0, 0.5}, patterns,
                  options, 2)) {
          for (auto& o : options) all.push_back(std::move(o));
        }
      }
    }
    ok = pick_route(all, bore, pts);
    line.to = "Utility station";
  }
  if (!ok) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  finish_branch(line, head, start, pts, segs, end, {joined});
  return true;
}

}  // namespace plantview::gen::pipelines
