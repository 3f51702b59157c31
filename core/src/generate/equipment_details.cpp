// Equipment details: the parts recipes build items from (nozzles, ladders with rungs and cage
// hoops, platforms, bolt rings, manways, stairs, skid frames) and the item's attributes. Rule: a
// detail is added only while the item's allowance pays for all of it, and it spends what it adds;
// kinds piping has little use for (rectangular tori, boxes, cylinders) also stay within the unit's
// share of their targets.
#include "equipment.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace plantview::gen::items {

bool ItemBuilder::kind_room(Tally t, int n, double share) {
  const int64_t here = mix_of(b_.object()).n[t];
  return double(unit_.emitted.n[t] + here + n) <= share * double(unit_.kind_targets[t]);
}

bool ItemBuilder::round() const {
  Mix box, cylinder;
  box.add(kBox);
  cylinder.add(kCylinder);
  const Mix options[] = {box, cylinder};
  return unit_.detail_ledger.choose(options) == 1;
}

void ItemBuilder::post(const dvec3& foot, const dvec3& facing, double height) {
  if (round()) {
    b_.cylinder(foot, foot + kUp * height, 0.024);
  } else {
    b_.box(foot + kUp * (0.5 * height), facing, kUp, dvec3(0.05, 0.05, height));
  }
}

void ItemBuilder::nozzle(const dvec3& base, const dvec3& dir, int bore, double neck,
                         NozzleRole role) {
  const PipeSize& s = pipe_size(bore);
  const dvec3 neck_end = base + dir * neck;
  b_.cylinder(base, neck_end, 0.5 * s.od_m);
  nozzle_end(neck_end, dir, bore, role);
}

void ItemBuilder::head_nozzle(const dvec3& head_base, const dvec3& axis, const dvec3& radial,
                              double radius, int bore, NozzleRole role) {
  const PipeSize& s = pipe_size(bore);
  const dvec3 base = head_base + radial * (0.6 * radius) + axis * (0.4 * radius);
  const dvec3 neck_end = base + axis * (0.35 + 0.2 * radius);
  b_.sheared_cylinder(base, neck_end, 0.5 * s.od_m, radial, -kHeadSlope_rad, 0.0f);
  nozzle_end(neck_end, axis, bore, role);
}

void ItemBuilder::nozzle_end(const dvec3& neck_end, const dvec3& dir, int bore, NozzleRole role) {
  if (welded_end(role)) {
    add_nozzle(neck_end, dir, bore, role, false);
    return;
  }
  const PipeSize& s = pipe_size(bore);
  const dvec3 face = neck_end + dir * s.flange_thk_m;
  b_.cylinder(neck_end, face, 0.5 * s.flange_od_m);
  add_nozzle(face, dir, bore, role, true);
}

bool ItemBuilder::welded_end(NozzleRole role) {
  return e_.type != EquipmentType::pump && e_.type != EquipmentType::compressor &&
         role != NozzleRole::pump_suction && unit_.rng.chance(unit_.spec.welded_nozzles_per_mille);
}

void ItemBuilder::ladder(const dvec3& foot, const dvec3& out, double z0, double z1,
                         bool round_rungs) {
  if (z1 - z0 < 1.0 || !afford(2)) return;
  const dvec3 side = glm::cross(kUp, out);
  for (double s : {-0.23, 0.23}) {
    const dvec3 p = foot + side * s;
    b_.box(dvec3(p.x, p.y, 0.5 * (z0 + z1)), out, kUp, dvec3(0.06, 0.012, z1 - z0));
  }
  spend(2);
  for (double z = z0 + 0.3; z < z1 - 0.1 && afford(1); z += 0.3) {
    const dvec3 c(foot.x, foot.y, z);
    if (round_rungs) {
      b_.cylinder(c - side * 0.23, c + side * 0.23, 0.011);
    } else {
      b_.box(c, out, kUp, dvec3(0.025, 0.46, 0.025));
    }
    spend(1);
  }
  for (double z = z0 + 2.5; z < z1 - 0.5 && afford(1) && kind_room(kRectTorus, 1, 0.75); z += 1.2) {
    b_.rect_torus(dvec3(foot.x, foot.y, z) + out * 0.35, kUp, side, 0.33, 0.38, 0.05, kHalfTurn);
    spend(1);
  }
}

