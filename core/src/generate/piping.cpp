// Piping: plans the unit's pipelines (utility headers with their drops, pump suction and
// discharge lines, process lines between nozzles, battery-limit lines), routes each branch
// orthogonally (elbows at every turn), fills the runs with fittings, valves and flanges, adds
// vents, drains and supports, and emits members, supports and pipeline objects.
//
// Counts: every optional choice (valve types, flange spec, inline groups, welds, closures,
// supports) goes through the unit's ledger, which steers the unit toward Su's pipe and component
// counts and Zhou's primitive mix.
#include "piping.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <unordered_map>

#include "presets.h"

namespace plantview::gen {

namespace {

constexpr dvec3 kUp(0, 0, 1), kDown(0, 0, -1), kX(1, 0, 0), kY(0, 1, 0);
constexpr double kMinPipe = 0.12;  // shortest pipe left between two members

double lr_bend_radius(int bore) { return pipe_size(bore).elbow_r_m; }
double tee_half(int bore) { return 0.5 * item_length(item(Part::tee, bore)); }

// ---------------------------------------------------------------------------------------------
// Routes: polylines of axis-aligned segments, [start, corners..., end].

enum Axis : uint8_t { kAxisX, kAxisY, kAxisZ };
struct Move {
  Axis axis;
  double target;            // NAN: the end's coordinate on that axis
  bool from_start = false;  // target is an offset from the route's start
};
using Pattern = std::vector<Move>;

double& coord(dvec3& p, Axis a) { return a == kAxisX ? p.x : a == kAxisY ? p.y : p.z; }

// A route under construction: a handful of points, no allocation.
struct Points {
  std::array<dvec3, 24> p;
  size_t n = 0;
  void push(const dvec3& q) {
    if (n < p.size()) p[n] = q;
    ++n;
  }
  std::vector<dvec3> vector() const {
    return std::vector<dvec3>(p.begin(), p.begin() + std::ptrdiff_t(n));
  }
};

// Drops zero-length moves and merges straight-on ones; false on a U-turn or a non-right angle.
template <class Seq>
bool simplify_into(const Seq& in, size_t count, Points& m) {
  m.n = 0;
  for (size_t i = 0; i < count; ++i) {
    const dvec3& p = in[i];
    if (m.n > 0 && glm::length(p - m.p[m.n - 1]) <= 1e-9) continue;
    if (m.n >= 2) {
      const dvec3 d0 = glm::normalize(m.p[m.n - 1] - m.p[m.n - 2]);
      const dvec3 d1 = glm::normalize(p - m.p[m.n - 1]);
      const double c = glm::dot(d0, d1);
      if (c > 1.0 - 1e-9) {
        m.p[m.n - 1] = p;
        continue;
      }
      if (std::abs(c) > 1e-9) return false;
    }
    m.push(p);
  }
  return m.n >= 2 && m.n <= m.p.size();
}

bool simplify(std::vector<dvec3>& pts) {
  Points m;
  if (pts.size() > m.p.size() || !simplify_into(pts, pts.size(), m)) return false;
  pts = m.vector();
  return true;
}

// Every segment holds its elbows' bend radii and a pipe, or exactly the bend radii (elbows
// welded to each other or to the end's fitting, no pipe); every point stays above min_z.
template <class Seq>
bool long_enough(const Seq& pts, size_t n, double bend_r, double min_z) {
  for (size_t k = 0; k + 1 < n; ++k) {
    const double bends = (k > 0 ? bend_r : 0.0) + (k + 2 < n ? bend_r : 0.0);
    const double len = glm::length(pts[k + 1] - pts[k]);
    if (len < bends + kMinPipe && !(bends > 0.0 && std::abs(len - bends) < 1e-6)) return false;
  }
  for (size_t k = 0; k < n; ++k) {
    if (pts[k].z < min_z) return false;
  }
  return true;
}
bool long_enough(const std::vector<dvec3>& pts, double bend_r, double min_z) {
  return long_enough(pts, pts.size(), bend_r, min_z);
}

// Pipes a route needs (segments longer than their bends).
template <class Seq>
int route_pipes(const Seq& pts, size_t n, double bend_r) {
  int pipes = 0;
  for (size_t k = 0; k + 1 < n; ++k) {
    const double bends = (k > 0 ? bend_r : 0.0) + (k + 2 < n ? bend_r : 0.0);
    if (glm::length(pts[k + 1] - pts[k]) > bends + 1e-6) ++pipes;
  }
  return pipes;
}
int route_pipes(const std::vector<dvec3>& pts, double bend_r) {
  return route_pipes(pts, pts.size(), bend_r);
}

// From s (flow along ds) to e (flow arriving along de): stubs along ds and de, then the moves of
// a pattern, for each stub length and pattern in turn. A stub of 0 puts the first (last) elbow
// right at s (e). Collects up to `max_options` valid routes (distinct in elbows or pipes) into
// `out`; returns whether it found any.
bool route(const dvec3& s, const dvec3& ds, const dvec3& e, const dvec3& de, double bend_r,
           double min_z, std::initializer_list<double> stubs, const std::vector<Pattern>& patterns,
           std::vector<std::vector<dvec3>>& out, size_t max_options = 1,
           double min_start_stub = 0.0, double min_end_stub = 0.0) {
  out.clear();
  for (double stub : stubs) {
    const double start = min_start_stub > 0.0 ? std::max(stub, min_start_stub)
                         : stub == 0.0        ? bend_r
                                              : std::max(stub, bend_r + kMinPipe + 0.02);
    const double end = min_end_stub > 0.0 ? std::max(stub, min_end_stub)
                       : stub == 0.0      ? bend_r
                                          : std::max(stub, bend_r + kMinPipe + 0.05);
    const dvec3 s1 = s + ds * start, e1 = e - de * end;
    for (const Pattern& pattern : patterns) {
      Points raw;
      raw.push(s);
      raw.push(s1);
      dvec3 p = s1, target_point = e1, start_point = s;
      for (const Move& mv : pattern) {
        coord(p, mv.axis) = std::isnan(mv.target) ? coord(target_point, mv.axis)
                            : mv.from_start       ? coord(start_point, mv.axis) + mv.target
                                                  : mv.target;
        raw.push(p);
      }
      for (Axis a : {kAxisX, kAxisY, kAxisZ}) {
        if (coord(p, a) != coord(target_point, a)) {
          coord(p, a) = coord(target_point, a);
          raw.push(p);
        }
      }
      raw.push(e);
      Points pts;
      if (raw.n > raw.p.size() || !simplify_into(raw.p, raw.n, pts) ||
          !long_enough(pts.p, pts.n, bend_r, min_z)) {
        continue;
      }
      bool seen = false;
      const int pipes = route_pipes(pts.p, pts.n, bend_r);
      for (const auto& o : out)
        seen = seen || (o.size() == pts.n && route_pipes(o, bend_r) == pipes);
      if (seen) continue;
      out.push_back(pts.vector());
      if (out.size() >= max_options) return true;
    }
  }
  return !out.empty();
}

std::vector<Pattern> permutations(const Pattern& prefix) {
  static const Axis orders[6][3] = {{kAxisZ, kAxisX, kAxisY}, {kAxisZ, kAxisY, kAxisX},
                                    {kAxisX, kAxisZ, kAxisY}, {kAxisY, kAxisZ, kAxisX},
                                    {kAxisX, kAxisY, kAxisZ}, {kAxisY, kAxisX, kAxisZ}};
  std::vector<Pattern> out;
  for (const auto& order : orders) {
    Pattern p = prefix;
    for (Axis a : order) p.push_back({a, NAN});
    out.push_back(std::move(p));
  }
  return out;
}

// Every order of the three moves, then the same after a 1.5 m sidestep along x, y or z (for ends
// that face each other across a body, or point away from where the route goes). Ends that
// differ by a few centimetres on some axes cannot be joined by a move that short: the last
// patterns step aside on all such axes at once (and come back later). The pattern sets are built
// once, one per set of such axes.
const std::vector<Pattern>& local_patterns(const dvec3& s, const dvec3& e, double bend_r) {
  constexpr double kAside = 1.5;
  static const std::array<std::vector<Pattern>, 8> table = [] {
    std::array<std::vector<Pattern>, 8> t;
    for (int mask = 0; mask < 8; ++mask) {
      std::vector<Pattern>& out = t[size_t(mask)];
      out = permutations({});
      for (Axis a : {kAxisY, kAxisX, kAxisZ}) {
        for (double sign : {1.0, -1.0}) {
          for (Pattern& r : permutations({{a, sign * kAside, true}})) out.push_back(std::move(r));
        }
      }
      std::vector<Axis> tiny;
      for (Axis a : {kAxisY, kAxisX, kAxisZ}) {
        if (mask & (1 << int(a))) tiny.push_back(a);
      }
      if (tiny.size() < 2) continue;
      for (int signs = 0; signs < (1 << tiny.size()); ++signs) {
        Pattern prefix;
        for (size_t i = 0; i < tiny.size(); ++i) {
          prefix.push_back({tiny[i], ((signs >> i) & 1) ? -kAside : kAside, true});
        }
        for (Pattern& r : permutations(prefix)) out.push_back(std::move(r));
      }
    }
    return t;
  }();
  int mask = 0;
  for (Axis a : {kAxisY, kAxisX, kAxisZ}) {
    dvec3 p = s, q = e;
    const double d = std::abs(coord(p, a) - coord(q, a));
    if (d > 1e-9 && d < 2.0 * bend_r + kMinPipe + 0.2) mask |= 1 << int(a);
  }
  return table[size_t(mask)];
}

// ---------------------------------------------------------------------------------------------
// Slots: what sits on a route segment besides pipes, at a distance from the segment's start.

enum class TeeUse : uint8_t { none, vent, drain, takeoff, pump_suction, pump_discharge };

struct Slot {
  double at = 0;  // from the segment's start point (a corner or the route start)
  double length = 0;
  std::vector<Item> items;
  TeeUse tee = TeeUse::none;
  dvec3 branch_dir{0.0};
  int branch_bore = 0;
  int tag = -1;                 // caller's index (drops)
  bool olet = false;            // tee slots: an olet on the run instead (no length along it)
  std::vector<Item> sub_items;  // vents and drains: the stub's members after its pipe
};

struct SegmentSlots {
  double u0 = 0, u1 = 0;  // usable stretch (outside the bends)
  std::vector<Slot> slots;
};

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

// The free stretches of a segment between its slots; a group goes right after the segment's
// start or before its end (no pipe in between), or in the middle of a gap (splitting a pipe),
// always leaving no pipe or one of at least kMinPipe.
struct Gap {
  double lo, hi;
  bool at_start, at_end;
};

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

// ---------------------------------------------------------------------------------------------

// An inline group the ledger may put on a run: its slot (length, members), what it adds, and
// where it may go.
struct Option {
  Slot slot;
  Mix mix;
  bool mid = true;  // in the middle of a run (else right after or before a bend)
  bool horizontal_only = false;
};

struct Drop {
  int header = 0;
  double x = 0;
  int bore = 2;
  int nozzle = -1;            // destination nozzle, or -1 for a utility station
  int side = 1;               // station side of the rack
  bool side_takeoff = false;  // stations: taken off the header's side, not its top
  std::optional<Port> port;   // the header tee's branch port, once built
};

class Piping {
 public:
  explicit Piping(Unit& unit) : unit_(unit), rng_(unit.rng) {}
  void run(const std::function<void(double)>& progress);

