#include "spatial.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>

#include "varint.h"

namespace plantview::detail {

namespace {

float round_down(double v) {
  const float f = float(v);
  return double(f) > v ? std::nextafter(f, -INFINITY) : f;
}
float round_up(double v) {
  const float f = float(v);
  return double(f) < v ? std::nextafter(f, INFINITY) : f;
}

bool fits_int32(int64_t v) {
  return v >= std::numeric_limits<int32_t>::min() && v <= std::numeric_limits<int32_t>::max();
}

// Adds a stored delta to a running value in [lo, hi] (bounds within +-2^62), keeping it there:
// false, with `value` unchanged, if the sum would leave the range. A corrupt delta may be any
// int64, so the test is made without forming a sum that could overflow.
bool add_within(int64_t& value, int64_t delta, int64_t lo, int64_t hi) {
  if (delta < lo - value || delta > hi - value) return false;
  value += delta;
  return true;
}

// Calls visit(first, count) for every leaf of a topology, in entry order: depth first, first
// child first (it holds the lower half of its parent's entries).
template <typename Visit>
void for_each_leaf(const std::vector<SpatialNode>& nodes, Visit&& visit) {
  if (nodes.empty()) return;
  uint32_t stack[64];  // the depth is about log2(n / kLeafSize) + 1
  int depth = 0;
  stack[depth++] = 0;
  while (depth > 0) {
    const SpatialNode& node = nodes[stack[--depth]];
    if (node.count > 0) {
      visit(node.first, node.count);
    } else {
      stack[depth++] = node.first + 1;
      stack[depth++] = node.first;
    }
  }
}

// The exact node count of spatial_topology(n): ranges of one depth have at most two sizes, so
// counting them level by level takes a few dozen steps.
size_t topology_node_count(uint32_t n) {
  if (n == 0) return 0;
  std::map<uint32_t, size_t> level{{n, 1}}, next;
  size_t nodes = 0;
  while (!level.empty()) {
    next.clear();
    for (const auto& [size, count] : level) {
      nodes += count;
      if (size > kLeafSize) {
        next[size / 2] += count;
        next[size - size / 2] += count;
      }
    }
    level.swap(next);
  }
  return nodes;
}

// Reads the stored form's header: the origin and the entry count, checked against the bytes
// left. Afterwards `r` is at the first leaf.
bool read_spatial_header(const uint8_t* data, size_t size, glm::dvec3& origin, uint64_t& n,
                         VarintReader& r, std::string& error) {
  if (size < 24) {
    error = "spatial index is truncated";
    return false;
  }
  std::memcpy(&origin, data, 24);
  if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z)) {
    error = "spatial origin is not finite";
    return false;
  }
  r = VarintReader(data + 24, size - 24);
  // An entry takes at least 7 bytes: the count is checked before anything is allocated.
  if (!r.get(n) || n > r.remaining() / 7) {
    error = "spatial index is truncated";
    return false;
  }
  return true;
}

