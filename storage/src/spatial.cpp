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

uint32_t pack_colour(const Colour& c) {
  return uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | uint32_t(c.a) << 24;
}
Colour unpack_colour(uint32_t rgba) {
  return Colour{uint8_t(rgba), uint8_t(rgba >> 8), uint8_t(rgba >> 16), uint8_t(rgba >> 24)};
}

MortonKey morton_key(const GridEntry& e) {
  uint32_t u[3];
  for (int a = 0; a < 3; ++a) {
    // floor((min + max) / 2) in 64 bits, then offset into [0, 2^32).
    const int64_t sum = int64_t(e.min[a]) + e.max[a];
    const int64_t centre = sum >= 0 ? sum / 2 : -((-sum + 1) / 2);
    u[a] = uint32_t(uint64_t(centre + (int64_t(1) << 31)));
  }
  MortonKey key{0, 0};
  for (int bit = 31; bit >= 0; --bit) {
    for (int a = 0; a < 3; ++a) {
      // Shift the 96-bit key left by one and append the bit.
      key.high = key.high << 1 | uint32_t(key.low >> 63);
      key.low = key.low << 1 | ((u[a] >> bit) & 1u);
    }
  }
  return key;
}

void spatial_topology(uint32_t n, uint32_t leaf_size, std::vector<SpatialNode>& nodes,
                      std::vector<NodeRange>& ranges) {
  nodes.clear();
  ranges.clear();
  if (n == 0) return;
  // Ranges of one depth have at most two sizes: count the nodes level by level first, so that
  // both arrays are allocated once to their exact size.
  size_t count = 0;
  {
    std::map<uint32_t, size_t> level{{n, 1}}, next;
    while (!level.empty()) {
      next.clear();
      for (const auto& [size, k] : level) {
        count += k;
        if (size > leaf_size) {
          next[size / 2] += k;
          next[size - size / 2] += k;
        }
      }
      level.swap(next);
    }
  }
  nodes.reserve(count);
  ranges.reserve(count);
  std::vector<uint32_t> stack{0};
  nodes.push_back({});
  ranges.push_back({0, n});
  while (!stack.empty()) {
    const uint32_t i = stack.back();
    stack.pop_back();
    const NodeRange r = ranges[i];
    if (r.end - r.begin <= leaf_size) {
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

void encode_block(const BlockEntry* entries, uint32_t n, std::vector<uint8_t>& out) {
  out.clear();
  put_varint(out, n);
  int64_t previous_min[3] = {0, 0, 0}, previous_slot = 0;
  for (uint32_t k = 0; k < n; ++k) {
    const GridEntry& e = entries[k].grid;
    for (int a = 0; a < 3; ++a) {
      put_varint(out, zigzag(int64_t(e.min[a]) - previous_min[a]));
      previous_min[a] = e.min[a];
    }
    for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(int64_t(e.max[a]) - e.min[a]));
    put_varint(out, zigzag(int64_t(e.slot) - previous_slot));
    previous_slot = e.slot;
    for (int i = 0; i < 4; ++i) out.push_back(uint8_t(entries[k].colour >> (8 * i)));
  }
}

bool decode_block(const uint8_t* data, size_t size, std::vector<BlockEntry>& entries,
                  std::string& error) {
  entries.clear();
  VarintReader r(data, size);
  uint64_t n = 0;
  // An entry takes at least 11 bytes: the count is checked before anything is allocated.
  if (!r.get(n) || n > r.remaining() / 11) {
    error = "block is truncated";
    return false;
  }
  if (n == 0 || n > kSpatialBlockObjects) {
    error = "block holds " + std::to_string(n) + " entries (1 to " +
            std::to_string(kSpatialBlockObjects) + " expected)";
    return false;
  }
  entries.resize(n);
  int64_t min[3] = {0, 0, 0}, slot = 0;
  constexpr int64_t kLo = std::numeric_limits<int32_t>::min(), kHi = std::numeric_limits<int32_t>::max();
  for (BlockEntry& out : entries) {
    for (int a = 0; a < 3; ++a) {
      int64_t delta;
      if (!r.get_signed(delta)) {
        error = "block is truncated";
        return false;
      }
      if (!add_within(min[a], delta, kLo, kHi)) {
        error = "block has bounds out of range";
        return false;
      }
      out.grid.min[a] = int32_t(min[a]);
    }
    for (int a = 0; a < 3; ++a) {
      uint64_t extent;
      if (!r.get(extent)) {
        error = "block is truncated";
        return false;
      }
      if (extent > uint64_t(kHi) * 2 + 1 || !fits_int32(min[a] + int64_t(extent))) {
        error = "block has bounds out of range";
        return false;
      }
      out.grid.max[a] = int32_t(min[a] + int64_t(extent));
    }
    int64_t delta;
    if (!r.get_signed(delta)) {
      error = "block is truncated";
      return false;
    }
    if (!add_within(slot, delta, 0, int64_t(UINT32_MAX))) {
      error = "block has a slot out of range";
      return false;
    }
    out.grid.slot = uint32_t(slot);
    if (r.remaining() < 4) {
      error = "block is truncated";
      return false;
    }
    const uint8_t* c = r.position();
    out.colour = uint32_t(c[0]) | uint32_t(c[1]) << 8 | uint32_t(c[2]) << 16 | uint32_t(c[3]) << 24;
    r.skip(4);
  }
  if (!r.at_end()) {
    error = "trailing bytes after the block";
    entries.clear();
    return false;
  }
  return true;
}

void grid_to_float(const int32_t grid_min[3], const int32_t grid_max[3], float min[3],
                   float max[3]) {
  for (int a = 0; a < 3; ++a) {
    min[a] = round_down(double(grid_min[a]) * kSpatialCellM);
    max[a] = round_up(double(grid_max[a]) * kSpatialCellM);
  }
}

void expand_block(const std::vector<BlockEntry>& entries, SpatialBlock& out) {
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(entries.size()), kLeafSize, out.nodes, ranges);
  out.entries.resize(entries.size());
  // Leaves: the union of their entries' float bounds, and each entry quantised within them
  // (rounded outward: a step is taken back whenever float rounding of entry_bounds() would cut
  // into the float bounds).
  for (SpatialNode& node : out.nodes) {
    if (node.count == 0) continue;
    float bounds[kLeafSize][6];
    for (uint32_t j = 0; j < node.count; ++j) {
      const GridEntry& e = entries[node.first + j].grid;
      grid_to_float(e.min, e.max, bounds[j], bounds[j] + 3);
    }
    for (int a = 0; a < 3; ++a) {
      node.min[a] = INFINITY;
      node.max[a] = -INFINITY;
      for (uint32_t j = 0; j < node.count; ++j) {
        node.min[a] = std::min(node.min[a], bounds[j][a]);
        node.max[a] = std::max(node.max[a], bounds[j][3 + a]);
      }
    }
    for (uint32_t j = 0; j < node.count; ++j) {
      SpatialEntry& e = out.entries[node.first + j];
      e.slot = entries[node.first + j].grid.slot;
      for (int a = 0; a < 3; ++a) {
        const float extent = node.max[a] - node.min[a];
        const double scale = extent > 0 ? 65535.0 / extent : 0.0;
        e.min[a] = uint16_t(std::clamp(std::floor((bounds[j][a] - node.min[a]) * scale), 0.0, 65535.0));
        e.max[a] = uint16_t(std::clamp(std::ceil((bounds[j][3 + a] - node.min[a]) * scale), 0.0, 65535.0));
      }
      float lo[3], hi[3];
      for (;;) {
        entry_bounds(node, e, lo, hi);
        bool moved = false;
        for (int a = 0; a < 3; ++a) {
          if (lo[a] > bounds[j][a] && e.min[a] > 0) e.min[a] -= 1, moved = true;
          if (hi[a] < bounds[j][3 + a] && e.max[a] < 65535) e.max[a] += 1, moved = true;
        }
        if (!moved) break;
      }
    }
  }
  // Children come after their parent: fill inner bounds from the last node back.
  for (size_t i = out.nodes.size(); i-- > 0;) {
    SpatialNode& node = out.nodes[i];
    if (node.count > 0) continue;
    const SpatialNode& a = out.nodes[node.first];
    const SpatialNode& b = out.nodes[node.first + 1];
    for (int k = 0; k < 3; ++k) {
      node.min[k] = std::min(a.min[k], b.min[k]);
      node.max[k] = std::max(a.max[k], b.max[k]);
    }
  }
}

void GroupSummary::add(const GroupSummary& other) {
  if (other.objects == 0) return;
  for (int a = 0; a < 3; ++a) {
    min[a] = objects == 0 ? other.min[a] : std::min(min[a], other.min[a]);
    max[a] = objects == 0 ? other.max[a] : std::max(max[a], other.max[a]);
  }
  objects += other.objects;
  if (other.largest_volume > largest_volume) {
    largest_volume = other.largest_volume;
    colour = other.colour;
  }
}

namespace {

// Summarises entries [begin, end) into heap node i of `out` and, down to depth 3, its children
// (split as spatial_topology splits).
void summarise_range(const BlockEntry* entries, uint32_t begin, uint32_t end, uint32_t i,
                     BlockSummary& out) {
  GroupSummary& g = out.nodes[i];
  g = GroupSummary{};
  g.leaf = end - begin <= kLeafSize;
  if (!g.leaf && 2 * i + 2 < out.nodes.size()) {
    const uint32_t mid = begin + (end - begin) / 2;
    summarise_range(entries, begin, mid, 2 * i + 1, out);
    summarise_range(entries, mid, end, 2 * i + 2, out);
    g.add(out.nodes[2 * i + 1]);
    g.add(out.nodes[2 * i + 2]);
    return;
  }
  for (uint32_t k = begin; k < end; ++k) {
    const GridEntry& e = entries[k].grid;
    GroupSummary one;
    double volume = 1;
    for (int a = 0; a < 3; ++a) {
      one.min[a] = e.min[a];
      one.max[a] = e.max[a];
      volume *= double(int64_t(e.max[a]) - e.min[a]);
    }
    one.objects = 1;
    one.largest_volume = volume;
    one.colour = entries[k].colour;
    g.add(one);
  }
}

// The boxes `depth` levels below top node `node` (see the top's layout in spatial.h).
void collect_proxies(const std::vector<SpatialNode>& top, const std::vector<BlockSummary>& blocks,
                     const std::vector<GroupSummary>& summaries, uint32_t node, int depth,
                     std::vector<const GroupSummary*>& out) {
  const SpatialNode& n = top[node];
  if (depth == 0) {
    out.push_back(&summaries[node]);
    return;
  }
  if (n.count == 0) {
    collect_proxies(top, blocks, summaries, n.first, depth - 1, out);
    collect_proxies(top, blocks, summaries, n.first + 1, depth - 1, out);
    return;
  }
  // Into the block's own nodes.
  const BlockSummary& b = blocks[n.first];
  std::vector<std::pair<uint32_t, int>> stack{{0u, depth}};
  while (!stack.empty()) {
    const auto [i, d] = stack.back();
    stack.pop_back();
    if (d == 0 || b.nodes[i].leaf || 2 * i + 2 >= b.nodes.size()) {
      out.push_back(&b.nodes[i]);
      continue;
    }
    stack.push_back({2 * i + 2, d - 1});
    stack.push_back({2 * i + 1, d - 1});
  }
}

}  // namespace

void summarise_block(const BlockEntry* entries, uint32_t n, BlockSummary& out) {
  summarise_range(entries, 0, n, 0, out);
}

void encode_top(const glm::dvec3& origin, uint8_t database, const std::vector<BlockSummary>& blocks,
                std::vector<uint8_t>& out) {
  out.resize(24);
  std::memcpy(out.data(), &origin, 24);
  out.push_back(database);
  uint64_t entries = 0;
  for (const BlockSummary& b : blocks) entries += b.nodes[0].objects;
  put_varint(out, entries);
  put_varint(out, blocks.size());
  int64_t previous_min[3] = {0, 0, 0};
  for (const BlockSummary& b : blocks) {
    const GroupSummary& g = b.nodes[0];
    put_varint(out, g.objects);
    for (int a = 0; a < 3; ++a) {
      put_varint(out, zigzag(int64_t(g.min[a]) - previous_min[a]));
      previous_min[a] = g.min[a];
    }
    for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(int64_t(g.max[a]) - g.min[a]));
  }
  // Node summaries bottom-up (children come after their parents), then each node's proxy.
  std::vector<SpatialNode> top;
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(blocks.size()), 1, top, ranges);
  std::vector<GroupSummary> summaries(top.size());
  for (size_t i = top.size(); i-- > 0;) {
    if (top[i].count > 0) {
      summaries[i] = blocks[top[i].first].nodes[0];
    } else {
      summaries[i].add(summaries[top[i].first]);
      summaries[i].add(summaries[top[i].first + 1]);
    }
  }
  std::vector<const GroupSummary*> boxes;
  for (uint32_t i = 0; i < top.size(); ++i) {
    boxes.clear();
    collect_proxies(top, blocks, summaries, i, 3, boxes);
    put_varint(out, boxes.size());
    const GroupSummary& n = summaries[i];
    for (const GroupSummary* g : boxes) {
      for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(int64_t(g->min[a]) - n.min[a]));
      for (int a = 0; a < 3; ++a) put_varint(out, uint64_t(int64_t(n.max[a]) - g->max[a]));
      for (int k = 0; k < 4; ++k) out.push_back(uint8_t(g->colour >> (8 * k)));
    }
  }
}

