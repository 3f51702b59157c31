// The properties every primitive kind must hold at every level (issue: multi-resolution
// templates). Cases come from tests/primitives/*_cases.cpp; each runs under three placements.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

enum class Pose { as_given, rotated, mirrored };

Primitive posed(const PrimitiveCase& c, Pose pose) {
  Primitive p = c.primitive;
  if (pose == Pose::as_given) return p;
  glm::mat3 r = rotation_about({0.3f, -0.5f, 0.8f}, 0.7f);
  if (pose == Pose::mirrored) r = r * glm::mat3(glm::vec3(-1, 0, 0), {0, 1, 0}, {0, 0, 1});
  p.placement.linear = r * p.placement.linear;
  p.placement.translation_m = r * p.placement.translation_m + glm::vec3(12.5f, -7.25f, 3.0f);
  return p;
}

float extent_of(const Primitive& p) {
  const Aabb b = model_bounds(p);
  return b.empty() ? 1.0f : std::max(glm::length(b.max - b.min), 1e-3f);
}

class PrimitiveProperties : public ::testing::TestWithParam<std::tuple<PrimitiveCase, Pose>> {
 protected:
  const PrimitiveCase& the_case() const { return std::get<0>(GetParam()); }
  Primitive primitive() const { return posed(the_case(), std::get<1>(GetParam())); }
};

TEST_P(PrimitiveProperties, PositionsAndNormalsAreFiniteAndIndicesInRange) {
  const Primitive p = primitive();
  const MeshPlan plan = plan_mesh(p);
  ASSERT_GE(plan.level_count, 1);
  ASSERT_LE(plan.level_count, kMaxLevels);
  const uint32_t per_element = plan.topology == Topology::lines ? 2 : 3;
  for (uint32_t level = 0; level < plan.level_count; ++level) {
    const LevelMesh mesh = tessellate_level(p, plan, level);
    EXPECT_EQ(mesh.indices.size() % per_element, 0u) << "level " << level;
    for (uint32_t i : mesh.indices) ASSERT_LT(i, plan.vertex_count) << "level " << level;
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
      ASSERT_TRUE(std::isfinite(mesh.positions[v].x) && std::isfinite(mesh.positions[v].y) &&
                  std::isfinite(mesh.positions[v].z))
          << "vertex " << v;
      ASSERT_NEAR(glm::length(mesh.normals[v]), 1.0f, 0.01f) << "vertex " << v;
    }
    EXPECT_TRUE(std::isfinite(plan.error_m[level]));
  }
}

TEST_P(PrimitiveProperties, CoarserLevelsUseASubsetOfTheFinestVertices) {
  const Primitive p = primitive();
  const MeshPlan plan = plan_mesh(p);
  std::set<uint32_t> finer;
  for (uint32_t level = 0; level < plan.level_count; ++level) {
    const std::set<uint32_t> used(plan.indices[level].begin(), plan.indices[level].end());
    if (level == 0 && !the_case().degenerate) {
      EXPECT_EQ(used.size(), plan.vertex_count) << "level 0 leaves vertices unused";
    }
    if (level > 0) {
      EXPECT_TRUE(std::includes(finer.begin(), finer.end(), used.begin(), used.end()))
          << "level " << level << " uses a vertex level " << level - 1 << " does not";
    }
    finer = used;
  }
}

TEST_P(PrimitiveProperties, ClosedSolidsAreWatertightWithOutwardNormals) {
  const Primitive p = primitive();
  const MeshPlan plan = plan_mesh(p);
  if (!plan.closed || the_case().degenerate) GTEST_SKIP() << "not a closed solid";
  const float weld_m = 1e-5f * extent_of(p);
  const glm::vec3 centre = 0.5f * (model_bounds(p).min + model_bounds(p).max);
  for (uint32_t level = 0; level < plan.level_count; ++level) {
    const LevelMesh mesh = tessellate_level(p, plan, level);
    std::map<std::tuple<long, long, long>, uint32_t> ids;
    auto id_of = [&](uint32_t v) {
      const glm::vec3 q = glm::round(mesh.positions[v] / weld_m);
      return ids.try_emplace({long(q.x), long(q.y), long(q.z)}, uint32_t(ids.size())).first->second;
    };
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    double volume = 0;
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const uint32_t v[3] = {mesh.indices[t], mesh.indices[t + 1], mesh.indices[t + 2]};
      const uint32_t w[3] = {id_of(v[0]), id_of(v[1]), id_of(v[2])};
      if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;  // collapsed by the weld
      for (int e = 0; e < 3; ++e) directed[{w[e], w[(e + 1) % 3]}]++;
      const glm::vec3 a = mesh.positions[v[0]] - centre, b = mesh.positions[v[1]] - centre,
                      c = mesh.positions[v[2]] - centre;
      volume += glm::dot(a, glm::cross(b, c)) / 6.0;
      const glm::vec3 face = glm::cross(b - a, c - a);
      if (glm::length(face) < 1e-8f * extent_of(p) * extent_of(p)) continue;
      for (int k = 0; k < 3; ++k) {
        EXPECT_GT(glm::dot(glm::normalize(face), mesh.normals[v[k]]), -1e-3f)
            << "level " << level << " triangle " << t / 3 << " vertex normal points inward";
      }
    }
    int bad = 0;
    for (const auto& [edge, count] : directed) {
      const auto reverse = directed.find({edge.second, edge.first});
      if (count != 1 || reverse == directed.end() || reverse->second != 1) ++bad;
    }
    EXPECT_EQ(bad, 0) << "level " << level << ": edges not shared by exactly two triangles";
    EXPECT_GT(volume, 0.0) << "level " << level << ": faces wound inward";
  }
}

