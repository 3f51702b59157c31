// The tessellation contract around the kinds: the size rule, shared templates, concatenation of
// an object's primitives, index widths, normal packing, mirrored placements and kind names.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "plantview/primitives.h"

namespace plantview {
namespace {

TEST(SegmentRule, FollowsZhouUpToOneMetreAndGrowsWithDiameter) {
  EXPECT_EQ(segment_exponents(0.05f).n_max, 5);
  EXPECT_EQ(segment_exponents(1.0f).n_max, 5);
  EXPECT_EQ(segment_exponents(1.5f).n_max, 6);
  EXPECT_EQ(segment_exponents(2.0f).n_max, 6);
  EXPECT_EQ(segment_exponents(4.0f).n_max, 7);
  EXPECT_EQ(segment_exponents(50.0f).n_max, 8);
  EXPECT_EQ(segment_exponents(NAN).n_max, 5);
  EXPECT_EQ(segment_exponents(0.2f).n_min, 2);
}

TEST(Templates, PrimitivesOfOneShapeShareTheirIndexArrays) {
  const MeshPlan a = plan_mesh(Primitive{{}, Cylinder{0.1f, 2.0f}});
  const MeshPlan b = plan_mesh(Primitive{{}, Cylinder{0.3f, 0.5f}});
  ASSERT_EQ(a.level_count, b.level_count);
  for (uint32_t l = 0; l < a.level_count; ++l) EXPECT_EQ(a.indices[l].data(), b.indices[l].data());
  // A larger diameter needs more segments: another template.
  const MeshPlan c = plan_mesh(Primitive{{}, Cylinder{2.0f, 1.0f}});
  EXPECT_NE(a.indices[0].data(), c.indices[0].data());
  EXPECT_GT(c.vertex_count, a.vertex_count);
}

TEST(Templates, ALevelSwitchIsOnlyAnIndexRangeOverOneVertexArray) {
  const MeshPlan plan = plan_mesh(Primitive{{}, Cylinder{0.1f, 1.0f}});
  ASSERT_EQ(plan.level_count, 4);
  // Zhou: a 32-segment cylinder has 124 triangles; each coarser level halves the segments.
  EXPECT_EQ(element_count(plan, 0), 124u);
  EXPECT_EQ(element_count(plan, 1), 60u);
  EXPECT_EQ(element_count(plan, 2), 28u);
  EXPECT_EQ(element_count(plan, 3), 12u);
  EXPECT_EQ(element_count(plan, 7), 12u) << "levels past the coarsest clamp to it";
  EXPECT_NEAR(plan.error_m[0], 0.1 * (1 - std::cos(std::numbers::pi / 32)), 1e-7);
}

TEST(FittedRings, ALevelFittedToStraddlesItsCircleAtHalfTheError) {
  const float r = 0.1f;
  const Primitive p{{}, Cylinder{r, 1.0f}};
  const MeshPlan plan = plan_mesh(p);
  ASSERT_EQ(plan.level_count, 4);
  std::vector<PackedVertex> v(plan.vertex_count);
  write_vertices(p, plan, glm::dvec3(0.0), v);  // the default: on the surface
  EXPECT_NEAR(glm::length(glm::vec2(v[0].position_m)), r, 1e-7f);
  for (uint32_t level = 0; level < plan.level_count; ++level) {
    const double c = std::cos(std::numbers::pi / double(32 >> level));
    write_vertices(p, plan, glm::dvec3(0.0), v, level);
    // s = 2 / (1 + cos(pi/N)): vertices r(s - 1) out, chord midpoints r(1 - s cos) in, equal.
    const double s = 2.0 / (1.0 + c);
    for (uint32_t i : {0u, 5u, 31u, 40u}) {
      EXPECT_NEAR(glm::length(glm::vec2(v[i].position_m)), r * s, 2e-7) << "vertex " << i;
    }
    EXPECT_NEAR(plan.straddled_error_m[level], r * (1 - c) / (1 + c), 1e-8) << "level " << level;
    // 1 / (1 + cos(pi/N)) of the inscribed error: 0.50 at 32 segments, 0.59 at 4.
    EXPECT_NEAR(plan.straddled_error_m[level], plan.error_m[level] / (1 + c), 1e-8);
  }
  write_vertices(p, plan, glm::dvec3(0.0), v, 7);  // past the coarsest: clamped to it
  EXPECT_NEAR(glm::length(glm::vec2(v[0].position_m)),
              r * 2.0 / (1.0 + std::cos(std::numbers::pi / 4)), 2e-7);
}

TEST(FittedRings, PipesOfOneRadiusFittedToOneLevelMeetRingToRing) {
  // A run of two cylinders and a concentric snout of the same radius: their shared end rings
  // coincide when fitted to the same level.
  const Primitive a{{glm::mat3(1.0f), {0, 0, 0.5f}}, Cylinder{0.1f, 1.0f}};
  const Primitive b{{glm::mat3(1.0f), {0, 0, 1.25f}}, Snout{0.1f, 0.1f, 0.5f}};
  const MeshPlan pa = plan_mesh(a), pb = plan_mesh(b);
  std::vector<PackedVertex> va(pa.vertex_count), vb(pb.vertex_count);
  write_vertices(a, pa, glm::dvec3(0.0), va, 2);
  write_vertices(b, pb, glm::dvec3(0.0), vb, 2);
  for (uint32_t i = 0; i < 32; ++i) {
    EXPECT_NEAR(glm::distance(va[32 + i].position_m, vb[i].position_m), 0.0f, 1e-6f) << i;
  }
}

TEST(Concatenation, AnObjectsPrimitivesShareOneVertexAndOneIndexArray) {
  const Primitive parts[] = {
      {{}, Cylinder{0.1f, 1.0f}},
      {{glm::mat3(1.0f), {0, 0, 1}}, Cylinder{0.05f, 0.5f}},
  };
  std::vector<PackedVertex> vertices;
  std::vector<uint32_t> indices;
  uint32_t base = 0;
  for (const Primitive& p : parts) {
    const MeshPlan plan = plan_mesh(p);
    vertices.resize(base + plan.vertex_count);
    write_vertices(p, plan, glm::dvec3(0.0), std::span(vertices).subspan(base));
    const size_t first = indices.size();
    indices.resize(first + plan.index_count(1));
    EXPECT_EQ(write_indices(plan, 1, base, std::span(indices).subspan(first)), plan.index_count(1));
    for (size_t i = first; i < indices.size(); ++i) {
      EXPECT_GE(indices[i], base);
      EXPECT_LT(indices[i], base + plan.vertex_count);
    }
    base += plan.vertex_count;
  }
  EXPECT_EQ(vertices.size(), 256u);
  // The second part's vertices sit 1 m up (its placement), the first part's around the origin.
  EXPECT_GT(vertices[128].position_m.z, 0.7f);
}

TEST(Concatenation, SixteenBitIndicesMatchThirtyTwoBitOnes) {
  const MeshPlan plan = plan_mesh(Primitive{{}, Cylinder{0.1f, 1.0f}});
  std::vector<uint32_t> wide(plan.index_count(0));
  std::vector<uint16_t> narrow(plan.index_count(0));
  write_indices(plan, 0, 1000, std::span(wide));
  write_indices(plan, 0, 1000, std::span(narrow));
  for (size_t i = 0; i < wide.size(); ++i) ASSERT_EQ(wide[i], narrow[i]);
}

TEST(Placement, PositionsAreRelativeToTheOriginWithKilometreCoordinates) {
  Primitive p{{glm::mat3(1.0f), {12000.5f, -8000.25f, 30.0f}}, Cylinder{0.1f, 1.0f}};
  const MeshPlan plan = plan_mesh(p);
  std::vector<PackedVertex> v(plan.vertex_count);
  write_vertices(p, plan, glm::dvec3(12000.0, -8000.0, 30.0), v);
  // Vertex 0 is at angle 0 on the bottom ring: (r, 0, -h/2) from the translation.
  EXPECT_NEAR(v[0].position_m.x, 0.6f, 1e-6f);
  EXPECT_NEAR(v[0].position_m.y, -0.25f, 1e-6f);
  EXPECT_NEAR(v[0].position_m.z, -0.5f, 1e-6f);
}

TEST(Placement, MirroringFlipsTheWindingAndKeepsNormalsOutward) {
  Primitive p{{glm::mat3(glm::vec3(-1, 0, 0), {0, 1, 0}, {0, 0, 1}), {}}, Cylinder{0.1f, 1.0f}};
  const MeshPlan plan = plan_mesh(p);
  EXPECT_TRUE(plan.flip_winding);
  std::vector<PackedVertex> v(plan.vertex_count);
  write_vertices(p, plan, glm::dvec3(0.0), v);
  std::vector<uint32_t> idx(plan.index_count(0));
  write_indices(plan, 0, 0, std::span(idx));
  // The first side quad's triangle faces outward: its normal agrees with its vertices' normals.
  const glm::vec3 a = v[idx[0]].position_m, b = v[idx[1]].position_m, c = v[idx[2]].position_m;
  EXPECT_GT(glm::dot(glm::cross(b - a, c - a), unpack_normal(v[idx[0]].normal)), 0.0f);
}

TEST(Placement, ErrorsAreInModelMetresAfterTheScale) {
  Primitive p{{glm::mat3(2.0f), {}}, Cylinder{0.1f, 1.0f}};
  const MeshPlan scaled = plan_mesh(p);
  const MeshPlan plain = plan_mesh(Primitive{{}, Cylinder{0.1f, 1.0f}});
  EXPECT_NEAR(scaled.error_m[0], 2.0f * plain.error_m[0], 1e-7f);
}

TEST(NormalPacking, RoundTripsWithinTheTenBitPrecision) {
  for (glm::vec3 n : {glm::vec3(1, 0, 0), glm::vec3(0, -1, 0), glm::vec3(0, 0, 1),
                      glm::normalize(glm::vec3(1, -2, 3)), glm::normalize(glm::vec3(-1, -1, -1))}) {
    const glm::vec3 back = unpack_normal(pack_normal(n));
    EXPECT_NEAR(back.x, n.x, 1.0f / 511);
    EXPECT_NEAR(back.y, n.y, 1.0f / 511);
    EXPECT_NEAR(back.z, n.z, 1.0f / 511);
  }
  EXPECT_EQ(pack_normal({0, 0, 0}) >> 30, 0u) << "w stays zero";
}

TEST(KindNames, RoundTripForEveryKind) {
  for (int i = 0; i < kPrimitiveKindCount; ++i) {
    PrimitiveKind back;
    ASSERT_TRUE(kind_from_name(kind_name(PrimitiveKind(i)), back));
    EXPECT_EQ(int(back), i);
  }
  PrimitiveKind unused;
  EXPECT_FALSE(kind_from_name("teapot", unused));
}

TEST(Representatives, EveryKindTessellatesToSomething) {
  const std::vector<Primitive> all = representative_primitives(0.2f);
  ASSERT_EQ(all.size(), size_t(kPrimitiveKindCount));
  for (size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(int(all[i].kind()), int(i));
    const MeshPlan plan = plan_mesh(all[i]);
    EXPECT_GT(plan.vertex_count, 0u) << kind_name(all[i].kind());
    EXPECT_GT(plan.index_count(0), 0u) << kind_name(all[i].kind());
  }
}

}  // namespace
}  // namespace plantview
