// plantview/model.h: the plant model, as parameters only.
//
// A plant is a list of objects: the smallest units a reviewer selects (Zhou et al. section 2; Su
// et al. section 5.1). Each object has a stable 64-bit id, a name, a class, a colour, its
// engineering attributes and its primitives. Piping (Su et al. section 3.2) adds topology: a
// pipeline object lists its branches, each branch its pipes and components in flow order; pipes
// and components carry their connection points ("duality points") and centreline segments
// ("smart lines"), which the pipeline HLOD uses.
//
// Units and frames: metres, radians. Each object has an origin in model space (double precision:
// plant coordinates reach kilometres); its primitives' placements, connection points and
// centrelines are relative to that origin in single precision.
//
// Threads: plain values; no internal synchronisation.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/primitives.h"

namespace plantview {

enum class ObjectClass : uint8_t { equipment, pipeline, pipe, component, structure, other };
inline constexpr int kObjectClassCount = 6;

// Stable lower-case names ("equipment", "pipeline", ...), used in JSON, XML and statistics.
std::string_view class_name(ObjectClass object_class);
bool class_from_name(std::string_view name, ObjectClass& object_class);

// sRGB colour with opacity (255 = opaque; RVM transparency t% gives 255 * (100 - t) / 100).
struct Colour {
  uint8_t r = 160, g = 160, b = 160, a = 255;
  bool operator==(const Colour&) const = default;
};

// A connection point of a piping object: where it joins its neighbour in the flow.
struct ConnectionPoint {
  glm::vec3 position_m{0};   // relative to the object's origin
  glm::vec3 direction{0, 0, 1};  // unit, pointing out of the object
  float diameter_m = 0;      // outside diameter at the connection
  bool operator==(const ConnectionPoint&) const = default;
};

// A straight piece of a piping object's centreline.
struct CentrelineSegment {
  glm::vec3 start_m{0}, end_m{0};  // relative to the object's origin
  float diameter_m = 0;            // outside diameter along the segment
  bool operator==(const CentrelineSegment&) const = default;
};

struct Attribute {
  std::string key, value;  // value bytes as the source gave them (not necessarily UTF-8)
  bool operator==(const Attribute&) const = default;
};

// A branch of a pipeline: its pipes and components, by object id, in flow order.
struct Branch {
  std::string name;
  std::vector<uint64_t> members;
  bool operator==(const Branch&) const = default;
};

struct Object {
  uint64_t id = 0;           // stable: see object_id()
  std::string name;          // unique within a model where the source gives unique names
  ObjectClass object_class = ObjectClass::other;
  Colour colour;
  glm::dvec3 origin_m{0.0};  // model-space origin of everything below
  std::vector<Primitive> primitives;  // placements relative to origin_m
  std::vector<Attribute> attributes;

  // Piping topology. Pipes and components: the pipeline they belong to (0: none), their
  // connection points and centreline. Pipelines: their branches (and usually no primitives).
  uint64_t pipeline_id = 0;
  std::vector<ConnectionPoint> connections;
  std::vector<CentrelineSegment> centreline;
  std::vector<Branch> branches;

  // Where the object came from (a file path as given to import, or "gen:<preset>"): importing the
  // same source again replaces every object it brought before.
  std::string source;

  bool operator==(const Object&) const = default;
};

struct PlantModel {
  std::vector<Object> objects;
};

// A stable id from the object's source and name (64-bit FNV-1a of "source\0name"); never 0.
uint64_t object_id(std::string_view source, std::string_view name);

// Model-space bounds of one object (its primitives, connection points and centreline) and of a
// whole model. Empty (min > max) when there is no geometry.
struct DAabb {
  glm::dvec3 min{INFINITY}, max{-INFINITY};
  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  void extend(const glm::dvec3& p) { min = glm::min(min, p); max = glm::max(max, p); }
  void extend(const DAabb& b) {
    if (!b.empty()) { extend(b.min); extend(b.max); }
  }
};
DAabb object_bounds(const Object& object);

// Counts for `plantview info` and for checking generated plants against the papers.
struct ModelStatistics {
  uint64_t objects = 0;
  uint64_t objects_by_class[kObjectClassCount] = {};
  uint64_t primitives = 0;
  uint64_t primitives_by_kind[kPrimitiveKindCount] = {};
  uint64_t primitives_by_class[kObjectClassCount] = {};
  uint64_t triangles = 0;                             // full resolution (level 0)
  uint64_t triangles_by_class[kObjectClassCount] = {};
  uint64_t triangles_by_kind[kPrimitiveKindCount] = {};
  DAabb bounds;
  void add(const Object& object);                     // adds one object's counts
  // Adds or takes away another's counts (not its bounds: those cannot be taken away).
  void add_counts(const ModelStatistics& part);
  void subtract_counts(const ModelStatistics& part);
};
ModelStatistics model_statistics(const PlantModel& model);

}  // namespace plantview