 private:
  // Planning.
  void set_targets();
  void plan();
  // Pipeline kinds; each returns false when it found no valid route (nothing emitted then).
  bool build_header(int h);
  bool build_drop(Drop& d);
  bool build_pump_suction(int pair);
  bool build_pump_discharge(int pair);
  bool build_process(int a, int b);
  bool build_battery_limit(int a);

  // Shared steps.
  LineContext new_line(Service service, int bore);
  void finish_line(LineContext& line);
  std::vector<Item> nozzle_group(LineContext& line, const Nozzle& nozzle, int line_bore,
                                 bool at_start, bool allow_valve);
  std::vector<Item> closure_group(LineContext& line, int bore, bool allow_valve);
  std::vector<SegmentSlots> segments_of(const std::vector<dvec3>& pts, int bore) const;
  bool add_forced_tee(std::vector<SegmentSlots>& segs, const std::vector<dvec3>& pts, int bore,
                      const dvec3& centre, const dvec3& branch_dir, int branch_bore, TeeUse use,
                      int tag, bool olet = false);
  void add_optional(LineContext& line, std::vector<SegmentSlots>& segs,
                    const std::vector<dvec3>& pts, int bore);
  // Builds a branch: start items from the head, the route with its slots, end items. Tee ports
  // go to `ports` (in slot order) with their slots.
  void build_branch(LineContext& line, const Port& head, const std::vector<Item>& start_items,
                    const std::vector<dvec3>& pts, std::vector<SegmentSlots>& segs,
                    const std::vector<Item>& end_items,
                    std::vector<std::pair<Slot, Port>>* tee_ports);
  void build_stub(LineContext& line, const Slot& slot, const Port& port);
  void add_supports(LineContext& line, const Run& run);
  // Picks one of the valid routes by the elbows and pipes it adds (and may insert jump-overs
  // into its long horizontal runs); false when there is none.
  bool pick_route(std::vector<std::vector<dvec3>>& options, int bore, std::vector<dvec3>& pts);
  const Mix& pipe_mix() const { return part_mix(Part::pipe); }
  // Bend radius of the current line's elbows.
  double bend_radius(int bore) const { return lr_bend_radius(bore) * bend_factor_; }