bool decode_top(const uint8_t* data, size_t size, DecodedTop& out, std::string& error) {
  out = DecodedTop{};
  const auto fail = [&](const std::string& why) {
    out = DecodedTop{};
    error = why;
    return false;
  };
  if (size < 25) return fail("spatial top is truncated");
  std::memcpy(&out.origin, data, 24);
  if (!std::isfinite(out.origin.x) || !std::isfinite(out.origin.y) ||
      !std::isfinite(out.origin.z)) {
    return fail("spatial origin is not finite");
  }
  out.database = data[24];
  if (out.database > 1) return fail("spatial top names block database " + std::to_string(out.database));
  VarintReader r(data + 25, size - 25);
  uint64_t blocks = 0;
  // A block takes at least 7 bytes, a proxy box 10.
  if (!r.get(out.entries) || !r.get(blocks) || blocks > r.remaining() / 7) {
    return fail("spatial top is truncated");
  }
  if (out.entries > uint64_t(blocks) * kSpatialBlockObjects) {
    return fail("spatial top counts more entries than its blocks can hold");
  }
  out.block_entries.resize(blocks);
  out.block_grid.resize(blocks);
  int64_t min[3] = {0, 0, 0};
  uint64_t total = 0;
  constexpr int64_t kLo = std::numeric_limits<int32_t>::min(), kHi = std::numeric_limits<int32_t>::max();
  for (uint64_t b = 0; b < blocks; ++b) {
    uint64_t n;
    if (!r.get(n)) return fail("spatial top is truncated");
    if (n == 0 || n > kSpatialBlockObjects) {
      return fail("spatial top: block " + std::to_string(b) + " holds " + std::to_string(n) +
                  " entries");
    }
    out.block_entries[b] = uint32_t(n);
    total += n;
    for (int a = 0; a < 3; ++a) {
      int64_t delta;
      if (!r.get_signed(delta)) return fail("spatial top is truncated");
      if (!add_within(min[a], delta, kLo, kHi)) return fail("spatial top has bounds out of range");
      out.block_grid[b][a] = int32_t(min[a]);
    }
    for (int a = 0; a < 3; ++a) {
      uint64_t extent;
      if (!r.get(extent)) return fail("spatial top is truncated");
      if (extent > uint64_t(kHi) * 2 + 1 || !fits_int32(min[a] + int64_t(extent))) {
        return fail("spatial top has bounds out of range");
      }
      out.block_grid[b][3 + a] = int32_t(min[a] + int64_t(extent));
    }
  }
  if (total != out.entries) return fail("spatial top: its blocks hold other than its entry count");
  std::vector<NodeRange> ranges;
  spatial_topology(uint32_t(blocks), 1, out.nodes, ranges);
  ranges = {};
  // Grid bounds and counts bottom-up.
  std::vector<std::array<int32_t, 6>> grid(out.nodes.size());
  out.objects.resize(out.nodes.size());
  out.block_node.resize(blocks);
  for (size_t i = out.nodes.size(); i-- > 0;) {
    const SpatialNode& n = out.nodes[i];
    if (n.count > 0) {
      grid[i] = out.block_grid[n.first];
      out.objects[i] = out.block_entries[n.first];
      out.block_node[n.first] = uint32_t(i);
      continue;
    }
    const auto& a = grid[n.first];
    const auto& b = grid[n.first + 1];
    for (int k = 0; k < 3; ++k) {
      grid[i][k] = std::min(a[k], b[k]);
      grid[i][3 + k] = std::max(a[3 + k], b[3 + k]);
    }
    out.objects[i] = out.objects[n.first] + out.objects[n.first + 1];
  }
  for (size_t i = 0; i < out.nodes.size(); ++i) {
    grid_to_float(grid[i].data(), grid[i].data() + 3, out.nodes[i].min, out.nodes[i].max);
  }
  // Proxies: within their node, and together exactly its bounds.
  out.proxy_first.reserve(out.nodes.size() + 1);
  for (size_t i = 0; i < out.nodes.size(); ++i) {
    out.proxy_first.push_back(uint32_t(out.proxies.size()));
    uint64_t k;
    if (!r.get(k) || k > r.remaining() / 10) return fail("spatial top is truncated");
    if (k == 0 || k > kProxyBoxes) {
      return fail("spatial top: node " + std::to_string(i) + " has " + std::to_string(k) +
                  " proxy boxes");
    }
    int64_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = kHi, hi[a] = kLo;
    for (uint64_t j = 0; j < k; ++j) {
      int32_t box[6];
      for (int s = 0; s < 6; ++s) {
        uint64_t v;
        if (!r.get(v)) return fail("spatial top is truncated");
        const int a = s % 3;
        const int64_t extent = int64_t(grid[i][3 + a]) - grid[i][a];
        if (v > uint64_t(extent)) {
          return fail("spatial top: a proxy box of node " + std::to_string(i) +
                      " lies outside the node");
        }
        box[s] = s < 3 ? int32_t(grid[i][a] + int64_t(v)) : int32_t(grid[i][3 + a] - int64_t(v));
      }
      for (int a = 0; a < 3; ++a) {
        if (box[a] > box[3 + a]) {
          return fail("spatial top: a proxy box of node " + std::to_string(i) + " is inverted");
        }
        lo[a] = std::min<int64_t>(lo[a], box[a]);
        hi[a] = std::max<int64_t>(hi[a], box[3 + a]);
      }
      if (r.remaining() < 4) return fail("spatial top is truncated");
      const uint8_t* c = r.position();
      ProxyBox p;
      grid_to_float(box, box + 3, p.min, p.max);
      p.colour = Colour{c[0], c[1], c[2], c[3]};
      r.skip(4);
      out.proxies.push_back(p);
    }
    for (int a = 0; a < 3; ++a) {
      if (lo[a] != grid[i][a] || hi[a] != grid[i][3 + a]) {
        return fail("spatial top: the proxy of node " + std::to_string(i) +
                    " does not cover its bounds");
      }
    }
  }
  out.proxy_first.push_back(uint32_t(out.proxies.size()));
  if (!r.at_end()) return fail("trailing bytes after the spatial top");
  return true;
}

}  // namespace plantview::detail
