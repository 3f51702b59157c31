// The generic tessellation driver: dispatches to the one file per kind, owns the template cache,
// and applies the placement (model-space errors, mirroring, origin-relative positions).
#include <algorithm>
#include <cassert>
#include <cmath>
#include <memory>
#include <mutex>
#include <numbers>
#include <shared_mutex>
#include <unordered_map>
#include <utility>

#include "kinds.h"

namespace plantview {
namespace detail {

namespace {
std::array<glm::vec2, kCircleSamples + 1> make_unit_circle() {
  // The first quadrant in double precision, the others turned from it by exact quarter turns.
  constexpr uint32_t quarter = kCircleSamples / 4;
  std::array<glm::vec2, kCircleSamples + 1> samples;
  for (uint32_t i = 0; i < quarter; ++i) {
    const double a = 2.0 * std::numbers::pi * double(i) / double(kCircleSamples);
    const glm::vec2 cs(float(std::cos(a)), float(std::sin(a)));
    samples[i] = cs;
    samples[i + quarter] = {-cs.y, cs.x};
    samples[i + 2 * quarter] = -cs;
    samples[i + 3 * quarter] = {cs.y, -cs.x};
  }
  // Exact values on the axes (no negative zeros) keep symmetric shapes symmetric.
  static const glm::vec2 axes[5] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}, {1, 0}};
  for (uint32_t q = 0; q <= 4; ++q) samples[q * quarter] = axes[q];
  return samples;
}
}  // namespace

// Used only after main() starts (no other static initialiser tessellates).
const std::array<glm::vec2, kCircleSamples + 1> kUnitCircle = make_unit_circle();

}  // namespace detail

namespace {

using detail::TemplateBuilder;
using detail::TemplateKey;

struct MeshTemplate {
  std::vector<uint32_t> indices;
  std::array<uint32_t, kMaxLevels + 1> level_begin{};
  uint32_t level_count = 0;
};

using BuildFn = void (*)(const TemplateKey&, TemplateBuilder&);
constexpr BuildFn kBuilders[kPrimitiveKindCount] = {
    detail::build_template_Box,
    detail::build_template_Pyramid,
    detail::build_template_Prism,
    detail::build_template_Cylinder,
    detail::build_template_Snout,
    detail::build_template_SquareToRound,
    detail::build_template_CircularTorus,
    detail::build_template_RectangularTorus,
    detail::build_template_Sphere,
    detail::build_template_EllipticalDish,
    detail::build_template_SphericalDish,
    detail::build_template_Saddle,
    detail::build_template_Line,
    nullptr,  // facet groups carry their own triangulation
};

// Process-wide cache of index templates. Templates are never removed, so references stay valid.
class TemplateCache {
 public:
  const MeshTemplate& get(const TemplateKey& key) {
    const uint64_t packed = key.packed();
    // Each thread remembers the templates it used last (templates are never removed, so the
    // pointers stay valid): the shared lock and the hash lookup cost as much as the rest of
    // planning a primitive, and a plant uses a few dozen shapes over and over.
    struct Recent {
      uint64_t packed = 0;
      const MeshTemplate* t = nullptr;
    };
    thread_local std::array<Recent, 64> recent;
    Recent& slot = recent[(packed * 0x9e3779b97f4a7c15ull) >> 58];
    if (slot.t == nullptr || slot.packed != packed) slot = {packed, &find_or_build(key, packed)};
    return *slot.t;
  }

 private:
  const MeshTemplate& find_or_build(const TemplateKey& key, uint64_t packed) {
    {
      std::shared_lock lock(mutex_);
      auto it = templates_.find(packed);
      if (it != templates_.end()) return *it->second;
    }
    // Build outside the lock; a racing builder of the same key loses and its result is dropped.
    assert(key.kind < kPrimitiveKindCount && kBuilders[key.kind] != nullptr);
    TemplateBuilder builder;
    kBuilders[key.kind](key, builder);
    auto built = std::make_unique<MeshTemplate>();
    built->indices = builder.indices();
    const auto& begins = builder.level_begin();
    assert(!begins.empty() && begins.size() <= size_t(kMaxLevels));
    built->level_count = uint32_t(begins.size());
    for (size_t l = 0; l < begins.size(); ++l) built->level_begin[l] = begins[l];
    built->level_begin[begins.size()] = uint32_t(built->indices.size());
    std::unique_lock lock(mutex_);
    auto [it, inserted] = templates_.try_emplace(packed, std::move(built));
    return *it->second;
  }