TEST_P(PrimitiveProperties, ReportedErrorBoundsTheMeasuredDeviation) {
  const PrimitiveCase& c = the_case();
  if (c.degenerate || !c.sample_surface) GTEST_SKIP() << "no surface to measure";
  const Primitive p = primitive();
  const MeshPlan plan = plan_mesh(p);
  if (plan.topology != Topology::triangles) GTEST_SKIP() << "lines have no surface";
  std::vector<glm::vec3> samples;
  c.sample_surface(samples);
  ASSERT_FALSE(samples.empty());
  for (glm::vec3& s : samples) s = p.placement.linear * s + p.placement.translation_m;
  // Float positions far from the origin carry rounding of about 1e-7 of their distance.
  const Aabb box = model_bounds(p);
  const float distance_m = std::max(glm::length(box.min), glm::length(box.max));
  const float slack_m = 2e-6f * extent_of(p) + 5e-7f * distance_m;
  float previous = 0;
  for (uint32_t level = 0; level < plan.level_count; ++level) {
    const float measured = max_distance_to_mesh(samples, tessellate_level(p, plan, level));
    const float reported = plan.error_m[level];
    EXPECT_GE(reported, measured * 0.99f - slack_m)
        << "level " << level << " reports " << reported << " m, measured " << measured << " m";
    EXPECT_LE(reported, 2.0f * measured + slack_m)
        << "level " << level << " reports " << reported << " m, measured " << measured << " m";
    EXPECT_GE(reported, previous) << "a coarser level reports a smaller error";
    previous = reported;
  }
}

// On the surface the mesh lies within the analytic bounds; fitted to level b it may reach out
// by that level's straddled error, and no further.
TEST_P(PrimitiveProperties, MeshLiesWithinTheAnalyticBounds) {
  const Primitive p = primitive();
  const MeshPlan plan = plan_mesh(p);
  const Aabb bounds = model_bounds(p);
  const float slack_m = 1e-5f * extent_of(p);
  for (uint32_t fit = 0; fit <= plan.level_count; ++fit) {
    const bool on_surface = fit == plan.level_count;
    const uint32_t fit_level = on_surface ? kOnSurface : fit;
    const float grown_m = on_surface ? 0.0f : plan.straddled_error_m[fit];
    const LevelMesh mesh = tessellate_level(p, plan, 0, fit_level);
    for (const glm::vec3& q : mesh.positions) {
      for (int axis = 0; axis < 3; ++axis) {
        ASSERT_GE(q[axis], bounds.min[axis] - grown_m - slack_m)
            << "axis " << axis << (on_surface ? ", on the surface" : ", fitted to level ") << fit;
        ASSERT_LE(q[axis], bounds.max[axis] + grown_m + slack_m)
            << "axis " << axis << (on_surface ? ", on the surface" : ", fitted to level ") << fit;
      }
    }
  }
}

