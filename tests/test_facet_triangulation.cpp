// FacetGroup::triangulate(): coverage (triangle areas add up to the polygons' areas minus their
// holes), facing, watertightness of a closed facet solid, and robustness against degenerate,
// non-finite, malformed and self-intersecting input, with bounded running time.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <tuple>

#include "plantview/primitives.h"

namespace plantview {
namespace {

// The sanity bound of a timed test: `seconds` in a release build, ten times that under the
// sanitizers (AddressSanitizer takes this file's 20,000 holes from under 2 s to about 18).
double time_bound_s(double seconds) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  return 10 * seconds;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
  return 10 * seconds;
#else
  return seconds;
#endif
#else
  return seconds;
#endif
}

constexpr double kPi = std::numbers::pi;
constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

using Ring = std::vector<glm::dvec2>;

// A polygon in the plane point(a, b) = origin + a * u + b * v, outer ring first.
struct PlanePolygon {
  std::vector<Ring> rings;
  glm::dvec3 origin{0}, u{1, 0, 0}, v{0, 1, 0};
  glm::vec3 normal{0};  // vertex normals; zero: u x v
};

void add_polygon(FacetGroup& g, const PlanePolygon& p) {
  const glm::vec3 normal =
      p.normal != glm::vec3(0) ? p.normal : glm::vec3(glm::normalize(glm::cross(p.u, p.v)));
  for (const Ring& ring : p.rings) {
    for (glm::dvec2 q : ring)
      g.vertices.push_back({glm::vec3(p.origin + q.x * p.u + q.y * p.v), normal});
    g.contour_ends.push_back(uint32_t(g.vertices.size()));
  }
  g.polygon_ends.push_back(uint32_t(g.contour_ends.size()));
}

FacetGroup group_of(const std::vector<PlanePolygon>& polygons) {
  FacetGroup g;
  for (const PlanePolygon& p : polygons) add_polygon(g, p);
  return g;
}

double ring_area(const Ring& r) {
  double a = 0;
  for (size_t i = 0, j = r.size() - 1; i < r.size(); j = i++)
    a += r[j].x * r[i].y - r[i].x * r[j].y;
  return std::abs(a) / 2;
}

// The true area: the outer rings' minus the holes'.
double polygon_area(const std::vector<PlanePolygon>& polygons) {
  double a = 0;
  for (const PlanePolygon& p : polygons) {
    a += ring_area(p.rings[0]);
    for (size_t h = 1; h < p.rings.size(); ++h) a -= ring_area(p.rings[h]);
  }
  return a;
}

glm::dvec3 position(const FacetGroup& g, uint32_t i) {
  return glm::dvec3(g.vertices[i].position_m);
}

double triangle_area(const FacetGroup& g) {
  double a = 0;
  for (size_t t = 0; t + 2 < g.triangles.size(); t += 3) {
    const glm::dvec3 p0 = position(g, g.triangles[t]), p1 = position(g, g.triangles[t + 1]),
                     p2 = position(g, g.triangles[t + 2]);
    a += glm::length(glm::cross(p1 - p0, p2 - p0)) / 2;
  }
  return a;
}

void expect_indices_in_range(const FacetGroup& g) {
  EXPECT_EQ(g.triangles.size() % 3, 0u);
  for (uint32_t i : g.triangles) ASSERT_LT(i, g.vertices.size());
}

Ring rectangle(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

Ring reversed(Ring r) {
  std::reverse(r.begin(), r.end());
  return r;
}

// A star of `tips` points: radius r_out at the tips, r_in between them.
Ring star(int tips, double r_out, double r_in) {
  Ring r;
  for (int i = 0; i < 2 * tips; ++i) {
    const double a = kPi * i / tips, rad = i % 2 ? r_in : r_out;
    r.push_back({rad * std::cos(a), rad * std::sin(a)});
  }
  return r;
}

TEST(FacetTriangulation, TriangleAreasAddUpToThePolygonAreaMinusHoles) {
  PlanePolygon holed{{rectangle(0, 0, 4, 2), rectangle(0.5, 0.5, 1.5, 1.5),
                      reversed(rectangle(2.5, 0.25, 3.5, 1.0))}};
  PlanePolygon l_shape{{{{0, 0}, {3, 0}, {3, 1}, {1, 1}, {1, 2.5}, {0, 2.5}}}};
  l_shape.origin = {10, -4, 2};
  l_shape.u = glm::normalize(glm::dvec3(1, 0, 1));
  l_shape.v = {0, 1, 0};
  PlanePolygon spiky{{star(7, 2.0, 0.5), rectangle(-0.2, -0.2, 0.2, 0.2)}};
  spiky.origin = {100, 200, 30};
  spiky.u = glm::normalize(glm::dvec3(1, 2, 3));
  spiky.v = glm::normalize(glm::cross(glm::dvec3(0, 0, 1), spiky.u));
  // A comb: deep concave notches.
  Ring comb;
  for (int i = 0; i < 10; ++i) {
    comb.push_back({2.0 * i, 0});
    comb.push_back({2.0 * i + 1, 0});
    comb.push_back({2.0 * i + 1, 5});
    comb.push_back({2.0 * i + 2, 5});
  }
  comb.push_back({20, -1});
  comb.push_back({0, -1});
  std::reverse(comb.begin(), comb.end());  // whichever winding, the area must match
  PlanePolygon combed{{comb}};

  const std::vector<PlanePolygon> all = {holed, l_shape, spiky, combed};
  FacetGroup g = group_of(all);
  EXPECT_EQ(g.triangulate(), 0u);
  expect_indices_in_range(g);
  EXPECT_NEAR(triangle_area(g), polygon_area(all), 1e-5 * polygon_area(all));
  for (size_t p = 0; p < all.size(); ++p) {
    FacetGroup single = group_of({all[p]});
    single.triangulate();
    EXPECT_NEAR(triangle_area(single), polygon_area({all[p]}), 1e-5 * polygon_area({all[p]}))
        << "polygon " << p;
  }
}

TEST(FacetTriangulation, EveryVertexOfASimplePolygonIsUsedAndCountsAreVPlus2HMinus2) {
  PlanePolygon collinear{
      {{{0, 0}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {3, 2}, {1.5, 2}, {0, 2}, {0, 1}}}};
  PlanePolygon holed{{rectangle(0, 0, 2, 2), rectangle(0.5, 0.5, 1.5, 1.5)}};
  for (const PlanePolygon& p : {collinear, holed}) {
    FacetGroup g = group_of({p});
    EXPECT_EQ(g.triangulate(), 0u);
    size_t holes = p.rings.size() - 1;
    EXPECT_EQ(g.triangles.size() / 3, g.vertices.size() + 2 * holes - 2);
    std::vector<bool> used(g.vertices.size());
    for (uint32_t i : g.triangles) used[i] = true;
    EXPECT_EQ(std::count(used.begin(), used.end(), false), 0);
    EXPECT_NEAR(triangle_area(g), polygon_area({p}), 1e-9);
  }
}

TEST(FacetTriangulation, TrianglesAreCounterClockwiseAboutTheFacingTheNormalsGive) {
  const Ring arrow = {{0, 0.5}, {2, 0.5}, {2, 1}, {3, 0}, {2, -1}, {2, -0.5}, {0, -0.5}};
  // Both windings, both normal directions: the triangles face the normals.
  for (bool flip_winding : {false, true}) {
    for (float nz : {1.0f, -1.0f}) {
      PlanePolygon p{{flip_winding ? reversed(arrow) : arrow}};
      p.normal = {0, 0, nz};
      FacetGroup g = group_of({p});
      EXPECT_EQ(g.triangulate(), 0u);
      ASSERT_EQ(g.triangles.size(), 15u);
      for (size_t t = 0; t < g.triangles.size(); t += 3) {
        const glm::dvec3 face =
            glm::cross(position(g, g.triangles[t + 1]) - position(g, g.triangles[t]),
                       position(g, g.triangles[t + 2]) - position(g, g.triangles[t]));
        EXPECT_GT(face.z * nz, 0.0) << "winding " << flip_winding << " normal " << nz;
      }
    }
  }
  // Normals that say nothing (perpendicular or zero) leave the winding's own facing.
  PlanePolygon sideways{{reversed(arrow)}};  // counter-clockwise about +z
  sideways.normal = {1, 0, 0};
  FacetGroup g = group_of({sideways});
  g.triangulate();
  ASSERT_FALSE(g.triangles.empty());
  const glm::dvec3 face = glm::cross(position(g, g.triangles[1]) - position(g, g.triangles[0]),
                                     position(g, g.triangles[2]) - position(g, g.triangles[0]));
  EXPECT_GT(face.z, 0.0);
}

TEST(FacetTriangulation, ClosedCubeOfSixSquaresIsWatertightAndFacesOut) {
  FacetGroup g;
  const glm::dvec3 centre(3.0, -2.0, 7.5);
  const double h = 0.25;
  for (int k = 0; k < 3; ++k) {
    glm::dvec3 ek(0), ei(0), ej(0);
    ek[k] = 1;
    ei[(k + 1) % 3] = 1;
    ej[(k + 2) % 3] = 1;
    for (double s : {-1.0, 1.0}) {
      PlanePolygon f{
          {rectangle(-h, -h, h, h)}, centre + s * h * ek, s > 0 ? ei : ej, s > 0 ? ej : ei};
      add_polygon(g, f);
    }
  }
  EXPECT_EQ(g.triangulate(), 0u);
  ASSERT_EQ(g.triangles.size(), 36u);
  std::map<std::tuple<long, long, long>, uint32_t> ids;
  auto id_of = [&](uint32_t v) {
    const glm::dvec3 q = glm::round(position(g, v) * 1e5);
    return ids.try_emplace({long(q.x), long(q.y), long(q.z)}, uint32_t(ids.size())).first->second;
  };
  std::map<std::pair<uint32_t, uint32_t>, int> directed;
  for (size_t t = 0; t < g.triangles.size(); t += 3) {
    const uint32_t w[3] = {id_of(g.triangles[t]), id_of(g.triangles[t + 1]),
                           id_of(g.triangles[t + 2])};
    for (int e = 0; e < 3; ++e) directed[{w[e], w[(e + 1) % 3]}]++;
    const glm::dvec3 a = position(g, g.triangles[t]), b = position(g, g.triangles[t + 1]),
                     c = position(g, g.triangles[t + 2]);
    EXPECT_GT(glm::dot(glm::cross(b - a, c - a), (a + b + c) / 3.0 - centre), 0.0) << "inward";
  }
  EXPECT_EQ(ids.size(), 8u);
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(directed.count({edge.second, edge.first}), 1u) << "an edge without its twin";
  }
}

TEST(FacetTriangulation, EmptyGroupsPolygonsAndContoursGiveNoTriangles) {
  FacetGroup empty;
  EXPECT_EQ(empty.triangulate(), 0u);
  EXPECT_TRUE(empty.triangles.empty());

  FacetGroup no_contours;  // a polygon of no contours
  no_contours.polygon_ends = {0};
  EXPECT_EQ(no_contours.triangulate(), 1u);
  EXPECT_TRUE(no_contours.triangles.empty());

  FacetGroup empty_contour;  // a polygon whose only contour has no vertex
  empty_contour.contour_ends = {0};
  empty_contour.polygon_ends = {1};
  EXPECT_EQ(empty_contour.triangulate(), 1u);
  EXPECT_TRUE(empty_contour.triangles.empty());

  // An empty hole is left out; the outer contour is still triangulated.
  FacetGroup empty_hole = group_of({PlanePolygon{{rectangle(0, 0, 1, 1)}}});
  empty_hole.contour_ends.push_back(empty_hole.contour_ends.back());
  empty_hole.polygon_ends = {2};
  EXPECT_EQ(empty_hole.triangulate(), 1u);
  EXPECT_EQ(empty_hole.triangles.size(), 6u);
}

TEST(FacetTriangulation, ContoursOfOneOrTwoVerticesAreSkipped) {
  FacetGroup g = group_of({PlanePolygon{{{{0, 0}, {1, 1}}}}, PlanePolygon{{{{5, 5}}}},
                           PlanePolygon{{{{0, 0}, {1, 0}, {0, 1}}}}});
  EXPECT_EQ(g.triangulate(), 2u);
  ASSERT_EQ(g.triangles.size(), 3u);
  EXPECT_EQ(g.triangles[0] + g.triangles[1] + g.triangles[2], 3u + 4u + 5u);

  // A two-vertex hole: the outer contour is kept.
  FacetGroup hole = group_of({PlanePolygon{{rectangle(0, 0, 1, 1), {{0.2, 0.2}, {0.4, 0.4}}}}});
  EXPECT_EQ(hole.triangulate(), 1u);
  EXPECT_NEAR(triangle_area(hole), 1.0, 1e-9);
}

TEST(FacetTriangulation, CollinearAndCoincidentContoursAreSkipped) {
  PlanePolygon line{{{{0, 0}, {1, 1}, {2, 2}, {3, 3}, {1.5, 1.5}}}};
  PlanePolygon tilted_line{{{{0, 0}, {1, 0}, {2, 0}, {0.5, 0}}}};
  tilted_line.u = glm::normalize(glm::dvec3(1, 1, 1));
  tilted_line.v = glm::normalize(glm::dvec3(1, -1, 0));
  PlanePolygon point{{{{4, 4}, {4, 4}, {4, 4}, {4, 4}}}};
  FacetGroup g = group_of({line, tilted_line, point});
  EXPECT_EQ(g.triangulate(), 3u);
  EXPECT_TRUE(g.triangles.empty());
  // A zero-area hole is left out, the outer contour kept.
  FacetGroup holed =
      group_of({PlanePolygon{{rectangle(0, 0, 2, 2), {{0.5, 0.5}, {1, 1}, {1.5, 1.5}}}}});
  EXPECT_EQ(holed.triangulate(), 1u);
  EXPECT_NEAR(triangle_area(holed), 4.0, 1e-9);
}

TEST(FacetTriangulation, DuplicatePointsDoNotChangeTheArea) {
  PlanePolygon p{
      {{{0, 0}, {0, 0}, {2, 0}, {2, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}}}};
  FacetGroup g = group_of({p});
  g.triangulate();
  expect_indices_in_range(g);
  EXPECT_NEAR(triangle_area(g), 3.0, 1e-9);
}

TEST(FacetTriangulation, NonFiniteCoordinatesAreSkippedWithoutCrashing) {
  const float inf = std::numeric_limits<float>::infinity();
  FacetGroup g =
      group_of({PlanePolygon{{rectangle(0, 0, 1, 1)}}, PlanePolygon{{rectangle(2, 0, 3, 1)}},
                PlanePolygon{{rectangle(4, 0, 5, 1), rectangle(4.2, 0.2, 4.8, 0.8)}}});
  g.vertices[5].position_m.y = kNan;       // the second polygon's outer contour
  g.vertices[13].position_m.x = inf;       // the third polygon's hole
  g.vertices[0].normal = glm::vec3(kNan);  // a bad normal does not matter
  EXPECT_EQ(g.triangulate(), 2u);
  expect_indices_in_range(g);
  for (uint32_t i : g.triangles) EXPECT_TRUE(i < 4 || i >= 8) << "the NaN polygon was used";
  EXPECT_NEAR(triangle_area(g), 1.0 + 1.0, 1e-6);  // the hole's polygon is filled whole

  // The plan and the vertices written stay finite.
  Primitive prim{{}, g};
  const MeshPlan plan = plan_mesh(prim);
  ASSERT_EQ(plan.vertex_count, g.vertices.size());
  std::vector<PackedVertex> out(plan.vertex_count);
  write_vertices(prim, plan, glm::dvec3(0), out);
  for (const PackedVertex& v : out) {
    EXPECT_TRUE(std::isfinite(v.position_m.x) && std::isfinite(v.position_m.y) &&
                std::isfinite(v.position_m.z));
  }
  const Aabb box = local_bounds(prim.shape);
  EXPECT_FALSE(box.empty());
  EXPECT_TRUE(std::isfinite(box.min.x) && std::isfinite(box.max.y));

  FacetGroup all_nan;
  all_nan.vertices.assign(3, FacetVertex{glm::vec3(kNan), glm::vec3(kNan)});
  all_nan.contour_ends = {3};
  all_nan.polygon_ends = {1};
  EXPECT_EQ(all_nan.triangulate(), 1u);
  EXPECT_TRUE(all_nan.triangles.empty());
  EXPECT_TRUE(local_bounds(all_nan).empty());
  EXPECT_EQ(plan_mesh(Primitive{{}, all_nan}).vertex_count, 0u);
}

TEST(FacetTriangulation, MalformedEndsNeverReadOutOfRange) {
  FacetGroup g =
      group_of({PlanePolygon{{rectangle(0, 0, 1, 1)}}, PlanePolygon{{rectangle(2, 0, 3, 1)}}});
  g.contour_ends = {4, 1000, 2, 8};
  g.polygon_ends = {1, 3, 2, 100};
  g.triangulate();
  expect_indices_in_range(g);
  g.contour_ends = {8, 4};
  g.polygon_ends = {2};
  g.triangulate();
  expect_indices_in_range(g);
}

TEST(FacetTriangulation, HolesTouchingTheOuterContourOrEachOther) {
  // A hole whose corner lies on the outer contour's edge, and two holes sharing a corner.
  PlanePolygon touching{{rectangle(0, 0, 4, 4), {{0, 1}, {1, 1.5}, {1, 0.5}}}};
  PlanePolygon shared{{rectangle(0, 0, 4, 4), rectangle(1, 1, 2, 2), rectangle(2, 2, 3, 3)}};
  for (const PlanePolygon& p : {touching, shared}) {
    FacetGroup g = group_of({p});
    g.triangulate();
    expect_indices_in_range(g);
    EXPECT_NEAR(triangle_area(g), polygon_area({p}), 1e-9);
  }
}

TEST(FacetTriangulation, ThousandVertexStarFinishesQuickly) {
  PlanePolygon p{{star(500, 10.0, 9.0)}};
  p.origin = {1000, 2000, 50};
  FacetGroup g = group_of({p});
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(g.triangulate(), 0u);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, time_bound_s(1.0));
  EXPECT_EQ(g.triangles.size(), 3u * 998);
  EXPECT_NEAR(triangle_area(g), polygon_area({p}), 1e-4 * polygon_area({p}));
}

