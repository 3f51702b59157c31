// Equipment: sizes and places every item of the preset's mix, then builds and emits it with its
// nozzles (the ends that pipelines connect to).
//
// Primitive budget: Su's equipment primitives per unit. Each item is built from a base recipe
// (shell, heads, supports, nozzles) plus details (platforms, ladders with rungs, cage hoops, level
// gauges, burners...) within an allowance, so that the unit total lands on the budget.
//
// This file runs the stage; equipment.h lists the files that hold its steps.
#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "equipment.h"

namespace plantview::gen {

namespace {

using T = EquipmentType;
using items::ItemBuilder;
using items::kTypes;
using items::TypeInfo;

std::string tag_of(const Unit& unit, T type, int seq) {
  std::string s = kTypes[size_t(type)].prefix;
  s += '-';
  s += unit.area;
  s += '-';
  std::string n = std::to_string(seq);
  s += std::string(n.size() < 3 ? 3 - n.size() : 0, '0') + n;
  return s;
}

}  // namespace

void build_equipment(Unit& unit) {
  // 1. The mix, tagged, with pumps in A/B pairs.
  // Sequence numbers per tag prefix (vertical and horizontal drums share "V").
  int seq[kEquipmentTypeCount] = {};
  auto prefix_index = [](T type) {
    for (int t = 0; t < kEquipmentTypeCount; ++t) {
      if (std::string_view(kTypes[size_t(t)].prefix) == kTypes[size_t(type)].prefix) return t;
    }
    return int(type);
  };
  int pairs = 0;
  for (int t = 0; t < kEquipmentTypeCount; ++t) {
    const int count = unit.spec.equipment_mix[size_t(t)];
    const T type = T(t);
    for (int i = 0; i < count; ++i) {
      EquipmentRecord e;
      e.type = type;
      int& n = seq[prefix_index(type)];
      if (type == T::pump) {
        if (i % 2 == 0) ++n;
        e.pump_pair = pairs + i / 2;
        e.pump_letter = char('A' + i % 2);
        e.tag = tag_of(unit, type, n) + e.pump_letter;
      } else {
        e.tag = tag_of(unit, type, ++n);
      }
      unit.equipment.push_back(std::move(e));
    }
    if (type == T::pump) pairs += count / 2;
  }
  int saddled = unit.spec.exchangers_on_saddles;
  for (EquipmentRecord& e : unit.equipment) {
    if (e.type == T::exchanger && saddled > 0) {
      e.on_saddles = true;
      --saddled;
    }
  }
  // Exchangers not on saddles stand in stacks of three where the plot is dense.
  if (unit.spec.equipment_scale < 1.0) {
    int below = -1, height = 0;
    for (size_t i = 0; i < unit.equipment.size(); ++i) {
      EquipmentRecord& e = unit.equipment[i];
      if (e.type != T::exchanger || e.on_saddles) continue;
      if (below >= 0 && height < 3) {
        e.stacked_on = below;
        ++height;
      } else {
        height = 1;
      }
      below = int(i);
    }
  }
  // 2. Sizes and places, shrinking until the plot holds everything (the last try lets a full
  // band grow beyond its edge).
  double shrink = unit.spec.equipment_scale;
  for (int attempt = 0;; ++attempt) {
    for (EquipmentRecord& e : unit.equipment) items::size_item(unit, e, shrink);
    for (EquipmentRecord& e : unit.equipment) {
      if (e.stacked_on >= 0) {
        // Same shell as the one below, on top of it.
        const EquipmentRecord& b = unit.equipment[size_t(e.stacked_on)];
        e.diameter = b.diameter;
        e.length = b.length;
        e.size_x = b.size_x;
        e.size_y = b.size_y;
      }
    }
    if (items::place_all(unit, attempt == 6)) break;
    shrink *= 0.92;
  }
  for (EquipmentRecord& e : unit.equipment) {
    if (e.stacked_on >= 0) {
      const EquipmentRecord& b = unit.equipment[size_t(e.stacked_on)];
      e.elevation = b.elevation + b.diameter + 2.1;
    }
  }
  // The two pumps of a pair are the same model.
  for (size_t i = 0; i + 1 < unit.equipment.size(); ++i) {
    EquipmentRecord& a = unit.equipment[i];
    if (a.type != T::pump || a.pump_letter != 'A') continue;
    EquipmentRecord& b = unit.equipment[i + 1];
    a.pump_bore = b.pump_bore = std::max(unit.spec.line_bore_min - 1, unit.rng.range(4, 8));
    b.diameter = a.diameter;
  }
  // 3. Builds in a shuffled order, spreading the detail budget by weight.
  std::vector<uint32_t> order(unit.equipment.size());
  for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  unit.rng.shuffle(order);
  int64_t base_left = 0, weight_left = 0;
  for (const EquipmentRecord& e : unit.equipment) {
    base_left += kTypes[size_t(e.type)].base_primitives;
    weight_left += kTypes[size_t(e.type)].detail_weight;
  }
  const int64_t budget = unit.info.equipment_primitives;
  const std::pair<Tally, PrimitiveKind> kinds[] = {{kBox, PrimitiveKind::box},
                                                   {kWedge, PrimitiveKind::pyramid},
                                                   {kPrism, PrimitiveKind::prism},
                                                   {kCylinder, PrimitiveKind::cylinder},
                                                   {kTorus, PrimitiveKind::circular_torus},
                                                   {kRectTorus, PrimitiveKind::rectangular_torus},
                                                   {kSphere, PrimitiveKind::sphere},
                                                   {kSaddle, PrimitiveKind::saddle},
                                                   {kDish, PrimitiveKind::elliptical_dish}};
  for (auto [t, k] : kinds) unit.kind_targets[t] = unit.info.kind_primitives[size_t(k)];
  // Details' kinds follow the plant's mix, scaled to the equipment's share of Su's primitives.
  const double share = double(budget) / double(unit.info.su_primitives);
  unit.detail_ledger.set_target(
      kBox, int64_t(1.1 * share * unit.info.kind_primitives[size_t(PrimitiveKind::box)]));
  unit.detail_ledger.set_target(
      kCylinder, int64_t(1.5 * share * unit.info.kind_primitives[size_t(PrimitiveKind::cylinder)]));
  uint64_t built = 0;
  for (uint32_t i : order) {
    unit.detail_ledger.set_progress(++built, order.size());
    EquipmentRecord& e = unit.equipment[i];
    const TypeInfo& ti = kTypes[size_t(e.type)];
    const int64_t spent = unit.primitives_by_class[size_t(ObjectClass::equipment)];
    const int64_t pool = budget - spent - base_left;
    const int allowance =
        weight_left > 0 && pool > 0 ? int(pool * ti.detail_weight / weight_left) : 0;
    base_left -= ti.base_primitives;
    weight_left -= ti.detail_weight;
    ItemBuilder it(unit, i, allowance);
    e.description = items::description_of(unit.rng, e.type);
    items::build_item(unit, it);
    it.finish(e.description.c_str());
  }
}

}  // namespace plantview::gen