  // Layout helpers.
  const Band* band_of_nozzle(int n) const {
    const EquipmentRecord& e = unit_.equipment[unit_.nozzles[size_t(n)].equipment];
    return e.band >= 0 ? &unit_.bands[size_t(e.band)] : nullptr;
  }
  int rack_of_nozzle(int n) const {
    const Band* b = band_of_nozzle(n);
    return b ? b->rack : 0;
  }
  double lane_z(int tier, const Rack& rack, int bore) const {
    return rack.tiers[size_t(tier)] + 0.1 + 0.5 * pipe_size(bore).od_m;
  }

  Unit& unit_;
  Rng& rng_;
  int line_seq_ = 0;
  int lines_total_ = 1, lines_done_ = 0;
  std::vector<Drop> drops_;
  std::vector<std::vector<int>> header_drops_;
  std::vector<std::pair<int, int>> process_pairs_;
  std::vector<int> battery_limit_nozzles_;
  std::vector<int> discharge_targets_;  // per pump pair: nozzle or -1 (battery limit)
  std::vector<int> feeders_;            // per pump pair: the vessel nozzle feeding it, or -1
  int pump_pairs_ = 0;
  int failures_ = 0;
  dvec3 line_head_{0.0};  // first branch head of the line being built
  Mix pending_;           // chosen for the line being built, not emitted yet
  std::unordered_map<uint32_t, std::vector<Option>> catalogue_;  // inline groups by spec and bore
  bool room(Tally t) const {
    return unit_.ledger.count(t) + pending_.n[t] + 1 <= unit_.ledger.target(t);
  }
  // Whether a mix keeps the small kinds (caps, plugs) within their targets.
  bool small_kinds_fit(const Mix& m) const {
    for (Tally t : {kPrism, kDish}) {
      if (m.n[t] > 0 && unit_.ledger.count(t) + pending_.n[t] + m.n[t] > unit_.ledger.target(t)) {
        return false;
      }
    }
    return true;
  }
  double bend_factor_ = 1.0;  // of the line being built
};

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
// Lines.

std::string four_digits(int n) {
  std::string s = std::to_string(n);
  return std::string(s.size() < 4 ? 4 - s.size() : 0, '0') + s;
}

LineContext Piping::new_line(Service service, int bore) {
  pending_ = Mix{};
  LineContext line(unit_);
  line.service = service;
  line.bore = bore;
  line.name = std::string("/") + service_info(service).code + "-" + unit_.area + "-" +
              four_digits(++line_seq_);
  line.id = unit_.id(line.name);
  unit_.ledger.set_progress(uint64_t(lines_done_ + 1), uint64_t(lines_total_));
  if (service == Service::process) {
    static const char* const kSpecs[] = {"A1A", "B1A", "A3B", "E1A"};
    static const char* const kRatings[] = {"CL150", "CL300", "CL150", "CL150"};
    const uint32_t k = rng_.below(4);
    line.spec = kSpecs[k];
    line.rating = kRatings[k];
  }
  // Flange type of the spec: slip-on or weld neck (a hub cone per flange).
  Mix so, wn;
  for (int i = 0; i < 4; ++i) {
    so += part_mix(Part::flange_so);
    wn += part_mix(Part::flange_wn);
  }
  const Mix options[] = {so, wn};
  line.weld_neck = unit_.ledger.choose(options) == 1;
  line.bend_factor = bend_factor_;
  return line;
}

void Piping::finish_line(LineContext& line) {
  ++lines_done_;
  if (line.branches.empty()) return;
  // The pipeline object sits at its first branch's head; it has no primitives.
  ObjectBuilder b(unit_.origin_m, line_head_, ObjectClass::pipeline);
  Object& o = b.object();
  o.colour = service_info(line.service).colour;
  o.branches = std::move(line.branches);
  const ServiceInfo& svc = service_info(line.service);
  b.attribute("Line number", line.name.substr(1));
  b.attribute("Service", svc.code);
  b.attribute("Fluid", svc.fluid);
  b.attribute("Bore", "DN" + std::to_string(pipe_size(line.bore).dn) + " (" +
                          pipe_size(line.bore).label + ")");
  b.attribute("Spec", line.spec);
  b.attribute("Rating", line.rating);
  b.attribute("Flanges", line.weld_neck ? "Weld neck" : "Slip-on");
  b.attribute("Design pressure", fixed(3.5 + double(rng_.below(300)) / 10.0, 1) + " barg");
  b.attribute("Design temperature", std::to_string(40 + 10 * int(rng_.below(25))) + " degC");
  b.attribute("Insulation", rng_.chance(400) ? "Hot, 50 mm" : "None");
  b.attribute("From", line.from);
  b.attribute("To", line.to);
  b.attribute("Branches", std::to_string(o.branches.size()));
  unit_.emit(b, line.name);
}

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

// ---------------------------------------------------------------------------------------------
// Slots on a route.

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

// ---------------------------------------------------------------------------------------------

bool Piping::pick_route(std::vector<std::vector<dvec3>>& options, int bore,
                        std::vector<dvec3>& pts) {
  if (options.empty()) return false;
  const double r = bend_radius(bore);
  auto mix_of_route = [&](const std::vector<dvec3>& route_pts) {
    Mix m;
    const int corners = int(route_pts.size()) - 2;
    for (int i = 0; i < corners; ++i) m += part_mix(Part::elbow);
    for (int i = route_pipes(route_pts, r); i > 0; --i) m += pipe_mix();
    return m;
  };
  std::vector<Mix> mixes;
  for (const auto& o : options) mixes.push_back(mix_of_route(o));
  pts = std::move(options[unit_.ledger.choose(mixes)]);
  // Jump-overs: a long horizontal run steps up over what it crosses, through four elbows welded
  // to each other at the rises (adds four elbows and two pipes).
  const double rise = 2.0 * r;
  const double width = 2.0 * r + kMinPipe + 0.6;
  Mix jump;
  for (int i = 0; i < 4; ++i) jump += part_mix(Part::elbow);
  jump += pipe_mix();
  jump += pipe_mix();
  for (size_t k = 0; k + 1 < pts.size(); ++k) {
    const dvec3 d = pts[k + 1] - pts[k];
    const double len = glm::length(d);
    const double need = 2.0 * r + 2.0 * kMinPipe + width + 2.0 * r + 1.0;
    if (std::abs(d.z) > 1e-9 || len < need + 4.0) continue;
    if (!unit_.ledger.wants(jump)) continue;
    const dvec3 dir = d / len;
    const double t = (k == 0 ? 0.0 : r) + kMinPipe + 0.5 + (len - need - 1.0) * rng_.unit();
    const dvec3 p = pts[k] + dir * (t + r);
    const dvec3 q = p + dir * width;
    const std::vector<dvec3> jumped{p, p + kUp * rise, q + kUp * rise, q};
    pts.insert(pts.begin() + std::ptrdiff_t(k + 1), jumped.begin(), jumped.end());
    k += 4;
  }
  return true;
}

void Piping::build_branch(LineContext& line, const Port& head, const std::vector<Item>& start_items,
                          const std::vector<dvec3>& pts, std::vector<SegmentSlots>& segs,
                          const std::vector<Item>& end_items,
                          std::vector<std::pair<Slot, Port>>* tee_ports) {
  Run run(line, int(line.branches.size()) + 1, head);
  if (line.branches.empty()) line_head_ = head.position;
  for (const Item& it : start_items) run.straight(it);
  const size_t n = pts.size();
  const Mix two_welds = [] {
    Mix m = part_mix(Part::weld);
    m += part_mix(Part::weld);
    return m;
  }();
  for (size_t k = 0; k + 1 < n; ++k) {
    const dvec3 dir = glm::normalize(pts[k + 1] - pts[k]);
    auto& slots = segs[k].slots;
    std::stable_sort(slots.begin(), slots.end(),
                     [](const Slot& a, const Slot& b) { return a.at < b.at; });
    for (const Slot& slot : slots) {
      const dvec3 p = pts[k] + dir * slot.at;
      if (glm::dot(p - run.position(), dir) > 1e-6) run.pipe_to(p);
      if (slot.tee != TeeUse::none) {
        const Port port = slot.olet ? run.olet(slot.branch_dir, slot.branch_bore)
                                    : run.tee(slot.branch_dir, slot.branch_bore);
        if (tee_ports) tee_ports->push_back({slot, port});
      } else {
        for (const Item& it : slot.items) run.straight(it);
      }
    }
    const bool corner = k + 2 < n;
    const dvec3 end = pts[k + 1] - dir * (corner ? bend_radius(run.bore()) : 0.0);
    if (glm::dot(end - run.position(), dir) > 1e-6) run.pipe_to(end);
    if (corner) {
      const bool welded = unit_.ledger.wants(two_welds);
      if (welded) run.weld();
      run.elbow(pts[k + 1], glm::normalize(pts[k + 2] - pts[k + 1]));
      if (welded) run.weld();
    }
  }
  for (const Item& it : end_items) run.straight(it);
  run.finish();
  add_supports(line, run);
}

// A vent or drain: a short pipe from the tee, then the closure group.
void Piping::build_stub(LineContext& line, const Slot& slot, const Port& port) {
  Run run(line, int(line.branches.size()) + 1, port);
  run.pipe_to(port.position + port.direction * 0.15);
  for (const Item& it : slot.sub_items) run.straight(it);
  run.finish();
}

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

// ---------------------------------------------------------------------------------------------
// Pipeline kinds.

constexpr Service kHeaderServices[] = {
    Service::lp_steam,
    Service::cooling_water_supply,
    Service::cooling_water_return,
    Service::nitrogen,
    Service::instrument_air,
    Service::mp_steam,
    Service::plant_air,
    Service::fuel_gas,
    Service::condensate,
    Service::flare,
};
constexpr int kHeaderServiceCount = int(sizeof kHeaderServices / sizeof kHeaderServices[0]);

// Rack route patterns from a start to an end through lane (y_lane, z_lane): up or down to the
// lane's elevation, across into the lane, along it, and out to the end; the variants first step
// aside (for starts pointing away from the lane's elevation) or reach the end's elevation first.
std::vector<Pattern> rack_patterns(double y_lane, double z_lane, double y_aside) {
  std::vector<Pattern> out;
  for (bool aside : {false, true}) {
    for (bool z_first : {false, true}) {
      Pattern p;
      if (aside) p.push_back({kAxisY, y_aside});
      p.push_back({kAxisZ, z_lane});
      p.push_back({kAxisY, y_lane});
      p.push_back({kAxisX, NAN});
      if (z_first) {
        p.push_back({kAxisZ, NAN});
        p.push_back({kAxisY, NAN});
      } else {
        p.push_back({kAxisY, NAN});
        p.push_back({kAxisZ, NAN});
      }
      out.push_back(std::move(p));
    }
  }
  return out;
}

// Tries the rack's tiers (from a random one) for a lane from x0 to x1; fills the patterns.
bool rack_route(Unit& unit, Rng& rng, int rack_index, int side, double x0, double x1, int bore,
                double bend_r, const dvec3& s, const dvec3& ds, const dvec3& e, const dvec3& de,
                std::vector<std::vector<dvec3>>& options) {
  Rack& rack = unit.racks[size_t(rack_index)];
  const double r = 0.5 * pipe_size(bore).od_m;
  const int tiers = int(rack.tiers.size());
  const int first = int(rng.below(uint32_t(tiers)));
  for (int t = 0; t < tiers; ++t) {
    const int tier = (first + t) % tiers;
    const double y = reserve_lane(rack, tier, x0, x1, pipe_size(bore).od_m, side);
    if (std::isnan(y)) continue;
    const double z = rack.tiers[size_t(tier)] + 0.1 + r;
    const double aside = s.y + side * 1.5;
    if (route(s, ds, e, de, bend_r, r + 0.1, {0.0, 0.4, 1.0}, rack_patterns(y, z, aside), options,
              3)) {
      return true;
    }
    // The lane stays reserved: a later line simply takes the next one.
  }
  return false;
}

bool Piping::build_header(int h) {
  const Service service = kHeaderServices[h % kHeaderServiceCount];
  const int rack_index = h % int(unit_.racks.size());
  Rack& rack = unit_.racks[size_t(rack_index)];
  const int tiers = int(rack.tiers.size());
  int bore = rng_.range(unit_.spec.header_bore_min, unit_.spec.header_bore_max);
  if (service == Service::flare) bore = std::min(kPipeSizeCount - 1, bore + 3);
  const double length = unit_.info.plan_x_m;
  double y = NAN;
  int tier = tiers - 1 - (h / int(unit_.racks.size())) % tiers;
  for (int t = 0; t < tiers && std::isnan(y); ++t) {
    tier = (tier + tiers - (t > 0 ? 1 : 0)) % tiers;
    y = reserve_lane(rack, tier, 0.0, length, pipe_size(bore).od_m, (h % 2) ? 1 : -1);
  }
  if (std::isnan(y)) return false;
  const double z = lane_z(tier, rack, bore);
  LineContext line = new_line(service, bore);
  line.from = "Battery limit";
  line.to = "Header end";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  const Port head{dvec3(0.0, y, z), kX, bore};
  const std::vector<Item> start{item(flange, bore, false)};
  const std::vector<Item> end = closure_group(line, bore, false);
  const dvec3 s = head.position + group_span(start, kX);
  const dvec3 e = dvec3(rack.x_end + 0.8, y, z) - group_span(end, kX);
  const std::vector<dvec3> pts{s, e};
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  // Take-offs for the drops, in x order, spaced apart.
  std::vector<int>& drops = header_drops_[size_t(h)];
  std::stable_sort(drops.begin(), drops.end(),
                   [&](int a, int b) { return drops_[size_t(a)].x < drops_[size_t(b)].x; });
  // Spaced apart: pushed forward from the start, then back from the end.
  const double c = tee_half(bore), spacing = 2 * c + 2 * kMinPipe + 0.2;
  const double first = s.x + c + kMinPipe + 1.0, last = e.x - c - kMinPipe - 0.5;
  double next = first;
  for (int d : drops) {
    Drop& drop = drops_[size_t(d)];
    drop.x = std::max(drop.x, next);
    next = drop.x + spacing;
  }
  next = last;
  for (auto it = drops.rbegin(); it != drops.rend(); ++it) {
    Drop& drop = drops_[size_t(*it)];
    drop.x = std::min(drop.x, next);
    next = drop.x - spacing;
  }
  for (int d : drops) {
    Drop& drop = drops_[size_t(d)];
    if (drop.x < first) continue;  // no room left: the drop will fail
    // Small take-offs from large headers are olets; the rest tees. Stations beside the rack
    // take off the header's top (up, across, down) or its side (across, down).
    bool olet = false;
    if (drop.bore <= 5 && bore - drop.bore >= 2) {
      const Mix options[] = {part_mix(Part::tee), part_mix(Part::olet)};
      olet = unit_.ledger.choose(options) == 1;
    }
    if (drop.nozzle < 0) {
      Mix top, side;  // the top take-off's first elbow can sit right on the tee (no pipe)
      top += part_mix(Part::elbow);
      top += part_mix(Part::elbow);
      side += part_mix(Part::elbow);
      const Mix options[] = {top, side};
      drop.side_takeoff = unit_.ledger.choose(options) == 1;
    }
    const dvec3 takeoff = drop.side_takeoff ? dvec3(0, drop.side, 0) : kUp;
    add_forced_tee(segs, pts, bore, dvec3(drop.x, y, z), takeoff, drop.bore, TeeUse::takeoff, d,
                   olet);
  }
  add_optional(line, segs, pts, bore);
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, head, start, pts, segs, end, &ports);
  for (auto& [slot, port] : ports) {
    if (slot.tee == TeeUse::takeoff) {
      drops_[size_t(slot.tag)].port = port;
    } else {
      build_stub(line, slot, port);
    }
  }
  finish_line(line);
  return true;
}

bool Piping::build_drop(Drop& d) {
  if (!d.port) return false;  // its header had no room left for the take-off
  const Service service = kHeaderServices[d.header % kHeaderServiceCount];
  const Rack& rack = unit_.racks[size_t(d.header % int(unit_.racks.size()))];
  const int bore = d.bore;
  const double r = 0.5 * pipe_size(bore).od_m;
  LineContext line = new_line(service, bore);
  const Port head = *d.port;
  // A block valve at the take-off, or straight on.
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  std::vector<Item> start;
  {
    const std::vector<Item> valve_set{item(flange, bore, true), item(Part::gasket, bore),
                                      item(Part::gate, bore), item(Part::gasket, bore),
                                      item(flange, bore, false)};
    const Mix options[] = {Mix{}, group_mix(valve_set)};
    if (unit_.ledger.choose(options) == 1) start = valve_set;
  }
  const dvec3 s = head.position + group_span(start, head.direction);
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  std::vector<Item> end;
  bool ok = false;
  line.from = "Header take-off";
  if (d.nozzle >= 0) {
    const Nozzle& n = unit_.nozzles[size_t(d.nozzle)];
    end = nozzle_group(line, n, bore, false, true);
    const dvec3 e = n.position - group_span(end, -n.direction);
    const Band* band = band_of_nozzle(d.nozzle);
    const int side = band ? band->side : 1;
    const double y_exit = rack.y_centre + side * (0.5 * rack.width + 0.6);
    std::vector<Pattern> patterns = permutations({{kAxisY, y_exit}});
    for (const Pattern& p : permutations({})) patterns.push_back(p);
    ok = route(s, head.direction, e, -n.direction, bend_radius(bore), r + 0.1, {0.0, 0.5, 1.0, 1.8},
               patterns, options, 4) &&
         pick_route(options, bore, pts);
    if (ok) {
      unit_.nozzles[size_t(d.nozzle)].used = true;
      line.to = unit_.equipment[n.equipment].tag;
    }
  }
  if (!ok) {
    // A utility station beside the rack: a hose connection 1 m above grade, below the take-off
    // or a few metres along the rack; steam stations drain through a trap first.
    end = closure_group(line, bore, true);
    if (service == Service::lp_steam || service == Service::mp_steam ||
        service == Service::condensate) {
      const Mix trap_options[] = {Mix{}, part_mix(Part::trap)};
      if (unit_.ledger.choose(trap_options) == 1) end.insert(end.begin(), item(Part::trap, bore));
    }
    const double y_station = rack.y_centre + d.side * (0.5 * rack.width + 0.6);
    // The hose connection points down, or along the rack from an elbow at the drop's foot.
    std::vector<std::vector<dvec3>> all;
    for (double shift : {0.0, 2.5, -2.5}) {
      for (const dvec3& de : {kDown, kX, -kX}) {
        const dvec3 q(head.position.x + shift, y_station, 1.0);
        const dvec3 e = q - group_span(end, de);
        const std::vector<Pattern> patterns{{{kAxisY, y_station}, {kAxisX, NAN}, {kAxisZ, NAN}},
                                            {{kAxisY, y_station}, {kAxisZ, NAN}, {kAxisX, NAN}}};
        if (route(s, head.direction, e, de, bend_radius(bore), r + 0.1, {0.0, 0.5}, patterns,
                  options, 2)) {
          for (auto& o : options) all.push_back(std::move(o));
        }
      }
    }
    ok = pick_route(all, bore, pts);
    line.to = "Utility station";
  }
  if (!ok) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  add_optional(line, segs, pts, bore);
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, head, start, pts, segs, end, &ports);
  for (auto& [slot, port] : ports) build_stub(line, slot, port);
  finish_line(line);
  return true;
}

