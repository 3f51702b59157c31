// Piping supports under a built branch: shoes, guides or U-bolts where a run crosses a rack
// bent, stanchions under low runs, hangers and brackets under high ones, brackets on risers,
// dummy legs and trunnions under elbows. Rule: a support stands where the steel or grade it
// bears on is (a beam top, grade, steel above), and the ledger decides whether and which.
#include "pipelines.h"

#include <algorithm>
#include <cmath>

namespace plantview::gen::pipelines {

// Supports where a reviewer expects them: shoes, guides or U-bolts where a run crosses a rack
// bent, stanchions under low runs, hangers under high ones, dummy legs under low elbows.
void Piping::add_supports(LineContext& line, const Run& run) {
  Ledger& ledger = unit_.ledger;
  for (const Run::PipeSpan& p : run.pipes()) {
    const dvec3 d = p.b - p.a;
    const double len = glm::length(d);
    if (len < 0.5 || std::abs(d.z) > 1e-6 * len) continue;
    const dvec3 dir = d / len;
    const double r = 0.5 * pipe_size(p.bore).od_m;
    // On a rack tier?
    const Rack* on_rack = nullptr;
    double beam = 0;
    for (const Rack& rack : unit_.racks) {
      if (std::abs(p.a.y - rack.y_centre) > 0.5 * rack.width || std::abs(dir.x) < 0.5) continue;
      for (double z : rack.tiers) {
        if (std::abs(p.a.z - r - 0.1 - z) < 1e-6) {
          on_rack = &rack;
          beam = z;
        }
      }
    }
    if (on_rack) {
      const double x0 = std::min(p.a.x, p.b.x) + 0.3, x1 = std::max(p.a.x, p.b.x) - 0.3;
      const int first = int(std::ceil((x0 - on_rack->x_begin) / on_rack->bent_pitch));
      for (int i = std::max(0, first);; ++i) {
        const double x = bent_x(*on_rack, i);
        if (x > x1 || x > on_rack->x_end + 1e-6) break;
        const Part parts[] = {Part::weld, Part::shoe, Part::shoe_gusseted, Part::guide};
        Mix mixes[4];
        for (int k = 1; k < 4; ++k) mixes[k] = part_mix(parts[k]);
        const Part part = parts[ledger.choose(mixes)];
        if (part != Part::weld)
          build_support(line, part, dvec3(x, p.a.y, p.a.z), dir, p.bore, beam);
      }
      continue;
    }
    // Off the racks: stanchions under low runs; hangers or brackets under high ones.
    const bool low = p.a.z < 3.5;
    const dvec3 across = glm::normalize(glm::cross(kUp, dir));
    for (double t = std::min(1.0, 0.5 * len); t < len - 0.3; t += low ? 4.0 : 3.0) {
      const dvec3 at = p.a + dir * t;
      if (low) {
        if (ledger.wants(part_mix(Part::stanchion))) {
          build_support(line, Part::stanchion, at, dir, p.bore, 0.0);
        }
        continue;
      }
      const Part parts[] = {Part::weld, Part::hanger, Part::bracket, Part::bracket_braced,
                            Part::strut};
      const Mix mixes[] = {Mix{}, part_mix(Part::hanger), part_mix(Part::bracket),
                           part_mix(Part::bracket_braced), part_mix(Part::strut)};
      const Part part = parts[ledger.choose(mixes)];
      if (part != Part::weld) {
        build_support(line, part, at, dir, p.bore, at.z + r + 1.0,
                      across * (rng_.chance(500) ? 1.0 : -1.0));
      }
    }
  }
  // Vertical runs: brackets from the steel or the vessel beside them, every 2.5 m.
  for (const Run::PipeSpan& p : run.pipes()) {
    const dvec3 d = p.b - p.a;
    const double len = glm::length(d);
    if (len < 1.5 || std::abs(d.z) < 0.999 * len) continue;
    const dvec3 side = rng_.chance(500) ? kX : kY;
    for (double t = 0.75; t < len - 0.4; t += 2.5) {
      const Part parts[] = {Part::weld, Part::bracket, Part::bracket_braced, Part::strut,
                            Part::clamp};
      const Mix mixes[] = {Mix{}, part_mix(Part::bracket), part_mix(Part::bracket_braced),
                           part_mix(Part::strut), part_mix(Part::clamp)};
      const Part part = parts[ledger.choose(mixes)];
      if (part == Part::weld) continue;
      build_support(line, part, p.a + d * (t / len), d / len, p.bore, 0.0,
                    side * (rng_.chance(500) ? 1.0 : -1.0));
    }
  }
  for (const Run::ElbowAt& e : run.elbows()) {
    // The bend's outside faces down when the vertical leg is above it.
    const bool up_leg = e.d_out.z > 0.5 || e.d_in.z < -0.5;
    if (!up_leg) continue;
    const dvec3 h = std::abs(e.d_in.z) < 0.5 ? e.d_in : -e.d_out;
    const double big_r = bend_radius(e.bore), r = 0.5 * pipe_size(e.bore).od_m;
    const double top = e.corner.z + big_r - std::sqrt(2.0 * big_r * r + r * r);
    if (top < 0.6) continue;
    if (top <= 4.0) {
      // Down to grade: a dummy leg.
      const Part parts[] = {Part::weld, Part::dummy_leg, Part::dummy_leg_bare,
                            Part::dummy_leg_gusseted};
      const Mix mixes[] = {Mix{}, part_mix(Part::dummy_leg), part_mix(Part::dummy_leg_bare),
                           part_mix(Part::dummy_leg_gusseted)};
      const Part part = parts[ledger.choose(mixes)];
      if (part != Part::weld) {
        build_support(line, part, dvec3(e.corner.x, e.corner.y, top), h, e.bore, 0.0);
      }
      continue;
    }
    // Over a rack tier a little below: a trunnion resting on its beam.
    double beam = -1.0;
    for (const Rack& rack : unit_.racks) {
      if (std::abs(e.corner.y - rack.y_centre) > 0.5 * rack.width) continue;
      for (double z : rack.tiers) {
        if (z < top - 0.3 && z > top - 2.5) beam = std::max(beam, z);
      }
    }
    if (beam > 0.0 && ledger.wants(part_mix(Part::trunnion))) {
      build_support(line, Part::trunnion, dvec3(e.corner.x, e.corner.y, top), h, e.bore, beam);
    }
  }
}

}  // namespace plantview::gen::pipelines
