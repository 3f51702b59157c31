// Piping groups: which fittings a line gets, in flow order: the end groups at nozzles, the
// closures of dead ends, and the optional inline groups (valve stations, control valves,
// strainers, orifice runs, spectacle blinds, spool joints, field welds, vents and drains). Rule:
// every choice among valid groups goes through the unit's ledger (what the group adds against
// the targets), never through a bare random draw.
#include "pipelines.h"

#include <cmath>
#include <string>

namespace plantview::gen::pipelines {

// End groups at a nozzle, in flow order: gasket, flange (and a valve bolted to the nozzle), and a
// reducer when the line's bore differs from the nozzle's.
std::vector<Item> Piping::nozzle_group(LineContext& line, const Nozzle& nozzle, int line_bore,
                                       bool at_start, bool allow_valve) {
  const int nozzle_bore = nozzle.bore;
  const bool horizontal = std::abs(nozzle.direction.z) < 0.5;
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  Part valve = Part::weld;  // none
  if (allow_valve) {
    std::vector<Part> parts{Part::weld, Part::gate, Part::globe, Part::ball, Part::globe_y};
    if (!nozzle.flanged) parts = {Part::weld, Part::gate, Part::globe, Part::ball_welded};
    if (nozzle_bore >= 8 && nozzle.flanged) parts.push_back(Part::butterfly);
    std::vector<Mix> mixes;
    for (Part p : parts) {
      Mix m;
      if (p != Part::weld)
        m += part_mix(p), m += part_mix(nozzle.flanged ? Part::gasket : Part::weld);
      mixes.push_back(m);
    }
    valve = parts[unit_.ledger.choose(mixes)];
  }
  Part reducer = Part::reducer_conc;
  if (nozzle_bore != line_bore && horizontal) {
    const Mix options[] = {part_mix(Part::reducer_conc), part_mix(Part::reducer_ecc)};
    if (unit_.ledger.choose(options) == 1) reducer = Part::reducer_ecc;
  }
  std::vector<Item> items;
  if (!nozzle.flanged) {
    // Butt-welded to the nozzle's bevelled end (and a welding-end valve after it).
    if (at_start) {
      items.push_back(item(Part::weld, nozzle_bore));
      if (valve != Part::weld) items.push_back(item(valve, nozzle_bore));
      if (nozzle_bore != line_bore) items.push_back({reducer, nozzle_bore, line_bore, true});
    } else {
      if (nozzle_bore != line_bore) items.push_back({reducer, line_bore, nozzle_bore, true});
      if (valve != Part::weld) items.push_back(item(valve, nozzle_bore));
      items.push_back(item(Part::weld, nozzle_bore));
    }
    return items;
  }
  if (at_start) {
    items.push_back(item(Part::gasket, nozzle_bore));
    if (valve != Part::weld) {
      items.push_back(item(valve, nozzle_bore));
      items.push_back(item(Part::gasket, nozzle_bore));
    }
    items.push_back(item(flange, nozzle_bore, false));
    if (nozzle_bore != line_bore) items.push_back({reducer, nozzle_bore, line_bore, true});
  } else {
    if (nozzle_bore != line_bore) items.push_back({reducer, line_bore, nozzle_bore, true});
    items.push_back(item(flange, nozzle_bore, true));
    if (valve != Part::weld) {
      items.push_back(item(Part::gasket, nozzle_bore));
      items.push_back(item(valve, nozzle_bore));
    }
    items.push_back(item(Part::gasket, nozzle_bore));
  }
  return items;
}

// Closed ends (header ends, vents, drains, hose connections), in flow order.
std::vector<Item> Piping::closure_group(LineContext& line, int bore, bool allow_valve) {
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  std::vector<std::vector<Item>> options;
  std::vector<Part> valves{Part::gate, Part::ball, Part::globe};
  if (bore <= 4) valves.push_back(Part::ball_sw);
  auto with_valve = [&](std::initializer_list<Part> before, Part valve,
                        std::initializer_list<Part> after) {
    std::vector<Item> v;
    for (Part p : before) v.push_back(item(p, bore, true));
    if (valve != Part::weld) v.push_back(item(valve, bore));
    for (Part p : after) v.push_back(item(p, bore, false));
    options.push_back(std::move(v));
  };
  for (Part valve : valves) {
    if (!allow_valve && valve != Part::gate) continue;
    const Part v = allow_valve ? valve : Part::weld;
    // Caps and plugs only while their (small) kinds have room.
    if (room(kDish)) with_valve({}, v, {Part::cap});
    if (bore <= 4 && room(kPrism)) with_valve({}, v, {Part::plug});
    if (v != Part::weld) {
      with_valve({flange, Part::gasket}, v, {Part::gasket, Part::blind});
      with_valve({}, v, {Part::gasket, Part::blind});  // welding inlet, flanged outlet
    } else {
      with_valve({flange, Part::gasket}, v, {Part::blind});
    }
  }
  std::vector<Mix> mixes;
  for (const auto& o : options) mixes.push_back(group_mix(o));
  return options[unit_.ledger.choose(mixes)];
}

// Optional inline groups on each segment, chosen by the ledger among those that fit: valve
// stations, control valves, strainers, orifice runs, spectacle blinds, flanged spool joints,
// field welds, vents and drains.
void Piping::add_optional(LineContext& line, std::vector<SegmentSlots>& segs,
                          const std::vector<dvec3>& pts, int bore) {
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  auto set_of = [&](Part middle, int b) {
    return std::vector<Item>{item(flange, b, true), item(Part::gasket, b), item(middle, b),
                             item(Part::gasket, b), item(flange, b, false)};
  };
  // The catalogue for this spec, service and bore (built once per unit): each group placed in
  // the middle of a run (splitting its pipe) or, where it may, right after or before a bend or
  // end.
  const uint32_t key =
      uint32_t(bore) * 64u + uint32_t(line.weld_neck) * 32u + uint32_t(line.service);
  auto cached = catalogue_.find(key);
  if (cached == catalogue_.end()) {
    std::vector<Option> built;
    auto offer = [&](std::vector<Item> items, bool attached_too, bool horizontal_only = false) {
      Option o;
      o.slot.length = group_length(items);
      o.slot.items = std::move(items);
      o.mix = group_mix(o.slot.items);
      o.horizontal_only = horizontal_only;
      if (attached_too) {
        o.mid = false;
        built.push_back(o);
      }
      o.mid = true;
      o.mix += pipe_mix();
      built.push_back(std::move(o));
    };
    std::vector<Part> valves{Part::gate, Part::globe, Part::globe_y, Part::ball, Part::check};
    if (bore >= 8) valves.push_back(Part::butterfly);
    for (Part v : valves) offer(set_of(v, bore), true);
    // Butt-welding valves straight in the run (socket-weld ball valves on small bores), and
    // steam traps on steam and condensate lines.
    for (Part v : {Part::gate, Part::globe, Part::ball_welded, Part::check})
      offer({item(v, bore)}, true);
    if (bore <= 4) offer({item(Part::ball_sw, bore)}, true);
    if (line.service == Service::lp_steam || line.service == Service::mp_steam ||
        line.service == Service::condensate) {
      offer({item(Part::trap, bore)}, true);
    }
    if (line.service == Service::process) {
      offer(set_of(Part::control, bore), true);
      offer(set_of(Part::orifice, bore), false);
    }
    offer(set_of(Part::strainer, bore), true, true);
    offer(set_of(Part::spectacle, bore), true);
    // Valves one size down between a pair of reducers (eccentric ones flat on top), as control
    // stations and large block valves are built.
    if (bore >= 4) {
      for (Part reducer : {Part::reducer_conc, Part::reducer_ecc}) {
        for (Part v : {Part::control, Part::gate, Part::ball, Part::globe, Part::check}) {
          if (v == Part::control && line.service != Service::process) continue;
          std::vector<Item> items{{reducer, bore, bore - 1, true}};
          for (const Item& it : set_of(v, bore - 1)) items.push_back(it);
          items.push_back({reducer, bore - 1, bore, true});
          offer(std::move(items), true);
        }
        for (Part v : {Part::ball_welded, Part::gate}) {
          offer(
              {{reducer, bore, bore - 1, true}, item(v, bore - 1), {reducer, bore - 1, bore, true}},
              true);
        }
      }
    }
    offer({item(flange, bore, true), item(Part::gasket, bore), item(flange, bore, false)}, false);
    offer({item(Part::weld, bore)}, false);
    cached = catalogue_.emplace(key, std::move(built)).first;
  }
  const std::vector<Option>& catalogue = cached->second;
  std::vector<Option> stubs;
  // Vents up and drains down from horizontal runs: a reducing tee or an olet, a short pipe, a
  // valve and a closure.
  const int sub_bore = bore >= 4 ? 2 : 1;
  const std::vector<Item> closure = closure_group(line, sub_bore, true);
  const double drain_drop = 0.15 + tee_half(bore) + group_length(closure);
  for (int drain = 0; drain < 2; ++drain) {
    for (bool olet : {false, true}) {
      Option o;
      o.slot.length = olet ? 0.0 : 2 * tee_half(bore);
      o.slot.olet = olet;
      o.slot.tee = drain ? TeeUse::drain : TeeUse::vent;
      o.slot.branch_dir = drain ? kDown : kUp;
      o.slot.branch_bore = sub_bore;
      o.slot.sub_items = closure;
      o.mix = part_mix(olet ? Part::olet : Part::tee);
      o.mix += pipe_mix();  // splits the run
      o.mix += pipe_mix();  // the stub's pipe
      o.mix += group_mix(closure);
      o.horizontal_only = true;
      stubs.push_back(std::move(o));
    }
  }
  std::vector<Mix> mixes;
  std::vector<const Option*> index;
  for (size_t k = 0; k < segs.size(); ++k) {
    SegmentSlots& seg = segs[k];
    const dvec3 dir = glm::normalize(pts[k + 1] - pts[k]);
    const bool horizontal = std::abs(dir.z) < 0.5;
    const bool drain_room = pts[k].z - drain_drop >= 0.25;
    for (int round = 0; round < 3; ++round) {
      const std::vector<Gap> gaps = gaps_of(seg);
      mixes.assign(1, Mix{});
      index.assign(1, nullptr);
      auto consider = [&](const Option& o) {
        if (o.horizontal_only && !horizontal) return;
        if (o.slot.tee == TeeUse::drain && !drain_room) return;
        if (!fits(gaps, o.slot.length, o.mid) || !small_kinds_fit(o.mix)) return;
        mixes.push_back(o.mix);
        index.push_back(&o);
      };
      for (const Option& o : catalogue) consider(o);
      for (const Option& o : stubs) consider(o);
      const size_t pick = unit_.ledger.choose(mixes);
      if (pick == 0) break;
      const Option& o = *index[pick];
      Slot slot = o.slot;
      slot.at = place(gaps, o.slot.length, o.mid, rng_);
      pending_ += o.mix;
      seg.slots.push_back(std::move(slot));
    }
  }
}

}  // namespace plantview::gen::pipelines