// Pump suction: from the feeding vessel's bottom outlet down to a header in front of the pump
// pair, a tee for the near pump and an elbow into the far one; each pump gets a block valve, a
// strainer and an eccentric reducer (flat on top) before its suction flange.
bool Piping::build_pump_suction(int pair) {
  const int feeder = feeders_[size_t(pair)];
  int ia = -1;
  for (size_t i = 0; i < unit_.equipment.size(); ++i) {
    if (unit_.equipment[i].pump_pair == pair && unit_.equipment[i].pump_letter == 'A') ia = int(i);
  }
  if (ia < 0) return false;
  const EquipmentRecord& pa = unit_.equipment[size_t(ia)];
  const EquipmentRecord& pb = unit_.equipment[size_t(ia + 1)];
  const Nozzle& na = unit_.nozzles[pa.nozzles[0]];
  const Nozzle& nb = unit_.nozzles[pb.nozzles[0]];
  // The source: the feeding vessel's outlet, or else a battery-limit flange on the rack.
  Nozzle f;
  int lane_tier = -1;
  const int rack_index = pa.band >= 0 ? unit_.bands[size_t(pa.band)].rack : 0;
  Rack& rack = unit_.racks[size_t(rack_index)];
  if (feeder >= 0) {
    f = unit_.nozzles[size_t(feeder)];
  } else {
    f.bore = std::min(kPipeSizeCount - 1, na.bore + 1);
    const bool west = na.position.x < 0.5 * unit_.info.plan_x_m;
    const double x_bl = west ? 0.0 : unit_.info.plan_x_m;
    const int side = pa.band >= 0 ? unit_.bands[size_t(pa.band)].side : 1;
    for (int t = 0; t < int(rack.tiers.size()) && lane_tier < 0; ++t) {
      const double y = reserve_lane(rack, t, x_bl, na.position.x, pipe_size(f.bore).od_m, side);
      if (std::isnan(y)) continue;
      lane_tier = t;
      f.position = dvec3(x_bl, y, lane_z(t, rack, f.bore));
    }
    if (lane_tier < 0) return false;
    f.direction = dvec3(west ? 1.0 : -1.0, 0, 0);
  }
  const int bore = std::min(kPipeSizeCount - 1, std::max(f.bore, na.bore + 1));
  const double big_r = bend_radius(bore), c = tee_half(bore);
  const double dx = f.position.x <= 0.5 * (na.position.x + nb.position.x) ? 1.0 : -1.0;
  const bool a_far = (na.position.x - nb.position.x) * dx > 0;
  const Nozzle& far = a_far ? na : nb;
  const Nozzle& near = a_far ? nb : na;
  LineContext line = new_line(Service::process, bore);
  line.from = feeder >= 0 ? unit_.equipment[f.equipment].tag : std::string("Battery limit");
  line.to = pa.tag + "/B";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  // Pump end group, in flow order.
  std::vector<Item> end;
  {
    // A block valve: flanged, or butt-welded into the line.
    const Part valve = bore >= 8 && rng_.chance(500) ? Part::butterfly : Part::gate;
    const std::vector<Item> flanged{item(flange, bore, true), item(Part::gasket, bore),
                                    item(valve, bore), item(Part::gasket, bore),
                                    item(flange, bore, false)};
    const std::vector<Item> welded{item(Part::weld, bore), item(Part::ball_welded, bore),
                                   item(Part::weld, bore)};
    const Mix valve_options[] = {group_mix(flanged), group_mix(welded)};
    end = unit_.ledger.choose(valve_options) == 0 ? flanged : welded;
    const Mix strainer_options[] = {Mix{}, part_mix(Part::strainer)};
    if (unit_.ledger.choose(strainer_options) == 1) end.push_back(item(Part::strainer, bore));
    const Mix reducer_options[] = {part_mix(Part::reducer_conc), part_mix(Part::reducer_ecc)};
    const Part reducer =
        unit_.ledger.choose(reducer_options) == 1 ? Part::reducer_ecc : Part::reducer_conc;
    end.push_back({reducer, bore, far.bore, true});
    end.push_back(item(flange, far.bore, true));
    end.push_back(item(Part::gasket, far.bore));
  }
  const dvec3 arrive = -far.direction;
  const dvec3 e_far = far.position - group_span(end, arrive);
  const dvec3 e_near = near.position - group_span(end, arrive);
  const double leg = std::max(big_r, c) + kMinPipe + 0.3;
  const dvec3 corner = e_far - arrive * leg;
  const dvec3 tee_centre(e_near.x, corner.y, corner.z);
  // Vessel side.
  const Port head{f.position, f.direction, f.bore};
  const std::vector<Item> start = feeder >= 0 ? nozzle_group(line, f, bore, true, true)
                                              : std::vector<Item>{item(flange, bore, false)};
  const dvec3 s = head.position + group_span(start, f.direction);
  std::vector<dvec3> pts;
  const double run_in = std::abs(far.position.x - near.position.x) + c + 2 * big_r + 0.4;
  std::vector<Pattern> patterns = local_patterns(s, corner, big_r);
  if (feeder < 0) {
    // Along the lane to above the pumps, then down beside the rack.
    const double y_out = corner.y;
    patterns.insert(patterns.begin(),
                    Pattern{{kAxisX, corner.x - dx * run_in}, {kAxisY, y_out}, {kAxisZ, NAN}});
  }
  std::vector<std::vector<dvec3>> options;
  if (!route(s, f.direction, corner, dvec3(dx, 0, 0), big_r, 0.5 * pipe_size(bore).od_m + 0.1,
             {0.0, 0.4, 1.0, 2.0}, patterns, options, 3, 0.0, run_in) ||
      !pick_route(options, bore, pts)) {
    return false;
  }
  pts.push_back(e_far);
  if (!simplify(pts) || !long_enough(pts, big_r, 0.1)) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  if (!add_forced_tee(segs, pts, bore, tee_centre, arrive, bore, TeeUse::pump_suction, 0)) {
    return false;
  }
  add_optional(line, segs, pts, bore);
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, head, start, pts, segs, end, &ports);
  for (auto& [slot, port] : ports) {
    if (slot.tee == TeeUse::pump_suction) {
      Run run(line, int(line.branches.size()) + 1, port);
      if (glm::dot(e_near - port.position, port.direction) > 1e-6) run.pipe_to(e_near);
      for (const Item& it : end) run.straight(it);
      run.finish();
    } else {
      build_stub(line, slot, port);
    }
  }
  if (feeder >= 0) unit_.nozzles[size_t(feeder)].used = true;
  finish_line(line);
  return true;
}

