// The primitive mix of Zhou et al. 2012, Table 1 (an ethylene plant of 21.9 M triangles):
// counts per kind, with sizes drawn like a plant's (pipe parts 0.05-1 m, a few large vessels).
#pragma once

#include <cstdint>
#include <vector>

#include "plantview/primitives.h"

namespace plantview::bench {

// Deterministic for a seed. `fraction` scales every count (1.0: the full 75,330 primitives).
std::vector<Primitive> zhou_table1_mix(uint32_t seed, double fraction);

}  // namespace plantview::bench
