// Representative primitives of every kind at a given part diameter.
#include <numbers>

#include "plantview/primitives.h"

namespace plantview {

std::vector<Primitive> representative_primitives(float d) {
  const float r = 0.5f * d;
  constexpr float kQuarter = 0.5f * std::numbers::pi_v<float>;
  FacetGroup plate;  // a square plate with a square hole
  for (glm::vec2 p : {glm::vec2(-r, -r), {r, -r}, {r, r}, {-r, r}}) plate.vertices.push_back({{p, 0}, {0, 0, 1}});
  plate.contour_ends.push_back(4);
  for (glm::vec2 p : {glm::vec2(-r, -r), {-r, r}, {r, r}, {r, -r}}) plate.vertices.push_back({{0.5f * p, 0}, {0, 0, 1}});
  plate.contour_ends.push_back(8);
  plate.polygon_ends.push_back(2);
  plate.triangulate();

  std::vector<Primitive> out(kPrimitiveKindCount);
  out[size_t(PrimitiveKind::box)].shape = Box{d, d, d};
  out[size_t(PrimitiveKind::pyramid)].shape = Pyramid{d, d, r, r, 0, 0, d};
  out[size_t(PrimitiveKind::prism)].shape = Prism{6, r, d};
  out[size_t(PrimitiveKind::cylinder)].shape = Cylinder{r, 4 * d};
  out[size_t(PrimitiveKind::snout)].shape = Snout{r, 0.75f * r, d, 0, 0, 0, 0, 0, 0};
  out[size_t(PrimitiveKind::square_to_round)].shape = SquareToRound{d, d, r, d, 0, 0};
  out[size_t(PrimitiveKind::circular_torus)].shape = CircularTorus{1.5f * d, r, kQuarter};
  out[size_t(PrimitiveKind::rectangular_torus)].shape = RectangularTorus{d, 2 * d, d, kQuarter};
  out[size_t(PrimitiveKind::sphere)].shape = Sphere{r};
  out[size_t(PrimitiveKind::elliptical_dish)].shape = EllipticalDish{r, 0.5f * r};
  out[size_t(PrimitiveKind::spherical_dish)].shape = SphericalDish{r, 0.3f * r};
  out[size_t(PrimitiveKind::saddle)].shape = Saddle{0.5f * d, d, 0.75f * d, r};
  out[size_t(PrimitiveKind::line)].shape = Line{0, d};
  out[size_t(PrimitiveKind::facet_group)].shape = std::move(plate);
  return out;
}

}  // namespace plantview
