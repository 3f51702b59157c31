// FacetGroup (RVM facet group): polygons with holes, triangulated once by triangulate(). No
// template: the plan's only level points straight at the group's own `triangles`, valid while the
// group lives unchanged. One level, no error (the mesh is the shape).
//
// Vertex layout: the group's vertices as they are (vertex_count = vertices.size(), 0 when there
// are no triangles), each with its own normal. A vertex with a non-finite position (triangulate()
// leaves it out of every triangle) is written at a finite stand-in, the first triangle's first
// vertex, so that no NaN reaches the renderer and the bounds still hold.
//
// Triangulation (per polygon): project the contours to the plane of the outer contour's Newell
// normal, facing the side the vertex normals point to; link the outer contour counter-clockwise
// and the holes clockwise; bridge each hole to a visible outer vertex (Eberly's method, holes from
// left to right); clip ears. Where no ear is left: drop duplicate and collinear points, then cure
// small self-intersections, then split the ring along a valid diagonal and start again on both
// halves. This is the approach of mapbox/earcut, with its z-order hashing for polygons of more
// than 80 points (the ear test looks only at points near the ear: same triangles, less work),
// and, for polygons of more than 64 holes, the bridge search looking only at the edges and
// points in horizontal bands at the hole's height (one walk of the whole ring per hole made
// 20,000 holes take a minute).
//
// Time bound: every loop draws on a work budget of 64 n min(n, 64) + 65536 steps (n points in
// the polygon; a step is one point or edge looked at, tens of nanoseconds at most), so a polygon
// of n points takes O(n) time: at most 4096 steps a point once n > 64, and a facet group, an
// RVM file, in time proportional to its bytes (a point is 24 bytes of RVM). Polygons of up to 64
// points keep the whole 64 n^2 + 65536 budget. Memory: about 80 bytes a point, plus the bands
// (at most 16 entries a point). When the budget runs out the polygon keeps the triangles made so
// far, the rest of its area is left out, and triangulate() counts it as skipped (the RVM
// parser's warning names the facet group). Measured: a 200 x 100 grid of square holes (80,004
// points) spends 2,800 steps a point, 70% of its budget (bridging is linear in the holes times
// the holes in a row, clipping the long ears between rows a little worse than linear), so a
// grid of much more than 20,000 holes in one polygon ends partly triangulated, with the warning.
#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "kinds.h"

namespace plantview::detail {

namespace {

bool is_finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// A contour (or a polygon's whole area) smaller than this times its extent squared has no area.
constexpr double kRelativeAreaEpsilon = 1e-12;

// Ear clipping of one polygon given in 2D, its outer contour counter-clockwise (or made so) and
// its holes. Appends triangles (vertex indices), counter-clockwise in the 2D frame.
class EarClipper {
 public:
  explicit EarClipper(std::vector<uint32_t>& out) : out_(out) {}

  // points[ring_ends[r-1] .. ring_ends[r]) is ring r (ring 0 outer, the rest holes), each with at
  // least 3 points; ids[i] is point i's vertex index. Returns false if part of the polygon was
  // left out (a hole without a bridge, or the work budget ran out).
  bool run(const std::vector<glm::dvec2>& points, const std::vector<uint32_t>& ids,
           std::span<const uint32_t> ring_ends);

 private:
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  struct Node {
    double x, y;
    uint32_t vertex;
    uint32_t prev, next;
    // The ring being clipped in z-order (is_ear's search), when it is hashed: kNone at the ends.
    uint32_t z, prev_z, next_z;
    bool removed;
  };
  struct Job {
    uint32_t ear;
    int pass;
  };

  Node& n(uint32_t i) { return nodes_[i]; }
  // One unit of work; false once the budget is spent (every loop then unwinds).
  bool tick() {
    if (steps_left_ == 0) return false;
    --steps_left_;
    return true;
  }

  // Twice the signed area of p, q, r: positive when they turn clockwise, negative when they turn
  // counter-clockwise (a convex corner of a counter-clockwise ring).
  static double cw_area(const Node& p, const Node& q, const Node& r) {
    return (q.y - p.y) * (r.x - q.x) - (q.x - p.x) * (r.y - q.y);
  }
  double cw_area(uint32_t p, uint32_t q, uint32_t r) { return cw_area(n(p), n(q), n(r)); }
  bool equals(uint32_t a, uint32_t b) { return n(a).x == n(b).x && n(a).y == n(b).y; }
  // Inclusive test against a counter-clockwise triangle.
  static bool point_in_triangle(double ax, double ay, double bx, double by, double cx, double cy,
                                double px, double py) {
    return (cx - px) * (ay - py) >= (ax - px) * (cy - py) &&
           (ax - px) * (by - py) >= (bx - px) * (ay - py) &&
           (bx - px) * (cy - py) >= (cx - px) * (by - py);
  }

