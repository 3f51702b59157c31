// Piping slots: where fittings, valves and tees sit on a route, as distances along its segments.
// Rule: a slot lies on the straight part of a segment (outside its bends) and leaves either no
// pipe or a pipe of at least kMinPipe to its neighbours; forced tees (take-offs, pump branches)
// are placed before the optional groups fill what is left.
#include "pipelines.h"

#include <algorithm>
#include <cmath>

namespace plantview::gen::pipelines {

double group_length(const std::vector<Item>& items) {
  double l = 0;
  for (const Item& it : items) l += item_length(it);
  return l;
}

dvec3 group_span(const std::vector<Item>& items, const dvec3& dir) {
  dvec3 p(0.0);
  for (const Item& it : items) p = advance(p, it, dir);
  return p;
}

Mix group_mix(const std::vector<Item>& items) {
  Mix m;
  for (const Item& it : items) m += part_mix(it.part);
  return m;
}

std::vector<Gap> gaps_of(const SegmentSlots& seg) {
  std::vector<std::pair<double, double>> taken;
  for (const Slot& s : seg.slots) taken.push_back({s.at, s.at + s.length});
  std::sort(taken.begin(), taken.end());
  std::vector<Gap> gaps;
  double lo = seg.u0;
  for (size_t i = 0; i <= taken.size(); ++i) {
    const double hi = i < taken.size() ? taken[i].first : seg.u1;
    gaps.push_back({lo, hi, std::abs(lo - seg.u0) < 1e-9, std::abs(hi - seg.u1) < 1e-9});
    if (i < taken.size()) lo = taken[i].second;
  }
  return gaps;
}

// Where `length` goes in the first gap that takes it (NAN if none); middle places are drawn.
double room_in(const Gap& g, double length, bool mid) {
  const double gap = g.hi - g.lo;
  if (mid) return gap >= length + 2 * kMinPipe ? g.lo + kMinPipe : NAN;
  if (gap < length - 1e-9) return NAN;
  const double rest = gap - length;
  if (!(rest < 1e-9 || rest >= kMinPipe)) return NAN;
  if (g.at_start) return g.lo;
  if (g.at_end) return g.hi - length;
  return NAN;
}

bool fits(const std::vector<Gap>& gaps, double length, bool mid) {
  for (const Gap& g : gaps) {
    if (!std::isnan(room_in(g, length, mid))) return true;
  }
  return false;
}

double place(const std::vector<Gap>& gaps, double length, bool mid, Rng& rng) {
  for (const Gap& g : gaps) {
    const double at = room_in(g, length, mid);
    if (std::isnan(at)) continue;
    if (!mid) return at;
    return at + (g.hi - g.lo - length - 2 * kMinPipe) * (0.25 + 0.5 * rng.unit());
  }
  return NAN;
}

std::vector<SegmentSlots> Piping::segments_of(const std::vector<dvec3>& pts, int bore) const {
  const double r = bend_radius(bore);
  std::vector<SegmentSlots> segs(pts.size() - 1);
  for (size_t k = 0; k + 1 < pts.size(); ++k) {
    segs[k].u0 = k > 0 ? r : 0.0;
    segs[k].u1 = glm::length(pts[k + 1] - pts[k]) - (k + 2 < pts.size() ? r : 0.0);
  }
  return segs;
}

bool Piping::add_forced_tee(std::vector<SegmentSlots>& segs, const std::vector<dvec3>& pts,
                            int bore, const dvec3& centre, const dvec3& branch_dir, int branch_bore,
                            TeeUse use, int tag, bool olet) {
  const double c = olet ? 0.0 : tee_half(bore);
  for (size_t k = 0; k + 1 < pts.size(); ++k) {
    const dvec3 d = pts[k + 1] - pts[k];
    const double len = glm::length(d);
    const dvec3 dir = d / len;
    const double t = glm::dot(centre - pts[k], dir);
    if (glm::length(pts[k] + dir * t - centre) > 1e-6) continue;
    const double at = t - c;
    SegmentSlots& seg = segs[k];
    if (at < seg.u0 + kMinPipe - 1e-9 || at + 2 * c > seg.u1 - kMinPipe + 1e-9) continue;
    for (const Slot& s : seg.slots) {
      if (at < s.at + s.length + kMinPipe && s.at < at + 2 * c + kMinPipe) return false;
    }
    Slot slot;
    slot.at = at;
    slot.length = 2 * c;
    slot.tee = use;
    slot.branch_dir = branch_dir;
    slot.branch_bore = branch_bore;
    slot.tag = tag;
    slot.olet = olet;
    seg.slots.push_back(std::move(slot));
    return true;
  }
  return false;
}

}  // namespace plantview::gen::pipelines
