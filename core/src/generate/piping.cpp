// Piping: plans the unit's pipelines (utility headers with their drops, pump suction and
// discharge lines, process lines between nozzles, battery-limit lines), routes each branch
// orthogonally (elbows at every turn), fills the runs with fittings, valves and flanges, adds
// vents, drains and supports, and emits members, supports and pipeline objects.
//
// Counts: every optional choice (valve types, flange spec, inline groups, welds, closures,
// supports) goes through the unit's ledger, which steers the unit toward Su's pipe and component
// counts and Zhou's primitive mix.
//
// This file runs the stage: the targets, the plan (which lines the unit gets) and the order the
// lines are built in; pipelines.h lists the files that build them.
#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "pipelines.h"

namespace plantview::gen {

namespace pipelines {

// ---------------------------------------------------------------------------------------------
// Targets: Su's pipes and components, Zhou's kinds less what equipment and structure hold.

void Piping::set_targets() {
  const PresetInfo& info = unit_.info;
  Ledger& l = unit_.ledger;
  const int64_t structure = unit_.primitives_by_class[size_t(ObjectClass::structure)];
  // Zhou's kinds cover equipment, piping and structure: scale them to Su's total plus the
  // structure actually built.
  const double f = double(info.su_primitives + structure) / double(info.zhou_primitives);
  auto kind = [&](PrimitiveKind k) { return double(info.kind_primitives[size_t(k)]) * f; };
  const double snouts = kind(PrimitiveKind::snout);
  const double snout_total =
      double(info.sheared_cylinders + info.eccentric_cones + info.concentric_cones);
  const std::pair<Tally, double> kinds[] = {
      {kBox, kind(PrimitiveKind::box)},
      {kWedge, kind(PrimitiveKind::pyramid)},
      {kPrism, kind(PrimitiveKind::prism)},
      {kCylinder, kind(PrimitiveKind::cylinder)},
      {kSheared, snouts * info.sheared_cylinders / snout_total},
      {kEccentric, snouts * info.eccentric_cones / snout_total},
      {kConcentric, snouts * info.concentric_cones / snout_total},
      {kTorus, kind(PrimitiveKind::circular_torus)},
      {kRectTorus, kind(PrimitiveKind::rectangular_torus)},
      {kSphere, kind(PrimitiveKind::sphere)},
      {kSaddle, kind(PrimitiveKind::saddle)},
      {kDish, kind(PrimitiveKind::elliptical_dish)},
  };
  for (auto [t, v] : kinds) {
    l.set_target(t, int64_t(std::llround(v)) - unit_.emitted.n[t]);
    l.set_scale(t, std::max<int64_t>(1, int64_t(std::llround(v))));
  }
  l.set_target(kPipes, info.pipes);
  l.set_target(kComponents, info.components);
  l.set_target(kComponentPrims, info.component_primitives);
}

// ---------------------------------------------------------------------------------------------
// Planning: which pipelines this unit gets.

void Piping::plan() {
  const int lines = int(unit_.info.pipelines);
  const int headers = unit_.spec.utility_headers;
  // Pump pairs and their feeders.
  std::vector<int> feeder_nozzle;  // per pair
  for (const EquipmentRecord& e : unit_.equipment) {
    if (e.type == EquipmentType::pump && e.pump_letter == 'A') ++pump_pairs_;
  }
  feeder_nozzle.assign(size_t(pump_pairs_), -1);
  std::vector<char> reserved(unit_.nozzles.size(), 0);
  for (const EquipmentRecord& e : unit_.equipment) {
    if (e.feeds_pair < 0) continue;
    for (uint32_t n : e.nozzles) {
      if (unit_.nozzles[n].role == NozzleRole::outlet_bottom) {
        feeder_nozzle[size_t(e.feeds_pair)] = int(n);
        reserved[n] = 1;
        break;
      }
    }
  }
  feeders_ = feeder_nozzle;
  // Process nozzles, by rack, in x order.
  std::vector<std::vector<int>> pool(unit_.racks.size());
  std::vector<int> utility;
  for (uint32_t n = 0; n < unit_.nozzles.size(); ++n) {
    const Nozzle& z = unit_.nozzles[n];
    if (reserved[n] || z.role == NozzleRole::pump_suction || z.role == NozzleRole::pump_discharge ||
        z.role == NozzleRole::spare) {
      continue;
    }
    if (z.role == NozzleRole::utility) {
      utility.push_back(int(n));
    } else {
      pool[size_t(rack_of_nozzle(int(n)))].push_back(int(n));
    }
  }
  for (auto& p : pool) {
    std::stable_sort(p.begin(), p.end(), [&](int a, int b) {
      return unit_.nozzles[size_t(a)].position.x < unit_.nozzles[size_t(b)].position.x;
    });
  }
  // Pump discharges go to a process nozzle on the same rack (or the battery limit).
  discharge_targets_.assign(size_t(pump_pairs_), -1);
  int pair = 0;
  for (const EquipmentRecord& e : unit_.equipment) {
    if (e.type != EquipmentType::pump || e.pump_letter != 'A') continue;
    auto& p = pool[size_t(e.band >= 0 ? unit_.bands[size_t(e.band)].rack : 0)];
    if (!p.empty() && rng_.chance(700)) {
      // One of the three nozzles nearest along the rack.
      std::vector<size_t> near(p.size());
      for (size_t k = 0; k < p.size(); ++k) near[k] = k;
      auto dist = [&](size_t k) {
        return std::abs(unit_.nozzles[size_t(p[k])].position.x - e.centre.x);
      };
      std::stable_sort(near.begin(), near.end(),
                       [&](size_t a, size_t b) { return dist(a) < dist(b); });
      const size_t k = near[rng_.below(uint32_t(std::min<size_t>(3, near.size())))];
      discharge_targets_[size_t(pair)] = p[k];
      p.erase(p.begin() + std::ptrdiff_t(k));
    }
    ++pair;
  }
  // Process lines pair neighbours (in x) on one rack; leftovers go to the battery limit.
  const int fixed_lines = headers + 2 * pump_pairs_;
  const int room = std::max(0, lines - fixed_lines - lines / 10);
  for (auto& p : pool) {
    rng_.shuffle(p);
    std::stable_sort(p.begin(), p.end(), [&](int a, int b) {
      return unit_.nozzles[size_t(a)].position.x < unit_.nozzles[size_t(b)].position.x;
    });
    size_t i = 0;
    for (; i + 1 < p.size(); i += 2) {
      if (int(process_pairs_.size() + battery_limit_nozzles_.size()) >= room) break;
      // Every third pair takes a farther partner, so that some lines run along the rack; no
      // line joins two nozzles of one item.
      if (rng_.chance(unit_.spec.far_partner_per_mille) && i + 3 < p.size()) {
        std::swap(p[i + 1], p[i + 3]);
      }
      auto owner = [&](size_t k) { return unit_.nozzles[size_t(p[k])].equipment; };
      for (size_t k = i + 2; k < p.size() && owner(i) == owner(i + 1); ++k) {
        if (owner(k) != owner(i)) std::swap(p[i + 1], p[k]);
      }
      if (owner(i) == owner(i + 1)) {
        battery_limit_nozzles_.push_back(p[i]);
        --i;  // p[i + 1] pairs with the next one
        continue;
      }
      process_pairs_.push_back({p[i], p[i + 1]});
    }
    for (; i < p.size(); ++i) {
      if (int(process_pairs_.size() + battery_limit_nozzles_.size()) >= room) break;
      battery_limit_nozzles_.push_back(p[i]);
    }
  }
  // Drops fill the rest: to utility nozzles first, then to utility stations.
  const int drops = std::max(
      0, lines - fixed_lines - int(process_pairs_.size()) - int(battery_limit_nozzles_.size()));
  header_drops_.assign(size_t(headers), {});
  rng_.shuffle(utility);
  for (int d = 0; d < drops; ++d) {
    Drop drop;
    drop.header = d % std::max(1, headers);
    drop.bore = rng_.range(2, 5);
    if (d < int(utility.size())) {
      drop.nozzle = utility[size_t(d)];
      drop.bore = unit_.nozzles[size_t(drop.nozzle)].bore;
      drop.x = unit_.nozzles[size_t(drop.nozzle)].position.x;
      // A header on the nozzle's rack (header h runs on rack h % racks).
      const int racks = int(unit_.racks.size());
      const int rack = rack_of_nozzle(drop.nozzle);
      const int on_rack = (headers - rack + racks - 1) / racks;
      drop.header = on_rack > 0 ? rack + racks * int(rng_.below(uint32_t(on_rack)))
                                : d % std::max(1, headers);
    } else {
      const Rack& rack = unit_.racks[size_t(drop.header % int(unit_.racks.size()))];
      drop.x = rack.x_begin + 1.0 + (rack.x_end - rack.x_begin - 2.0) * rng_.unit();
      drop.side = (drop.header % 2) ? 1 : -1;  // the header's edge of the rack
    }
    header_drops_[size_t(drop.header)].push_back(int(drops_.size()));
    drops_.push_back(drop);
  }
  lines_total_ = headers + 2 * pump_pairs_ + int(process_pairs_.size()) +
                 int(battery_limit_nozzles_.size()) + int(drops_.size());
}

// ---------------------------------------------------------------------------------------------

void Piping::run(const std::function<void(double)>& progress) {
  set_targets();
  plan();
  unit_.piping = true;
  enum Kind : uint8_t { kHeader, kDrop, kSuction, kDischarge, kProcess, kBatteryLimit };
  std::vector<std::pair<Kind, int>> tasks;
  for (int h = 0; h < unit_.spec.utility_headers; ++h) tasks.push_back({kHeader, h});
  std::vector<std::pair<Kind, int>> rest;
  for (int d = 0; d < int(drops_.size()); ++d) rest.push_back({kDrop, d});
  for (int p = 0; p < pump_pairs_; ++p) {
    rest.push_back({kSuction, p});
    rest.push_back({kDischarge, p});
  }
  for (int i = 0; i < int(process_pairs_.size()); ++i) rest.push_back({kProcess, i});
  for (int i = 0; i < int(battery_limit_nozzles_.size()); ++i) rest.push_back({kBatteryLimit, i});
  rng_.shuffle(rest);
  tasks.insert(tasks.end(), rest.begin(), rest.end());
  for (size_t i = 0; i < tasks.size(); ++i) {
    // Plain copies, not a structured binding: the build lambda below captures them (which
    // clang 14 rejects for structured bindings).
    const Kind kind = tasks[i].first;
    const int index = tasks[i].second;
    // Elbows: long radius, or 3D and 5D pulled bends on some lines (not on headers).
    const uint32_t roll = rng_.below(1000);
    bend_factor_ = kind == kHeader                        ? 1.0
                   : roll < unit_.spec.bends_5d_per_mille ? 5.0 / 1.5
                   : roll < unit_.spec.bends_5d_per_mille + unit_.spec.bends_3d_per_mille ? 2.0
                                                                                          : 1.0;
    bool ok = true;
    auto build = [&] {
      switch (kind) {
        case kHeader:
          return build_header(index);
        case kDrop:
          return build_drop(drops_[size_t(index)]);
        case kSuction:
          return build_pump_suction(index);
        case kDischarge:
          return build_pump_discharge(index);
        case kProcess:
          return build_process(process_pairs_[size_t(index)].first,
                               process_pairs_[size_t(index)].second);
        case kBatteryLimit:
          return build_battery_limit(battery_limit_nozzles_[size_t(index)]);
      }
      return false;
    };
    ok = build();
    if (!ok && bend_factor_ > 1.0) {
      // Pulled bends need room; where there is none, long-radius elbows.
      bend_factor_ = 1.0;
      ok = build();
    }
    if (!ok) {
      ++failures_;
      ++lines_done_;
    }
    if (progress && (i % 64 == 63)) progress(double(i + 1) / double(tasks.size()));
  }
  unit_.piping = false;
  unit_.pipelines_skipped += uint32_t(failures_);
}

}  // namespace pipelines

void build_piping(Unit& unit, const std::function<void(double)>& progress) {
  pipelines::Piping piping(unit);
  piping.run(progress);
}

}  // namespace plantview::gen
