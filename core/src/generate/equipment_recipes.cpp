// Equipment recipes: one per type. Each places its primitives around rec().centre (on grade) and
// lists its nozzles, from a base (shell, heads, supports, process nozzles) and then details while
// the item's allowance lasts. Rule: a recipe draws every dimension it needs from the record or
// the unit's Rng, in a fixed order.
#include "equipment.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace plantview::gen::items {

using T = EquipmentType;

namespace {

const char* const kColumnServices[] = {
    "Demethanizer", "Deethanizer",  "Depropanizer",  "Debutanizer", "C2 splitter",
    "C3 splitter",  "Quench tower", "Caustic tower", "Stripper",    "Absorber"};
const char* const kDrumServices[] = {"Reflux drum", "Feed surge drum", "Knock-out drum",
                                     "Flash drum",  "Condensate drum", "Suction drum",
                                     "Separator",   "Blowdown drum"};
const char* const kExchangerServices[] = {"Reboiler",    "Condenser", "Feed/effluent exchanger",
                                          "Trim cooler", "Preheater", "Product cooler"};
const char* const kPumpServices[] = {"Reflux pump",  "Bottoms pump",    "Feed pump",
                                     "Product pump", "Quench oil pump", "Condensate pump"};

template <size_t N>
const char* pick(Rng& rng, const char* const (&list)[N]) {
  return list[rng.below(uint32_t(N))];
}

// Nozzle bores: process connections within the preset's line sizes, utilities small.
int process_bore(Unit& unit) {
  return unit.rng.range(unit.spec.line_bore_min, unit.spec.line_bore_max);
}
int utility_bore(Unit& unit) { return unit.rng.range(2, 4); }

// Direction from an item toward its rack (pipes leave that way), and along the rack.
dvec3 toward_rack(const Unit& unit, const EquipmentRecord& e) {
  if (e.band < 0) return kY;
  return dvec3(0, -unit.bands[size_t(e.band)].side, 0);
}

void build_column(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const dvec3 in = toward_rack(unit, e);
  const double r = 0.5 * e.diameter;
  const double pedestal = 0.6, skirt = it.rng().metres(2500, 4000);
  const double z_b = pedestal + skirt;
  if (it.kind_room(kPrism, 1, 0.8)) {
    b.prism(c, kUp, 8, 0.55 * e.diameter + 0.5, pedestal);
  } else {
    b.box_axes(c - dvec3(0.55 * e.diameter + 0.4, 0.55 * e.diameter + 0.4, 0.0),
               c + dvec3(0.55 * e.diameter + 0.4, 0.55 * e.diameter + 0.4, pedestal));
  }
  b.cylinder(c + kUp * pedestal, c + kUp * z_b, r);
  b.dish(c + kUp * z_b, kDown, r, 0.5 * r);
  // Shell, narrowing through a cone on tall columns.
  double r_top = r;
  const double z_t = e.height - 0.5 * r;
  if (e.height > 20.0 && it.rng().chance(600)) {
    r_top = 0.75 * r;
    const double z_m = z_b + 0.55 * (z_t - z_b);
    b.cylinder(c + kUp * z_b, c + kUp * z_m, r);
    b.snout(c + kUp * z_m, c + kUp * (z_m + 1.2), r, r_top, kUp);
    b.cylinder(c + kUp * (z_m + 1.2), c + kUp * z_t, r_top);
  } else {
    b.cylinder(c + kUp * z_b, c + kUp * z_t, r);
  }
  b.dish(c + kUp * z_t, kUp, r_top, 0.5 * r_top);
  // Nozzles: vapour outlet on top, bottoms outlet toward the rack, feeds and draws on the side.
  it.nozzle(c + kUp * (z_t + 0.5 * r_top - 0.02), kUp, std::min(process_bore(unit) + 2, 14), 0.4,
            NozzleRole::top);
  it.nozzle(c + kUp * (z_b + 0.5) + in * (r - 0.02), in, process_bore(unit), 0.35,
            NozzleRole::outlet_bottom);
  const int sides = 3 + int(it.rng().below(4));
  for (int i = 0; i < sides; ++i) {
    const double z = z_b + 1.5 + (z_t - z_b - 2.5) * (double(i) + 0.5) / double(sides);
    const dvec3 d = kCardinal[it.rng().below(4)];
    const double rr = z > z_b + 0.55 * (z_t - z_b) ? r_top : r;
    it.nozzle(c + kUp * z + d * (rr - 0.02), d, process_bore(unit), 0.3, NozzleRole::process);
  }
  it.nozzle(c + kUp * (z_b + 1.0) - in * (r - 0.02), -in, utility_bore(unit), 0.25,
            NozzleRole::utility);
  const dvec3 radial = kCardinal[it.rng().below(4)];
  it.head_nozzle(c + kUp * z_t, kUp, radial, r_top, utility_bore(unit) + 1, NozzleRole::top);
  // Details: platforms every 5.5 m with ladders between them, rungs and cage hoops.
  const dvec3 ladder_dir = -in;
  double z_prev = 0.0;
  if (it.afford(40)) {
    // A stair up to the first platform along the column's side.
    const dvec3 t = glm::cross(kUp, ladder_dir);
    const double z1 = std::min(z_b + 1.5, 6.0);
    it.stair(c + ladder_dir * (r + 1.8) - t * (0.5 * z1), t, 0.0, z1);
  }
  for (double z = z_b + 1.5; z < z_t - 0.5 && it.afford(4); z += 5.5) {
    const double rr = z > z_b + 0.55 * (z_t - z_b) ? r_top : r;
    it.ring_platform(rr, z, glm::cross(kUp, ladder_dir));
    it.ladder(c + ladder_dir * (rr + 0.8), ladder_dir, z_prev, z, it.round());
    z_prev = z;
  }
  for (double z = z_b + 2.5; z < z_t - 1.0; z += 8.0) {
    const double rr = z > z_b + 0.55 * (z_t - z_b) ? r_top : r;
    it.manway(c + kUp * z + ladder_dir * (rr - 0.02), ladder_dir);
  }
  it.extra_head_nozzles(c + kUp * z_t, kUp, r_top);
  while (it.afford(2) && e.nozzles.size() < 16) {
    const double z = z_b + 1.0 + (z_t - z_b - 2.0) * it.rng().unit();
    const dvec3 d = kCardinal[it.rng().below(4)];
    const double rr = z > z_b + 0.55 * (z_t - z_b) ? r_top : r;
    it.nozzle(c + kUp * z + d * (rr - 0.02), d, utility_bore(unit), 0.25, NozzleRole::utility);
    it.spend(2);
  }
}

void build_vertical_drum(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const dvec3 in = toward_rack(unit, e);
  const double r = 0.5 * e.diameter;
  const bool skirt = e.diameter >= 2.0;
  const double z_b = skirt ? 0.6 + it.rng().metres(2000, 3000) : it.rng().metres(2000, 3200);
  const double z_t = z_b + e.height;
  if (skirt) {
    if (it.kind_room(kPrism, 1, 0.8)) {
      b.prism(c, kUp, 8, 0.55 * e.diameter + 0.45, 0.6);
    } else {
      b.box_axes(c - dvec3(0.55 * e.diameter + 0.3, 0.55 * e.diameter + 0.3, 0.0),
                 c + dvec3(0.55 * e.diameter + 0.3, 0.55 * e.diameter + 0.3, 0.6));
    }
    b.cylinder(c + kUp * 0.6, c + kUp * z_b, r);
  } else {
    for (int i = 0; i < 4; ++i) {
      const dvec3 d = (kCardinal[i] + kCardinal[(i + 1) % 4]) * (0.70710678 * (r + 0.02));
      b.box_axes(c + d + dvec3(-0.09, -0.09, 0.0), c + d + dvec3(0.09, 0.09, z_b + 0.3));
    }
  }
  b.dish(c + kUp * z_b, kDown, r, 0.5 * r);
  b.cylinder(c + kUp * z_b, c + kUp * z_t, r);
  b.dish(c + kUp * z_t, kUp, r, 0.5 * r);
  it.nozzle(c + kUp * (z_t + 0.5 * r - 0.02), kUp, process_bore(unit), 0.3, NozzleRole::top);
  if (skirt) {
    it.nozzle(c + kUp * (z_b + 0.35) + in * (r - 0.02), in, process_bore(unit), 0.3,
              NozzleRole::outlet_bottom);
  } else {
    it.nozzle(c + kUp * (z_b - 0.5 * r + 0.02), kDown, process_bore(unit), 0.25,
              NozzleRole::outlet_bottom);
  }
  const int sides = 1 + int(it.rng().below(3));
  for (int i = 0; i < sides; ++i) {
    const double z = z_b + e.height * (0.25 + 0.5 * double(i) / double(sides));
    const dvec3 d = kCardinal[it.rng().below(4)];
    it.nozzle(c + kUp * z + d * (r - 0.02), d, process_bore(unit), 0.25, NozzleRole::process);
  }
  it.nozzle(c + kUp * (z_b + 0.4 * e.height) - in * (r - 0.02), -in, utility_bore(unit), 0.2,
            NozzleRole::utility);
  if (it.rng().chance(500)) {
    it.head_nozzle(c + kUp * z_t, kUp, kCardinal[it.rng().below(4)], r, utility_bore(unit) + 1,
                   NozzleRole::top);
  }
  // Details: a level gauge, a top platform and its ladder.
  if (it.afford(3)) {
    const dvec3 g = c + kCardinal[1] * (r + 0.3);
    b.cylinder(g + kUp * (z_b + 0.3), g + kUp * (z_t - 0.3), 0.04);
    b.cylinder(g + kUp * (z_b + 0.5) - kCardinal[1] * 0.3, g + kUp * (z_b + 0.5), 0.02);
    b.cylinder(g + kUp * (z_t - 0.5) - kCardinal[1] * 0.3, g + kUp * (z_t - 0.5), 0.02);
    it.spend(3);
  }
  it.manway(c + kUp * (z_b + 0.8) - in * (r - 0.02), -in);
  it.lifting_lugs(c + kUp * (z_t + 0.45 * r), kX, 0.3 * r);
  it.extra_side_nozzles(r, z_b + 0.5, z_t - 0.3, 8);
  it.extra_head_nozzles(c + kUp * z_t, kUp, r);
  const double deck = z_t + 0.5 * r + 0.1;
  if (it.afford(12)) {
    it.top_platform(e.diameter + 0.6, e.diameter + 0.6, deck);
    const dvec3 t = glm::cross(kUp, in);
    if (it.afford(deck / 0.2 + 4)) {
      it.stair(c - in * (r + 1.0) - t * deck, t, 0.0, deck);
    } else {
      it.ladder(c - in * (r + 0.7), -in, 0.0, deck, it.round());
    }
  }
}

void build_horizontal_drum(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double r = 0.5 * e.diameter, half = 0.5 * e.length;
  const double width = 0.8 * e.diameter, cradle = r + 0.01;
  const double saddle_h = it.rng().metres(2300, 3000);
  const double z = saddle_h + std::sqrt(cradle * cradle - 0.25 * width * width);
  const dvec3 axis_c = c + kUp * z;
  b.cylinder(axis_c - kX * half, axis_c + kX * half, r);
  b.dish(axis_c - kX * half, -kX, r, 0.5 * r);
  b.dish(axis_c + kX * half, kX, r, 0.5 * r);
  for (double s : {-0.6, 0.6}) b.saddle(c + kX * (s * half), kX, 0.3, width, saddle_h, cradle);
  it.nozzle(axis_c + kX * (-0.6 * half) + kUp * (r - 0.02), kUp, process_bore(unit), 0.3,
            NozzleRole::top);
  it.nozzle(axis_c + kX * (0.6 * half) + kUp * (r - 0.02), kUp, process_bore(unit), 0.3,
            NozzleRole::top);
  it.nozzle(axis_c + kUp * (r - 0.02), kUp, utility_bore(unit), 0.3, NozzleRole::utility);
  if (it.rng().chance(400) && it.afford(3)) {
    // A boot under the drum collects water; the outlet leaves from its bottom.
    const double rb = std::min(0.35, 0.3 * r);
    const dvec3 boot = axis_c + kX * (0.3 * half);
    b.cylinder(boot - kUp * (r - 0.05), boot - kUp * (r + 0.45), rb);
    it.nozzle(boot - kUp * (r + 0.45), kDown, process_bore(unit), 0.15, NozzleRole::outlet_bottom);
    it.spend(1);
  } else {
    it.nozzle(axis_c + kX * (0.3 * half) - kUp * (r - 0.02), kDown, process_bore(unit), 0.25,
              NozzleRole::outlet_bottom);
  }
  it.nozzle(axis_c - kX * (half + 0.5 * r - 0.02), -kX, process_bore(unit), 0.25,
            NozzleRole::process);
  it.manway(axis_c + kX * (half + 0.5 * r - 0.1), kX);
  it.lifting_lugs(axis_c + kUp * r, kX, 0.5 * half);
  const double deck = z + r + 0.1;
  if (it.afford(12)) {
    it.top_platform(std::min(3.0, e.length * 0.5), e.diameter * 0.7, deck);
    const dvec3 foot = c + kY * (r + 0.9) - kX * (0.5 * half + deck);
    if (it.afford(30)) {
      it.stair(foot, kX, 0.0, deck);
    } else {
      it.ladder(c + kX * (0.25 * half) + kY * (r + 0.6), kY, 0.0, deck, it.round());
    }
  }
}

void build_exchanger(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double r = 0.5 * e.diameter, half = 0.5 * e.length;
  const double z = e.elevation + r + (e.stacked_on >= 0 ? 0.35 : it.rng().metres(1600, 2000));
  const dvec3 a = c + kUp * z;
  // Shell from -x (channel side) to +x (rear head).
  const dvec3 front = a - kX * half, rear = a + kX * half;
  b.cylinder(front, rear, r);
  b.dish(rear, kX, r, 0.5 * r);
  b.cylinder(front, front - kX * 0.12, r + 0.1);               // shell flange
  b.cylinder(front - kX * 0.12, front - kX * 0.92, r + 0.03);  // channel
  b.cylinder(front - kX * 0.92, front - kX * 1.04, r + 0.1);   // channel flange
  b.dish(front - kX * 1.04, -kX, r + 0.03, 0.25 * r);          // channel cover
  if (e.on_saddles) {
    const double width = 0.8 * e.diameter, cradle = r + 0.01;
    const double h = z - std::sqrt(cradle * cradle - 0.25 * width * width);
    for (double s : {-0.55, 0.55}) b.saddle(c + kX * (s * half), kX, 0.25, width, h, cradle);
  } else {
    // Concrete piers (or the shell below) and steel support plates up to the shell.
    const double base = e.stacked_on >= 0 ? e.elevation - 0.1 : 0.0;
    for (double s : {-0.55, 0.55}) {
      const dvec3 p = c + kX * (s * half);
      b.box_axes(p + dvec3(-0.3, -0.5 * e.diameter - 0.1, base),
                 p + dvec3(0.3, 0.5 * e.diameter + 0.1, base + 0.3));
      b.box_axes(p + dvec3(-0.1, -0.4 * e.diameter, base + 0.3),
                 p + dvec3(0.1, 0.4 * e.diameter, z - 0.5 * r));
    }
  }
  const int bore = std::max(unit.spec.line_bore_min,
                            std::min(bore_at_least(0.3 * e.diameter), unit.spec.line_bore_max));
  it.nozzle(rear - kX * 0.5 + kUp * (r - 0.02), kUp, bore, 0.25, NozzleRole::process);
  it.nozzle(front + kX * 0.5 - kUp * (r - 0.02), kDown, bore, 0.2, NozzleRole::process);
  it.nozzle(front - kX * 0.5 + kUp * (r + 0.01), kUp, bore, 0.25, NozzleRole::process);
  it.nozzle(front - kX * 0.5 - kUp * (r + 0.01), kDown, bore, 0.2, NozzleRole::process);
  // Details: studs on the body flanges, vent and drain on the shell, lifting lugs.
  it.body_flange_bolts(front - kX * 0.06, kX, r + 0.1, 0.12);
  it.body_flange_bolts(front - kX * 0.98, kX, r + 0.1, 0.12);
  if (it.afford(4)) {
    it.nozzle(a + kUp * (r - 0.02), kUp, 2, 0.15, NozzleRole::utility);
    it.nozzle(a + kX * (0.5 * half) - kUp * (r - 0.02), kDown, 2, 0.15, NozzleRole::utility);
    it.spend(4);
  }
  if (it.afford(2)) {
    for (double s : {-0.3, 0.3}) {
      b.wedge(a + kX * (s * half) + kUp * (r - 0.01), kY, kUp, 0.12, 0.02, 0.15);
    }
    it.spend(2);
  }
  // A platform at the channel end for opening the cover.
  if (e.stacked_on < 0) it.end_platform(front - kX * 1.6 + kUp * (r - 0.3), -kX, e.diameter + 0.8);
  // Anchor bolts through the support feet.
  for (double s : {-0.55, 0.55}) {
    for (double sy : {-1.0, 1.0}) {
      if (!it.afford(2) || e.stacked_on >= 0) break;
      const dvec3 p = c + kX * (s * half) + kY * (sy * 0.35 * e.diameter);
      for (double dx : {-0.2, 0.2}) b.cylinder(p + kX * dx, p + kX * dx + kUp * 0.12, 0.012);
      it.spend(2);
    }
  }
}

void build_pump(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const dvec3 s = -toward_rack(unit, e);  // shaft axis: casing away from the rack
  const dvec3 side = glm::cross(kUp, s);
  const double rc = 0.5 * e.diameter * 0.6;
  const double hs = 0.35 + rc + 0.1;
  b.box(c + kUp * 0.125, side, kUp, dvec3(0.9, 2.6, 0.25));
  b.box(c + kUp * 0.3, side, kUp, dvec3(0.8, 2.4, 0.1));
  const dvec3 shaft = c + kUp * hs;
  b.cylinder(shaft + s * 0.55, shaft + s * 0.85, rc);         // volute
  b.cylinder(shaft + s * 0.05, shaft + s * 0.55, 0.11);       // bearing frame
  b.box(shaft - s * 0.15, side, kUp, dvec3(0.3, 0.35, 0.3));  // coupling guard
  const double rm = 0.2 + 0.1 * it.rng().unit();
  b.cylinder(shaft - s * 0.32, shaft - s * 1.05, rm);        // motor
  b.cylinder(shaft - s * 1.05, shaft - s * 1.2, rm + 0.02);  // fan cowl
  b.box(shaft - s * 0.6 + kUp * (rm + 0.08), side, kUp, dvec3(0.2, 0.2, 0.16));
  const int suction = e.pump_bore;
  it.nozzle(shaft + s * 0.85, s, suction, 0.12, NozzleRole::pump_suction);
  it.nozzle(shaft + s * 0.7 + kUp * (rc - 0.02), kUp, std::max(3, suction - 1), 0.15,
            NozzleRole::pump_discharge);
}

void build_compressor(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double r = 0.5 * e.diameter, half = 0.5 * e.length;
  b.box_axes(c + dvec3(-0.5 * e.size_x + 0.3, -r - 0.8, 0.0),
             c + dvec3(0.5 * e.size_x - 0.3, r + 0.8, 0.6));
  b.box_axes(c + dvec3(-0.5 * e.size_x + 0.4, -r - 0.6, 0.6),
             c + dvec3(0.5 * e.size_x - 0.4, r + 0.6, 0.8));
  const dvec3 a = c + kUp * (0.8 + r + 0.2) + kX * 1.0;
  b.cylinder(a - kX * half, a + kX * half, r);
  b.cylinder(a - kX * (half + 0.4), a - kX * half, 0.35 * r);
  b.cylinder(a + kX * half, a + kX * (half + 0.4), 0.35 * r);
  b.box(a - kX * (half + 0.7), kX, kUp, dvec3(0.5, 0.6, 0.6));
  const dvec3 d = a - kX * (half + 2.0);
  b.cylinder(d + kX * 1.0, d - kX * 1.0, 0.75 * r);  // driver
  b.box(c + dvec3(0.5 * e.size_x - 1.0, r + 0.4, 1.4), kX, kUp, dvec3(1.2, 0.8, 1.2));
  it.nozzle(a - kX * (0.5 * half) + kUp * (r - 0.02), kUp, std::min(process_bore(unit) + 3, 15),
            0.4, NozzleRole::process);
  it.nozzle(a + kX * (0.5 * half) + kUp * (r - 0.02), kUp, std::min(process_bore(unit) + 2, 14),
            0.4, NozzleRole::process);
  it.nozzle(a + kX * (0.2 * half) - kY * (r - 0.02), -kY, utility_bore(unit), 0.2,
            NozzleRole::utility);
  if (it.afford(6)) {
    it.top_platform(e.length, 0.8, 0.8 + 2 * r + 0.6);
    it.spend(1);
  }
}

void build_air_cooler(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const Rack& rack = unit.racks[0];
  const dvec3 c = e.centre;
  const double w = rack.width, z0 = rack.tiers.back() + 2.2;
  // Legs from the top tier, plenum, two bundles with their headers, two fans.
  for (double sx : {-2.9, 2.9}) {
    for (double sy : {-0.5 * w + 0.1, 0.5 * w - 0.1}) {
      b.box_axes(c + dvec3(sx - 0.1, sy - 0.1, rack.tiers.back()),
                 c + dvec3(sx + 0.1, sy + 0.1, z0));
    }
  }
  b.box_axes(c + dvec3(-2.9, -0.5 * w, z0), c + dvec3(2.9, 0.5 * w, z0 + 0.2));
  for (double sx : {-1.45, 1.45}) {
    b.box_axes(c + dvec3(sx - 1.35, -0.5 * w + 0.4, z0 + 0.2),
               c + dvec3(sx + 1.35, 0.5 * w - 0.4, z0 + 0.5));
    for (double sy : {-0.5 * w + 0.2, 0.5 * w - 0.2}) {
      b.box_axes(c + dvec3(sx - 1.4, sy - 0.2, z0 + 0.15),
                 c + dvec3(sx + 1.4, sy + 0.2, z0 + 0.55));
    }
  }
  const double fan_r = std::min(1.4, 0.5 * w - 0.6);
  for (double sx : {-1.45, 1.45}) {
    b.cylinder(c + dvec3(sx, 0, z0 - 0.7), c + dvec3(sx, 0, z0 - 0.1), fan_r);
    b.cylinder(c + dvec3(sx, 0, z0 - 1.6), c + dvec3(sx, 0, z0 - 0.8), 0.22);
  }
  const int bore = process_bore(unit);
  it.nozzle(c + dvec3(-1.45, -0.5 * w + 0.2, z0 + 0.55), kUp, bore, 0.2, NozzleRole::top);
  it.nozzle(c + dvec3(1.45, 0.5 * w - 0.2, z0 + 0.55), kUp, bore, 0.2, NozzleRole::top);
  // Details: a walkway along one side with its rails, louvres.
  if (it.afford(3)) {
    b.box_axes(c + dvec3(-3.0, 0.5 * w, z0 + 0.1), c + dvec3(3.0, 0.5 * w + 0.8, z0 + 0.15));
    b.box_axes(c + dvec3(-3.0, 0.5 * w + 0.75, z0 + 1.15), c + dvec3(3.0, 0.5 * w + 0.8, z0 + 1.2));
    b.box_axes(c + dvec3(-3.0, 0.5 * w + 0.75, z0 + 0.6), c + dvec3(3.0, 0.5 * w + 0.8, z0 + 0.65));
    it.spend(3);
  }
  for (double y = -0.5 * w + 0.6; y < 0.5 * w - 0.5 && it.afford(1); y += 0.4) {
    b.box_axes(c + dvec3(-2.8, y, z0 + 0.6), c + dvec3(2.8, y + 0.05, z0 + 0.7));
    it.spend(1);
  }
  // Plugs on the headers' outer faces, one per tube row.
  for (double sx : {-1.45, 1.45}) {
    for (double x = -1.3; x <= 1.3 && it.afford(2); x += 0.26) {
      for (double sy : {-1.0, 1.0}) {
        const dvec3 p = c + dvec3(sx + x, sy * (0.5 * w), z0 + 0.35);
        b.box(p, kX, kUp, dvec3(0.04, 0.03, 0.04));
      }
      it.spend(2);
    }
  }
}

void build_furnace(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double lx = e.length, ly = e.size_y - 1.5;
  const double fire_h = std::min(12.0, 0.45 * e.height), conv_h = 3.0;
  b.box_axes(c + dvec3(-0.5 * lx, -0.5 * ly, 1.8), c + dvec3(0.5 * lx, 0.5 * ly, 1.8 + fire_h));
  const double z_c = 1.8 + fire_h;
  b.box_axes(c + dvec3(-0.35 * lx, -0.35 * ly, z_c), c + dvec3(0.35 * lx, 0.35 * ly, z_c + conv_h));
  // Hood: two wedges meeting under the stack.
  const double z_h = z_c + conv_h;
  b.wedge(c + dvec3(0, 0, z_h), kX, kUp, 0.35 * lx, 0.7 * ly, 1.5);
  b.wedge(c + dvec3(0, 0, z_h), -kX, kUp, 0.35 * lx, 0.7 * ly, 1.5);
  b.cylinder(c + kUp * (z_h + 1.2), c + kUp * e.height, 0.5 * e.diameter);
  // Legs under the firebox (burners fire from below).
  for (double sx : {-0.45, 0.45}) {
    for (double sy : {-0.45, 0.45}) {
      const dvec3 p = c + dvec3(sx * lx, sy * ly, 0);
      b.box_axes(p - dvec3(0.15, 0.15, 0), p + dvec3(0.15, 0.15, 1.8));
    }
  }
  const dvec3 in = toward_rack(unit, e);
  const int bore = process_bore(unit);
  for (double sx : {-0.25, 0.25}) {
    it.nozzle(c + dvec3(sx * lx, 0, z_c + 1.5) + in * (0.35 * ly), in, bore, 0.3,
              NozzleRole::process);
    it.nozzle(c + dvec3(sx * lx, 0, 1.8 + 0.5 * fire_h) + in * (0.5 * ly), in, bore, 0.3,
              NozzleRole::process);
  }
  // Details: floor burners in four rows, a platform with its stair.
  for (int i = 0; i < 32 && it.afford(1); ++i) {
    const dvec3 p =
        c + dvec3((double(i % 8) - 3.5) / 8.0 * lx, (double(i / 8) - 1.5) * 0.2 * ly, 0);
    b.cylinder(p + kUp * 1.0, p + kUp * 1.8, 0.15);
    it.spend(1);
  }
  if (it.afford(6)) {
    b.box_axes(c + dvec3(-0.5 * lx, -0.5 * ly - 1.0, z_c - 0.05),
               c + dvec3(0.5 * lx, -0.5 * ly, z_c));
    it.spend(1);
    if (it.afford(60)) {
      it.stair(c + dvec3(-0.5 * lx - z_c, -0.5 * ly - 0.6, 0), kX, 0.0, z_c);
    } else {
      it.ladder(c + dvec3(-0.5 * lx - 0.6, -0.5 * ly - 0.5, 0), -kX, 0.0, z_c, it.round());
    }
  }
  for (double z = 2.6; z < 1.8 + fire_h - 0.5 && it.afford(2); z += 1.6) {
    // Peep doors on both long sides.
    b.box(c + dvec3(0, -0.5 * ly - 0.05, z), kX, kUp, dvec3(0.3, 0.1, 0.3));
    b.box(c + dvec3(0, 0.5 * ly + 0.05, z), kX, kUp, dvec3(0.3, 0.1, 0.3));
    it.spend(2);
  }
}

void build_filter(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double r = 0.5 * e.diameter, z0 = 0.6, z1 = z0 + e.height;
  for (int i = 0; i < 3; ++i) {
    const dvec3 d = kCardinal[i] * (r * 0.8);
    b.box_axes(c + d + dvec3(-0.05, -0.05, 0.0), c + d + dvec3(0.05, 0.05, z0 + 0.3));
  }
  b.cylinder(c + kUp * z0, c + kUp * z1, r);
  b.cylinder(c + kUp * (z0 - 0.05), c + kUp * z0, r);
  b.cylinder(c + kUp * z1, c + kUp * (z1 + 0.1), r + 0.08);
  b.cylinder(c + kUp * (z1 + 0.1), c + kUp * (z1 + 0.16), r + 0.08);
  it.body_flange_bolts(c + kUp * (z1 + 0.08), kUp, r + 0.08, 0.16);
  const dvec3 in = toward_rack(unit, e);
  const int bore = std::min(process_bore(unit), 7);
  it.nozzle(c + kUp * (z1 - 0.3) + in * (r - 0.02), in, bore, 0.2, NozzleRole::process);
  it.nozzle(c + kUp * (z0 + 0.3) + in * (r - 0.02), in, bore, 0.2, NozzleRole::process);
  it.lifting_lugs(c + kUp * (z1 + 0.16), kX, 0.5 * r);
  it.extra_side_nozzles(r, z0 + 0.5, z1 - 0.4, 5);
}

void build_tank(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double r = 0.5 * e.diameter;
  b.rect_torus(c + kUp * 0.2, kUp, kX, r - 0.4, r + 0.4, 0.4, kFullTurn);  // ring wall
  b.cylinder(c + kUp * 0.4, c + kUp * (0.4 + e.height), r);
  b.snout(c + kUp * (0.4 + e.height), c + kUp * (0.4 + e.height + 0.1 * r), r, 0.4, kUp);
  b.rect_torus(c + kUp * (e.height - 0.6), kUp, kX, r, r + 0.6, 0.06, kFullTurn);  // wind girder
  const dvec3 in = toward_rack(unit, e);
  it.nozzle(c + kUp * 0.9 + in * (r - 0.02), in, process_bore(unit), 0.3,
            NozzleRole::outlet_bottom);
  it.nozzle(c + kUp * 1.2 + glm::cross(kUp, in) * (r - 0.02), glm::cross(kUp, in),
            process_bore(unit), 0.3, NozzleRole::process);
  it.nozzle(c + kUp * (0.4 + e.height + 0.05 * r) + in * (0.5 * r), kUp, process_bore(unit), 0.3,
            NozzleRole::top);
  // Details: stair flights up the shell.
  const dvec3 t = glm::cross(kUp, in);
  for (int i = 0; i < 6 && it.afford(1); ++i) {
    const double z = 0.4 + e.height * (i + 0.5) / 6.0;
    b.box(c - in * (r + 0.5) + t * ((i % 2) ? 1.0 : -1.0) + kUp * z, t, kUp, dvec3(2.0, 0.8, 0.05));
    it.spend(1);
  }
}

void build_sphere_tank(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double r = 0.5 * e.diameter, zc = r + 2.2;
  b.sphere(c + kUp * zc, r);
  for (int i = 0; i < 8; ++i) {
    const dvec3 d = i % 2 == 0 ? kCardinal[i / 2]
                               : (kCardinal[i / 2] + kCardinal[(i / 2 + 1) % 4]) * 0.70710678;
    b.cylinder(c + d * r, c + d * r + kUp * zc, 0.25);
  }
  it.nozzle(c + kUp * (zc - r + 0.02), kDown, process_bore(unit), 0.4, NozzleRole::outlet_bottom);
  it.nozzle(c + kUp * (zc + r - 0.02), kUp, process_bore(unit), 0.4, NozzleRole::top);
  if (it.afford(8)) {
    it.top_platform(2.0, 2.0, zc + r + 0.3);
    it.ladder(c - toward_rack(unit, e) * (r + 0.8), -toward_rack(unit, e), 0.0, zc + r, it.round());
  }
}

void build_package(Unit& unit, ItemBuilder& it) {
  EquipmentRecord& e = it.rec();
  ObjectBuilder& b = it.b();
  const dvec3 c = e.centre;
  const double lx = e.size_x, ly = e.size_y;
  b.box_axes(c + dvec3(-0.5 * lx, -0.5 * ly, 0), c + dvec3(0.5 * lx, 0.5 * ly, 0.3));
  const double r = std::min(0.4, 0.2 * ly);
  b.cylinder(c + dvec3(-0.25 * lx, 0, 0.3), c + dvec3(-0.25 * lx, 0, 2.2), r);
  b.cylinder(c + dvec3(-0.25 * lx, 0, 2.2), c + dvec3(-0.25 * lx, 0, 2.26), r + 0.03);
  b.cylinder(c + dvec3(0.05 * lx, 0, 0.3), c + dvec3(0.05 * lx, 0, 1.8), 0.8 * r);
  b.box_axes(c + dvec3(0.25 * lx, -0.4 * ly, 0.3), c + dvec3(0.45 * lx, 0.4 * ly, 2.0));
  const dvec3 in = toward_rack(unit, e);
  const int bore = std::min(process_bore(unit), 6);
  it.nozzle(c + dvec3(-0.25 * lx, 0, 1.0) + in * (r - 0.02), in, bore, 0.2, NozzleRole::process);
  it.nozzle(c + dvec3(0.05 * lx, 0, 0.8) + in * (0.8 * r - 0.02), in, bore, 0.2,
            NozzleRole::process);
  for (int i = 0; i < 6 && it.afford(1); ++i) {
    b.box_axes(c + dvec3(-0.5 * lx + 0.1, 0.5 * ly - 0.1, 0.3 + 0.4 * i),
               c + dvec3(0.5 * lx - 0.1, 0.5 * ly, 0.35 + 0.4 * i));
    it.spend(1);
  }
  it.skid_frame(lx, ly, 2.6);
}

}  // namespace

