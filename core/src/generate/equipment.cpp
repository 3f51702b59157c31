// Equipment: sizes and places every item of the preset's mix, then builds and emits it with its
// nozzles (the ends that pipelines connect to).
//
// Primitive budget: Su's equipment primitives per unit. Each item is built from a base recipe
// (shell, heads, supports, nozzles) plus details (platforms, ladders with rungs, cage hoops, level
// gauges, burners...) within an allowance, so that the unit total lands on the budget.
#include <algorithm>
#include <cmath>
#include <string>

#include "presets.h"

namespace plantview::gen {

namespace {

using T = EquipmentType;
// Slope of a 2:1 elliptical head at 0.6 of its radius: atan(0.375).
constexpr float kHeadSlope_rad = 0.3587707f;

const dvec3 kCardinal[4] = {dvec3(1, 0, 0), dvec3(0, 1, 0), dvec3(-1, 0, 0), dvec3(0, -1, 0)};

struct TypeInfo {
  const char* prefix;
  const char* type_name;
  int base_primitives;  // typical recipe without details (for the allowance estimate)
  int detail_weight;    // share of the detail budget
  Colour colour;
};
constexpr TypeInfo kTypes[kEquipmentTypeCount] = {
    {"C", "Column", 22, 10, {178, 190, 170, 255}},
    {"V", "Vertical drum", 14, 4, {172, 188, 176, 255}},
    {"V", "Horizontal drum", 14, 4, {172, 188, 176, 255}},
    {"E", "Shell and tube exchanger", 15, 4, {150, 172, 200, 255}},
    {"P", "Centrifugal pump", 12, 0, {60, 110, 190, 255}},
    {"K", "Compressor", 14, 3, {205, 125, 60, 255}},
    {"EA", "Air cooler", 16, 4, {190, 192, 205, 255}},
    {"F", "Cracking furnace", 16, 10, {176, 92, 70, 255}},
    {"S", "Filter", 10, 2, {160, 160, 120, 255}},
    {"TK", "Storage tank", 10, 4, {222, 222, 212, 255}},
    {"TK", "Spherical tank", 14, 3, {222, 222, 212, 255}},
    {"PK", "Package unit", 10, 3, {120, 162, 120, 255}},
};

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

std::string tag_of(const Unit& unit, T type, int seq) {
  std::string s = kTypes[size_t(type)].prefix;
  s += '-';
  s += unit.area;
  s += '-';
  std::string n = std::to_string(seq);
  s += std::string(n.size() < 3 ? 3 - n.size() : 0, '0') + n;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Sizing: the main dimensions of each item, drawn before placement. `shrink` (<= 1) scales them
// down when the unit's plot is too small for the first draw.

void size_item(Unit& unit, EquipmentRecord& e, double shrink) {
  Rng& rng = unit.rng;
  const double top = unit.info.height_m;
  switch (e.type) {
    case T::column:
      e.diameter = rng.metres(1600, 4200) * shrink;
      e.height = std::min(unit.spec.column_height_max_m, top - 1.0) * (0.55 + 0.45 * rng.unit());
      e.size_x = e.size_y = e.diameter + 2.8;
      break;
    case T::vertical_drum:
      e.diameter = rng.metres(1000, 2600) * shrink;
      e.height = std::min(rng.metres(2500, 7000), top - 4.5);
      e.size_x = e.size_y = e.diameter + 1.6;
      break;
    case T::horizontal_drum:
      e.diameter = rng.metres(1400, 3000) * shrink;
      e.length = rng.metres(4000, 9000) * shrink;
      e.size_x = e.length + e.diameter * 0.5 + 1.2;
      e.size_y = e.diameter + 1.6;
      break;
    case T::exchanger:
      e.diameter = rng.metres(450, 1200) * shrink;
      e.length = rng.metres(3000, 6500) * shrink;
      e.size_x = e.length + 1.6 + e.diameter * 0.5;
      e.size_y = e.diameter + 1.4;
      break;
    case T::pump:
      e.diameter = rng.metres(440, 700);
      e.size_x = 1.2;
      e.size_y = 2.8;
      break;
    case T::compressor:
      e.diameter = rng.metres(1000, 1600) * shrink;
      e.length = rng.metres(1500, 2500);
      e.size_x = e.length + 4.5;
      e.size_y = e.diameter + 2.6;
      break;
    case T::air_cooler:
      e.length = 6.0;
      e.size_x = 6.0;
      break;
    case T::furnace:
      e.length = rng.metres(6000, 9000) * shrink;
      e.diameter = rng.metres(1400, 2000);
      e.height = std::min(top - 1.0, rng.metres(18000, 30000));
      e.size_x = e.length + 1.5;
      e.size_y = rng.metres(3500, 5000) * shrink + 1.5;
      break;
    case T::filter:
      e.diameter = rng.metres(450, 800);
      e.height = rng.metres(1200, 1800);
      e.size_x = e.size_y = e.diameter + 1.2;
      break;
    case T::tank:
      e.diameter = rng.metres(6000, 10000) * shrink;
      e.height = std::min(top - 2.0, rng.metres(6000, 11000));
      e.size_x = e.size_y = e.diameter + 2.0;
      break;
    case T::sphere_tank:
      e.diameter = rng.metres(7000, 10000) * shrink;
      e.size_x = e.size_y = e.diameter + 2.0;
      break;
    case T::package:
      e.length = rng.metres(3000, 4500) * shrink;
      e.size_x = e.length;
      e.size_y = rng.metres(2000, 3000) * shrink;
      break;
  }
  // Nothing may be deeper than the shallowest band can take.
  double band_depth = 1e9;
  for (const Band& b : unit.bands) band_depth = std::min(band_depth, std::abs(b.y_far - b.y_near));
  const double max_y = std::max(2.0, band_depth - 4.2);
  if (e.size_y > max_y) {
    const double f = max_y / e.size_y;
    e.size_y = max_y;
    if (e.type == T::column || e.type == T::vertical_drum || e.type == T::tank ||
        e.type == T::sphere_tank || e.type == T::filter) {
      e.diameter *= f;
      e.size_x = e.size_y;
    } else if (e.type == T::horizontal_drum || e.type == T::exchanger || e.type == T::compressor) {
      e.diameter = std::min(e.diameter, max_y - 1.4);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Building.

class ItemBuilder {
 public:
  ItemBuilder(Unit& unit, uint32_t index, int allowance)
      : unit_(unit),
        e_(unit.equipment[index]),
        index_(index),
        b_(unit.origin_m, unit.equipment[index].centre, ObjectClass::equipment),
        allowance_(allowance) {}

  Rng& rng() { return unit_.rng; }
  // Whether equipment may still add `n` primitives of a kind that piping has little use for
  // without taking more than `share` of the unit's target.
  bool kind_room(Tally t, int n, double share) {
    const int64_t here = mix_of(b_.object()).n[t];
    return double(unit_.emitted.n[t] + here + n) <= share * double(unit_.kind_targets[t]);
  }
  // Whether a rung or post is a round bar (a cylinder) rather than a flat one (a box): whichever
  // keeps the equipment's kinds in proportion.
  bool round() const {
    Mix box, cylinder;
    box.add(kBox);
    cylinder.add(kCylinder);
    const Mix options[] = {box, cylinder};
    return unit_.detail_ledger.choose(options) == 1;
  }
  void post(const dvec3& foot, const dvec3& facing, double height) {
    if (round()) {
      b_.cylinder(foot, foot + kUp * height, 0.024);
    } else {
      b_.box(foot + kUp * (0.5 * height), facing, kUp, dvec3(0.05, 0.05, height));
    }
  }
  EquipmentRecord& rec() { return e_; }
  ObjectBuilder& b() { return b_; }
  int allowance() const { return allowance_; }
  bool afford(int n) const { return allowance_ >= n; }
  void spend(int n) { allowance_ -= n; }

  // A flanged nozzle: neck from `base` along `dir`, then the flange; the pipe side starts at the
  // flange face.
  // Pumps' and compressors' nozzles are always flanged; others may have butt-weld ends (no
  // flange primitive, the pipe side starts at the neck's end).
  void nozzle(const dvec3& base, const dvec3& dir, int bore, double neck, NozzleRole role) {
    const PipeSize& s = pipe_size(bore);
    const dvec3 neck_end = base + dir * neck;
    b_.cylinder(base, neck_end, 0.5 * s.od_m);
    if (welded_end(role)) {
      add_nozzle(neck_end, dir, bore, role, false);
      return;
    }
    const dvec3 face = neck_end + dir * s.flange_thk_m;
    b_.cylinder(neck_end, face, 0.5 * s.flange_od_m);
    add_nozzle(face, dir, bore, role, true);
  }
  // A nozzle on an elliptical head at 0.6 of its radius, pointing along the head's axis: its neck
  // is cut along the head's slope there.
  void head_nozzle(const dvec3& head_base, const dvec3& axis, const dvec3& radial, double radius,
                   int bore, NozzleRole role) {
    const PipeSize& s = pipe_size(bore);
    const dvec3 base = head_base + radial * (0.6 * radius) + axis * (0.4 * radius);
    const dvec3 neck_end = base + axis * (0.35 + 0.2 * radius);
    b_.sheared_cylinder(base, neck_end, 0.5 * s.od_m, radial, -kHeadSlope_rad, 0.0f);
    if (welded_end(role)) {
      add_nozzle(neck_end, axis, bore, role, false);
      return;
    }
    const dvec3 face = neck_end + axis * s.flange_thk_m;
    b_.cylinder(neck_end, face, 0.5 * s.flange_od_m);
    add_nozzle(face, axis, bore, role, true);
  }
  bool welded_end(NozzleRole role) {
    return e_.type != EquipmentType::pump && e_.type != EquipmentType::compressor &&
           role != NozzleRole::pump_suction &&
           unit_.rng.chance(unit_.spec.welded_nozzles_per_mille);
  }

  // A vertical ladder from z0 to z1 at `foot` (on grade plan position), rungs facing `out`:
  // two rails, rungs every 0.3 m and cage hoops every 1.2 m above 2.5 m, within the allowance.
  void ladder(const dvec3& foot, const dvec3& out, double z0, double z1, bool round_rungs) {
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
    for (double z = z0 + 2.5; z < z1 - 0.5 && afford(1) && kind_room(kRectTorus, 1, 0.75);
         z += 1.2) {
      b_.rect_torus(dvec3(foot.x, foot.y, z) + out * 0.35, kUp, side, 0.33, 0.38, 0.05, kHalfTurn);
      spend(1);
    }
  }

  // A circular platform around a vertical body of radius r at elevation z: deck and top rail as
  // rectangular tori over three quarters of a turn.
  void ring_platform(double r, double z, const dvec3& start) {
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
    const double c8 = 0.70710678118654752;
    const dvec3 dirs[7] = {s0, (s0 + s1) * c8, s1, (s1 - s0) * c8, -s0, (-s0 - s1) * c8, -s1};
    for (const dvec3& d : dirs) {
      if (!afford(1)) break;
      const dvec3 p = c + d * (r + 1.225);
      post(p + kUp * 0.005, d, 1.05);
      spend(1);
    }
  }

  // Stud bolts through a flanged joint: `count` (8, 16, 24 or 32) studs parallel to `axis` on a
  // circle of `circle_r` around `centre`, within the allowance.
  void bolt_ring(const dvec3& centre, const dvec3& axis, double circle_r, double length,
                 double stud_r, int count) {
    // Rotation steps of 2 pi / count as literals: no libm call, the same on every machine.
    double c = 0, s = 0;
    switch (count) {
      case 8:
        c = s = 0.70710678118654752;
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
  // Studs for a body flange of outside radius `flange_r`.
  void body_flange_bolts(const dvec3& centre, const dvec3& axis, double flange_r,
                         double thickness) {
    const int count = flange_r < 0.35 ? 8 : flange_r < 0.6 ? 16 : flange_r < 0.9 ? 24 : 32;
    bolt_ring(centre, axis, flange_r - 0.045, thickness + 0.08, flange_r < 0.6 ? 0.01 : 0.016,
              count);
  }
  // A manway on a shell: neck, blind cover and its studs.
  void manway(const dvec3& base, const dvec3& dir) {
    if (!afford(18)) return;
    const dvec3 neck_end = base + dir * 0.3, cover_end = neck_end + dir * 0.08;
    b_.cylinder(base, neck_end, 0.3);
    b_.cylinder(neck_end, cover_end, 0.38);
    spend(2);
    bolt_ring(0.5 * (neck_end + cover_end), dir, 0.345, 0.12, 0.012, 16);
  }

  // More process connections on a vertical shell of radius r between z0 and z1 while the
  // allowance lasts (at most `limit` nozzles in all).
  void extra_side_nozzles(double r, double z0, double z1, size_t limit) {
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
  // Lifting lugs: two gusset plates standing on top of a body.
  void lifting_lugs(const dvec3& top_centre, const dvec3& along, double spread) {
    if (!afford(2)) return;
    for (double s : {-1.0, 1.0})
      b_.wedge(top_centre + along * (s * spread), along * s, kUp, 0.15, 0.025, 0.18);
    spend(2);
  }

  // A 45 degree stair flight rising along `t` (horizontal) from `foot` (at z0) to z1: two
  // stringers, treads every 0.2 m and two tube handrails cut square to the posts at their ends.
  void stair(const dvec3& foot, const dvec3& t, double z0, double z1) {
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

  // Vents, instrument and relief connections on a head at 0.6 of its radius (four at most).
  void extra_head_nozzles(const dvec3& head_base, const dvec3& axis, double r) {
    const double c8 = 0.70710678118654752;
    for (int i = 0; i < 8 && afford(2); ++i) {
      const dvec3 radial =
          i % 2 == 0 ? kCardinal[i / 2] : (kCardinal[i / 2] + kCardinal[(i / 2 + 1) % 4]) * c8;
      head_nozzle(head_base, axis, radial, r, 2 + int(rng().below(3)), NozzleRole::spare);
      spend(2);
    }
  }

  // A rectangular platform (deck and four rails) on top of a body at elevation z.
  void top_platform(double sx, double sy, double z) {
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
  // A skid frame around a package: posts along both long sides and top rails between them.
  void skid_frame(double lx, double ly, double height) {
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
  // An access platform at an end of a horizontal body: deck, rails and posts, and its ladder.
  void end_platform(const dvec3& deck_centre, const dvec3& out, double width) {
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

  void finish(const char* description) {
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

 private:
  void add_nozzle(const dvec3& face, const dvec3& dir, int bore, NozzleRole role, bool flanged) {
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

  Unit& unit_;
  EquipmentRecord& e_;
  uint32_t index_;
  ObjectBuilder b_;
  int allowance_;
};

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

// ---------------------------------------------------------------------------------------------
// Recipes. Each places its primitives around rec().centre (on grade) and lists its nozzles.

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

// ---------------------------------------------------------------------------------------------
// Placement: shelves for the plot items (deepest first, in the least filled band), pump pairs in
// the pump row beside the vessel that feeds them, air coolers on the first rack's top.

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
    for (EquipmentRecord& e : unit.equipment) size_item(unit, e, shrink);
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
    if (place_all(unit, attempt == 6)) break;
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
    e.description = description_of(unit.rng, e.type);
    build_item(unit, it);
    it.finish(e.description.c_str());
  }
}

}  // namespace plantview::gen
