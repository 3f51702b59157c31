// Facet group cases: flat polygons triangulated by FacetGroup::triangulate(). The sampler walks
// the TRUE polygons (inside the outer contour, outside the holes; written here independently of
// the triangulator), so the error test, with its reported 0, checks that the triangles cover every
// polygon. Counts: a polygon of V vertices and H holes gives V + 2H - 2 triangles.
// The cube is watertight although a facet group reports closed = false (so the generic
// watertightness test skips it; tests/test_facet_triangulation.cpp checks it directly).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

// A plane frame: point(a, b) = origin + a * u + b * v; the polygon faces u x v.
struct Plane {
  glm::vec3 origin{0}, u{1, 0, 0}, v{0, 1, 0};
  glm::vec3 at(glm::vec2 p) const { return origin + p.x * u + p.y * v; }
};
using Ring = std::vector<glm::vec2>;
struct FlatPolygon {
  Plane plane;
  std::vector<Ring> rings;  // outer contour first, then holes (either winding)
  // The vertex normals; zero means the plane's u x v.
  glm::vec3 normal{0};
};

FacetGroup make_group(const std::vector<FlatPolygon>& polygons) {
  FacetGroup g;
  for (const FlatPolygon& poly : polygons) {
    const glm::vec3 normal = poly.normal != glm::vec3(0)
                                 ? poly.normal
                                 : glm::normalize(glm::cross(poly.plane.u, poly.plane.v));
    for (const Ring& ring : poly.rings) {
      for (glm::vec2 p : ring) g.vertices.push_back({poly.plane.at(p), normal});
      g.contour_ends.push_back(uint32_t(g.vertices.size()));
    }
    g.polygon_ends.push_back(uint32_t(g.contour_ends.size()));
  }
  g.triangulate();
  return g;
}

// Crossing-number test; points on the boundary may go either way (they lie on the mesh anyway).
bool inside(const Ring& ring, glm::vec2 p) {
  bool in = false;
  for (size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
    const glm::vec2 a = ring[i], b = ring[j];
    if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x) in = !in;
  }
  return in;
}

// The true surface: a grid over each polygon's outer contour, kept where inside the outer contour
// and outside every hole, and points along every contour.
void sample_polygons(const std::vector<FlatPolygon>& polygons, std::vector<glm::vec3>& out) {
  for (const FlatPolygon& poly : polygons) {
    glm::vec2 lo(INFINITY), hi(-INFINITY);
    for (glm::vec2 p : poly.rings[0]) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    const int steps = 48;
    for (int i = 0; i <= steps; ++i) {
      for (int j = 0; j <= steps; ++j) {
        const glm::vec2 p = lo + (hi - lo) * glm::vec2(float(i) / steps, float(j) / steps);
        bool keep = inside(poly.rings[0], p);
        for (size_t h = 1; keep && h < poly.rings.size(); ++h) keep = !inside(poly.rings[h], p);
        if (keep) out.push_back(poly.plane.at(p));
      }
    }
    for (const Ring& ring : poly.rings) {
      for (size_t i = 0; i < ring.size(); ++i) {
        const glm::vec2 a = ring[i], b = ring[(i + 1) % ring.size()];
        for (int k = 0; k < 8; ++k) out.push_back(poly.plane.at(a + (b - a) * (float(k) / 8)));
      }
    }
  }
}

PrimitiveCase facet_case(std::string name, std::vector<FlatPolygon> polygons, Placement placement,
                         uint32_t triangles) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = make_group(polygons);
  c.primitive.placement = placement;
  c.sample_surface = [polygons](std::vector<glm::vec3>& out) { sample_polygons(polygons, out); };
  c.expected_elements = {triangles};
  return c;
}

Ring rectangle(glm::vec2 lo, glm::vec2 hi) { return {lo, {hi.x, lo.y}, hi, {lo.x, hi.y}}; }

// A cube of side 2h centred at `centre`: six square polygons facing out.
std::vector<FlatPolygon> cube(glm::vec3 centre, float h) {
  std::vector<FlatPolygon> faces;
  for (int k = 0; k < 3; ++k) {
    glm::vec3 ek(0), ei(0), ej(0);
    ek[k] = 1;
    ei[(k + 1) % 3] = 1;
    ej[(k + 2) % 3] = 1;
    for (float s : {-1.0f, 1.0f}) {
      FlatPolygon f;
      f.plane = {centre + s * h * ek, s > 0 ? ei : ej, s > 0 ? ej : ei};
      f.rings = {rectangle({-h, -h}, {h, h})};
      faces.push_back(f);
    }
  }
  return faces;
}