// Fitted vertices (primitives.h, "Fitted vertices"). The deviation is measured from the true
// surface's samples to the mesh, which sees a vertex placed h outside the surface at h times the
// cosine of the faces' turn around it, and the deepest points inside in full; fitted, the two
// are equal by construction, so the figure is the latter's (test_tessellation_api.cpp checks
// where the vertices lie).
class FittedVertices : public PrimitiveProperties {
 protected:
  void SetUp() override {
    const PrimitiveCase& c = the_case();
    if (c.degenerate || !c.sample_surface) GTEST_SKIP() << "no surface to measure";
    p_ = primitive();
    plan_ = plan_mesh(p_);
    if (plan_.topology != Topology::triangles) GTEST_SKIP() << "lines have no surface";
    c.sample_surface(samples_);
    ASSERT_FALSE(samples_.empty());
    for (glm::vec3& q : samples_) q = p_.placement.linear * q + p_.placement.translation_m;
    const Aabb box = model_bounds(p_);
    const float distance_m = std::max(glm::length(box.min), glm::length(box.max));
    slack_m_ = 2e-6f * extent_of(p_) + 5e-7f * distance_m;
  }
  // Whether write_vertices moves this shape's vertices: its plan then reports less error fitted
  // (FittedVertices.ShapesThatAreNeverFittedWriteTheirVerticesOnTheSurface checks the others).
  bool fitted() const {
    for (uint32_t l = 0; l < plan_.level_count; ++l)
      if (plan_.straddled_error_m[l] < plan_.error_m[l]) return true;
    return false;
  }
  float measured(uint32_t level, uint32_t fit_level) const {
    return max_distance_to_mesh(samples_, tessellate_level(p_, plan_, level, fit_level));
  }
  Primitive p_;
  MeshPlan plan_;
  std::vector<glm::vec3> samples_;
  float slack_m_ = 0;
};

TEST_P(FittedVertices, StraddledLevelsHalveTheMeasuredDeviation) {
  if (!fitted()) GTEST_SKIP() << "a shape whose vertices are never moved";
  for (uint32_t level = 0; level < plan_.level_count; ++level) {
    const float inscribed = measured(level, kOnSurface), straddled = measured(level, level);
    // A circle of N segments: 1 / (1 + cos(pi/N)) of the inscribed error, 0.52 from N = 8 on,
    // 0.586 at the coarsest four; plus 5% for two directions straddling at once.
    const bool four_segments = (plan_.segments[0] >> level) <= 4;
    EXPECT_LE(straddled, (four_segments ? 0.62f : 0.55f) * inscribed + slack_m_)
        << "level " << level << ": fitted " << straddled << " m, on the surface " << inscribed
        << " m";
  }
}

TEST_P(FittedVertices, ReportedStraddledErrorBoundsTheMeasuredDeviation) {
  float previous = 0;
  for (uint32_t level = 0; level < plan_.level_count; ++level) {
    const float measured_m = measured(level, level);
    const float reported = plan_.straddled_error_m[level];
    EXPECT_GE(reported, measured_m * 0.99f - slack_m_)
        << "level " << level << " reports " << reported << " m, measured " << measured_m << " m";
    EXPECT_LE(reported, 2.0f * measured_m + slack_m_)
        << "level " << level << " reports " << reported << " m, measured " << measured_m << " m";
    EXPECT_LE(reported, plan_.error_m[level] + slack_m_) << "level " << level;
    EXPECT_GE(reported, previous) << "a coarser level reports a smaller error";
    previous = reported;
  }
}

// Saddles, square-to-rounds, spherical dishes, twisted snouts and elliptical dishes other than
// vessel heads report no gain: then fitting
// must leave every vertex where it was. The curved kinds that fit must report one.
TEST_P(FittedVertices, ShapesThatAreNeverFittedWriteTheirVerticesOnTheSurface) {
  const PrimitiveKind kind = p_.kind();
  const bool fitted_kind = kind == PrimitiveKind::cylinder || kind == PrimitiveKind::circular_torus ||
                           kind == PrimitiveKind::rectangular_torus || kind == PrimitiveKind::sphere;
  if (fitted_kind) {
    EXPECT_TRUE(fitted()) << "a kind that is always fitted reports no gain";
  }
  if (fitted()) GTEST_SKIP() << "fitted";
  const LevelMesh on_surface = tessellate_level(p_, plan_, 0, kOnSurface);
  for (uint32_t fit = 0; fit < plan_.level_count; ++fit) {
    EXPECT_EQ(tessellate_level(p_, plan_, 0, fit).positions, on_surface.positions)
        << "fitted to level " << fit;
  }
}

// The rule for a coarser level l drawn from vertices fitted to b < l: it errs at most
// error_m[l]. The extremes of b: 0 (its chords' midpoints dip deepest) and l - 1 (its vertices
// stick out furthest).
TEST_P(FittedVertices, CoarserLevelsOfFittedVerticesStayWithinTheirInscribedError) {
  for (uint32_t level = 1; level < plan_.level_count; ++level) {
    const uint32_t fits[2] = {0, level - 1};
    for (uint32_t k = 0; k < (level > 1 ? 2u : 1u); ++k) {
      const uint32_t fit = fits[k];
      const float measured_m = measured(level, fit);
      EXPECT_LE(measured_m, plan_.error_m[level] + slack_m_)
          << "level " << level << " fitted to " << fit << ": measured " << measured_m
          << " m, error_m " << plan_.error_m[level] << " m";
    }
  }
}