  std::shared_mutex mutex_;
  std::unordered_map<uint64_t, std::unique_ptr<MeshTemplate>> templates_;
};

TemplateCache& template_cache() {
  static TemplateCache cache;
  return cache;
}

// Largest stretch of a linear map: the square root of the largest eigenvalue of M^T M
// (closed form for symmetric 3x3 matrices).
float max_stretch(const glm::mat3& m) {
  const glm::dmat3 md(m);
  const glm::dmat3 a = glm::transpose(md) * md;
  const double p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
  const double q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
  double eig;
  if (p1 <= 1e-30 * (q * q + 1e-300)) {
    eig = std::max({a[0][0], a[1][1], a[2][2]});
  } else {
    const double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) +
                      (a[2][2] - q) * (a[2][2] - q) + 2.0 * p1;
    const double p = std::sqrt(p2 / 6.0);
    const glm::dmat3 b = (1.0 / p) * (a - q * glm::dmat3(1.0));
    const double r = std::clamp(glm::determinant(b) / 2.0, -1.0, 1.0);
    eig = q + 2.0 * p * std::cos(std::acos(r) / 3.0);
  }
  return float(std::sqrt(std::max(eig, 0.0)));
}

// A similarity (rotation, mirror, uniform scale: orthogonal columns of equal length, within
// float noise) keeps angles, so unit normals stay unit once the normal matrix is rescaled to a
// rotation. Pipe racks are built almost entirely of such placements.
bool is_similarity(const glm::mat3& m) {
  const float l0 = glm::dot(m[0], m[0]), l1 = glm::dot(m[1], m[1]), l2 = glm::dot(m[2], m[2]);
  const float tol = 1e-5f * l0;
  return l0 > 1e-30f && std::abs(l1 - l0) <= tol && std::abs(l2 - l0) <= tol &&
         std::abs(glm::dot(m[0], m[1])) <= tol && std::abs(glm::dot(m[0], m[2])) <= tol &&
         std::abs(glm::dot(m[1], m[2])) <= tol;
}

}  // namespace

std::string_view kind_name(PrimitiveKind kind) {
  static constexpr std::string_view names[kPrimitiveKindCount] = {
      "box",    "pyramid",         "prism",          "cylinder", "snout",
      "square_to_round", "circular_torus", "rectangular_torus", "sphere", "elliptical_dish",
      "spherical_dish", "saddle", "line", "facet_group"};
  const auto i = static_cast<size_t>(kind);
  return i < kPrimitiveKindCount ? names[i] : std::string_view("unknown");
}

bool kind_from_name(std::string_view name, PrimitiveKind& kind) {
  for (int i = 0; i < kPrimitiveKindCount; ++i) {
    if (kind_name(PrimitiveKind(i)) == name) {
      kind = PrimitiveKind(i);
      return true;
    }
  }
  return false;
}

uint32_t pack_normal(glm::vec3 n) { return detail::pack_unit_normal(n); }

glm::vec3 unpack_normal(uint32_t packed) {
  auto component = [](uint32_t bits) {
    int32_t v = static_cast<int32_t>(bits & 0x3ffu);
    if (v & 0x200) v -= 0x400;
    return std::max(float(v) / 511.0f, -1.0f);
  };
  return {component(packed), component(packed >> 10), component(packed >> 20)};
}

SegmentExponents segment_exponents(float diameter_m) {
  SegmentExponents e;
  if (diameter_m > 1.0f && std::isfinite(diameter_m)) {
    const int extra = int(std::ceil(std::log2(double(diameter_m)) - 1e-6));
    e.n_max = uint8_t(std::clamp(5 + extra, 5, 8));
  }
  return e;
}

Aabb local_bounds(const Shape& shape) {
  return std::visit([](const auto& s) { return detail::bounds(s); }, shape);
}