// Reads the entries of the topology `nodes`, leaf by leaf, calling put(k, entry) for entry k in
// tree order; then checks that the bytes end there.
template <typename Put>
bool read_spatial_entries(VarintReader& r, const std::vector<SpatialNode>& nodes, Put&& put,
                          std::string& error) {
  int64_t leaf_min[3] = {0, 0, 0}, slot = 0;
  bool ok = true;
  for_each_leaf(nodes, [&](uint32_t first, uint32_t count) {
    if (!ok) return;
    ok = false;
    for (int a = 0; a < 3; ++a) {
      int64_t delta;
      if (!r.get_signed(delta)) {
        error = "spatial index is truncated";
        return;
      }
      if (!add_within(leaf_min[a], delta, std::numeric_limits<int32_t>::min(),
                      std::numeric_limits<int32_t>::max())) {
        error = "spatial index has bounds out of range";
        return;
      }
    }
    for (uint32_t k = first; k < first + count; ++k) {
      GridEntry e;
      uint64_t v[6];
      int64_t slot_delta;
      for (uint64_t& x : v) {
        if (!r.get(x)) {
          error = "spatial index is truncated";
          return;
        }
      }
      if (!r.get_signed(slot_delta)) {
        error = "spatial index is truncated";
        return;
      }
      for (int a = 0; a < 3; ++a) {
        // Varints are below 2^64; anything past int32 is out of range whichever way it adds up.
        if (v[a] > UINT32_MAX || v[3 + a] > UINT32_MAX ||
            !fits_int32(leaf_min[a] + int64_t(v[a])) ||
            !fits_int32(leaf_min[a] + int64_t(v[a]) + int64_t(v[3 + a]))) {
          error = "spatial index has bounds out of range";
          return;
        }
        e.min[a] = int32_t(leaf_min[a] + int64_t(v[a]));
        e.max[a] = int32_t(e.min[a] + int64_t(v[3 + a]));
      }
      if (!add_within(slot, slot_delta, 0, int64_t(UINT32_MAX))) {
        error = "spatial index has a slot out of range";
        return;
      }
      e.slot = uint32_t(slot);
      put(k, e);
    }
    ok = true;
  });
  if (!ok) return false;
  if (!r.at_end()) {
    error = "trailing bytes after the spatial index";
    return false;
  }
  return true;
}

}  // namespace

bool quantise_bounds(const DAabb& bounds, const glm::dvec3& origin, uint32_t slot, GridEntry& out) {
  constexpr double kLimit = 2147483000.0;  // inside int32, with room for the outward steps below
  out.slot = slot;
  for (int a = 0; a < 3; ++a) {
    const double lo = std::floor((bounds.min[a] - origin[a]) / kSpatialCellM);
    const double hi = std::ceil((bounds.max[a] - origin[a]) / kSpatialCellM);
    if (!(lo >= -kLimit && lo <= kLimit && hi >= -kLimit && hi <= kLimit)) return false;  // NaN too
    int64_t qlo = int64_t(lo), qhi = int64_t(hi);
    // The subtraction above may round: step outward until the box, computed as readers compute
    // it, really contains the bounds. (A few steps at most, unless the origin is so far out that
    // a cell is below its precision: such a model is refused.)
    for (int step = 0; origin[a] + double(qlo) * kSpatialCellM > bounds.min[a]; ++step, --qlo) {
      if (step == 16) return false;
    }
    for (int step = 0; origin[a] + double(qhi) * kSpatialCellM < bounds.max[a]; ++step, ++qhi) {
      if (step == 16) return false;
    }
    if (!fits_int32(qlo) || !fits_int32(qhi)) return false;
    out.min[a] = int32_t(qlo);
    out.max[a] = int32_t(qhi);
  }
  return true;
}

DAabb grid_bounds(const GridEntry& e, const glm::dvec3& origin) {
  DAabb b;
  for (int a = 0; a < 3; ++a) {
    b.min[a] = origin[a] + double(e.min[a]) * kSpatialCellM;
    b.max[a] = origin[a] + double(e.max[a]) * kSpatialCellM;
  }
  return b;
}

void spatial_topology(uint32_t n, std::vector<SpatialNode>& nodes, std::vector<NodeRange>& ranges) {
  nodes.clear();
  ranges.clear();
  if (n == 0) return;
  const size_t count = topology_node_count(n);
  nodes.reserve(count);
  ranges.reserve(count);
  std::vector<uint32_t> stack{0};
  nodes.push_back({});
  ranges.push_back({0, n});
  while (!stack.empty()) {
    const uint32_t i = stack.back();
    stack.pop_back();
    const NodeRange r = ranges[i];
    if (r.end - r.begin <= kLeafSize) {
      nodes[i].first = r.begin;
      nodes[i].count = r.end - r.begin;
      continue;
    }
    const uint32_t mid = r.begin + (r.end - r.begin) / 2;
    const uint32_t children = uint32_t(nodes.size());
    nodes[i].first = children;
    nodes[i].count = 0;
    nodes.push_back({});
    nodes.push_back({});
    ranges.push_back({r.begin, mid});
    ranges.push_back({mid, r.end});
    stack.push_back(children);
    stack.push_back(children + 1);
  }
}

