// Structure: the steel pipe racks, one object per bent (columns on pedestals, tier beams, knee
// gussets) and one per bay (longitudinal and intermediate beams, cable tray, tubular bracing).
#include <cmath>
#include <string>

#include "presets.h"

namespace plantview::gen {

namespace {

constexpr float kBraceShear_rad = kQuarterPi;  // 45 degree braces end in horizontal cuts
constexpr Colour kSteel{150, 150, 162, 255};

std::string two_digits(int n) { return (n < 10 ? "0" : "") + std::to_string(n); }

void finish(Unit& unit, ObjectBuilder& b, std::string name, const char* type, const char* profile) {
  b.object().colour = kSteel;
  b.attribute("Type", type);
  b.attribute("Profile", profile);
  b.attribute("Material", "S355JR");
  b.attribute("Fireproofing", "To 9 m");
  unit.emit(b, std::move(name));
}

void build_bent(Unit& unit, const Rack& rack, const std::string& rack_name, int index, double x) {
  ObjectBuilder b(unit.origin_m, dvec3(x, rack.y_centre, 0.0), ObjectClass::structure);
  const double top = rack.tiers.back();
  const double half = 0.5 * rack.width - 0.15;
  for (double s : {-1.0, 1.0}) {
    const double y = rack.y_centre + s * half;
    b.box_axes(dvec3(x - 0.3, y - 0.3, -0.3), dvec3(x + 0.3, y + 0.3, 0.3));     // pedestal
    b.box_axes(dvec3(x - 0.15, y - 0.15, 0.3), dvec3(x + 0.15, y + 0.15, top));  // column
    // Knee gussets under every tier beam, against the column's inner face.
    for (double z : rack.tiers)
      b.wedge(dvec3(x, y - s * 0.15, z - 0.3), kY * -s, -kUp, 0.4, 0.02, 0.4);
  }
  for (double z : rack.tiers) {
    b.box_axes(dvec3(x - 0.12, rack.y_centre - half - 0.15, z - 0.3),
               dvec3(x + 0.12, rack.y_centre + half + 0.15, z));
  }
  finish(unit, b, rack_name + "/BENT-" + two_digits(index), "Rack bent", "HEA 300");
}

void build_bay(Unit& unit, const Rack& rack, const std::string& rack_name, int index, double x0,
               double x1, bool braced) {
  ObjectBuilder b(unit.origin_m, dvec3(0.5 * (x0 + x1), rack.y_centre, 0.0),
                  ObjectClass::structure);
  const double half = 0.5 * rack.width - 0.15;
  const double xm = 0.5 * (x0 + x1);
  for (double z : rack.tiers) {
    for (double s : {-1.0, 1.0}) {
      const double y = rack.y_centre + s * half;
      b.box_axes(dvec3(x0 + 0.15, y - 0.1, z - 0.25), dvec3(x1 - 0.15, y + 0.1, z));
    }
  }
  // An intermediate beam at mid bay under the top tier (small pipes span less).
  const double top_tier = rack.tiers.back();
  b.box_axes(dvec3(xm - 0.08, rack.y_centre - half + 0.1, top_tier - 0.2),
             dvec3(xm + 0.08, rack.y_centre + half - 0.1, top_tier));
  // Cable tray along the top tier's edge.
  const double top = rack.tiers.back();
  b.box_axes(dvec3(x0 + 0.15, rack.y_centre + half - 0.8, top + 0.4),
             dvec3(x1 - 0.15, rack.y_centre + half - 0.2, top + 0.5));
  // Tubular 45 degree braces from the column bases toward the first tier (a K in braced bays,
  // one diagonal elsewhere), their ends cut level with base plate and beam.
  const double rise = std::min(rack.tiers.front() - 0.6, 0.5 * (x1 - x0) - 0.3);
  for (double s : {-1.0, 1.0}) {
    const double y = rack.y_centre + s * half;
    const dvec3 a(x0 + 0.2, y, 0.3), c(x0 + 0.2 + rise, y, 0.3 + rise);
    b.sheared_cylinder(a, c, 0.08, glm::normalize(kX - kUp), kBraceShear_rad, kBraceShear_rad);
    if (braced) {
      const dvec3 a2(x1 - 0.2, y, 0.3), c2(x1 - 0.2 - rise, y, 0.3 + rise);
      b.sheared_cylinder(a2, c2, 0.08, glm::normalize(-kX - kUp), kBraceShear_rad, kBraceShear_rad);
    }
  }
  finish(unit, b, rack_name + "/BAY-" + two_digits(index), "Rack bay", "IPE 240");
}

}  // namespace

void build_structure(Unit& unit) {
  for (size_t r = 0; r < unit.racks.size(); ++r) {
    const Rack& rack = unit.racks[r];
    const std::string name = "/RACK-" + unit.area + "-" + std::to_string(r + 1);
    const int bays = int((rack.x_end - rack.x_begin) / rack.bent_pitch + 0.5);
    for (int i = 0; i <= bays; ++i) build_bent(unit, rack, name, i + 1, bent_x(rack, i));
    for (int i = 0; i < bays; ++i) {
      build_bay(unit, rack, name, i + 1, bent_x(rack, i), bent_x(rack, i + 1), i % 2 == 1);
    }
  }
}

}  // namespace plantview::gen