void ItemBuilder::ring_platform(double r, double z, const dvec3& start) {
  if (!afford(2) || !kind_room(kRectTorus, 2, 0.85)) return;
  const dvec3 c(e_.centre.x, e_.centre.y, z);
  b_.rect_torus(c, kUp, start, r + 0.08, r + 1.25, 0.05, kThreeQuarterTurn);
  b_.rect_torus(c + kUp * 1.05, kUp, start, r + 1.2, r + 1.25, 0.05, kThreeQuarterTurn);
  spend(2);
  // Knee braces (tubes, cut square to the shell and to the deck) under the deck's edge.
  for (int i = 0; i < 3 && afford(1); ++i) {
    const dvec3 d = i == 0 ? start : i == 1 ? glm::cross(kUp, start) : -start;
    const dvec3 top = c + d * (r + 1.0) - kUp * 0.03, bottom = c + d * (r + 0.02) - kUp * 1.0;
    b_.sheared_cylinder(bottom, top, 0.03, glm::normalize(d - kUp), -kQuarterPi, kQuarterPi);
    spend(1);
  }
  // Rail posts every eighth of a turn over the three quarters.
  const dvec3 s0 = start, s1 = glm::cross(kUp, start);
  const double c8 = kCos45;
  const dvec3 dirs[7] = {s0, (s0 + s1) * c8, s1, (s1 - s0) * c8, -s0, (-s0 - s1) * c8, -s1};
  for (const dvec3& d : dirs) {
    if (!afford(1)) break;
    const dvec3 p = c + d * (r + 1.225);
    post(p + kUp * 0.005, d, 1.05);
    spend(1);
  }
}

void ItemBuilder::bolt_ring(const dvec3& centre, const dvec3& axis, double circle_r, double length,
                            double stud_r, int count) {
  // Rotation steps of 2 pi / count as literals: no libm call, the same on every machine.
  double c = 0, s = 0;
  switch (count) {
    case 8:
      c = s = kCos45;
      break;
    case 16:
      c = 0.92387953251128674;
      s = 0.38268343236508977;
      break;
    case 24:
      c = 0.96592582628906829;
      s = 0.25881904510252076;
      break;
    default:
      count = 32;
      c = 0.98078528040323043;
      s = 0.19509032201612825;
      break;
  }
  if (!afford(count) || !unit_.detail_ledger.room(kCylinder, count)) return;
  const glm::mat3 f = frame_z(axis);
  const dvec3 u(f[0]), v(f[1]);
  double x = 1.0, y = 0.0;
  for (int i = 0; i < count; ++i) {
    const dvec3 p = centre + (u * x + v * y) * circle_r;
    b_.cylinder(p - axis * (0.5 * length), p + axis * (0.5 * length), stud_r);
    const double xn = x * c - y * s;
    y = x * s + y * c;
    x = xn;
  }
  spend(count);
}

void ItemBuilder::body_flange_bolts(const dvec3& centre, const dvec3& axis, double flange_r,
                                    double thickness) {
  const int count = flange_r < 0.35 ? 8 : flange_r < 0.6 ? 16 : flange_r < 0.9 ? 24 : 32;
  bolt_ring(centre, axis, flange_r - 0.045, thickness + 0.08, flange_r < 0.6 ? 0.01 : 0.016, count);
}

void ItemBuilder::manway(const dvec3& base, const dvec3& dir) {
  if (!afford(18)) return;
  const dvec3 neck_end = base + dir * 0.3, cover_end = neck_end + dir * 0.08;
  b_.cylinder(base, neck_end, 0.3);
  b_.cylinder(neck_end, cover_end, 0.38);
  spend(2);
  bolt_ring(0.5 * (neck_end + cover_end), dir, 0.345, 0.12, 0.012, 16);
}

