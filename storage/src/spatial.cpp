#include "spatial.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

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

// Leaves as entry ranges, in entry order.
std::vector<NodeRange> leaves_in_order(uint32_t n) {
  std::vector<SpatialNode> nodes;
  std::vector<NodeRange> ranges, leaves;
  spatial_topology(n, nodes, ranges);
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].count > 0) leaves.push_back(ranges[i]);
  }
  std::sort(leaves.begin(), leaves.end(),
            [](const NodeRange& a, const NodeRange& b) { return a.begin < b.begin; });
  return leaves;
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
  nodes.reserve(2 * (n / kLeafSize + 1));
  ranges.reserve(nodes.capacity());
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
  int64_t previous_min[3] = {0, 0, 0}, previous_slot = 0;
  for (const NodeRange& leaf : leaves_in_order(uint32_t(entries.size()))) {
    int64_t leaf_min[3];
    for (int a = 0; a < 3; ++a) {
      leaf_min[a] = std::numeric_limits<int64_t>::max();
      for (uint32_t k = leaf.begin; k < leaf.end; ++k) {
        leaf_min[a] = std::min<int64_t>(leaf_min[a], entries[k].min[a]);
      }
      put_varint(out, zigzag(leaf_min[a] - previous_min[a]));
      previous_min[a] = leaf_min[a];
    }
    for (uint32_t k = leaf.begin; k < leaf.end; ++k) {
      const GridEntry& e = entries[k];
      for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(e.min[a] - leaf_min[a]));
      for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(int64_t(e.max[a]) - e.min[a]));
      put_varint(out, zigzag(int64_t(e.slot) - previous_slot));
      previous_slot = e.slot;
    }
  }
}

bool decode_spatial(const uint8_t* data, size_t size, glm::dvec3& origin,
                    std::vector<GridEntry>& entries, std::string& error) {
  entries.clear();
  if (size < 24) {
    error = "spatial index is truncated";
    return false;
  }
  std::memcpy(&origin, data, 24);
  if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z)) {
    error = "spatial origin is not finite";
    return false;
  }
  VarintReader r(data + 24, size - 24);
  uint64_t n = 0;
  // An entry takes at least 7 bytes: the count is checked before anything is allocated.
  if (!r.get(n) || n > r.remaining() / 7) {
    error = "spatial index is truncated";
    return false;
  }
  entries.resize(n);
  int64_t leaf_min[3] = {0, 0, 0}, slot = 0;
  for (const NodeRange& leaf : leaves_in_order(uint32_t(n))) {
    for (int a = 0; a < 3; ++a) {
      int64_t delta;
      if (!r.get_signed(delta)) {
        error = "spatial index is truncated";
        return false;
      }
      leaf_min[a] += delta;
      if (!fits_int32(leaf_min[a])) {
        error = "spatial index has bounds out of range";
        return false;
      }
    }
    for (uint32_t k = leaf.begin; k < leaf.end; ++k) {
      GridEntry& e = entries[k];
      uint64_t v[6];
      int64_t slot_delta;
      for (uint64_t& x : v) {
        if (!r.get(x)) {
          error = "spatial index is truncated";
          return false;
        }
      }
      if (!r.get_signed(slot_delta)) {
        error = "spatial index is truncated";
        return false;
      }
      for (int a = 0; a < 3; ++a) {
        // Varints are below 2^64; anything past int32 is out of range whichever way it adds up.
        if (v[a] > UINT32_MAX || v[3 + a] > UINT32_MAX ||
            !fits_int32(leaf_min[a] + int64_t(v[a])) ||
            !fits_int32(leaf_min[a] + int64_t(v[a]) + int64_t(v[3 + a]))) {
          error = "spatial index has bounds out of range";
          return false;
        }
        e.min[a] = int32_t(leaf_min[a] + int64_t(v[a]));
        e.max[a] = int32_t(e.min[a] + int64_t(v[3 + a]));
      }
      slot += slot_delta;
      if (slot < 0 || slot > int64_t(UINT32_MAX)) {
        error = "spatial index has a slot out of range";
        return false;
      }
      e.slot = uint32_t(slot);
    }
  }
  if (!r.at_end()) {
    error = "trailing bytes after the spatial index";
    return false;
  }
  return true;
}

void expand_spatial(const std::vector<GridEntry>& entries, std::vector<SpatialNode>& nodes,
                    std::vector<SpatialEntry>& packed) {
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(entries.size()), nodes, ranges);
  packed.resize(entries.size());
  for (size_t k = 0; k < entries.size(); ++k) {
    for (int a = 0; a < 3; ++a) {
      packed[k].min[a] = round_down(double(entries[k].min[a]) * kSpatialCellM);
      packed[k].max[a] = round_up(double(entries[k].max[a]) * kSpatialCellM);
    }
    packed[k].slot = entries[k].slot;
  }
  // Children come after their parent: fill bounds from the last node back.
  for (size_t i = nodes.size(); i-- > 0;) {
    SpatialNode& node = nodes[i];
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
    if (node.count > 0) {
      for (uint32_t k = node.first; k < node.first + node.count; ++k) {
        extend(packed[k].min, packed[k].max);
      }
    } else {
      extend(nodes[node.first].min, nodes[node.first].max);
      extend(nodes[node.first + 1].min, nodes[node.first + 1].max);
    }
  }
}

}  // namespace plantview::detail
