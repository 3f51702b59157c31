#include "spatial.h"

#include <algorithm>
#include <cmath>

namespace plantview {

namespace {

constexpr uint32_t kLeafSize = 8;

float round_down(double v) {
  const float f = float(v);
  return double(f) > v ? std::nextafter(f, -INFINITY) : f;
}
float round_up(double v) {
  const float f = float(v);
  return double(f) < v ? std::nextafter(f, INFINITY) : f;
}

}  // namespace

void build_spatial_tree(std::vector<SpatialEntryD>& entries, const glm::dvec3& origin,
                        std::vector<SpatialNode>& nodes, std::vector<SpatialEntry>& packed) {
  nodes.clear();
  packed.clear();
  if (entries.empty()) return;
  nodes.reserve(2 * (entries.size() / kLeafSize + 1));
  struct Task {
    uint32_t node, begin, end;
  };
  std::vector<Task> stack;
  nodes.push_back({});
  stack.push_back({0, 0, uint32_t(entries.size())});
  while (!stack.empty()) {
    const Task t = stack.back();
    stack.pop_back();
    DAabb box, centres;
    for (uint32_t i = t.begin; i < t.end; ++i) {
      box.extend(DAabb{entries[i].min, entries[i].max});
      centres.extend(0.5 * (entries[i].min + entries[i].max));
    }
    SpatialNode& node = nodes[t.node];
    for (int a = 0; a < 3; ++a) {
      node.min[a] = round_down(box.min[a] - origin[a]);
      node.max[a] = round_up(box.max[a] - origin[a]);
    }
    if (t.end - t.begin <= kLeafSize) {
      node.first = t.begin;
      node.count = t.end - t.begin;
      continue;
    }
    const glm::dvec3 extent = centres.max - centres.min;
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const uint32_t mid = t.begin + (t.end - t.begin) / 2;
    std::nth_element(entries.begin() + t.begin, entries.begin() + mid, entries.begin() + t.end,
                     [axis](const SpatialEntryD& a, const SpatialEntryD& b) {
                       return a.min[axis] + a.max[axis] < b.min[axis] + b.max[axis];
                     });
    const uint32_t children = uint32_t(nodes.size());
    node.first = children;
    node.count = 0;
    nodes.push_back({});  // invalidates `node`
    nodes.push_back({});
    stack.push_back({children, t.begin, mid});
    stack.push_back({children + 1, mid, t.end});
  }
  packed.reserve(entries.size());
  for (const SpatialEntryD& e : entries) {
    SpatialEntry p;
    for (int a = 0; a < 3; ++a) {
      p.min[a] = round_down(e.min[a] - origin[a]);
      p.max[a] = round_up(e.max[a] - origin[a]);
    }
    p.slot = e.slot;
    packed.push_back(p);
  }
}

}  // namespace plantview
