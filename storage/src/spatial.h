// Internal: the paged spatial hierarchy (format 3): how its blocks and its top are built, stored
// and expanded into the SpatialBlock / SpatialNode / ProxyBox forms readers walk.
//
// Grid: bounds are kept as int32 cell indices of a kSpatialCellM grid (2^-10 m, about a
// millimetre) around the store's spatial origin, rounded outward: an entry's box is
// origin + [min, max] * kSpatialCellM, computed in double, and contains the object's bounds.
// Grid values are exact in double, so rewriting the blocks at every import never moves them.
//
// Order: every entry of the store sits in one sequence sorted by (Morton code of the centre cell
// of its grid box, slot) (morton_key). The sequence is cut into blocks of kSpatialBlockObjects
// entries (the last one fewer), stored as spatial_a|spatial_b/<u32 BE block>.
//
// Shapes follow from counts alone, so only entries are stored:
//   - inside a block of n entries, the balanced binary topology of spatial_topology(n,
//     kLeafSize): node 0 over [0, n); a range over more than kLeafSize entries has children over
//     [begin, mid) and [mid, end), mid = begin + (end - begin) / 2;
//   - the top: spatial_topology(blocks, 1): the same over the blocks, each leaf one block.
// Node bounds are the unions of what they hold.
//
// Block (before zstd): varint n (1 to kSpatialBlockObjects) | per entry, in order:
//   zigzag varint (min - previous min)[3] | varint (max - min)[3]
//   | zigzag varint (slot - previous slot) | u8 r, g, b, a
// ("previous" starts at 0).
// Top (before zstd, meta/"spatial_top"): f64 origin[3] (metres, little-endian) | u8 database
//   (0: spatial_a, 1: spatial_b) | varint entries | varint blocks
//   | per block: varint entries | zigzag varint (min - previous block's min)[3] | varint (max - min)[3]
//   | per top node, in node order: varint boxes (1 to kProxyBoxes)
//     | per box: varint (min - node min)[3] | varint (node max - max)[3] | u8 r, g, b, a
// A top node's proxy boxes are the bounds of its descendants three levels down (top nodes, then
// a block's own nodes; a leaf that comes sooner stands for itself), each coloured as the
// largest (by grid volume) entry beneath it; their union is the node's bounds exactly.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "plantview/store.h"

namespace plantview::detail {

inline constexpr double kSpatialCellM = 1.0 / 1024;
inline constexpr uint32_t kLeafSize = 8;

struct GridEntry {
  int32_t min[3], max[3];  // cells relative to the spatial origin
  uint32_t slot;
};
// A stored entry: its grid box and its object's colour (r | g << 8 | b << 16 | a << 24), which
// proxies are painted with.
struct BlockEntry {
  GridEntry grid;
  uint32_t colour;
};

uint32_t pack_colour(const Colour& c);
Colour unpack_colour(uint32_t rgba);

// Rounds `bounds` outward onto the grid. False when they are not finite or lie beyond the grid's
// reach (about 2000 km from the origin).
bool quantise_bounds(const DAabb& bounds, const glm::dvec3& origin, uint32_t slot, GridEntry& out);
// The model-space box of an entry (contains the bounds it was quantised from).
DAabb grid_bounds(const GridEntry& entry, const glm::dvec3& origin);

// The 96-bit Morton code of the centre cell of an entry's box (each axis offset by 2^31 to be
// unsigned, bits interleaved x, y, z from the top): the order of the spatial sequence.
struct MortonKey {
  uint32_t high;
  uint64_t low;
  friend auto operator<=>(const MortonKey&, const MortonKey&) = default;
};
MortonKey morton_key(const GridEntry& entry);

// Node n's range [begin, end), alongside the topology's nodes.
struct NodeRange {
  uint32_t begin, end;
};
// The balanced binary topology over n items with leaves of at most `leaf_size`: nodes with first
// and count set (bounds left unset) and ranges, each allocated to its exact size.
void spatial_topology(uint32_t n, uint32_t leaf_size, std::vector<SpatialNode>& nodes,
                      std::vector<NodeRange>& ranges);

// A block's raw form. `n` in [1, kSpatialBlockObjects].
void encode_block(const BlockEntry* entries, uint32_t n, std::vector<uint8_t>& out);
// False with a message (without the store or block, which the caller adds) on malformed bytes.
bool decode_block(const uint8_t* data, size_t size, std::vector<BlockEntry>& entries,
                  std::string& error);
// The readers' form of a decoded block: float bounds relative to the origin, rounded outward;
// leaf bounds the union of their entries', entries quantised within them (SpatialEntry); inner
// bounds the union of their children's.
void expand_block(const std::vector<BlockEntry>& entries, SpatialBlock& out);
// The float form of grid bounds (rounded outward).
void grid_to_float(const int32_t grid_min[3], const int32_t grid_max[3], float min[3], float max[3]);

// What the top keeps of a group of entries (a block's node): its grid bounds, how many entries,
// the colour of the largest of them.
struct GroupSummary {
  int32_t min[3], max[3];
  uint64_t objects = 0;
  double largest_volume = -1;
  uint32_t colour = 0;
  bool leaf = false;  // no children (a block leaf's range)
  void add(const GroupSummary& other);
};
// A block's nodes down to depth 3 in heap order (node i's children 2i + 1 and 2i + 2), enough to
// make the proxies of the top nodes above it. Nodes below a leaf are left with objects == 0.
struct BlockSummary {
  std::array<GroupSummary, 15> nodes;
};
void summarise_block(const BlockEntry* entries, uint32_t n, BlockSummary& out);

// Writes the top's raw form over the summaries of every block, in block order.
void encode_top(const glm::dvec3& origin, uint8_t database, const std::vector<BlockSummary>& blocks,
                std::vector<uint8_t>& out);

// The readers' form of the top.
struct DecodedTop {
  glm::dvec3 origin{0.0};
  uint8_t database = 0;
  uint64_t entries = 0;
  std::vector<SpatialNode> nodes;
  std::vector<uint32_t> objects;             // beneath each node
  std::vector<uint32_t> proxy_first;         // node i's boxes: [proxy_first[i], proxy_first[i + 1])
  std::vector<ProxyBox> proxies;
  std::vector<uint32_t> block_entries;       // per block
  std::vector<std::array<int32_t, 6>> block_grid;  // per block: grid min[3], max[3]
  std::vector<uint32_t> block_node;          // per block: its top leaf
};
// False with a message on malformed bytes, or a proxy whose union is not its node's bounds.
bool decode_top(const uint8_t* data, size_t size, DecodedTop& out, std::string& error);

// The block cache bound of states first read after the call (kSpatialCacheBytes by default);
// tests make it small.
void set_spatial_cache_bytes(size_t bytes);

}  // namespace plantview::detail
