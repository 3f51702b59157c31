// Plant model helpers: names, ids, bounds and statistics.
#include "plantview/model.h"

namespace plantview {

std::string_view class_name(ObjectClass object_class) {
  static constexpr std::string_view names[kObjectClassCount] = {
      "equipment", "pipeline", "pipe", "component", "structure", "other"};
  const auto i = static_cast<size_t>(object_class);
  return i < kObjectClassCount ? names[i] : std::string_view("unknown");
}

bool class_from_name(std::string_view name, ObjectClass& object_class) {
  for (int i = 0; i < kObjectClassCount; ++i) {
    if (class_name(ObjectClass(i)) == name) {
      object_class = ObjectClass(i);
      return true;
    }
  }
  return false;
}

uint64_t object_id(std::string_view source, std::string_view name) {
  uint64_t h = 14695981039346656037ull;
  auto mix = [&h](std::string_view s) {
    for (unsigned char c : s) {
      h ^= c;
      h *= 1099511628211ull;
    }
  };
  mix(source);
  mix(std::string_view("\0", 1));
  mix(name);
  return h == 0 ? 1 : h;
}

DAabb object_bounds(const Object& object) {
  DAabb b;
  for (const Primitive& p : object.primitives) {
    const Aabb local = model_bounds(p);
    if (local.empty()) continue;
    b.extend(object.origin_m + glm::dvec3(local.min));
    b.extend(object.origin_m + glm::dvec3(local.max));
  }
  for (const ConnectionPoint& c : object.connections) b.extend(object.origin_m + glm::dvec3(c.position_m));
  for (const CentrelineSegment& s : object.centreline) {
    b.extend(object.origin_m + glm::dvec3(s.start_m));
    b.extend(object.origin_m + glm::dvec3(s.end_m));
  }
  return b;
}

void ModelStatistics::add(const Object& object) {
  const auto c = static_cast<size_t>(object.object_class);
  ++objects;
  ++objects_by_class[c];
  for (const Primitive& p : object.primitives) {
    const auto k = static_cast<size_t>(p.kind());
    const uint64_t t = element_count(plan_mesh(p), 0);
    ++primitives;
    ++primitives_by_kind[k];
    ++primitives_by_class[c];
    if (p.kind() != PrimitiveKind::line) {
      triangles += t;
      triangles_by_class[c] += t;
      triangles_by_kind[k] += t;
    }
  }
  bounds.extend(object_bounds(object));
}

namespace {

// total += sign * part, count by count (unsigned arithmetic wraps, so -1 takes away).
void combine_counts(ModelStatistics& total, const ModelStatistics& part, uint64_t sign) {
  total.objects += sign * part.objects;
  total.primitives += sign * part.primitives;
  total.triangles += sign * part.triangles;
  for (size_t c = 0; c < kObjectClassCount; ++c) {
    total.objects_by_class[c] += sign * part.objects_by_class[c];
    total.primitives_by_class[c] += sign * part.primitives_by_class[c];
    total.triangles_by_class[c] += sign * part.triangles_by_class[c];
  }
  for (size_t k = 0; k < kPrimitiveKindCount; ++k) {
    total.primitives_by_kind[k] += sign * part.primitives_by_kind[k];
    total.triangles_by_kind[k] += sign * part.triangles_by_kind[k];
  }
}

}  // namespace

void ModelStatistics::add_counts(const ModelStatistics& part) { combine_counts(*this, part, 1); }
void ModelStatistics::subtract_counts(const ModelStatistics& part) {
  combine_counts(*this, part, ~uint64_t(0));
}

ModelStatistics model_statistics(const PlantModel& model) {
  ModelStatistics s;
  for (const Object& o : model.objects) s.add(o);
  return s;
}

}  // namespace plantview