Aabb model_bounds(const Primitive& primitive) {
  const Aabb local = local_bounds(primitive.shape);
  if (local.empty()) return local;
  Aabb out{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
  for (int corner = 0; corner < 8; ++corner) {
    const glm::vec3 p((corner & 1) ? local.max.x : local.min.x,
                      (corner & 2) ? local.max.y : local.min.y,
                      (corner & 4) ? local.max.z : local.min.z);
    const glm::vec3 q = primitive.placement.linear * p + primitive.placement.translation_m;
    out.min = glm::min(out.min, q);
    out.max = glm::max(out.max, q);
  }
  return out;
}

MeshPlan plan_mesh(const Primitive& primitive) {
  MeshPlan plan;
  TemplateKey key;
  std::visit([&](const auto& s) { detail::plan(s, plan, key); }, primitive.shape);
  assert(plan.level_count >= 1 && plan.level_count <= kMaxLevels);

  if (plan.vertex_count == 0) {
    plan.level_count = 1;
    plan.indices = {};
    plan.error_m = {};
    plan.straddled_error_m = {};
    return plan;
  }
  if (key.kind != detail::kNoTemplate) {
    const MeshTemplate& t = template_cache().get(key);
    assert(t.level_count == plan.level_count);
    for (uint32_t l = 0; l < t.level_count; ++l) {
      plan.indices[l] = std::span<const uint32_t>(t.indices.data() + t.level_begin[l],
                                                  t.level_begin[l + 1] - t.level_begin[l]);
    }
  }
  // Errors were computed in the local frame; the placement may scale them. A similarity
  // stretches every direction by its column length (the eigen solve is for the general case).
  const glm::mat3& m = primitive.placement.linear;
  const float stretch =
      is_similarity(m)
          ? std::sqrt(std::max({glm::dot(m[0], m[0]), glm::dot(m[1], m[1]), glm::dot(m[2], m[2])}))
          : max_stretch(m);
  for (uint32_t l = 0; l < plan.level_count; ++l) {
    plan.error_m[l] *= stretch;
    plan.straddled_error_m[l] *= stretch;
  }
  plan.flip_winding = glm::determinant(m) < 0.0f;
  return plan;
}

void write_vertices(const Primitive& primitive, const MeshPlan& plan, const glm::dvec3& origin_m,
                    std::span<PackedVertex> out, uint32_t fit_level) {
  assert(out.size() >= plan.vertex_count);
  if (plan.vertex_count == 0) return;
  detail::VertexSink sink;
  sink.fit_level = fit_level == kOnSurface ? -1 : int(plan.clamp_level(fit_level));
  sink.linear = primitive.placement.linear;
  sink.translation_m = glm::vec3(glm::dvec3(primitive.placement.translation_m) - origin_m);
  if (is_similarity(sink.linear)) {
    // The normal matrix is the placement rescaled to a rotation (no inverse needed), and unit
    // normals stay unit.
    const glm::mat3& m = sink.linear;
    sink.normal_matrix = m * (1.0f / std::sqrt(glm::dot(m[0], m[0])));
    sink.preserves_unit_normals = true;
  } else {
    // A singular placement flattens the shape; its normals fall back to the local ones.
    const float det = glm::determinant(sink.linear);
    sink.normal_matrix =
        std::abs(det) > 1e-30f ? glm::transpose(glm::inverse(sink.linear)) : glm::mat3(1.0f);
  }
  sink.out = out.data();
  std::visit([&](const auto& s) { detail::write(s, plan, sink); }, primitive.shape);
}

namespace {

// dst[i] = src[i] + base for i < count. Four at a time with the buffers declared apart, so that
// the compiler turns each group into one vector add (GCC's -O2 vectoriser takes straight-line
// groups, not loops of unknown length).
template <typename Index>
void offset_indices(const uint32_t* __restrict src, Index* __restrict dst, size_t count,
                    uint32_t base) {
  size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    dst[i] = Index(src[i] + base);
    dst[i + 1] = Index(src[i + 1] + base);
    dst[i + 2] = Index(src[i + 2] + base);
    dst[i + 3] = Index(src[i + 3] + base);
  }
  for (; i < count; ++i) dst[i] = Index(src[i] + base);
}

template <typename Index>
uint32_t write_indices_impl(const MeshPlan& plan, uint32_t level, uint32_t base_vertex,
                            std::span<Index> out) {
  const std::span<const uint32_t> in = plan.indices[plan.clamp_level(level)];
  assert(out.size() >= in.size());
  const size_t n = in.size();
  Index* dst = out.data();
  const uint32_t* src = in.data();
  if (!plan.flip_winding || plan.topology != Topology::triangles) {
    offset_indices(src, dst, n, base_vertex);
    return uint32_t(n);
  }
  // Mirrored: offset a block of triangles (vectorised), then swap each one's last two corners
  // while the block is still in the first-level cache.
  constexpr size_t kBlock = 3 * 256;
  for (size_t begin = 0; begin < n; begin += kBlock) {
    const size_t count = std::min(kBlock, n - begin);
    offset_indices(src + begin, dst + begin, count, base_vertex);
    for (size_t i = begin; i + 2 < begin + count; i += 3) std::swap(dst[i + 1], dst[i + 2]);
  }
  return uint32_t(n);
}

}  // namespace

uint32_t write_indices(const MeshPlan& plan, uint32_t level, uint32_t base_vertex,
                       std::span<uint32_t> out) {
  return write_indices_impl(plan, level, base_vertex, out);
}

uint32_t write_indices(const MeshPlan& plan, uint32_t level, uint32_t base_vertex,
                       std::span<uint16_t> out) {
  assert(base_vertex + plan.vertex_count <= 65536u);
  return write_indices_impl(plan, level, base_vertex, out);
}

}  // namespace plantview
