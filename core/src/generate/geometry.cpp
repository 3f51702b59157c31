// Geometry helpers: pipe sizes, frames, and ObjectBuilder (primitives placed in unit-local
// coordinates, stored relative to the object's origin); emission of finished objects.
#include <charconv>
#include <cmath>

#include "generator.h"

namespace plantview::gen {

// label, DN, OD, flange OD, flange length, gate valve face to face, long-radius bend radius.
const std::array<PipeSize, kPipeSizeCount> kPipeSizes = {{
    {"1/2\"", 15, 0.0213, 0.089, 0.048, 0.108, 0.019},
    {"3/4\"", 20, 0.0267, 0.099, 0.052, 0.117, 0.029},
    {"1\"", 25, 0.0334, 0.108, 0.056, 0.127, 0.038},
    {"1-1/2\"", 40, 0.0483, 0.127, 0.062, 0.165, 0.057},
    {"2\"", 50, 0.0603, 0.152, 0.064, 0.178, 0.076},
    {"3\"", 80, 0.0889, 0.191, 0.070, 0.203, 0.114},
    {"4\"", 100, 0.1143, 0.229, 0.076, 0.229, 0.152},
    {"6\"", 150, 0.1683, 0.279, 0.089, 0.267, 0.229},
    {"8\"", 200, 0.2191, 0.343, 0.102, 0.292, 0.305},
    {"10\"", 250, 0.2730, 0.406, 0.102, 0.330, 0.381},
    {"12\"", 300, 0.3239, 0.483, 0.114, 0.356, 0.457},
    {"14\"", 350, 0.3556, 0.533, 0.127, 0.381, 0.533},
    {"16\"", 400, 0.4064, 0.597, 0.127, 0.406, 0.610},
    {"18\"", 450, 0.4572, 0.635, 0.140, 0.432, 0.686},
    {"20\"", 500, 0.5080, 0.699, 0.144, 0.457, 0.762},
    {"24\"", 600, 0.6096, 0.813, 0.152, 0.508, 0.914},
    {"30\"", 750, 0.7620, 0.984, 0.175, 0.610, 1.143},
    {"36\"", 900, 0.9144, 1.168, 0.190, 0.711, 1.372},
    {"42\"", 1050, 1.0668, 1.346, 0.210, 0.787, 1.600},
    {"48\"", 1200, 1.2192, 1.511, 0.230, 0.864, 1.829},
}};

int bore_at_least(double od_m) {
  for (int i = 0; i < kPipeSizeCount; ++i) {
    if (kPipeSizes[size_t(i)].od_m >= od_m) return i;
  }
  return kPipeSizeCount - 1;
}

glm::mat3 frame_xz(const dvec3& x, const dvec3& z) {
  const dvec3 y = glm::cross(z, x);
  return glm::mat3(glm::vec3(x), glm::vec3(y), glm::vec3(z));
}

glm::mat3 frame_z(const dvec3& z) {
  const dvec3 helper = std::abs(z.z) < 0.9 ? dvec3(0, 0, 1) : dvec3(0, 1, 0);
  const dvec3 x = glm::normalize(glm::cross(helper, z));
  return frame_xz(x, z);
}

dvec3 perpendicular_up(const dvec3& d) {
  if (std::abs(d.z) < 0.9) {
    // Up, made perpendicular to d.
    const dvec3 up = dvec3(0, 0, 1) - d * d.z;
    return glm::normalize(up);
  }
  return glm::normalize(glm::cross(dvec3(0, 1, 0), d));
}

ObjectBuilder::ObjectBuilder(const dvec3& unit_origin_m, const dvec3& local_origin,
                             ObjectClass object_class)
    : local_origin_(local_origin) {
  object_.object_class = object_class;
  object_.attributes.reserve(10);
  object_.origin_m = unit_origin_m + local_origin;
}

void ObjectBuilder::add(const Shape& shape, const glm::mat3& linear, const dvec3& centre) {
  Primitive p;
  p.placement.linear = linear;
  p.placement.translation_m = rel(centre);
  p.shape = shape;
  object_.primitives.push_back(std::move(p));
}

void ObjectBuilder::cylinder(const dvec3& a, const dvec3& b, double radius) {
  const dvec3 d = b - a;
  const double h = glm::length(d);
  if (!(h > 0.0) || !(radius > 0.0)) return;
  add(Cylinder{float(radius), float(h)}, frame_z(d / h), 0.5 * (a + b));
}

void ObjectBuilder::snout(const dvec3& a, const dvec3& b, double ra, double rb, const dvec3& axis) {
  const dvec3 d = b - a;
  const double h = glm::dot(d, axis);
  const dvec3 lateral = d - axis * h;
  const double offset = glm::length(lateral);
  glm::mat3 frame = offset > 1e-9 ? frame_xz(lateral / offset, axis) : frame_z(axis);
  Snout s;
  s.radius_bottom_m = float(ra);
  s.radius_top_m = float(rb);
  s.height_m = float(h);
  s.offset_x_m = offset > 1e-9 ? float(offset) : 0.0f;
  add(s, frame, 0.5 * (a + b));
}

void ObjectBuilder::sheared_cylinder(const dvec3& a, const dvec3& b, double radius,
                                     const dvec3& tilt_toward, float bottom_shear_rad,
                                     float top_shear_rad) {
  const dvec3 d = b - a;
  const double h = glm::length(d);
  Snout s;
  s.radius_bottom_m = s.radius_top_m = float(radius);
  s.height_m = float(h);
  s.bottom_shear_x_rad = bottom_shear_rad;
  s.top_shear_x_rad = top_shear_rad;
  add(s, frame_xz(tilt_toward, d / h), 0.5 * (a + b));
}

void ObjectBuilder::box(const dvec3& centre, const dvec3& x_axis, const dvec3& z_axis,
                        const dvec3& size) {
  add(Box{float(size.x), float(size.y), float(size.z)}, frame_xz(x_axis, z_axis), centre);
}

void ObjectBuilder::box_axes(const dvec3& lo, const dvec3& hi) {
  const dvec3 size = hi - lo;
  add(Box{float(size.x), float(size.y), float(size.z)}, glm::mat3(1.0f), 0.5 * (lo + hi));
}

void ObjectBuilder::wedge(const dvec3& p, const dvec3& x_axis, const dvec3& z_axis, double sx,
                          double sy, double h) {
  Pyramid w;
  w.bottom_x_m = float(sx);
  w.bottom_y_m = float(sy);
  w.top_x_m = 0.0f;
  w.top_y_m = float(sy);
  w.offset_x_m = float(-0.5 * sx);
  w.height_m = float(h);
  add(w, frame_xz(x_axis, z_axis), p + x_axis * (0.25 * sx) + z_axis * (0.5 * h));
}

void ObjectBuilder::prism(const dvec3& base, const dvec3& axis, uint32_t sides, double radius,
                          double height) {
  add(Prism{sides, float(radius), float(height)}, frame_z(axis), base + axis * (0.5 * height));
}

void ObjectBuilder::sphere(const dvec3& centre, double radius) {
  add(Sphere{float(radius)}, glm::mat3(1.0f), centre);
}

void ObjectBuilder::dish(const dvec3& base, const dvec3& axis, double base_radius, double height) {
  add(EllipticalDish{float(base_radius), float(height)}, frame_z(axis), base);
}

void ObjectBuilder::elbow(const dvec3& corner, const dvec3& d_in, const dvec3& d_out, double bend_r,
                          double tube_r) {
  const dvec3 centre = corner - d_in * bend_r + d_out * bend_r;
  add(CircularTorus{float(bend_r), float(tube_r), kQuarterTurn},
      frame_xz(-d_out, glm::cross(d_in, d_out)), centre);
}

void ObjectBuilder::rect_torus(const dvec3& centre, const dvec3& axis, const dvec3& start_dir,
                               double inner_r, double outer_r, double height, float angle_rad) {
  add(RectangularTorus{float(inner_r), float(outer_r), float(height), angle_rad},
      frame_xz(start_dir, axis), centre);
}

void ObjectBuilder::saddle(const dvec3& base, const dvec3& vessel_axis, double length, double width,
                           double height, double cradle_radius) {
  add(Saddle{float(length), float(width), float(height), float(cradle_radius)},
      frame_xz(vessel_axis, dvec3(0, 0, 1)), base);
}

void ObjectBuilder::connection(const dvec3& position, const dvec3& direction, double diameter) {
  object_.connections.push_back({rel(position), glm::vec3(direction), float(diameter)});
}

void ObjectBuilder::centreline(const dvec3& a, const dvec3& b, double diameter) {
  object_.centreline.push_back({rel(a), rel(b), float(diameter)});
}

std::string fixed(double value, int decimals) {
  char buffer[64];
  const auto result =
      std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::fixed, decimals);
  return std::string(buffer, result.ptr);
}

void Emitter::emit(Object&& object) {
  ++summary_.objects;
  ++summary_.objects_by_class[size_t(object.object_class)];
  summary_.primitives += object.primitives.size();
  summary_.bounds.extend(object_bounds(object));
  sink_(std::move(object));
}

void Unit::emit(ObjectBuilder& builder, std::string name) {
  Object& o = builder.object();
  const Mix mix = mix_of(o);
  emitted += mix;
  if (piping) {
    ledger.add(mix);
  } else if (o.object_class == ObjectClass::equipment) {
    detail_ledger.add(mix);
  }
  primitives_by_class[size_t(o.object_class)] += int64_t(o.primitives.size());
  ++objects_by_class[size_t(o.object_class)];
  o.id = id(name);
  o.name = std::move(name);
  o.source = source;
  out.emit(std::move(o));
}

}  // namespace plantview::gen
