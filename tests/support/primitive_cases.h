// Test support: the registry of primitive test cases that the generic property tests
// (tests/test_primitive_properties.cpp) run, and the mesh measurements they use.
//
// Each primitive kind registers its cases from its own file, tests/primitives/<kind>_cases.cpp:
//
//   static std::vector<PrimitiveCase> cylinder_cases() { ... }
//   PLANTVIEW_REGISTER_CASES(cylinder_cases)
//
// A case gives a primitive (any placement), a sampler of its TRUE surface written independently
// of the tessellator (closed-form, in the shape's local frame), and the triangle count that
// primitives.h documents for each level. The generic tests then check, for every case and level:
// indices in range, coarser vertex sets inside finer ones, watertight and outward for closed
// kinds, the reported error against the measured deviation, analytic bounds, triangle counts.
#pragma once

#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/primitives.h"

namespace plantview::testing {

struct PrimitiveCase {
  std::string name;  // unique, [A-Za-z0-9_] only (it names the test)
  Primitive primitive;
  // Appends points on the true surface, in the shape's LOCAL frame, dense enough to find the
  // largest deviation: at least 8 samples per finest-level segment in every curved direction.
  // Leave empty for degenerate cases.
  std::function<void(std::vector<glm::vec3>& out)> sample_surface;
  // Documented triangle (or line) count per level; empty to skip the count check.
  std::vector<uint32_t> expected_elements;
  // Degenerate parameters: only "valid, finite, no crash" is checked (and closedness is not).
  bool degenerate = false;
};

using CaseFactory = std::vector<PrimitiveCase> (*)();
bool register_cases(CaseFactory factory);
std::vector<PrimitiveCase> all_cases();

#define PLANTVIEW_REGISTER_CASES(factory) \
  [[maybe_unused]] static const bool registered_##factory = ::plantview::testing::register_cases(factory);

// A tessellated level in model space (origin 0), unpacked for measuring.
struct LevelMesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<uint32_t> indices;  // this level's triangles (or lines)
};
// Level `level` drawn from vertices fitted to `fit_level` (kOnSurface: on the true surface).
LevelMesh tessellate_level(const Primitive& primitive, const MeshPlan& plan, uint32_t level,
                           uint32_t fit_level = kOnSurface);

// Largest distance from any of `points` to the triangle mesh: brute force over every triangle,
// with the test's own point-to-triangle distance (no code shared with the tessellators, which
// measure twisted snout sides with one of their own). For tests only.
float max_distance_to_mesh(const std::vector<glm::vec3>& points, const LevelMesh& mesh);

// Placements to exercise: identity, a rotated and translated one, a mirrored one.
glm::mat3 rotation_about(glm::vec3 axis, float angle_rad);

}  // namespace plantview::testing

namespace plantview::testing {
// Test output names a case, not its bytes.
inline void PrintTo(const PrimitiveCase& c, std::ostream* os) { *os << c.name; }
}  // namespace plantview::testing
