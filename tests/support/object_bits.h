// Bit-exact comparison of plant objects, for round-trip tests and fuzz harnesses: floats are
// equal only when their bits are (so -0 differs from 0 and a NaN equals the same NaN).
// FacetGroup::triangles is left out: it is derived data, made again by triangulate().
#pragma once

#include <cstring>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "plantview/model.h"

namespace plantview::test {

template <class T>
bool same_bits(const T& a, const T& b) {
  static_assert(std::is_trivially_copyable_v<T>);
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Returns an empty string when `a` and `b` are the same, else the first field that differs.
inline std::string object_difference(const Object& a, const Object& b) {
  if (a.id != b.id) return "id";
  if (a.name != b.name) return "name";
  if (a.object_class != b.object_class) return "class";
  if (!(a.colour == b.colour)) return "colour";
  if (!same_bits(a.origin_m, b.origin_m)) return "origin_m";
  if (a.source != b.source) return "source";
  if (a.pipeline_id != b.pipeline_id) return "pipeline_id";
  if (a.primitives.size() != b.primitives.size()) return "primitive count";
  for (size_t i = 0; i < a.primitives.size(); ++i) {
    const Primitive& p = a.primitives[i];
    const Primitive& q = b.primitives[i];
    const std::string where = "primitive " + std::to_string(i) + ": ";
    if (p.kind() != q.kind()) return where + "kind";
    if (!same_bits(p.placement.linear, q.placement.linear)) return where + "linear";
    if (!same_bits(p.placement.translation_m, q.placement.translation_m))
      return where + "translation_m";
    const bool same_shape = std::visit(
        [&](const auto& s) {
          using S = std::decay_t<decltype(s)>;
          const S& t = std::get<S>(q.shape);
          if constexpr (std::is_same_v<S, FacetGroup>) {
            return same_bits(s.vertices, t.vertices) && s.contour_ends == t.contour_ends &&
                   s.polygon_ends == t.polygon_ends;
          } else {
            return same_bits(s, t);
          }
        },
        p.shape);
    if (!same_shape) return where + "shape fields";
  }
  if (a.attributes != b.attributes) return "attributes";
  if (!same_bits(a.connections, b.connections)) return "connections";
  if (!same_bits(a.centreline, b.centreline)) return "centreline";
  if (a.branches != b.branches) return "branches";
  return {};
}

}  // namespace plantview::test
