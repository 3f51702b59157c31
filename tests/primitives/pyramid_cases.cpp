// Pyramid cases: a rectangular frustum with an offset (an eccentric duct transition), wedges (a
// zero top side), pyramids (a zero top, apex centred or not), an inverted pyramid, a tetrahedron
// (a zero bottom side and a zero top side across it), and degenerate ones.
// Counts (primitives.h): 2 triangles per face with area, 1 for a side with a collapsed edge:
// frustum 12, wedge 8, pyramid 6, tetrahedron 4.
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "support/primitive_cases.h"

namespace plantview::testing {
namespace {

// Points on the bilinear patch p00 p10 p11 p01 (a planar trapezoid here, or a triangle where two
// corners coincide).
void sample_patch(glm::vec3 p00, glm::vec3 p10, glm::vec3 p11, glm::vec3 p01,
                  std::vector<glm::vec3>& out) {
  const int steps = 8;
  for (int i = 0; i <= steps; ++i) {
    const float s = float(i) / steps;
    for (int j = 0; j <= steps; ++j) {
      const float t = float(j) / steps;
      out.push_back((1 - s) * (1 - t) * p00 + s * (1 - t) * p10 + s * t * p11 + (1 - s) * t * p01);
    }
  }
}

// The true surface: bottom and top rectangles and the four ruled sides between them.
void sample_pyramid(const Pyramid& p, std::vector<glm::vec3>& out) {
  const float sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1};
  glm::vec3 b[4], t[4];
  for (int c = 0; c < 4; ++c) {
    b[c] = {-p.offset_x_m / 2 + sx[c] * p.bottom_x_m / 2,
            -p.offset_y_m / 2 + sy[c] * p.bottom_y_m / 2, -p.height_m / 2};
    t[c] = {p.offset_x_m / 2 + sx[c] * p.top_x_m / 2, p.offset_y_m / 2 + sy[c] * p.top_y_m / 2,
            p.height_m / 2};
  }
  sample_patch(b[0], b[1], b[2], b[3], out);
  sample_patch(t[0], t[1], t[2], t[3], out);
  for (int s = 0; s < 4; ++s) sample_patch(b[s], b[(s + 1) % 4], t[(s + 1) % 4], t[s], out);
}

PrimitiveCase pyramid_case(std::string name, Pyramid shape, glm::vec3 translation_m,
                           uint32_t triangles, glm::mat3 linear = glm::mat3(1.0f)) {
  PrimitiveCase c;
  c.name = std::move(name);
  c.primitive.shape = shape;
  c.primitive.placement = {linear, translation_m};
  c.sample_surface = [shape](std::vector<glm::vec3>& out) { sample_pyramid(shape, out); };
  c.expected_elements = {triangles};
  return c;
}

std::vector<PrimitiveCase> pyramid_cases() {
  constexpr float kPi = std::numbers::pi_v<float>;
  std::vector<PrimitiveCase> cases;
  // Pyramid{bottom_x, bottom_y, top_x, top_y, offset_x, offset_y, height}.
  // A duct transition from 1.0 x 0.8 down to 0.5 x 0.4, its top shifted 0.2 m in x and -0.1 in y.
  cases.push_back(pyramid_case("pyramid_frustum_offset",
                               {1.0f, 0.8f, 0.5f, 0.4f, 0.2f, -0.1f, 1.2f}, {45.0f, -12.0f, 8.5f},
                               12));
  cases.push_back(pyramid_case("pyramid_frustum_rotated",
                               {0.6f, 0.6f, 0.3f, 0.45f, 0.0f, 0.0f, 0.25f}, {3.0f, 4.0f, 5.0f}, 12,
                               rotation_about({1, 0, 0}, kPi / 2)));
  // Equal ends: a box-shaped frustum, offset into a parallelepiped.
  cases.push_back(pyramid_case("pyramid_parallelepiped", {0.4f, 0.3f, 0.4f, 0.3f, 0.5f, 0.0f, 1.0f},
                               {0, 0, 0}, 12));
  // Wedges: a zero top side along x (a roof ridge along y), then along y.
  cases.push_back(pyramid_case("pyramid_wedge_top_x", {0.6f, 0.4f, 0.0f, 0.4f, 0.0f, 0.0f, 0.5f},
                               {10.0f, 2.0f, 1.0f}, 8));
  cases.push_back(pyramid_case("pyramid_wedge_top_y_offset",
                               {2.0f, 1.0f, 2.0f, 0.0f, 0.0f, 0.5f, 0.8f}, {-7.0f, 30.0f, 0.4f},
                               8));
  // A bottom side of zero: a wedge standing on its edge.
  cases.push_back(pyramid_case("pyramid_wedge_bottom_x", {0.0f, 0.5f, 0.7f, 0.5f, 0.0f, 0.0f, 0.3f},
                               {1.0f, 1.0f, 1.0f}, 8));
  // Pyramids: apex centred, apex off-centre, and upside down (a zero bottom).
  cases.push_back(pyramid_case("pyramid_apex_centred", {1.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.8f},
                               {8.0f, 6.0f, 2.5f}, 6));
  cases.push_back(pyramid_case("pyramid_apex_offset", {0.8f, 0.5f, 0.0f, 0.0f, 0.6f, -0.3f, 0.4f},
                               {2.0f, -3.0f, 0.2f}, 6));
  cases.push_back(pyramid_case("pyramid_inverted", {0.0f, 0.0f, 1.2f, 0.9f, 0.0f, 0.0f, 0.6f},
                               {0.0f, 0.0f, 3.0f}, 6));
  // Bottom collapsed along x, top along y: a tetrahedron, every face a triangle.
  cases.push_back(pyramid_case("pyramid_tetrahedron", {0.0f, 1.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f},
                               {5.0f, 5.0f, 5.0f}, 4));

  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (auto [name, shape] :
       {std::pair{"pyramid_zero_height", Pyramid{1, 1, 0.5f, 0.5f, 0, 0, 0}},
        std::pair{"pyramid_both_ends_zero", Pyramid{0, 0, 0, 0, 0.2f, 0.1f, 1}},
        std::pair{"pyramid_flat_in_x", Pyramid{0, 1, 0, 0.5f, 0.3f, 0, 1}},
        std::pair{"pyramid_nan_height", Pyramid{1, 1, 0.5f, 0.5f, 0, 0, nan}},
        std::pair{"pyramid_nan_offset", Pyramid{1, 1, 0.5f, 0.5f, nan, 0.2f, 1}},
        std::pair{"pyramid_negative_sides", Pyramid{-1, 1, 0.5f, -0.5f, 0, 0, 1}}}) {
    PrimitiveCase c;
    c.name = name;
    c.primitive.shape = shape;
    c.primitive.placement.translation_m = {4.0f, -2.0f, 1.0f};
    c.degenerate = true;
    cases.push_back(c);
  }
  return cases;
}

}  // namespace
PLANTVIEW_REGISTER_CASES(pyramid_cases)
}  // namespace plantview::testing
