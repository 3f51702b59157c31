// Piping routes: orthogonal polylines between two branch ends. Rule: every turn is a right angle
// (an elbow of the line's bend radius), every segment holds its elbows' bends plus a pipe of at
// least kMinPipe or no pipe at all, and no point sinks below the route's lowest centreline.
// Patterns name the order of the moves; candidates are tried in a fixed order, so that the same
// ends give the same routes on every machine.
#include "pipelines.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace plantview::gen::pipelines {

namespace {

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

// simplify, long_enough and route_pipes (pipelines.h) over the first `count` points of any
// sequence: the route search runs them on fixed arrays.
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

template <class Seq>
int route_pipes(const Seq& pts, size_t n, double bend_r) {
  int pipes = 0;
  for (size_t k = 0; k + 1 < n; ++k) {
    const double bends = (k > 0 ? bend_r : 0.0) + (k + 2 < n ? bend_r : 0.0);
    if (glm::length(pts[k + 1] - pts[k]) > bends + 1e-6) ++pipes;
  }
  return pipes;
}

}  // namespace

bool simplify(std::vector<dvec3>& pts) {
  Points m;
  if (pts.size() > m.p.size() || !simplify_into(pts, pts.size(), m)) return false;
  pts = m.vector();
  return true;
}

bool long_enough(const std::vector<dvec3>& pts, double bend_r, double min_z) {
  return long_enough(pts, pts.size(), bend_r, min_z);
}

int route_pipes(const std::vector<dvec3>& pts, double bend_r) {
  return route_pipes(pts, pts.size(), bend_r);
}

bool route(const dvec3& s, const dvec3& ds, const dvec3& e, const dvec3& de, double bend_r,
           double min_z, std::initializer_list<double> stubs, const std::vector<Pattern>& patterns,
           std::vector<std::vector<dvec3>>& out, size_t max_options, double min_start_stub,
           double min_end_stub) {
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

}  // namespace plantview::gen::pipelines