const char* description_of(Rng& rng, T type) {
  switch (type) {
    case T::column:
      return pick(rng, kColumnServices);
    case T::vertical_drum:
    case T::horizontal_drum:
      return pick(rng, kDrumServices);
    case T::exchanger:
      return pick(rng, kExchangerServices);
    case T::pump:
      return pick(rng, kPumpServices);
    case T::compressor:
      return "Cracked gas compressor";
    case T::air_cooler:
      return "Overhead air condenser";
    case T::furnace:
      return "Cracking furnace";
    case T::filter:
      return "Suction filter";
    case T::tank:
      return "Day tank";
    case T::sphere_tank:
      return "LPG sphere";
    case T::package:
      return "Chemical injection package";
  }
  return "";
}

void build_item(Unit& unit, ItemBuilder& it) {
  switch (it.rec().type) {
    case T::column:
      build_column(unit, it);
      break;
    case T::vertical_drum:
      build_vertical_drum(unit, it);
      break;
    case T::horizontal_drum:
      build_horizontal_drum(unit, it);
      break;
    case T::exchanger:
      build_exchanger(unit, it);
      break;
    case T::pump:
      build_pump(unit, it);
      break;
    case T::compressor:
      build_compressor(unit, it);
      break;
    case T::air_cooler:
      build_air_cooler(unit, it);
      break;
    case T::furnace:
      build_furnace(unit, it);
      break;
    case T::filter:
      build_filter(unit, it);
      break;
    case T::tank:
      build_tank(unit, it);
      break;
    case T::sphere_tank:
      build_sphere_tank(unit, it);
      break;
    case T::package:
      build_package(unit, it);
      break;
  }
}

}  // namespace plantview::gen::items