  // The work budget of a polygon of `points` points (see the file comment).
  static uint64_t work_budget(uint64_t points) {
    return 64 * points * std::min<uint64_t>(points, kQuadraticPoints) + 65536;
  }
  static constexpr uint64_t kQuadraticPoints = 64;

  uint32_t insert(uint32_t vertex, glm::dvec2 p, uint32_t last);
  void remove(uint32_t p);
  uint32_t add_ring(const glm::dvec2* points, const uint32_t* ids, uint32_t count,
                    bool counter_clockwise);
  uint32_t filter(uint32_t start, uint32_t end);
  uint32_t filter_near(uint32_t a, uint32_t b);
  void emit(uint32_t a, uint32_t b, uint32_t c);
  void clip(uint32_t ear, int pass);
  bool is_ear(uint32_t ear);
  bool blocks_ear(uint32_t p, uint32_t a, uint32_t b, uint32_t c, double x0, double y0, double x1,
                  double y1);
  uint32_t z_order(double x, double y) const;
  bool index_curve(uint32_t start);
  // Edges of the outer ring by horizontal band, for find_hole_bridge (many holes only).
  void band_edges(uint32_t outer);
  void band_edge(uint32_t p);
  void band_ring(uint32_t start);
  uint32_t band_of(double y) const;
  bool ray_hit(uint32_t hole, uint32_t p, double& qx, uint32_t& m, bool& done);
  uint32_t cure_local_intersections(uint32_t start);
  void split_and_clip(uint32_t start);
  uint32_t eliminate_holes(uint32_t outer, bool& complete);
  uint32_t find_hole_bridge(uint32_t hole, uint32_t outer);
  bool sector_contains_sector(uint32_t m, uint32_t p) {
    return cw_area(n(m).prev, m, n(p).prev) < 0 && cw_area(n(p).next, m, n(m).next) < 0;
  }
  uint32_t leftmost(uint32_t start);
  bool is_valid_diagonal(uint32_t a, uint32_t b);
  bool intersects(uint32_t p1, uint32_t q1, uint32_t p2, uint32_t q2);
  bool intersects_polygon(uint32_t a, uint32_t b);
  bool locally_inside(uint32_t a, uint32_t b);
  bool middle_inside(uint32_t a, uint32_t b);
  uint32_t split_polygon(uint32_t a, uint32_t b);

