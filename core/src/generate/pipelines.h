// Internal: the piping stage's pipelines, shared by its files. piping.cpp runs the stage (targets,
// plan, one line after another); the others each hold one step of building a line:
//   piping_route.cpp     orthogonal routes between two ends
//   piping_slots.cpp     where fittings and tees sit on a route
//   piping_groups.cpp    which fittings: nozzle ends, closures, optional inline groups
//   piping_branch.cpp    a line's start, its branches and its common tail
//   piping_supports.cpp  supports under a branch's pipes and elbows
//   piping_headers.cpp   utility headers and their drops
//   piping_pumps.cpp     pump suction and discharge lines
//   piping_process.cpp   process lines between nozzles and to the battery limit
//
// Lengths in metres, unit-local coordinates (generator.h). Every choice that changes what is
// emitted goes through the unit's ledger or its Rng, in a fixed order: the same seed builds the
// same lines on every machine.
#pragma once

#include <array>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "piping.h"
#include "presets.h"

namespace plantview::gen::pipelines {

inline constexpr double kMinPipe = 0.12;  // shortest pipe left between two members

inline double lr_bend_radius(int bore) { return pipe_size(bore).elbow_r_m; }
inline double tee_half(int bore) { return 0.5 * item_length(item(Part::tee, bore)); }

// ---------------------------------------------------------------------------------------------
// Routes (piping_route.cpp): polylines of axis-aligned segments, [start, corners..., end].

enum Axis : uint8_t { kAxisX, kAxisY, kAxisZ };
struct Move {
  Axis axis;
  double target;            // NAN: the end's coordinate on that axis
  bool from_start = false;  // target is an offset from the route's start
};
using Pattern = std::vector<Move>;

// Drops zero-length moves and merges straight-on ones; false on a U-turn or a non-right angle.
bool simplify(std::vector<dvec3>& pts);
// Every segment holds its elbows' bend radii and a pipe, or exactly the bend radii (elbows
// welded to each other or to the end's fitting, no pipe); every point stays above min_z.
bool long_enough(const std::vector<dvec3>& pts, double bend_r, double min_z);
// Pipes a route needs (segments longer than their bends).
int route_pipes(const std::vector<dvec3>& pts, double bend_r);

// From s (flow along ds) to e (flow arriving along de): stubs along ds and de, then the moves of
// a pattern, for each stub length and pattern in turn. A stub of 0 puts the first (last) elbow
// right at s (e). Collects up to `max_options` valid routes (distinct in elbows or pipes) into
// `out`; returns whether it found any.
bool route(const dvec3& s, const dvec3& ds, const dvec3& e, const dvec3& de, double bend_r,
           double min_z, std::initializer_list<double> stubs, const std::vector<Pattern>& patterns,
           std::vector<std::vector<dvec3>>& out, size_t max_options = 1,
           double min_start_stub = 0.0, double min_end_stub = 0.0);

// The three moves in every order, after the moves of `prefix`.
std::vector<Pattern> permutations(const Pattern& prefix);
// Patterns between two nearby ends (the same for every call with the same ends and radius).
const std::vector<Pattern>& local_patterns(const dvec3& s, const dvec3& e, double bend_r);
// Patterns through a rack lane at (y_lane, z_lane); the variants step aside to y_aside first.
std::vector<Pattern> rack_patterns(double y_lane, double z_lane, double y_aside);
// Tries the rack's tiers (from a random one) for a lane from x0 to x1 and routes through it;
// the lane stays reserved whether or not a route is found.
bool rack_route(Unit& unit, Rng& rng, int rack_index, int side, double x0, double x1, int bore,
                double bend_r, const dvec3& s, const dvec3& ds, const dvec3& e, const dvec3& de,
                std::vector<std::vector<dvec3>>& options);

// ---------------------------------------------------------------------------------------------
// Slots (piping_slots.cpp): what sits on a route segment besides pipes, at a distance from the
// segment's start.

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

double group_length(const std::vector<Item>& items);
dvec3 group_span(const std::vector<Item>& items, const dvec3& dir);
Mix group_mix(const std::vector<Item>& items);

// The free stretches of a segment between its slots; a group goes right after the segment's
// start or before its end (no pipe in between), or in the middle of a gap (splitting a pipe),
// always leaving no pipe or one of at least kMinPipe.
struct Gap {
  double lo, hi;
  bool at_start, at_end;
};
std::vector<Gap> gaps_of(const SegmentSlots& seg);
// Whether a group of `length` fits one of the gaps (in the middle of one when `mid`).
bool fits(const std::vector<Gap>& gaps, double length, bool mid);
// Where a group of `length` goes in the first gap that takes it (NAN if none); middle places
// are drawn from `rng`.
double place(const std::vector<Gap>& gaps, double length, bool mid, Rng& rng);

// ---------------------------------------------------------------------------------------------
// The stage.

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

// Builds one unit's pipelines: one object holds the stage's state for the unit, and every line
// is built by one of the six build_* functions below, which end in finish_branch.
class Piping {
 public:
  explicit Piping(Unit& unit) : unit_(unit), rng_(unit.rng) {}
  void run(const std::function<void(double)>& progress);

