// Transitional, from the `store` branch (issue 15): the format 2 flat arrays of the spatial
// hierarchy (nodes and entries, node 0 the root) rebuilt from format 3's top and blocks, so that
// the renderer's walks build and run until they page blocks themselves (helper `pager`). Its
// memory grows with the plant (48 bytes an object), exactly what issue 15 removes: delete this
// file when no caller is left.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "plantview/store.h"

namespace plantview::detail {

struct FlatSpatial {
  std::vector<SpatialNode> nodes;
  std::vector<SpatialEntry> entries;
};

// The flat hierarchy of `view`'s state, built on the first call on this thread for that view and
// kept until a call for another view (one per thread). Empty if a block cannot be read.
inline const FlatSpatial& flat_spatial(const ReadView& view) {
  struct Cached {
    const ReadView* view = nullptr;
    const void* top = nullptr;
    uint64_t objects = 0;
    FlatSpatial flat;
  };
  thread_local Cached cached;
  const auto top = view.spatial_top();
  if (cached.view == &view && cached.top == top.data() && cached.objects == view.spatial_objects()) {
    return cached.flat;
  }
  cached = Cached{&view, top.data(), view.spatial_objects(), {}};
  FlatSpatial& out = cached.flat;
  if (top.empty()) return out;
  out.nodes.reserve(view.spatial_objects() / 4 + top.size());
  out.entries.reserve(view.spatial_objects());
  std::string error;
  // (top node, flat index) pairs still to place; the flat node is allocated already.
  std::vector<std::pair<uint32_t, uint32_t>> stack{{0u, 0u}};
  out.nodes.push_back({});
  while (!stack.empty()) {
    const auto [t, at] = stack.back();
    stack.pop_back();
    const SpatialNode& node = top[t];
    if (node.count == 0) {
      const uint32_t children = uint32_t(out.nodes.size());
      out.nodes.push_back({});
      out.nodes.push_back({});
      out.nodes[at] = node;
      out.nodes[at].first = children;
      stack.push_back({node.first + 1, children + 1});
      stack.push_back({node.first, children});
      continue;
    }
    const auto block = view.spatial_block(node.first, error);
    if (!block) {
      cached.flat = {};
      return cached.flat;
    }
    const uint32_t base = uint32_t(out.nodes.size()) - 1;  // block node j > 0 -> base + j
    const uint32_t entry_base = uint32_t(out.entries.size());
    for (uint32_t j = 0; j < block->nodes.size(); ++j) {
      SpatialNode n = block->nodes[j];
      n.first = n.count == 0 ? base + n.first : entry_base + n.first;
      if (j == 0) {
        out.nodes[at] = n;
      } else {
        out.nodes.push_back(n);
      }
    }
    out.entries.insert(out.entries.end(), block->entries.begin(), block->entries.end());
  }
  return out;
}

}  // namespace plantview::detail