  std::vector<uint32_t>& out_;
  std::vector<Node> nodes_;
  std::vector<uint32_t> holes_;
  std::vector<Job> jobs_;
  uint64_t steps_left_ = 0;
  // z-order hashing (as mapbox/earcut's): on for polygons of more than kHashPoints points. It
  // only narrows is_ear's search to the points that can lie in the ear's bounding box, so the
  // triangles are the same with it or without.
  static constexpr size_t kHashPoints = 80;
  bool hashed_ = false;
  double min_x_ = 0, min_y_ = 0, inv_size_ = 0;
  std::vector<uint32_t> z_sorted_;
  std::vector<uint32_t> near_;  // filter_near's points to look at
  // Bands (empty unless in use): band i holds the nodes whose edge (node, next) spanned band i's
  // heights when added; an entry may be stale (the node removed, its edge changed) and is
  // checked when read. Used where the holes are many: one walk of the whole ring per hole is
  // quadratic in them.
  static constexpr size_t kBandHoles = 64;
  std::vector<std::vector<uint32_t>> bands_;
  double band_y0_ = 0, band_inv_height_ = 0;
  uint64_t band_entries_left_ = 0;
};

bool EarClipper::run(const std::vector<glm::dvec2>& points, const std::vector<uint32_t>& ids,
                     std::span<const uint32_t> ring_ends) {
  const uint64_t count = points.size();
  steps_left_ = work_budget(count);
  nodes_.clear();
  nodes_.reserve(points.size() + 2 * ring_ends.size() + 16);
  holes_.clear();

  // Stage 1: link the outer contour counter-clockwise and every hole clockwise.
  uint32_t outer = add_ring(points.data(), ids.data(), ring_ends[0], true);
  if (outer == kNone || n(outer).next == n(outer).prev) return false;
  for (size_t r = 1; r < ring_ends.size(); ++r) {
    const uint32_t hole = add_ring(points.data() + ring_ends[r - 1], ids.data() + ring_ends[r - 1],
                                   ring_ends[r] - ring_ends[r - 1], false);
    if (hole != kNone) holes_.push_back(leftmost(hole));
  }

  // z-order hashing over the outer contour's bounds (the holes lie inside them; any outside
  // are clamped, which keeps the order monotonic).
  hashed_ = points.size() > kHashPoints;
  if (hashed_) {
    double max_x = points[0].x, max_y = points[0].y;
    min_x_ = max_x;
    min_y_ = max_y;
    for (uint32_t i = 0; i < ring_ends[0]; ++i) {
      min_x_ = std::min(min_x_, points[i].x);
      min_y_ = std::min(min_y_, points[i].y);
      max_x = std::max(max_x, points[i].x);
      max_y = std::max(max_y, points[i].y);
    }
    const double size = std::max(max_x - min_x_, max_y - min_y_);
    inv_size_ = size > 0 ? 32767.0 / size : 0.0;
  }

  // Stage 2: one ring without holes.
  bool complete = true;
  if (!holes_.empty()) outer = eliminate_holes(outer, complete);

  // Stage 3: clip ears; a ring with no ear left is retried by the later passes.
  jobs_.clear();
  jobs_.push_back({outer, 0});
  while (!jobs_.empty() && steps_left_ > 0) {
    const Job job = jobs_.back();
    jobs_.pop_back();
    clip(job.ear, job.pass);
  }
  return complete && steps_left_ > 0;
}

uint32_t EarClipper::insert(uint32_t vertex, glm::dvec2 p, uint32_t last) {
  const auto i = uint32_t(nodes_.size());
  nodes_.push_back({p.x, p.y, vertex, i, i, 0, kNone, kNone, false});
  if (last != kNone) {
    n(i).next = n(last).next;
    n(i).prev = last;
    n(n(last).next).prev = i;
    n(last).next = i;
  }
  return i;
}

void EarClipper::remove(uint32_t p) {
  Node& node = n(p);
  n(node.next).prev = node.prev;
  n(node.prev).next = node.next;
  if (node.prev_z != kNone) n(node.prev_z).next_z = node.next_z;
  if (node.next_z != kNone) n(node.next_z).prev_z = node.prev_z;
  node.removed = true;
  if (!bands_.empty()) band_edge(node.prev);  // its edge now ends where p's did
}

uint32_t EarClipper::add_ring(const glm::dvec2* points, const uint32_t* ids, uint32_t count,
                              bool counter_clockwise) {
  double area = 0.0;  // positive for a counter-clockwise ring
  for (uint32_t i = 0, j = count - 1; i < count; j = i++) {
    area += (points[j].x - points[i].x) * (points[i].y + points[j].y);
  }
  uint32_t last = kNone;
  if (counter_clockwise == (area > 0)) {
    for (uint32_t i = 0; i < count; ++i) last = insert(ids[i], points[i], last);
  } else {
    for (uint32_t i = count; i-- > 0;) last = insert(ids[i], points[i], last);
  }
  if (last != kNone && equals(last, n(last).next)) {  // a closing point repeating the first
    remove(last);
    last = n(last).next;
  }
  return last;
}

// Removes duplicate and collinear points from start up to end (the whole ring if end is kNone).
uint32_t EarClipper::filter(uint32_t start, uint32_t end) {
  if (start == kNone) return start;
  if (end == kNone) end = start;
  uint32_t p = start;
  bool again;
  do {
    if (!tick()) return end;
    again = false;
    const uint32_t prev = n(p).prev, next = n(p).next;
    if (equals(p, next) || cw_area(prev, p, next) == 0) {
      remove(p);
      p = end = prev;
      if (p == n(p).next) break;
      again = true;
    } else {
      p = next;
    }
  } while (again || p != end);
  return end;
}

// Removes duplicate and collinear points among a, b and, after each removal, the removed
// point's neighbours: work proportional to what is removed. Returns a point of the ring near b.
uint32_t EarClipper::filter_near(uint32_t a, uint32_t b) {
  near_.assign({b, a});
  uint32_t live = b;
  while (!near_.empty() && tick()) {
    const uint32_t p = near_.back();
    near_.pop_back();
    if (n(p).removed) continue;
    live = p;
    const uint32_t prev = n(p).prev, next = n(p).next;
    if (p == next) break;
    if (equals(p, next) || cw_area(prev, p, next) == 0) {
      remove(p);
      live = prev;
      near_.push_back(next);
      near_.push_back(prev);
    }
  }
  while (n(live).removed) live = n(live).prev;  // a removed point's prev was alive after it
  return live;
}

void EarClipper::emit(uint32_t a, uint32_t b, uint32_t c) {
  out_.push_back(n(a).vertex);
  out_.push_back(n(b).vertex);
  out_.push_back(n(c).vertex);
}

void EarClipper::clip(uint32_t ear, int pass) {
  if (pass == 0 && hashed_ && ear != kNone && !index_curve(ear)) return;
  while (ear != kNone) {
    uint32_t stop = ear;
    bool stuck = false;
    while (n(ear).prev != n(ear).next) {
      if (!tick()) return;
      const uint32_t prev = n(ear).prev, next = n(ear).next;
      if (is_ear(ear)) {
        emit(prev, ear, next);
        remove(ear);
        // Skipping the next vertex gives fewer sliver triangles.
        ear = stop = n(next).next;
        continue;
      }
      ear = next;
      if (ear == stop) {
        stuck = true;
        break;
      }
    }
    if (!stuck) return;
    if (pass == 0) {
      ear = filter(ear, kNone);
      pass = 1;
    } else if (pass == 1) {
      ear = cure_local_intersections(filter(ear, kNone));
      pass = 2;
    } else {
      split_and_clip(ear);
      return;
    }
  }
}

bool EarClipper::is_ear(uint32_t ear) {
  const uint32_t a = n(ear).prev, b = ear, c = n(ear).next;
  if (cw_area(a, b, c) >= 0) return false;  // reflex or straight
  const Node &na = n(a), &nb = n(b), &nc = n(c);
  const double x0 = std::min({na.x, nb.x, nc.x}), x1 = std::max({na.x, nb.x, nc.x});
  const double y0 = std::min({na.y, nb.y, nc.y}), y1 = std::max({na.y, nb.y, nc.y});
  if (!hashed_) {
    for (uint32_t p = nc.next; p != a; p = n(p).next) {
      if (!tick() || blocks_ear(p, a, b, c, x0, y0, x1, y1)) return false;
    }
    return true;
  }
  // Only points whose z lies between the bounding box's corners' can be in it: walk the ring's
  // z-order both ways from the ear.
  const uint32_t min_z = z_order(x0, y0), max_z = z_order(x1, y1);
  for (uint32_t p = nb.prev_z; p != kNone && n(p).z >= min_z; p = n(p).prev_z) {
    if (!tick() || blocks_ear(p, a, b, c, x0, y0, x1, y1)) return false;
  }
  for (uint32_t p = nb.next_z; p != kNone && n(p).z <= max_z; p = n(p).next_z) {
    if (!tick() || blocks_ear(p, a, b, c, x0, y0, x1, y1)) return false;
  }
  return true;
}

// Whether point p keeps the corner a, b, c (counter-clockwise, bounding box x0..x1, y0..y1) from
// being an ear: only a reflex (or straight) point inside can, other than the corner's own nodes
// and points on a.
bool EarClipper::blocks_ear(uint32_t p, uint32_t a, uint32_t b, uint32_t c, double x0, double y0,
                            double x1, double y1) {
  const Node& q = n(p);
  const Node &na = n(a), &nb = n(b), &nc = n(c);
  return p != a && p != b && p != c && q.x >= x0 && q.x <= x1 && q.y >= y0 && q.y <= y1 &&
         !(q.x == na.x && q.y == na.y) &&
         point_in_triangle(na.x, na.y, nb.x, nb.y, nc.x, nc.y, q.x, q.y) &&
         cw_area(n(q.prev), q, n(q.next)) >= 0;
}

// The point's place on a Morton curve over the outer contour's bounds (15 bits an axis),
// monotonic in x and in y.
uint32_t EarClipper::z_order(double x, double y) const {
  const auto cell = [&](double v, double min) {
    return uint32_t(std::clamp((v - min) * inv_size_, 0.0, 32767.0));
  };
  const auto spread = [](uint32_t v) {
    v = (v | (v << 8)) & 0x00FF00FFu;
    v = (v | (v << 4)) & 0x0F0F0F0Fu;
    v = (v | (v << 2)) & 0x33333333u;
    v = (v | (v << 1)) & 0x55555555u;
    return v;
  };
  return spread(cell(x, min_x_)) | (spread(cell(y, min_y_)) << 1);
}

// Links the ring of `start` in z-order (prev_z, next_z), for is_ear. False if the budget ran out.
bool EarClipper::index_curve(uint32_t start) {
  z_sorted_.clear();
  uint32_t p = start;
  do {
    if (!tick()) return false;
    n(p).z = z_order(n(p).x, n(p).y);
    z_sorted_.push_back(p);
    p = n(p).next;
  } while (p != start);
  std::sort(z_sorted_.begin(), z_sorted_.end(), [this](uint32_t l, uint32_t r) {
    return n(l).z != n(r).z ? n(l).z < n(r).z : l < r;
  });
  uint32_t prev = kNone;
  for (uint32_t q : z_sorted_) {
    n(q).prev_z = prev;
    if (prev != kNone) n(prev).next_z = q;
    prev = q;
  }
  n(prev).next_z = kNone;
  return true;
}

uint32_t EarClipper::cure_local_intersections(uint32_t start) {
  if (start == kNone) return start;
  uint32_t p = start;
  do {
    if (!tick()) return p;
    const uint32_t a = n(p).prev, next = n(p).next, b = n(next).next;
    if (!equals(a, b) && intersects(a, p, next, b) && locally_inside(a, b) &&
        locally_inside(b, a)) {
      emit(a, p, b);
      remove(p);
      remove(next);
      p = start = b;
    }
    p = n(p).next;
  } while (p != start);
  return filter(p, kNone);
}

void EarClipper::split_and_clip(uint32_t start) {
  uint32_t a = start;
  do {
    for (uint32_t b = n(n(a).next).next; b != n(a).prev; b = n(b).next) {
      if (!tick()) return;
      if (n(a).vertex != n(b).vertex && is_valid_diagonal(a, b)) {
        uint32_t c = split_polygon(a, b);
        a = filter(a, n(a).next);
        c = filter(c, n(c).next);
        jobs_.push_back({a, 0});
        jobs_.push_back({c, 0});
        return;
      }
    }
    a = n(a).next;
  } while (a != start);
}

uint32_t EarClipper::eliminate_holes(uint32_t outer, bool& complete) {
  // Left to right; holes meeting at their leftmost point in the order of their first edge's
  // slope, so that the bridge found is the point where they meet.
  struct Entry {
    double x, y, slope;
    uint32_t node;
  };
  std::vector<Entry> order;
  order.reserve(holes_.size());
  for (uint32_t h : holes_) {
    const Node& a = n(h);
    const Node& b = n(a.next);
    double slope = (b.y - a.y) / (b.x - a.x);
    if (std::isnan(slope)) slope = 0.0;
    order.push_back({a.x, a.y, slope, h});
  }
  std::sort(order.begin(), order.end(), [](const Entry& l, const Entry& r) {
    if (l.x != r.x) return l.x < r.x;
    if (l.y != r.y) return l.y < r.y;
    return l.slope < r.slope;
  });
  if (order.size() > kBandHoles) band_edges(outer);
  for (const Entry& e : order) {
    const uint32_t bridge = find_hole_bridge(e.node, outer);
    if (bridge == kNone) {
      complete = false;
      continue;
    }
    band_ring(e.node);  // the hole's edges join the outer ring
    const uint32_t reverse = split_polygon(bridge, e.node);
    if (order.size() > kBandHoles) {
      // filter() walks the whole ring after a removal; here only the bridge's ends changed.
      filter_near(reverse, n(reverse).next);
      outer = filter_near(bridge, n(bridge).next);
    } else {
      filter(reverse, n(reverse).next);
      outer = filter(bridge, n(bridge).next);
    }
  }
  bands_ = {};
  return outer;
}

// Starts the bands with the outer ring's edges: about 32 nodes a band over the heights of every
// ring, and at most 16 entries a node in all (past that, bands_ is dropped and the bridges are
// found by walking the ring).
void EarClipper::band_edges(uint32_t outer) {
  double y0 = nodes_[0].y, y1 = y0;
  for (const Node& node : nodes_) {
    y0 = std::min(y0, node.y);
    y1 = std::max(y1, node.y);
  }
  const size_t count = std::max<size_t>(1, nodes_.size() / 32);
  bands_.assign(count, {});
  band_y0_ = y0;
  band_inv_height_ = y1 > y0 ? double(count) / (y1 - y0) : 0.0;
  band_entries_left_ = 16 * uint64_t(nodes_.size()) + 4096;
  band_ring(outer);
}

void EarClipper::band_ring(uint32_t start) {
  uint32_t p = start;
  do {
    band_edge(p);
    p = n(p).next;
  } while (p != start && !bands_.empty());
}

uint32_t EarClipper::band_of(double y) const {
  const double band = std::floor((y - band_y0_) * band_inv_height_);
  return uint32_t(std::clamp(band, 0.0, double(bands_.size() - 1)));
}

void EarClipper::band_edge(uint32_t p) {
  if (bands_.empty()) return;
  const double ya = n(p).y, yb = n(n(p).next).y;
  const uint32_t first = band_of(std::min(ya, yb)), last = band_of(std::max(ya, yb));
  if (last - first + 1 > band_entries_left_) {
    bands_ = {};
    return;
  }
  band_entries_left_ -= last - first + 1;
  for (uint32_t b = first; b <= last; ++b) bands_[b].push_back(p);
}

// One edge (p, next) against the ray from the hole's leftmost point to the left: keeps in
// (qx, m) the nearest crossing's x and the left end of its edge; `done` when the hole touches
// the edge or its end (m is then the bridge).
bool EarClipper::ray_hit(uint32_t hole, uint32_t p, double& qx, uint32_t& m, bool& done) {
  const double hx = n(hole).x, hy = n(hole).y;
  const uint32_t next = n(p).next;
  if (equals(hole, next)) {
    m = next;
    done = true;
    return true;
  }
  const Node& a = n(p);
  const Node& b = n(next);
  if (hy <= a.y && hy >= b.y && b.y != a.y) {
    const double x = a.x + (hy - a.y) * (b.x - a.x) / (b.y - a.y);
    if (x <= hx && x > qx) {
      qx = x;
      m = a.x < b.x ? p : next;
      if (x == hx) done = true;  // the hole touches the edge
    }
  }
  return done;
}

// Eberly's method: the outer vertex that the hole's leftmost point sees first to its left.
// With bands, only the edges and points at the heights that matter are looked at; the answer
// is the same but for ties between equally good candidates.
uint32_t EarClipper::find_hole_bridge(uint32_t hole, uint32_t outer) {
  const double hx = n(hole).x, hy = n(hole).y;
  double qx = -std::numeric_limits<double>::infinity();
  uint32_t m = kNone;
  if (equals(hole, outer)) return outer;
  // The nearest edge crossed by a ray from the hole to the left; its left end is the candidate.
  bool done = false;
  if (!bands_.empty()) {
    for (uint32_t p : bands_[band_of(hy)]) {
      if (!tick()) return kNone;
      if (!n(p).removed && ray_hit(hole, p, qx, m, done)) return m;
    }
  } else {
    uint32_t p = outer;
    do {
      if (!tick()) return kNone;
      if (ray_hit(hole, p, qx, m, done)) return m;
      p = n(p).next;
    } while (p != outer);
  }
  if (m == kNone) return kNone;

  // A vertex inside the triangle (hole, ray hit, candidate) would hide the candidate: then take
  // the one at the smallest angle to the ray.
  const uint32_t candidate = m;
  const double mx = n(m).x, my = n(m).y;
  double tan_min = std::numeric_limits<double>::infinity();
  const auto consider = [&](uint32_t p) {
    const Node& q = n(p);
    if (hx >= q.x && q.x >= mx && hx != q.x &&
        point_in_triangle(hy < my ? hx : qx, hy, mx, my, hy < my ? qx : hx, hy, q.x, q.y)) {
      const double tan = std::abs(hy - q.y) / (hx - q.x);
      if (locally_inside(p, hole) &&
          (tan < tan_min ||
           (tan == tan_min && (q.x > n(m).x || (q.x == n(m).x && sector_contains_sector(m, p)))))) {
        m = p;
        tan_min = tan;
      }
    }
  };
  if (!bands_.empty()) {
    if (!tick()) return kNone;
    consider(candidate);
    const uint32_t last = band_of(std::max(hy, my));
    for (uint32_t b = band_of(std::min(hy, my)); b <= last; ++b) {
      for (uint32_t p : bands_[b]) {
        if (!tick()) return kNone;
        if (!n(p).removed) consider(p);
      }
    }
    return m;
  }
  uint32_t p = candidate;
  do {
    if (!tick()) return kNone;
    consider(p);
    p = n(p).next;
  } while (p != candidate);
  return m;
}

uint32_t EarClipper::leftmost(uint32_t start) {
  uint32_t p = start, best = start;
  do {
    if (n(p).x < n(best).x || (n(p).x == n(best).x && n(p).y < n(best).y)) best = p;
    p = n(p).next;
  } while (p != start);
  return best;
}

bool EarClipper::is_valid_diagonal(uint32_t a, uint32_t b) {
  const uint32_t vb = n(b).vertex;
  if (n(n(a).next).vertex == vb || n(n(a).prev).vertex == vb || intersects_polygon(a, b)) {
    return false;
  }
  // Locally visible both ways and not making sectors that face each other...
  if (locally_inside(a, b) && locally_inside(b, a) && middle_inside(a, b) &&
      (cw_area(n(a).prev, a, n(b).prev) != 0 || cw_area(a, n(b).prev, b) != 0)) {
    return true;
  }
  // ...or a zero-length diagonal between two reflex corners.
  return equals(a, b) && cw_area(n(a).prev, a, n(a).next) > 0 &&
         cw_area(n(b).prev, b, n(b).next) > 0;
}

bool EarClipper::intersects(uint32_t p1, uint32_t q1, uint32_t p2, uint32_t q2) {
  auto sign = [](double v) { return v > 0 ? 1 : v < 0 ? -1 : 0; };
  // Whether q, known to be collinear with p and r, lies between them.
  auto on_segment = [this](uint32_t p, uint32_t q, uint32_t r) {
    return n(q).x <= std::max(n(p).x, n(r).x) && n(q).x >= std::min(n(p).x, n(r).x) &&
           n(q).y <= std::max(n(p).y, n(r).y) && n(q).y >= std::min(n(p).y, n(r).y);
  };
  const int o1 = sign(cw_area(p1, q1, p2)), o2 = sign(cw_area(p1, q1, q2));
  const int o3 = sign(cw_area(p2, q2, p1)), o4 = sign(cw_area(p2, q2, q1));
  if (o1 != o2 && o3 != o4) return true;
  return (o1 == 0 && on_segment(p1, p2, q1)) || (o2 == 0 && on_segment(p1, q2, q1)) ||
         (o3 == 0 && on_segment(p2, p1, q2)) || (o4 == 0 && on_segment(p2, q1, q2));
}

bool EarClipper::intersects_polygon(uint32_t a, uint32_t b) {
  const uint32_t va = n(a).vertex, vb = n(b).vertex;
  uint32_t p = a;
  do {
    if (!tick()) return true;
    const uint32_t next = n(p).next;
    const uint32_t vp = n(p).vertex, vn = n(next).vertex;
    if (vp != va && vn != va && vp != vb && vn != vb && intersects(p, next, a, b)) return true;
    p = next;
  } while (p != a);
  return false;
}

bool EarClipper::locally_inside(uint32_t a, uint32_t b) {
  const uint32_t prev = n(a).prev, next = n(a).next;
  return cw_area(prev, a, next) < 0 ? cw_area(a, b, next) >= 0 && cw_area(a, prev, b) >= 0
                                    : cw_area(a, b, prev) < 0 || cw_area(a, next, b) < 0;
}

bool EarClipper::middle_inside(uint32_t a, uint32_t b) {
  const double px = 0.5 * (n(a).x + n(b).x), py = 0.5 * (n(a).y + n(b).y);
  bool inside = false;
  uint32_t p = a;
  do {
    if (!tick()) return false;
    const Node& s = n(p);
    const Node& t = n(s.next);
    if ((s.y > py) != (t.y > py) && t.y != s.y &&
        px < (t.x - s.x) * (py - s.y) / (t.y - s.y) + s.x) {
      inside = !inside;
    }
    p = s.next;
  } while (p != a);
  return inside;
}

// Links a to b. Splits a ring in two (returning a node of the second), or joins a hole's ring
// into the outer one.
uint32_t EarClipper::split_polygon(uint32_t a, uint32_t b) {
  const uint32_t a2 = insert(n(a).vertex, {n(a).x, n(a).y}, kNone);
  const uint32_t b2 = insert(n(b).vertex, {n(b).x, n(b).y}, kNone);
  const uint32_t an = n(a).next, bp = n(b).prev;
  n(a).next = b;
  n(b).prev = a;
  n(a2).next = an;
  n(an).prev = a2;
  n(b2).next = a2;
  n(a2).prev = b2;
  n(bp).next = b2;
  n(b2).prev = bp;
  if (!bands_.empty()) {
    band_edge(a);
    band_edge(a2);
    band_edge(b2);
  }
  return b2;
}

}  // namespace

void plan(const FacetGroup& g, MeshPlan& plan, TemplateKey&) {
  const size_t index_count = g.triangles.size() - g.triangles.size() % 3;
  if (index_count == 0 || g.vertices.empty()) return;
  plan.topology = Topology::triangles;
  plan.closed = false;
  plan.level_count = 1;
  plan.vertex_count = uint32_t(g.vertices.size());
  plan.indices[0] = std::span<const uint32_t>(g.triangles.data(), index_count);
  plan.error_m[0] = 0.0f;
}

void write(const FacetGroup& g, const MeshPlan& plan, const VertexSink& sink) {
  glm::vec3 stand_in(0.0f);
  if (!g.triangles.empty() && g.triangles[0] < g.vertices.size() &&
      is_finite(g.vertices[g.triangles[0]].position_m)) {
    stand_in = g.vertices[g.triangles[0]].position_m;
  }
  for (uint32_t i = 0; i < plan.vertex_count; ++i) {
    const FacetVertex& v = g.vertices[i];
    sink.put(i, is_finite(v.position_m) ? v.position_m : stand_in, sink.normal(v.normal));
  }
}

Aabb bounds(const FacetGroup& g) {
  Aabb box{glm::vec3(std::numeric_limits<float>::infinity()),
           glm::vec3(-std::numeric_limits<float>::infinity())};
  for (const FacetVertex& v : g.vertices) {
    if (!is_finite(v.position_m)) continue;
    box.min = glm::min(box.min, v.position_m);
    box.max = glm::max(box.max, v.position_m);
  }
  return box;
}

}  // namespace plantview::detail

