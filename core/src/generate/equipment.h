// Internal: what the equipment stage's files share. equipment.cpp runs the stage (the mix, sizes
// and places, then builds every item within its share of the primitive budget); the others hold
// one step each:
//   equipment_sizes.cpp    the per-type table and each item's main dimensions
//   equipment_layout.cpp   where each item stands on the plot
//   equipment_details.cpp  ItemBuilder: nozzles, ladders, platforms, bolts... within an allowance
//   equipment_recipes.cpp  one recipe per equipment type, built from those details
//
// Lengths in metres, unit-local coordinates (generator.h); every draw goes through the unit's Rng
// in a fixed order, so that a seed builds the same items on every machine.
#pragma once

#include <cstdint>
#include <string>

#include "presets.h"

namespace plantview::gen::items {

// Slope of a 2:1 elliptical head at 0.6 of its radius: atan(0.375).
inline constexpr float kHeadSlope_rad = 0.3587707f;
inline constexpr double kCos45 = 0.70710678118654752;  // cos and sin of 45 degrees
// The four horizontal directions, counterclockwise from +x.
inline constexpr dvec3 kCardinal[4] = {dvec3(1, 0, 0), dvec3(0, 1, 0), dvec3(-1, 0, 0),
                                       dvec3(0, -1, 0)};

// ---------------------------------------------------------------------------------------------
// Per-type table and sizes (equipment_sizes.cpp).

struct TypeInfo {
  const char* prefix;
  const char* type_name;
  int base_primitives;  // typical recipe without details (for the allowance estimate)
  int detail_weight;    // share of the detail budget
  Colour colour;
};
extern const TypeInfo kTypes[kEquipmentTypeCount];  // by EquipmentType

// The main dimensions of an item, drawn before placement. `shrink` (<= 1) scales them down when
// the unit's plot is too small for the first draw.
void size_item(Unit& unit, EquipmentRecord& e, double shrink);

// ---------------------------------------------------------------------------------------------
// Placement (equipment_layout.cpp).

// Places every item: shelves for the plot items (deepest first, in the least filled band), pump
// pairs in the pump row beside the vessel that feeds them, air coolers on the first rack's top.
// False when the plot cannot hold them (with `overflow`, a full band grows beyond its edge).
bool place_all(Unit& unit, bool overflow);

// ---------------------------------------------------------------------------------------------
// Details (equipment_details.cpp). Builds one item's object: every detail checks the item's
// allowance (primitives it may still add) and spends what it adds; details the allowance cannot
// pay for are left out whole.

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
  bool kind_room(Tally t, int n, double share);
  // Whether a rung or post is a round bar (a cylinder) rather than a flat one (a box): whichever
  // keeps the equipment's kinds in proportion.
  bool round() const;
  // A rail post of `height` standing on `foot`, round or flat as round() decides.
  void post(const dvec3& foot, const dvec3& facing, double height);
  EquipmentRecord& rec() { return e_; }
  ObjectBuilder& b() { return b_; }
  int allowance() const { return allowance_; }
  bool afford(int n) const { return allowance_ >= n; }
  void spend(int n) { allowance_ -= n; }

  // A flanged nozzle: neck from `base` along `dir`, then the flange; the pipe side starts at the
  // flange face.
  // Pumps' and compressors' nozzles are always flanged; others may have butt-weld ends (no
  // flange primitive, the pipe side starts at the neck's end).
  void nozzle(const dvec3& base, const dvec3& dir, int bore, double neck, NozzleRole role);
  // A nozzle on an elliptical head at 0.6 of its radius, pointing along the head's axis: its neck
  // is cut along the head's slope there.
  void head_nozzle(const dvec3& head_base, const dvec3& axis, const dvec3& radial, double radius,
                   int bore, NozzleRole role);

  // A vertical ladder from z0 to z1 at `foot` (on grade plan position), rungs facing `out`:
  // two rails, rungs every 0.3 m and cage hoops every 1.2 m above 2.5 m, within the allowance.
  void ladder(const dvec3& foot, const dvec3& out, double z0, double z1, bool round_rungs);

  // A circular platform around a vertical body of radius r at elevation z: deck and top rail as
  // rectangular tori over three quarters of a turn.
  void ring_platform(double r, double z, const dvec3& start);

  // Stud bolts through a flanged joint: `count` (8, 16, 24 or 32) studs parallel to `axis` on a
  // circle of `circle_r` around `centre`, within the allowance.
  void bolt_ring(const dvec3& centre, const dvec3& axis, double circle_r, double length,
                 double stud_r, int count);
  // Studs for a body flange of outside radius `flange_r`.
  void body_flange_bolts(const dvec3& centre, const dvec3& axis, double flange_r, double thickness);
  // A manway on a shell: neck, blind cover and its studs.
  void manway(const dvec3& base, const dvec3& dir);

  // More process connections on a vertical shell of radius r between z0 and z1 while the
  // allowance lasts (at most `limit` nozzles in all).
  void extra_side_nozzles(double r, double z0, double z1, size_t limit);
  // Lifting lugs: two gusset plates standing on top of a body.
  void lifting_lugs(const dvec3& top_centre, const dvec3& along, double spread);

  // A 45 degree stair flight rising along `t` (horizontal) from `foot` (at z0) to z1: two
  // stringers, treads every 0.2 m and two tube handrails cut square to the posts at their ends.
  void stair(const dvec3& foot, const dvec3& t, double z0, double z1);

  // Vents, instrument and relief connections on a head at 0.6 of its radius (four at most).
  void extra_head_nozzles(const dvec3& head_base, const dvec3& axis, double r);

  // A rectangular platform (deck and four rails) on top of a body at elevation z.
  void top_platform(double sx, double sy, double z);
  // A skid frame around a package: posts along both long sides and top rails between them.
  void skid_frame(double lx, double ly, double height);
  // An access platform at an end of a horizontal body: deck, rails and posts, and its ladder.
  void end_platform(const dvec3& deck_centre, const dvec3& out, double width);

  void finish(const char* description);

 private:
  // Whether a nozzle gets a butt-weld end: never on pumps, compressors and pump suctions, else
  // drawn at the preset's rate.
  bool welded_end(NozzleRole role);
  // The end of a nozzle's neck: a flange (the pipe side starts at its face) or, where
  // welded_end() draws one, a bevel for a butt weld (the pipe side starts at the neck's end).
  void nozzle_end(const dvec3& neck_end, const dvec3& dir, int bore, NozzleRole role);
  void add_nozzle(const dvec3& face, const dvec3& dir, int bore, NozzleRole role, bool flanged);

  Unit& unit_;
  EquipmentRecord& e_;
  uint32_t index_;
  ObjectBuilder b_;
  int allowance_;
};

// ---------------------------------------------------------------------------------------------
// Recipes (equipment_recipes.cpp).

// The reader's description of an item ("Depropanizer").
const char* description_of(Rng& rng, EquipmentType type);
// Builds the item's primitives and nozzles by its type's recipe (it.finish() emits it).
void build_item(Unit& unit, ItemBuilder& it);

}  // namespace plantview::gen::items