std::vector<PrimitiveCase> facet_group_cases() {
  constexpr float kPi = std::numbers::pi_v<float>;
  std::vector<PrimitiveCase> cases;
  const Placement identity{glm::mat3(1.0f), {0, 0, 0}};

  // A 0.5 m equipment housing as six square facets: 6 x 2 triangles.
  cases.push_back(facet_case("facet_group_closed_cube", cube({0.1f, 0.2f, 0.3f}, 0.25f),
                             {glm::mat3(1.0f), {6.0f, -2.5f, 4.0f}}, 12));

  // A 2 x 2 m floor plate with a 0.8 x 0.8 m opening (clockwise hole): 8 + 2 - 2 = 8.
  {
    FlatPolygon plate;
    plate.plane.origin = {0, 0, 3.5f};
    Ring hole = rectangle({0.5f, 0.6f}, {1.3f, 1.4f});
    std::reverse(hole.begin(), hole.end());
    plate.rings = {rectangle({0, 0}, {2, 2}), hole};
    cases.push_back(facet_case("facet_group_plate_with_hole", {plate},
                               {glm::mat3(1.0f), {12.0f, 7.0f, 0.0f}}, 8));
  }
  // A 4 x 2 m plate with two openings, both given counter-clockwise: 12 + 4 - 2 = 14.
  {
    FlatPolygon plate;
    plate.rings = {rectangle({0, 0}, {4, 2}), rectangle({0.5f, 0.5f}, {1.5f, 1.5f}),
                   rectangle({2.5f, 0.25f}, {3.5f, 1.0f})};
    cases.push_back(facet_case("facet_group_plate_with_two_holes", {plate},
                               {rotation_about({0, 0, 1}, kPi / 5), {-3.0f, 2.0f, 1.0f}}, 14));
  }
  // An L-shaped (concave) gusset plate in a plane tilted 45 degrees: 6 - 2 = 4.
  {
    FlatPolygon gusset;
    gusset.plane = {{5.0f, -3.0f, 2.0f}, glm::normalize(glm::vec3(1, 0, 1)), {0, 1, 0}};
    gusset.rings = {{{0, 0}, {0.9f, 0}, {0.9f, 0.3f}, {0.3f, 0.3f}, {0.3f, 0.75f}, {0, 0.75f}}};
    cases.push_back(facet_case("facet_group_l_shape_tilted", {gusset}, identity, 4));
  }
  // A rectangle with extra points along two of its edges (as RVM exporters write where facets
  // meet): 7 - 2 = 5; every point is used, so the neighbours' edges meet without T-junctions.
  {
    FlatPolygon panel;
    panel.plane = {{1.0f, 1.0f, 1.0f}, {0, 1, 0}, {0, 0, 1}};
    panel.rings = {{{0, 0}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {3, 2}, {0, 2}}};
    cases.push_back(facet_case("facet_group_collinear_points", {panel},
                               {glm::mat3(1.0f), {0.0f, 0.0f, 10.0f}}, 5));
  }
  // A concave arrow wound clockwise in its plane while its vertex normals point to +z: the
  // triangles face the normals. 7 - 2 = 5.
  {
    FlatPolygon arrow;
    arrow.rings = {{{0, 0.5f}, {2, 0.5f}, {2, 1}, {3, 0}, {2, -1}, {2, -0.5f}, {0, -0.5f}}};
    arrow.normal = {0, 0, 1};
    cases.push_back(facet_case("facet_group_clockwise_arrow", {arrow},
                               {glm::mat3(1.0f), {-8.0f, 0.0f, 0.0f}}, 5));
  }
  // Several polygons in one group: a triangle and a pentagon side by side. 1 + 3 = 4.
  {
    FlatPolygon tri, penta;
    tri.rings = {{{0, 0}, {1, 0}, {0.5f, 0.8f}}};
    penta.plane.origin = {2, 0, 0};
    for (int i = 0; i < 5; ++i) {
      const float a = 2 * kPi * float(i) / 5;
      penta.rings.resize(1);
      penta.rings[0].push_back({0.5f * std::cos(a), 0.5f * std::sin(a)});
    }
    cases.push_back(facet_case("facet_group_two_polygons", {tri, penta},
                               {glm::mat3(1.0f), {0.0f, 10.0f, 0.0f}}, 4));
  }

  // Degenerate groups: only validity is checked (some vertices are left out of every triangle).
  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto degenerate = [&](std::string name, FacetGroup g) {
    PrimitiveCase c;
    c.name = std::move(name);
    c.primitive.shape = std::move(g);
    c.primitive.placement.translation_m = {2.0f, 3.0f, 4.0f};
    c.degenerate = true;
    cases.push_back(std::move(c));
  };
  degenerate("facet_group_empty", FacetGroup{});
  {
    FlatPolygon good, two;
    good.rings = {{{0, 0}, {1, 0}, {0, 1}}};
    two.rings = {{{2, 2}, {3, 3}}};
    degenerate("facet_group_two_vertex_contour", make_group({good, two}));
  }
  {
    FlatPolygon line;
    line.rings = {{{0, 0}, {1, 1}, {2, 2}, {3, 3}}};
    degenerate("facet_group_all_collinear", make_group({line}));
  }
  {
    FlatPolygon good, bad;
    good.rings = {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}};
    bad.rings = {{{2, 0}, {3, 0}, {nan, 1}, {2, 1}}};
    degenerate("facet_group_nan_vertex", make_group({good, bad}));
  }
  {
    FlatPolygon holed;
    holed.rings = {rectangle({0, 0}, {2, 2}), {{0.5f, 0.5f}, {1.0f, 1.0f}, {1.5f, 1.5f}}};
    degenerate("facet_group_zero_area_hole", make_group({holed}));
  }
  {
    FacetGroup g = make_group({FlatPolygon{Plane{}, {rectangle({0, 0}, {1, 1})}, glm::vec3(0)}});
    g.contour_ends = {3, 99, 2};  // past the end, then backwards
    g.polygon_ends = {1, 7, 2};
    g.triangulate();
    degenerate("facet_group_malformed_ends", std::move(g));
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(facet_group_cases)
}  // namespace plantview::testing