void build_spatial_tree(std::vector<GridEntry>& entries) {
  std::vector<SpatialNode> nodes;
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(entries.size()), nodes, ranges);
  const auto at = entries.begin();
  // Children come after their parent in node order, so each range is split before its halves.
  for (size_t i = 0; i < nodes.size(); ++i) {
    const NodeRange r = ranges[i];
    if (nodes[i].count > 0) {
      std::sort(at + r.begin, at + r.end,
                [](const GridEntry& a, const GridEntry& b) { return a.slot < b.slot; });
      continue;
    }
    // Twice the centroid (min + max) keeps the arithmetic in integers.
    int64_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::numeric_limits<int64_t>::max();
      hi[a] = std::numeric_limits<int64_t>::min();
    }
    for (uint32_t k = r.begin; k < r.end; ++k) {
      for (int a = 0; a < 3; ++a) {
        const int64_t c = int64_t(entries[k].min[a]) + entries[k].max[a];
        lo[a] = std::min(lo[a], c);
        hi[a] = std::max(hi[a], c);
      }
    }
    const int64_t ex = hi[0] - lo[0], ey = hi[1] - lo[1], ez = hi[2] - lo[2];
    const int axis = ex >= ey && ex >= ez ? 0 : (ey >= ez ? 1 : 2);
    const uint32_t mid = r.begin + (r.end - r.begin) / 2;
    std::nth_element(at + r.begin, at + mid, at + r.end,
                     [axis](const GridEntry& a, const GridEntry& b) {
                       const int64_t ca = int64_t(a.min[axis]) + a.max[axis],
                                     cb = int64_t(b.min[axis]) + b.max[axis];
                       return ca != cb ? ca < cb : a.slot < b.slot;
                     });
  }
}

void encode_spatial(const glm::dvec3& origin, const std::vector<GridEntry>& entries,
                    std::vector<uint8_t>& out) {
  out.resize(24);
  std::memcpy(out.data(), &origin, 24);
  put_varint(out, entries.size());
  std::vector<SpatialNode> nodes;
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(entries.size()), nodes, ranges);
  int64_t previous_min[3] = {0, 0, 0}, previous_slot = 0;
  for_each_leaf(nodes, [&](uint32_t first, uint32_t count) {
    int64_t leaf_min[3];
    for (int a = 0; a < 3; ++a) {
      leaf_min[a] = std::numeric_limits<int64_t>::max();
      for (uint32_t k = first; k < first + count; ++k) {
        leaf_min[a] = std::min<int64_t>(leaf_min[a], entries[k].min[a]);
      }
      put_varint(out, zigzag(leaf_min[a] - previous_min[a]));
      previous_min[a] = leaf_min[a];
    }
    for (uint32_t k = first; k < first + count; ++k) {
      const GridEntry& e = entries[k];
      for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(e.min[a] - leaf_min[a]));
      for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(int64_t(e.max[a]) - e.min[a]));
      put_varint(out, zigzag(int64_t(e.slot) - previous_slot));
      previous_slot = e.slot;
    }
  });
}

bool decode_spatial(const uint8_t* data, size_t size, glm::dvec3& origin,
                    std::vector<GridEntry>& entries, std::string& error) {
  entries.clear();
  VarintReader r(data, 0);
  uint64_t n = 0;
  if (!read_spatial_header(data, size, origin, n, r, error)) return false;
  std::vector<SpatialNode> nodes;
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(n), nodes, ranges);
  ranges = {};
  entries.resize(n);
  return read_spatial_entries(
      r, nodes, [&entries](uint32_t k, const GridEntry& e) { entries[k] = e; }, error);
}