// A perforated plate: a cols x rows grid of square holes (half a cell wide) in one rectangle.
PlanePolygon perforated_plate(int cols, int rows) {
  PlanePolygon p{{rectangle(0, 0, cols, rows)}};
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      p.rings.push_back(rectangle(c + 0.25, r + 0.25, c + 0.75, r + 0.75));
    }
  }
  return p;
}

// 20,000 holes took a minute (every hole walked the whole ring to find its bridge, and filtered
// it whole); the work is now bounded by a multiple of the points (facet_group.cpp).
TEST(FacetTriangulation, TwentyThousandHolesTriangulateInTimeProportionalToThePoints) {
  const PlanePolygon plate = perforated_plate(200, 100);
  FacetGroup g = group_of({plate});
  const auto start = std::chrono::steady_clock::now();
  const uint32_t skipped = g.triangulate();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, time_bound_s(20.0));
  expect_indices_in_range(g);
  // Whole: the plate's area exactly (no triangle lost, none overlapping), and no more triangles
  // than a triangulation of its 80,004 points and 20,000 holes has (V + 2H - 2).
  EXPECT_EQ(skipped, 0u);
  EXPECT_NEAR(triangle_area(g), polygon_area({plate}), 1e-6 * polygon_area({plate}));
  EXPECT_LE(g.triangles.size() / 3, g.vertices.size() + 2 * 20000 - 2);
  EXPECT_GE(g.triangles.size() / 3, 20000u * 4);  // each hole's 4 corners meet triangles
}