 private:
  // Planning (piping.cpp).
  void set_targets();
  void plan();
  // Pipeline kinds; each returns false when it found no valid route (nothing emitted then).
  bool build_header(int h);             // piping_headers.cpp
  bool build_drop(Drop& d);             // piping_headers.cpp
  bool build_pump_suction(int pair);    // piping_pumps.cpp
  bool build_pump_discharge(int pair);  // piping_pumps.cpp
  bool build_process(int a, int b);     // piping_process.cpp
  bool build_battery_limit(int a);      // piping_process.cpp

  // A line's start and end (piping_branch.cpp).
  LineContext new_line(Service service, int bore);
  void finish_line(LineContext& line);
  // Fittings (piping_groups.cpp).
  std::vector<Item> nozzle_group(LineContext& line, const Nozzle& nozzle, int line_bore,
                                 bool at_start, bool allow_valve);
  std::vector<Item> closure_group(LineContext& line, int bore, bool allow_valve);
  void add_optional(LineContext& line, std::vector<SegmentSlots>& segs,
                    const std::vector<dvec3>& pts, int bore);
  // Slots (piping_slots.cpp).
  std::vector<SegmentSlots> segments_of(const std::vector<dvec3>& pts, int bore) const;
  bool add_forced_tee(std::vector<SegmentSlots>& segs, const std::vector<dvec3>& pts, int bore,
                      const dvec3& centre, const dvec3& branch_dir, int branch_bore, TeeUse use,
                      int tag, bool olet = false);
  // Branches (piping_branch.cpp).
  // Picks one of the valid routes by the elbows and pipes it adds (and may insert jump-overs
  // into its long horizontal runs); false when there is none.
  bool pick_route(std::vector<std::vector<dvec3>>& options, int bore, std::vector<dvec3>& pts);
  // Builds a branch: start items from the head, the route with its slots, end items. Tee ports
  // go to `tee_ports` (in slot order) with their slots.
  void build_branch(LineContext& line, const Port& head, const std::vector<Item>& start_items,
                    const std::vector<dvec3>& pts, std::vector<SegmentSlots>& segs,
                    const std::vector<Item>& end_items,
                    std::vector<std::pair<Slot, Port>>* tee_ports);
  void build_stub(LineContext& line, const Slot& slot, const Port& port);
  // The tail every line kind ends with, once its route and forced tees are in `segs`: optional
  // inline groups, the main branch from `head`, a stub on every vent and drain tee, the nozzles
  // it joins (indices, -1 for none) marked used, and the pipeline object. `on_tee` builds what
  // the kind's own tees (take-offs, the second pump's branch) carry, in slot order with the
  // stubs; a line without such tees passes none.
  using TeeBuilder = std::function<void(const Slot& slot, const Port& port)>;
  void finish_branch(LineContext& line, const Port& head, const std::vector<Item>& start_items,
                     const std::vector<dvec3>& pts, std::vector<SegmentSlots>& segs,
                     const std::vector<Item>& end_items, std::initializer_list<int> joined_nozzles,
                     const TeeBuilder& on_tee = nullptr);
  // Supports (piping_supports.cpp).
  void add_supports(LineContext& line, const Run& run);

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
  double bend_factor_ = 1.0;  // bend radius factor of the line being built
};

}  // namespace plantview::gen::pipelines