// Pump discharge: each pump rises through a check valve and a block valve; the second pump's
// riser joins the first one's line at a tee, which then runs to its destination over the rack.
bool Piping::build_pump_discharge(int pair) {
  int ia = -1;
  for (size_t i = 0; i < unit_.equipment.size(); ++i) {
    if (unit_.equipment[i].pump_pair == pair && unit_.equipment[i].pump_letter == 'A') ia = int(i);
  }
  if (ia < 0) {
    return false;
  }
  const EquipmentRecord& pa = unit_.equipment[size_t(ia)];
  const EquipmentRecord& pb = unit_.equipment[size_t(ia + 1)];
  const Nozzle& na = unit_.nozzles[pa.nozzles[1]];
  const Nozzle& nb = unit_.nozzles[pb.nozzles[1]];
  const int target = discharge_targets_[size_t(pair)];
  const int bore = std::min(unit_.spec.line_bore_max + 1, na.bore + 1);
  const double big_r = bend_radius(bore), c = tee_half(bore);
  const int rack_index = pa.band >= 0 ? unit_.bands[size_t(pa.band)].rack : 0;
  const Rack& rack = unit_.racks[size_t(rack_index)];
  const int side = pa.band >= 0 ? unit_.bands[size_t(pa.band)].side : 1;
  const double x_dest =
      target >= 0 ? unit_.nozzles[size_t(target)].position.x
                  : (na.position.x < 0.5 * unit_.info.plan_x_m ? 0.0 : unit_.info.plan_x_m);
  const double dx = x_dest >= 0.5 * (na.position.x + nb.position.x) ? 1.0 : -1.0;
  const bool a_first = (nb.position.x - na.position.x) * dx > 0;
  const Nozzle& first = a_first ? na : nb;
  const Nozzle& second = a_first ? nb : na;
  LineContext line = new_line(Service::process, bore);
  line.from = pa.tag + "/B";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  // Each riser: the pump's flange, a reducer, then a check valve and a block valve (bolted
  // together between flanges, or butt-welded).
  const std::vector<Item> flanged{item(Part::gasket, na.bore),
                                  item(flange, na.bore, false),
                                  {Part::reducer_conc, na.bore, bore, true},
                                  item(flange, bore, true),
                                  item(Part::gasket, bore),
                                  item(Part::check, bore),
                                  item(Part::gasket, bore),
                                  item(Part::gate, bore),
                                  item(Part::gasket, bore),
                                  item(flange, bore, false)};
  const std::vector<Item> welded{item(Part::gasket, na.bore),
                                 item(flange, na.bore, false),
                                 {Part::reducer_conc, na.bore, bore, true},
                                 item(Part::weld, bore),
                                 item(Part::check, bore),
                                 item(Part::weld, bore),
                                 item(Part::ball_welded, bore),
                                 item(Part::weld, bore)};
  const std::vector<Item> check_only{item(Part::gasket, na.bore),
                                     item(flange, na.bore, false),
                                     {Part::reducer_conc, na.bore, bore, true},
                                     item(Part::weld, bore),
                                     item(Part::check, bore),
                                     item(Part::weld, bore)};
  const Mix riser_options[] = {group_mix(flanged), group_mix(welded), group_mix(check_only)};
  const size_t riser = unit_.ledger.choose(riser_options);
  const std::vector<Item> start = riser == 0 ? flanged : riser == 1 ? welded : check_only;
  const dvec3 s_first = first.position + group_span(start, kUp);
  const dvec3 s_second = second.position + group_span(start, kUp);
  const dvec3 corner(s_first.x, s_first.y, s_first.z + big_r + kMinPipe + 0.3 + c);
  const dvec3 tee_centre(s_second.x, corner.y, corner.z);
  // Destination.
  std::vector<Item> end;
  dvec3 e, de;
  if (target >= 0) {
    const Nozzle& t = unit_.nozzles[size_t(target)];
    end = nozzle_group(line, t, bore, false, false);
    e = t.position - group_span(end, -t.direction);
    de = -t.direction;
    line.to = unit_.equipment[t.equipment].tag;
  } else {
    end = {item(flange, bore, true), item(Part::gasket, bore),  item(Part::gate, bore),
           item(Part::gasket, bore), item(flange, bore, false), item(flange, bore, true)};
    de = dvec3(dx, 0, 0);
    line.to = "Battery limit";
  }
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  const double run_out = std::abs(second.position.x - first.position.x) + c + 2 * big_r + 0.4;
  bool ok = false;
  if (target >= 0) {
    for (int attempt = 0; attempt < 3 && !ok; ++attempt) {
      const int tier = int(rng_.below(uint32_t(rack.tiers.size())));
      Rack& rk = unit_.racks[size_t(rack_index)];
      const double y = reserve_lane(rk, tier, corner.x, e.x, pipe_size(bore).od_m, side);
      if (std::isnan(y)) continue;
      const double z = lane_z(tier, rk, bore);
      std::vector<Pattern> patterns = rack_patterns(y, z, corner.y);
      for (const Pattern& p : local_patterns(corner, e, big_r)) patterns.push_back(p);
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.5 * pipe_size(bore).od_m + 0.1,
                 {0.0, 0.5, 1.2}, patterns, options, 3, run_out) &&
           pick_route(options, bore, pts);
    }
    if (!ok) {
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.5 * pipe_size(bore).od_m + 0.1,
                 {0.0, 0.5, 1.2}, local_patterns(corner, e, big_r), options, 3, run_out) &&
           pick_route(options, bore, pts);
    }
  } else {
    Rack& rk = unit_.racks[size_t(rack_index)];
    for (int tier = 0; tier < int(rk.tiers.size()) && !ok; ++tier) {
      const double y = reserve_lane(rk, tier, corner.x, x_dest, pipe_size(bore).od_m, side);
      if (std::isnan(y)) continue;
      const double z = lane_z(tier, rk, bore);
      const dvec3 q(dx > 0 ? unit_.info.plan_x_m - 0.02 : 0.02, y, z);
      e = q - group_span(end, de);
      const std::vector<Pattern> patterns{{{kAxisZ, z}, {kAxisY, y}, {kAxisX, NAN}}};
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.1, {0.0, 0.5, 1.2}, patterns, options, 3,
                 run_out) &&
           pick_route(options, bore, pts);
    }
    if (!ok) {
      // No lane left toward that end: along the pump row to a battery limit at grade level.
      const dvec3 q(dx > 0 ? unit_.info.plan_x_m - 0.02 : 0.02, corner.y, corner.z);
      e = q - group_span(end, de);
      ok = route(corner, dvec3(dx, 0, 0), e, de, big_r, 0.1, {0.0, 0.5, 1.2},
                 local_patterns(corner, e, big_r), options, 3, run_out) &&
           pick_route(options, bore, pts);
    }
  }
  if (!ok) {
    return false;
  }
  pts.insert(pts.begin(), s_first);
  if (!simplify(pts) || !long_enough(pts, big_r, 0.1)) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  if (!add_forced_tee(segs, pts, bore, tee_centre, kDown, bore, TeeUse::pump_discharge, 0)) {
    return false;
  }
  add_optional(line, segs, pts, bore);
  const Port head{first.position, kUp, first.bore};
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, head, start, pts, segs, end, &ports);
  for (auto& [slot, port] : ports) {
    if (slot.tee == TeeUse::pump_discharge) {
      // The second pump's riser flows up into the tee.
      Run run(line, int(line.branches.size()) + 1, Port{second.position, kUp, second.bore});
      for (const Item& it : start) run.straight(it);
      if (glm::dot(port.position - run.position(), kUp) > 1e-6) run.pipe_to(port.position);
      run.finish();
    } else {
      build_stub(line, slot, port);
    }
  }
  if (target >= 0) unit_.nozzles[size_t(target)].used = true;
  finish_line(line);
  return true;
}