bool decode_spatial_expanded(const uint8_t* data, size_t size, glm::dvec3& origin,
                             std::vector<SpatialNode>& nodes, std::vector<SpatialEntry>& entries,
                             std::string& error) {
  nodes.clear();
  entries.clear();
  VarintReader r(data, 0);
  uint64_t n = 0;
  if (!read_spatial_header(data, size, origin, n, r, error)) return false;
  {
    std::vector<NodeRange> ranges;  // not needed here: leaves name their entries
    spatial_topology(uint32_t(n), nodes, ranges);
  }
  entries.resize(n);
  // Entries arrive leaf by leaf: a leaf's float bounds are gathered, the leaf's bounds are
  // their union, and then each is quantised within them (rounded outward: a step is taken
  // back whenever float rounding of entry_bounds() would cut into the float bounds).
  std::vector<std::pair<uint32_t, uint32_t>> leaves;  // (first entry, node index)
  leaves.reserve(nodes.size() / 2 + 1);
  for (uint32_t i = 0; i < nodes.size(); ++i)
    if (nodes[i].count > 0) leaves.emplace_back(nodes[i].first, i);
  std::sort(leaves.begin(), leaves.end());
  size_t leaf = 0;
  float bounds[kLeafSize][6];
  uint32_t slots[kLeafSize];
  const bool ok = read_spatial_entries(
      r, nodes,
      [&](uint32_t k, const GridEntry& e) {
        SpatialNode& node = nodes[leaves[leaf].second];
        const uint32_t at = k - node.first;
        for (int a = 0; a < 3; ++a) {
          bounds[at][a] = round_down(double(e.min[a]) * kSpatialCellM);
          bounds[at][3 + a] = round_up(double(e.max[a]) * kSpatialCellM);
        }
        slots[at] = e.slot;
        if (at + 1 < node.count) return;
        for (int a = 0; a < 3; ++a) {
          node.min[a] = INFINITY;
          node.max[a] = -INFINITY;
          for (uint32_t j = 0; j < node.count; ++j) {
            node.min[a] = std::min(node.min[a], bounds[j][a]);
            node.max[a] = std::max(node.max[a], bounds[j][3 + a]);
          }
        }
        for (uint32_t j = 0; j < node.count; ++j) {
          SpatialEntry& out = entries[node.first + j];
          out.slot = slots[j];
          for (int a = 0; a < 3; ++a) {
            const float extent = node.max[a] - node.min[a];
            const double scale = extent > 0 ? 65535.0 / extent : 0.0;
            out.min[a] = uint16_t(std::clamp(std::floor((bounds[j][a] - node.min[a]) * scale), 0.0, 65535.0));
            out.max[a] = uint16_t(std::clamp(std::ceil((bounds[j][3 + a] - node.min[a]) * scale), 0.0, 65535.0));
          }
          float lo[3], hi[3];
          for (;;) {
            entry_bounds(node, out, lo, hi);
            bool moved = false;
            for (int a = 0; a < 3; ++a) {
              if (lo[a] > bounds[j][a] && out.min[a] > 0) out.min[a] -= 1, moved = true;
              if (hi[a] < bounds[j][3 + a] && out.max[a] < 65535) out.max[a] += 1, moved = true;
            }
            if (!moved) break;
          }
        }
        ++leaf;
      },
      error);
  if (!ok) {
    nodes = {};
    entries = {};
    return false;
  }
  // Children come after their parent: fill bounds from the last node back.
  for (size_t i = nodes.size(); i-- > 0;) {
    SpatialNode& node = nodes[i];
    if (node.count > 0) continue;  // leaves were bounded as their entries came
    for (int a = 0; a < 3; ++a) {
      node.min[a] = INFINITY;
      node.max[a] = -INFINITY;
    }
    auto extend = [&node](const float* lo, const float* hi) {
      for (int a = 0; a < 3; ++a) {
        node.min[a] = std::min(node.min[a], lo[a]);
        node.max[a] = std::max(node.max[a], hi[a]);
      }
    };
    extend(nodes[node.first].min, nodes[node.first].max);
    extend(nodes[node.first + 1].min, nodes[node.first + 1].max);
  }
  return true;
}

}  // namespace plantview::detail
