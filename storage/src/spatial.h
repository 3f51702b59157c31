// Internal: the spatial hierarchy under indexes/"spatial": how it is built, stored and expanded
// into the SpatialNode/SpatialEntry arrays readers walk.
//
// Grid: bounds are kept as int32 cell indices of a kSpatialCellM grid (2^-10 m, about a
// millimetre) around the store's spatial origin, rounded outward: an entry's box is
// origin + [min, max] * kSpatialCellM, computed in double, and contains the object's bounds.
// Grid values are exact in double, so rebuilding the index at every import never moves them.
//
// Shape: the hierarchy's topology is a function of the entry count alone (spatial_topology), so
// only entries are stored. Node 0 is the root over entries [0, n); a node over more than
// kLeafSize entries is inner: its children, allocated together when it is visited (depth first,
// second half first), hold [begin, mid) and [mid, end) with mid = begin + (end - begin) / 2.
// The builder orders entries so that each split is a median along the longest axis of the
// centroids, and each leaf's entries by slot. Node bounds are the union of what they hold.
//
// Stored form (before zstd), entries in tree order:
//   f64 origin[3] (metres, little-endian) | varint n
//   | per leaf, in entry order: zigzag varint (leaf min - previous leaf min)[3], then per entry:
//     varint (min - leaf min)[3] | varint (max - min)[3] | zigzag varint (slot - previous slot)
// (varint.h; "previous" starts at 0 and runs on across leaves.)
#pragma once

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

// Rounds `bounds` outward onto the grid. False when they are not finite or lie beyond the grid's
// reach (about 2000 km from the origin).
bool quantise_bounds(const DAabb& bounds, const glm::dvec3& origin, uint32_t slot, GridEntry& out);
// The model-space box of an entry (contains the bounds it was quantised from).
DAabb grid_bounds(const GridEntry& entry, const glm::dvec3& origin);

// Node n's entry range [begin, end), alongside the topology's nodes.
struct NodeRange {
  uint32_t begin, end;
};
// The hierarchy over n entries: nodes with first and count set (bounds left unset) and ranges,
// each allocated to its exact size (32 and 8 bytes a node; about n / 4 nodes).
void spatial_topology(uint32_t n, std::vector<SpatialNode>& nodes, std::vector<NodeRange>& ranges);

// Puts `entries` in tree order (see Shape above).
void build_spatial_tree(std::vector<GridEntry>& entries);

// `entries` in tree order.
void encode_spatial(const glm::dvec3& origin, const std::vector<GridEntry>& entries,
                    std::vector<uint8_t>& out);
// The stored form back on the grid (for an import, which rebuilds the hierarchy). False with a
// message on malformed bytes.
bool decode_spatial(const uint8_t* data, size_t size, glm::dvec3& origin,
                    std::vector<GridEntry>& entries, std::string& error);
// The stored form straight into the readers' form: float bounds relative to the origin, rounded
// outward; a leaf's bounds the union of its entries', each entry quantised within them (see
// SpatialEntry); an inner node's the union of its children's. Allocates exactly the two arrays
// (and a transient 8 bytes per leaf), never the grid entries. False with a message on malformed
// bytes.
bool decode_spatial_expanded(const uint8_t* data, size_t size, glm::dvec3& origin,
                             std::vector<SpatialNode>& nodes, std::vector<SpatialEntry>& entries,
                             std::string& error);

}  // namespace plantview::detail
