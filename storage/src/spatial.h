// Internal: building the spatial hierarchy stored under spatial/"nodes" and "entries".
#pragma once

#include <vector>

#include "plantview/store.h"

namespace plantview {

// An object's bounds in model space (double) with its slot, before packing.
struct SpatialEntryD {
  glm::dvec3 min, max;
  uint32_t slot;
};

// Builds a bounding volume hierarchy (median split on the longest axis of the centroids, at
// most kLeafSize entries a leaf) over `entries`; bounds are stored relative to `origin` and
// rounded outward so that no object pokes out of its float box. Reorders `entries`.
void build_spatial_tree(std::vector<SpatialEntryD>& entries, const glm::dvec3& origin,
                        std::vector<SpatialNode>& nodes, std::vector<SpatialEntry>& packed);

}  // namespace plantview