namespace plantview {

uint32_t FacetGroup::triangulate() {
  using detail::is_finite;
  triangles.clear();
  detail::EarClipper clipper(triangles);
  std::vector<glm::dvec2> points;
  std::vector<uint32_t> ids, ring_ends;

  // Contour c's vertex range, empty when the ends are out of order or out of range.
  const auto contour = [&](size_t c) {
    const size_t end = std::min<size_t>(contour_ends[c], vertices.size());
    const size_t begin = c ? std::min<size_t>(contour_ends[c - 1], vertices.size()) : 0;
    return std::pair<uint32_t, uint32_t>(uint32_t(begin), uint32_t(std::max(begin, end)));
  };
  // Whether a contour has 3 or more vertices, all finite.
  const auto usable = [&](std::pair<uint32_t, uint32_t> range) {
    if (range.second - range.first < 3) return false;
    for (uint32_t i = range.first; i < range.second; ++i) {
      if (!is_finite(vertices[i].position_m)) return false;
    }
    return true;
  };
  // The largest side of a contour's bounding box.
  const auto extent = [&](std::pair<uint32_t, uint32_t> range) {
    glm::dvec3 lo(vertices[range.first].position_m), hi = lo;
    for (uint32_t i = range.first; i < range.second; ++i) {
      lo = glm::min(lo, glm::dvec3(vertices[i].position_m));
      hi = glm::max(hi, glm::dvec3(vertices[i].position_m));
    }
    const glm::dvec3 size = hi - lo;
    return std::max({size.x, size.y, size.z});
  };

  uint32_t skipped = 0;
  for (size_t p = 0; p < polygon_ends.size(); ++p) {
    const size_t first = p ? polygon_ends[p - 1] : 0;
    const size_t last = std::min<size_t>(polygon_ends[p], contour_ends.size());
    if (first >= last) {
      ++skipped;
      continue;
    }

    // Stage 1: the outer contour's plane (Newell's normal) and the side it faces.
    const auto outer = contour(first);
    if (!usable(outer)) {
      ++skipped;
      continue;
    }
    const glm::dvec3 origin(vertices[outer.first].position_m);
    glm::dvec3 newell(0.0), normal_sum(0.0);
    for (uint32_t i = outer.first; i < outer.second; ++i) {
      const uint32_t j = i + 1 < outer.second ? i + 1 : outer.first;
      const glm::dvec3 a = glm::dvec3(vertices[i].position_m) - origin;
      const glm::dvec3 b = glm::dvec3(vertices[j].position_m) - origin;
      newell += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x),
                           (a.x - b.x) * (a.y + b.y));
      if (is_finite(vertices[i].normal)) normal_sum += glm::dvec3(vertices[i].normal);
    }
    const double twice_area = glm::length(newell);
    const double size = extent(outer);
    if (!(twice_area > 2.0 * detail::kRelativeAreaEpsilon * size * size)) {
      ++skipped;
      continue;
    }
    // The vertex normals decide which side the polygon faces when they disagree with its winding.
    const glm::dvec3 facing =
        newell * ((glm::dot(newell, normal_sum) < 0 ? -1.0 : 1.0) / twice_area);

