// The clash engine's insides (plantview/clash.h): the rules that say a pair is no clash, the
// narrow phase on two objects' distance shapes, and ids and groups.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/clash.h"
#include "plantview/measure.h"
#include "plantview/model.h"

namespace plantview::clash_detail {

// The rule that says the pair is meant to touch, or none. Same-pipeline is decided earlier from
// the records' keys (cheaper); this repeats it for callers holding objects.
std::optional<ClashRule> exempting_rule(const Object& a, const Object& b);
bool is_support(const Object& object);

// What the narrow phase found for one pair (kind, depth or distance, error, points).
struct PairClash {
  ClashKind kind = ClashKind::hard;
  double depth_m = 0, distance_m = 0, error_m = 0;
  std::vector<glm::dvec3> points_m;
};
// The clash between two objects' shapes (same frame origin, neither empty), or none.
std::optional<PairClash> narrow_phase(const MeasureShapes& a, const MeasureShapes& b,
                                      double tolerance_m, double clearance_m);

// The stable id (clash.h): FNV-1a of the ids (lower first) and the point on kClashIdGridM.
uint64_t clash_id(uint64_t id_a, uint64_t id_b, const glm::dvec3& point_m);

}  // namespace plantview::clash_detail