bool Piping::build_process(int ia, int ib) {
  const Nozzle& a = unit_.nozzles[size_t(ia)];
  const Nozzle& b = unit_.nozzles[size_t(ib)];
  int bore = std::max(a.bore, b.bore);
  {
    // One size up now and then (reducers at both ends).
    Mix same, up;
    up += part_mix(Part::reducer_conc);
    up += part_mix(Part::reducer_conc);
    const Mix options[] = {same, up};
    if (bore + 1 <= unit_.spec.line_bore_max + 1 && unit_.ledger.choose(options) == 1) ++bore;
  }
  LineContext line = new_line(Service::process, bore);
  line.from = unit_.equipment[a.equipment].tag;
  line.to = unit_.equipment[b.equipment].tag;
  const std::vector<Item> start =
      nozzle_group(line, a, bore, true, a.direction.z > -0.5 || a.position.z > 2.2);
  const std::vector<Item> end =
      nozzle_group(line, b, bore, false, b.direction.z > -0.5 || b.position.z > 2.2);
  const dvec3 s = a.position + group_span(start, a.direction);
  const dvec3 e = b.position - group_span(end, -b.direction);
  const double big_r = bend_radius(bore), min_z = 0.5 * pipe_size(bore).od_m + 0.1;
  const Band* band_a = band_of_nozzle(ia);
  const Band* band_b = band_of_nozzle(ib);
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  bool ok = false;
  const bool local = band_a == band_b && std::abs(a.position.x - b.position.x) < 25.0;
  if (local) {
    ok = route(s, a.direction, e, -b.direction, big_r, min_z, {0.0, 0.4, 1.0, 2.0},
               local_patterns(s, e, big_r), options, 3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    ok = rack_route(unit_, rng_, rack_of_nozzle(ia), band_a ? band_a->side : 1, s.x, e.x, bore,
                    big_r, s, a.direction, e, -b.direction, options) &&
         pick_route(options, bore, pts);
  }
  if (!ok && !local) {
    ok = route(s, a.direction, e, -b.direction, big_r, min_z, {0.0, 0.4, 1.0, 2.0},
               local_patterns(s, e, big_r), options, 3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  add_optional(line, segs, pts, bore);
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, Port{a.position, a.direction, a.bore}, start, pts, segs, end, &ports);
  for (auto& [slot, port] : ports) build_stub(line, slot, port);
  unit_.nozzles[size_t(ia)].used = unit_.nozzles[size_t(ib)].used = true;
  finish_line(line);
  return true;
}

bool Piping::build_battery_limit(int ia) {
  const Nozzle& a = unit_.nozzles[size_t(ia)];
  const int bore = a.bore;
  LineContext line = new_line(Service::process, bore);
  line.from = unit_.equipment[a.equipment].tag;
  line.to = "Battery limit";
  const Part flange = line.weld_neck ? Part::flange_wn : Part::flange_so;
  const std::vector<Item> start = nozzle_group(line, a, bore, true, true);
  const std::vector<Item> end{item(flange, bore, true),  item(Part::gasket, bore),
                              item(Part::gate, bore),    item(Part::gasket, bore),
                              item(flange, bore, false), item(Part::spectacle, bore),
                              item(flange, bore, true)};
  const dvec3 s = a.position + group_span(start, a.direction);
  const double x_bl = a.position.x < 0.5 * unit_.info.plan_x_m ? 0.02 : unit_.info.plan_x_m - 0.02;
  const dvec3 de(x_bl < 1.0 ? -1.0 : 1.0, 0, 0);
  const Band* band = band_of_nozzle(ia);
  Rack& rack = unit_.racks[size_t(rack_of_nozzle(ia))];
  std::vector<dvec3> pts;
  std::vector<std::vector<dvec3>> options;
  bool ok = false;
  for (int tier = 0; tier < int(rack.tiers.size()) && !ok; ++tier) {
    const double y =
        reserve_lane(rack, tier, s.x, x_bl, pipe_size(bore).od_m, band ? band->side : 1);
    if (std::isnan(y)) continue;
    const double z = lane_z(tier, rack, bore);
    const dvec3 e = dvec3(x_bl, y, z) - group_span(end, de);
    std::vector<Pattern> patterns;
    for (bool aside : {false, true}) {
      Pattern p;
      if (aside) p.push_back({kAxisY, s.y + (band ? band->side : 1) * 1.5});
      p.push_back({kAxisZ, z});
      p.push_back({kAxisY, y});
      p.push_back({kAxisX, NAN});
      patterns.push_back(p);
    }
    ok = route(s, a.direction, e, de, bend_radius(bore), 0.1, {0.0, 0.4, 1.0}, patterns, options,
               3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    // No lane left toward that end: to a battery limit at the nozzle's elevation.
    const dvec3 e = dvec3(x_bl, s.y, std::max(s.z, 1.0)) - group_span(end, de);
    ok = route(s, a.direction, e, de, bend_radius(bore), 0.1, {0.0, 0.4, 1.0},
               local_patterns(s, e, bend_radius(bore)), options, 3) &&
         pick_route(options, bore, pts);
  }
  if (!ok) {
    return false;
  }
  std::vector<SegmentSlots> segs = segments_of(pts, bore);
  add_optional(line, segs, pts, bore);
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, Port{a.position, a.direction, a.bore}, start, pts, segs, end, &ports);
  for (auto& [slot, port] : ports) build_stub(line, slot, port);
  unit_.nozzles[size_t(ia)].used = true;
  finish_line(line);
  return true;
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
    const auto [kind, index] = tasks[i];
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

}  // namespace

void build_piping(Unit& unit, const std::function<void(double)>& progress) {
  Piping piping(unit);
  piping.run(progress);
}

}  // namespace plantview::gen