// The work budget is linear in the points past 64 (it was 64 n^2: hours for this ring). A
// polygon that spends it keeps the triangles made so far and is counted as skipped.
TEST(FacetTriangulation, ATwentyThousandPointRandomRingEndsWithinTheLinearBudget) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-1.0, 1.0);
  // Random points: a self-intersecting ring that keeps every fallback busy.
  PlanePolygon knot{{Ring{}}};
  for (int i = 0; i < 20000; ++i) knot.rings[0].push_back({coord(rng), coord(rng)});
  FacetGroup g = group_of({knot});
  const auto start = std::chrono::steady_clock::now();
  const uint32_t skipped = g.triangulate();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, time_bound_s(20.0));
  EXPECT_LE(skipped, 1u);
  expect_indices_in_range(g);
}

TEST(FacetTriangulation, SelfIntersectingAndRandomInputTerminates) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> coord(-1.0, 1.0);
  std::uniform_int_distribution<int> ring_size(0, 40), hole_count(0, 3);
  const auto start = std::chrono::steady_clock::now();
  for (int trial = 0; trial < 300; ++trial) {
    PlanePolygon p;
    p.rings.resize(1 + hole_count(rng));
    for (Ring& r : p.rings) {
      const int n = ring_size(rng);
      for (int i = 0; i < n; ++i) {
        // Snap some points to a coarse grid: duplicates and collinear runs.
        glm::dvec2 q(coord(rng), coord(rng));
        if (i % 3 == 0) q = glm::round(q * 4.0) / 4.0;
        r.push_back(q);
      }
    }
    FacetGroup g = group_of({p});
    g.triangulate();
    expect_indices_in_range(g);
  }
  // A 2000-point random polygon: its self-intersections exercise every fallback.
  PlanePolygon big{{Ring{}}};
  for (int i = 0; i < 2000; ++i) big.rings[0].push_back({coord(rng), coord(rng)});
  FacetGroup g = group_of({big});
  g.triangulate();
  expect_indices_in_range(g);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, time_bound_s(20.0));
}

TEST(FacetTriangulation, TriangulateReplacesTheTrianglesAndThePlanPointsAtThem) {
  FacetGroup g = group_of({PlanePolygon{{rectangle(0, 0, 1, 1)}}});
  g.triangles = {9, 9, 9};
  g.triangulate();
  const std::vector<uint32_t> first = g.triangles;
  g.triangulate();
  EXPECT_EQ(g.triangles, first);
  EXPECT_EQ(g.triangles.size(), 6u);

  const Primitive prim{{}, g};
  const MeshPlan plan = plan_mesh(prim);
  const auto& held = std::get<FacetGroup>(prim.shape);
  EXPECT_EQ(plan.indices[0].data(), held.triangles.data());
  EXPECT_EQ(plan.index_count(0), 6u);
  EXPECT_EQ(plan.vertex_count, 4u);
  EXPECT_FALSE(plan.closed);
  EXPECT_EQ(plan.error_m[0], 0.0f);
}

}  // namespace
}  // namespace plantview