void ItemBuilder::extra_side_nozzles(double r, double z0, double z1, size_t limit) {
  while (afford(2) && e_.nozzles.size() < limit && z1 > z0) {
    const double z = z0 + (z1 - z0) * rng().unit();
    const dvec3 d = kCardinal[rng().below(4)];
    // Every other one a utility connection (steam-out, purge, flushing).
    const bool utility = e_.nozzles.size() % 2 == 1;
    nozzle(dvec3(e_.centre.x, e_.centre.y, z) + d * (r - 0.02), d,
           utility ? rng().range(2, 4)
                   : rng().range(unit_.spec.line_bore_min, unit_.spec.line_bore_max),
           0.25, utility ? NozzleRole::utility : NozzleRole::process);
    spend(2);
  }
}

void ItemBuilder::lifting_lugs(const dvec3& top_centre, const dvec3& along, double spread) {
  if (!afford(2)) return;
  for (double s : {-1.0, 1.0})
    b_.wedge(top_centre + along * (s * spread), along * s, kUp, 0.15, 0.025, 0.18);
  spend(2);
}

void ItemBuilder::stair(const dvec3& foot, const dvec3& t, double z0, double z1) {
  const double rise = z1 - z0;
  const int treads = int(rise / 0.2);
  if (rise < 1.0 || !afford(4 + treads)) return;
  const dvec3 slope = glm::normalize(t + kUp), normal = glm::normalize(kUp - t);
  const dvec3 side = glm::cross(kUp, t);
  const dvec3 base(foot.x, foot.y, z0);
  const double length = rise * 1.4142135623730951;
  for (double s : {-0.4, 0.4}) {
    b_.box(base + side * s + (t + kUp) * (0.5 * rise), slope, normal, dvec3(length, 0.012, 0.2));
    const dvec3 a = base + side * s + kUp * 0.95, e = a + (t + kUp) * rise;
    b_.sheared_cylinder(a, e, 0.021, glm::normalize(t - kUp), -kQuarterPi, -kQuarterPi);
  }
  for (int i = 1; i <= treads; ++i) {
    const double h = rise * double(i) / double(treads + 1);
    b_.box(base + t * h + kUp * h, t, kUp, dvec3(0.25, 0.8, 0.03));
  }
  spend(4 + treads);
}

void ItemBuilder::extra_head_nozzles(const dvec3& head_base, const dvec3& axis, double r) {
  const double c8 = kCos45;
  for (int i = 0; i < 8 && afford(2); ++i) {
    const dvec3 radial =
        i % 2 == 0 ? kCardinal[i / 2] : (kCardinal[i / 2] + kCardinal[(i / 2 + 1) % 4]) * c8;
    head_nozzle(head_base, axis, radial, r, 2 + int(rng().below(3)), NozzleRole::spare);
    spend(2);
  }
}

void ItemBuilder::top_platform(double sx, double sy, double z) {
  if (!afford(5)) return;
  const dvec3 c(e_.centre.x, e_.centre.y, z);
  b_.box_axes(c - dvec3(0.5 * sx, 0.5 * sy, 0.05), c + dvec3(0.5 * sx, 0.5 * sy, 0.0));
  for (int i = 0; i < 4; ++i) {
    const dvec3 n = kCardinal[i];
    const double along = (i % 2 == 0) ? sy : sx, across = (i % 2 == 0) ? sx : sy;
    const dvec3 mid = c + n * (0.5 * across) + kUp * 1.05;
    b_.box(mid, glm::cross(kUp, n), kUp, dvec3(along, 0.05, 0.05));
  }
  spend(5);
  // Rail posts about every 0.8 m around the edge.
  for (int i = 0; i < 4; ++i) {
    const dvec3 n = kCardinal[i], t = glm::cross(kUp, n);
    const double along = (i % 2 == 0) ? sy : sx, across = (i % 2 == 0) ? sx : sy;
    const int posts = std::max(1, int(along / 0.8));
    for (int k = 0; k < posts && afford(1); ++k) {
      const dvec3 p = c + n * (0.5 * across) + t * (along * (double(k) / posts - 0.5));
      post(p + kUp * 0.005, n, 1.05);
      spend(1);
    }
  }
}