TEST_P(FittedVertices, FittedClosedSolidsStayWatertight) {
  if (!plan_.closed || !fitted()) GTEST_SKIP() << "not a fitted closed solid";
  const float weld_m = 1e-5f * extent_of(p_);
  for (uint32_t level = 0; level < plan_.level_count; ++level) {
    const LevelMesh mesh = tessellate_level(p_, plan_, level, level);
    std::map<std::tuple<long, long, long>, uint32_t> ids;
    auto id_of = [&](uint32_t v) {
      const glm::vec3 q = glm::round(mesh.positions[v] / weld_m);
      return ids.try_emplace({long(q.x), long(q.y), long(q.z)}, uint32_t(ids.size())).first->second;
    };
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const uint32_t w[3] = {id_of(mesh.indices[t]), id_of(mesh.indices[t + 1]),
                             id_of(mesh.indices[t + 2])};
      if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;  // collapsed by the weld
      for (int e = 0; e < 3; ++e) directed[{w[e], w[(e + 1) % 3]}]++;
    }
    int bad = 0;
    for (const auto& [edge, count] : directed) {
      const auto reverse = directed.find({edge.second, edge.first});
      if (count != 1 || reverse == directed.end() || reverse->second != 1) ++bad;
    }
    EXPECT_EQ(bad, 0) << "level " << level << ": edges not shared by exactly two triangles";
  }
}

TEST_P(PrimitiveProperties, ElementCountsMatchTheDocumentation) {
  const PrimitiveCase& c = the_case();
  if (c.expected_elements.empty()) GTEST_SKIP() << "no documented count for this case";
  const MeshPlan plan = plan_mesh(primitive());
  ASSERT_EQ(plan.level_count, c.expected_elements.size());
  for (uint32_t level = 0; level < plan.level_count; ++level) {
    EXPECT_EQ(element_count(plan, level), c.expected_elements[level]) << "level " << level;
  }
}

// The oracle the error test measures with: exact distances to a triangle's face, edges and
// corners, and to a degenerate (collinear) triangle.
TEST(MeshDistance, MeasuresToTheNearestFaceEdgeOrCorner) {
  LevelMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 5}, {1, 0, 5}, {2, 0, 5}};
  mesh.indices = {0, 1, 2};
  const std::pair<glm::vec3, float> expected[] = {
      {{0.2f, 0.2f, 0.5f}, 0.5f},          // over the face
      {{0.5f, -0.3f, 0.4f}, 0.5f},         // beside edge 01
      {{1.0f, 1.0f, 0.0f}, 0.70710678f},   // beside edge 12
      {{-0.3f, -0.4f, 0.0f}, 0.5f},        // off corner 0
      {{2.0f, -1.0f, 0.0f}, 1.41421356f},  // off corner 1
  };
  for (const auto& [point, distance] : expected) {
    EXPECT_NEAR(max_distance_to_mesh({point}, mesh), distance, 1e-6f)
        << point.x << " " << point.y << " " << point.z;
  }
  mesh.indices = {3, 4, 5};  // collinear: only its segments count
  EXPECT_NEAR(max_distance_to_mesh({{1, 1, 5}}, mesh), 1.0f, 1e-6f);
  EXPECT_NEAR(max_distance_to_mesh({{3, 0, 5}}, mesh), 1.0f, 1e-6f);
  mesh.indices = {0, 1, 2, 3, 4, 5};  // the nearest triangle counts; the farthest point wins
  EXPECT_NEAR(max_distance_to_mesh({{0.2f, 0.2f, 0.5f}, {0.5f, 0, 4}}, mesh), 1.0f, 1e-6f);
}

std::string case_name(const ::testing::TestParamInfo<std::tuple<PrimitiveCase, Pose>>& info) {
  static const char* poses[] = {"as_given", "rotated", "mirrored"};
  return std::get<0>(info.param).name + "_" + poses[int(std::get<1>(info.param))];
}

INSTANTIATE_TEST_SUITE_P(AllKinds, PrimitiveProperties,
                         ::testing::Combine(::testing::ValuesIn(all_cases()),
                                            ::testing::Values(Pose::as_given, Pose::rotated,
                                                              Pose::mirrored)),
                         case_name);
// Fitting happens in the shape's frame; the placement only maps it (and the mirrored pose is
// rotated too), so two poses suffice here: the measurements are the suite's costliest.
INSTANTIATE_TEST_SUITE_P(AllKinds, FittedVertices,
                         ::testing::Combine(::testing::ValuesIn(all_cases()),
                                            ::testing::Values(Pose::as_given, Pose::mirrored)),
                         case_name);

}  // namespace
}  // namespace plantview::testing