    // Stage 2: project every usable contour to a frame (u, v) with u x v = facing.
    const glm::dvec3 helper = std::abs(facing.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 u = glm::normalize(glm::cross(helper, facing));
    const glm::dvec3 v = glm::cross(facing, u);
    points.clear();
    ids.clear();
    ring_ends.clear();
    bool partial = false;
    for (size_t c = first; c < last; ++c) {
      const auto range = contour(c);
      if (c != first && !usable(range)) {
        partial = true;
        continue;
      }
      const size_t begin = points.size();
      for (uint32_t i = range.first; i < range.second; ++i) {
        const glm::dvec3 q = glm::dvec3(vertices[i].position_m) - origin;
        points.push_back({glm::dot(q, u), glm::dot(q, v)});
        ids.push_back(i);
      }
      double area = 0.0;
      for (size_t i = begin, j = points.size() - 1; i < points.size(); j = i++) {
        area += points[j].x * points[i].y - points[i].x * points[j].y;
      }
      const double hole_size = c == first ? size : extent(range);
      if (!(std::abs(area) > 2.0 * detail::kRelativeAreaEpsilon * hole_size * hole_size)) {
        points.resize(begin);
        ids.resize(begin);
        partial = true;
        if (c == first) break;
        continue;
      }
      ring_ends.push_back(uint32_t(points.size()));
    }

    // Stage 3: bridge the holes and clip ears.
    if (ring_ends.empty() || !clipper.run(points, ids, ring_ends)) partial = true;
    if (partial) ++skipped;
  }
  return skipped;
}

}  // namespace plantview
