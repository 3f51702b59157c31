// Radix sort of a frame's sort keys: (key, index) pairs ordered by key, equal keys in the order
// they were given, which for indices pushed in increasing order is std::sort's order of the
// pairs. The frame sorts its visible objects (largest on screen first) and its draws (nearest
// first) every phase: tens of thousands of pairs, where a comparison sort was 2 ms of a wide
// view's CPU frame.
//
// Rules: least significant byte first, one counting pass for all eight bytes, and a byte that is
//   the same in every key is skipped. Linear in the pairs; no allocation once `scratch` is warm.
// Threads: pure; `items` and `scratch` belong to the caller.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace plantview::detail {

using SortPair = std::pair<uint64_t, uint32_t>;

// Sorts `items` by key, stably. `scratch` is working space (its contents are lost; `items` may
// come back in what was scratch's storage: both are swapped when that is where the sort ends).
inline void radix_sort(std::vector<SortPair>& items, std::vector<SortPair>& scratch) {
  constexpr size_t kSmall = 256;  // below this a comparison sort is as fast
  if (items.size() < kSmall) {
    std::sort(items.begin(), items.end());
    return;
  }
  std::array<std::array<uint32_t, 256>, 8> counts{};
  for (const SortPair& p : items)
    for (int b = 0; b < 8; ++b) ++counts[b][(p.first >> (8 * b)) & 0xff];
  scratch.resize(items.size());
  std::vector<SortPair>* from = &items;
  std::vector<SortPair>* to = &scratch;
  for (int b = 0; b < 8; ++b) {
    std::array<uint32_t, 256>& c = counts[b];
    if (c[(items.front().first >> (8 * b)) & 0xff] == items.size()) continue;  // one bucket
    uint32_t at = 0;
    for (uint32_t& n : c) at += std::exchange(n, at);  // counts -> first position
    for (const SortPair& p : *from) (*to)[c[(p.first >> (8 * b)) & 0xff]++] = p;
    std::swap(from, to);
  }
  if (from != &items) items.swap(scratch);
}

}  // namespace plantview::detail