void ItemBuilder::skid_frame(double lx, double ly, double height) {
  const dvec3 c = e_.centre;
  for (double x = -0.5 * lx + 0.1; x <= 0.5 * lx - 0.1 && afford(4); x += 0.9) {
    for (double s : {-1.0, 1.0}) {
      const dvec3 p = c + dvec3(x, s * (0.5 * ly - 0.08), 0.3);
      b_.box_axes(p - dvec3(0.05, 0.05, 0.0), p + dvec3(0.05, 0.05, height));
      b_.box_axes(p + dvec3(0.0, -0.04, height - 0.08), p + dvec3(0.9, 0.04, height));
    }
    spend(4);
  }
  // Cross beams at mid height and on top, and a cable ladder along one side.
  for (double x = -0.5 * lx + 0.1;
       x <= 0.5 * lx - 0.1 && afford(3) && unit_.detail_ledger.room(kBox, 3); x += 0.9) {
    for (double z : {0.5 * height, height}) {
      b_.box_axes(c + dvec3(x - 0.04, -0.5 * ly + 0.1, z - 0.08),
                  c + dvec3(x + 0.04, 0.5 * ly - 0.1, z));
    }
    b_.box_axes(c + dvec3(x, 0.5 * ly - 0.3, height + 0.05),
                c + dvec3(x + 0.85, 0.5 * ly - 0.05, height + 0.12));
    spend(3);
  }
}

void ItemBuilder::end_platform(const dvec3& deck_centre, const dvec3& out, double width) {
  if (!afford(8) || !unit_.detail_ledger.room(kBox, 30)) return;
  const dvec3 side = glm::cross(kUp, out);
  b_.box(deck_centre, out, kUp, dvec3(1.0, width, 0.05));
  for (double s : {-0.5, 0.5}) {
    b_.box(deck_centre + side * (s * width) + kUp * 1.05, out, kUp, dvec3(1.0, 0.05, 0.05));
  }
  b_.box(deck_centre + out * 0.5 + kUp * 1.05, side, kUp, dvec3(width, 0.05, 0.05));
  spend(4);
  for (double s : {-0.5, 0.5}) {
    for (double t : {-0.45, 0.45}) {
      if (!afford(1)) break;
      b_.box(deck_centre + side * (s * width) + out * t + kUp * 0.55, out, kUp,
             dvec3(0.05, 0.05, 1.05));
      spend(1);
    }
  }
  ladder(dvec3(deck_centre.x, deck_centre.y, 0.0) + out * 0.55, out, 0.0, deck_centre.z, round());
}

void ItemBuilder::finish(const char* description) {
  Object& o = b_.object();
  o.colour = kTypes[size_t(e_.type)].colour;
  b_.attribute("Type", kTypes[size_t(e_.type)].type_name);
  b_.attribute("Tag", e_.tag);
  b_.attribute("Description", description);
  const int pressure_dbar = 35 + int(rng().below(400));
  b_.attribute("Design pressure", fixed(pressure_dbar / 10.0, 1) + " barg");
  b_.attribute("Design temperature", std::to_string(60 + 10 * int(rng().below(30))) + " degC");
  static const char* const kMaterials[] = {"SA-516 Gr.70", "SA-240 304L", "SA-387 Gr.11",
                                           "SA-106 Gr.B", "SA-283 Gr.C"};
  b_.attribute("Material", kMaterials[rng().below(5)]);
  if (e_.diameter > 0) {
    b_.attribute("Diameter", std::to_string(int(std::lround(e_.diameter * 1000))) + " mm");
  }
  if (e_.height > 0) {
    b_.attribute("Height", std::to_string(int(std::lround(e_.height * 1000))) + " mm");
  }
  if (e_.length > 0) {
    b_.attribute("Length", std::to_string(int(std::lround(e_.length * 1000))) + " mm");
  }
  b_.attribute("Nozzles", std::to_string(e_.nozzles.size()));
  unit_.emit(b_, "/" + e_.tag);
}

void ItemBuilder::add_nozzle(const dvec3& face, const dvec3& dir, int bore, NozzleRole role,
                             bool flanged) {
  Nozzle n;
  n.position = face;
  n.direction = dir;
  n.bore = bore;
  n.role = role;
  n.flanged = flanged;
  n.equipment = index_;
  e_.nozzles.push_back(uint32_t(unit_.nozzles.size()));
  unit_.nozzles.push_back(n);
  b_.connection(face, dir, pipe_size(bore).od_m);
}

}  // namespace plantview::gen::items
