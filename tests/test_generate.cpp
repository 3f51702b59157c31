// The synthetic plant generator: the papers' statistics per preset, determinism, the grid of
// units, piping topology (connections, straight runs, elbows, inline flanges) and sane geometry.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "plantview/generate.h"
#include "plantview/model.h"

namespace plantview {
namespace {

// Preset a, seed 1, at scale 3, generated once for every test that reads it. Objects of a unit
// carry its area in their first name component ("/C-02-004", "/P-03-0203-B1/ELBO-3").
struct ThreeUnits {
  std::vector<Object> unit0;  // the first unit's objects, in order
  std::unordered_map<std::string, DAabb> plots;
  std::unordered_map<std::string, uint64_t> objects_per_unit;
  std::unordered_set<uint64_t> ids;
  uint64_t objects = 0;
  std::vector<double> progress;
  GenerateSummary summary;
};

const ThreeUnits& three_units() {
  static const ThreeUnits run = [] {
    ThreeUnits r;
    r.summary = generate_plant(
        {'a', 3, 1},
        [&](Object&& o) {
          ++r.objects;
          r.ids.insert(o.id);
          const size_t a = o.name.find('-') + 1;
          const std::string area = o.name.substr(a, o.name.find('-', a) - a);
          r.plots[area].extend(object_bounds(o));
          ++r.objects_per_unit[area];
          if (area == "01") r.unit0.push_back(std::move(o));
        },
        [&](double f) { r.progress.push_back(f); });
    return r;
  }();
  return run;
}

// Preset a at scale 1 (the first of the three units: a unit depends only on preset, seed and its
// index, which the scale test checks).
const PlantModel& preset_a() {
  static const PlantModel model{three_units().unit0};
  return model;
}

std::string attribute(const Object& o, std::string_view key) {
  for (const Attribute& a : o.attributes) {
    if (a.key == key) return a.value;
  }
  return {};
}

// Relative deviation of `ours` from `paper`.
double deviation(double ours, double paper) { return (ours - paper) / paper; }

#define EXPECT_WITHIN(ours, paper, tolerance)                              \
  EXPECT_LE(std::abs(deviation(double(ours), double(paper))), (tolerance)) \
      << #ours << " = " << (ours) << " vs " << (paper) << " ("             \
      << 100.0 * deviation(double(ours), double(paper)) << " %)"

struct Counts {
  ModelStatistics stats;
  uint64_t snouts[3] = {};  // SnoutVariant order
  void add(const Object& o) {
    stats.add(o);
    for (const Primitive& p : o.primitives) {
      if (p.kind() == PrimitiveKind::snout)
        ++snouts[size_t(snout_variant(std::get<Snout>(p.shape)))];
    }
  }
};

// Su et al. Tables 1-3 (10 %, triangles 15 %) and Zhou et al. Table 1 (10 % per kind with a count).
void expect_paper_figures(const Counts& c, const PresetInfo& info) {
  const ModelStatistics& s = c.stats;
  auto objects = [&](ObjectClass k) { return s.objects_by_class[size_t(k)]; };
  auto prims = [&](ObjectClass k) { return s.primitives_by_class[size_t(k)]; };
  EXPECT_WITHIN(objects(ObjectClass::equipment), info.equipment, 0.10);
  EXPECT_WITHIN(objects(ObjectClass::pipe), info.pipes, 0.10);
  EXPECT_WITHIN(objects(ObjectClass::component), info.components, 0.10);
  EXPECT_WITHIN(objects(ObjectClass::pipeline), info.pipelines, 0.10);
  EXPECT_WITHIN(prims(ObjectClass::equipment), info.equipment_primitives, 0.10);
  EXPECT_WITHIN(prims(ObjectClass::pipe), info.pipe_primitives, 0.10);
  EXPECT_WITHIN(prims(ObjectClass::component), info.component_primitives, 0.10);
  const uint64_t su =
      prims(ObjectClass::equipment) + prims(ObjectClass::pipe) + prims(ObjectClass::component);
  EXPECT_WITHIN(su, info.su_primitives, 0.10);
  EXPECT_WITHIN(s.primitives, info.zhou_primitives, 0.10);
  // Each pipe is one cylinder; pipelines carry no primitives.
  EXPECT_EQ(prims(ObjectClass::pipe), objects(ObjectClass::pipe));
  EXPECT_EQ(prims(ObjectClass::pipeline), 0u);
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    SCOPED_TRACE(kind_name(PrimitiveKind(k)));
    if (info.kind_primitives[k] == 0) {
      EXPECT_EQ(s.primitives_by_kind[k], 0u);
    } else {
      EXPECT_WITHIN(s.primitives_by_kind[k], info.kind_primitives[k], 0.10);
    }
  }
  EXPECT_WITHIN(c.snouts[size_t(SnoutVariant::sheared_cylinder)], info.sheared_cylinders, 0.10);
  EXPECT_WITHIN(c.snouts[size_t(SnoutVariant::eccentric_cone)], info.eccentric_cones, 0.10);
  EXPECT_WITHIN(c.snouts[size_t(SnoutVariant::concentric_cone)], info.concentric_cones, 0.10);
  EXPECT_WITHIN(s.triangles, info.triangles, 0.15);
  // Plan and height as Su et al. Fig. 1 (within 15 %: pipes and platforms reach past equipment).
  const glm::dvec3 size = s.bounds.max - s.bounds.min;
  EXPECT_WITHIN(size.x, info.plan_x_m, 0.15);
  EXPECT_WITHIN(size.y, info.plan_y_m, 0.15);
  EXPECT_WITHIN(size.z, info.height_m, 0.15);
}

Counts count_preset(char preset) {
  Counts c;
  generate_plant({preset, 1, 1}, [&](Object&& o) { c.add(o); });
  return c;
}

TEST(GeneratePresets, PresetAMatchesThePapersFigures) {
  Counts c;
  for (const Object& o : preset_a().objects) c.add(o);
  expect_paper_figures(c, *preset_info('a'));
}

TEST(GeneratePresets, PresetBMatchesThePapersFigures) {
  expect_paper_figures(count_preset('b'), *preset_info('b'));
}

TEST(GeneratePresets, PresetCMatchesThePapersFigures) {
  expect_paper_figures(count_preset('c'), *preset_info('c'));
}

TEST(GeneratePresets, ParsePresetAcceptsTheThreePresetsOnly) {
  char p = 0;
  EXPECT_TRUE(parse_preset("a", p));
  EXPECT_EQ(p, 'a');
  EXPECT_TRUE(parse_preset("C", p));
  EXPECT_EQ(p, 'c');
  EXPECT_FALSE(parse_preset("d", p));
  EXPECT_FALSE(parse_preset("", p));
  EXPECT_FALSE(parse_preset("ab", p));
  EXPECT_EQ(preset_info('x'), nullptr);
  ASSERT_NE(preset_info('c'), nullptr);
  EXPECT_EQ(preset_info('c')->kind_primitives[size_t(PrimitiveKind::cylinder)], 30354u);
}

// A sink may stop the generator by throwing; nothing is left behind.
struct Enough {};

TEST(GenerateDeterminism, AnotherSeedGivesAnotherPlant) {
  std::vector<Object> first;
  try {
    generate_plant({'a', 1, 2}, [&](Object&& o) {
      first.push_back(std::move(o));
      if (first.size() == 50) throw Enough{};
    });
  } catch (const Enough&) {
  }
  ASSERT_EQ(first.size(), 50u);
  const std::vector<Object> seed1(preset_a().objects.begin(), preset_a().objects.begin() + 50);
  EXPECT_FALSE(first == seed1);
}

// Three units: three times the objects on disjoint plots; the first unit is exactly the plant
// of scale 1 with the same seed (generation is a pure function of preset, seed and unit index),
// the others are variations of it.
TEST(GenerateScale, UnitsTripleTheObjectsInDisjointPlotsAndRepeatExactly) {
  const ThreeUnits& r = three_units();
  EXPECT_EQ(r.summary.units, 3u);
  EXPECT_EQ(r.summary.objects, r.objects);
  EXPECT_EQ(r.ids.size(), r.objects) << "ids are unique";
  ASSERT_FALSE(r.progress.empty());
  for (size_t i = 1; i < r.progress.size(); ++i) EXPECT_GE(r.progress[i], r.progress[i - 1]);
  EXPECT_DOUBLE_EQ(r.progress.back(), 1.0);
  EXPECT_WITHIN(r.objects, 3 * r.unit0.size(), 0.05);
  EXPECT_NE(r.objects_per_unit.at("02"), r.objects_per_unit.at("01")) << "each unit varies";
  // The first unit again, alone: identical objects.
  std::vector<Object> again;
  try {
    generate_plant({'a', 1, 1}, [&](Object&& o) {
      again.push_back(std::move(o));
      if (again.size() == 400) throw Enough{};
    });
  } catch (const Enough&) {
  }
  ASSERT_EQ(again.size(), 400u);
  EXPECT_TRUE(std::equal(again.begin(), again.end(), r.unit0.begin())) << "same seed, same plant";
  ASSERT_EQ(r.plots.size(), 3u);
  std::vector<DAabb> boxes;
  for (const auto& [area, box] : r.plots) boxes.push_back(box);
  for (size_t i = 0; i < boxes.size(); ++i) {
    for (size_t j = i + 1; j < boxes.size(); ++j) {
      const bool overlap = boxes[i].min.x < boxes[j].max.x && boxes[j].min.x < boxes[i].max.x &&
                           boxes[i].min.y < boxes[j].max.y && boxes[j].min.y < boxes[i].max.y;
      EXPECT_FALSE(overlap) << "units " << i << " and " << j;
    }
  }
}

// --- Piping topology -----------------------------------------------------------------------------

glm::dvec3 at(const Object& o, const ConnectionPoint& c) {
  return o.origin_m + glm::dvec3(c.position_m);
}

double distance_to_line(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
  const glm::dvec3 d = glm::normalize(b - a);
  const glm::dvec3 v = p - a;
  return glm::length(v - d * glm::dot(v, d));
}

TEST(GeneratePiping, BranchesAreConnectedStraightExceptAtElbows) {
  const PlantModel& model = preset_a();
  std::unordered_map<uint64_t, const Object*> by_id;
  for (const Object& o : model.objects) by_id[o.id] = &o;
  // Where a branch may start or end: equipment nozzles, tee and olet branch ports (by mm grid).
  auto key = [](const glm::dvec3& p) {
    return std::to_string(std::llround(p.x * 100)) + "," + std::to_string(std::llround(p.y * 100)) +
           "," + std::to_string(std::llround(p.z * 100));
  };
  // Points are filed under every neighbouring cell of a 1 cm grid, so that a lookup within a
  // millimetre never misses across a cell border.
  std::unordered_set<std::string> ends;
  auto file = [&](const glm::dvec3& p) {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) ends.insert(key(p + glm::dvec3(dx, dy, dz) * 0.01));
      }
    }
  };
  for (const Object& o : model.objects) {
    if (o.object_class == ObjectClass::equipment) {
      for (const ConnectionPoint& c : o.connections) file(at(o, c));
    }
    if (o.object_class == ObjectClass::component && o.connections.size() == 3) {
      file(at(o, o.connections[2]));
    }
  }
  const double plan_x = preset_info('a')->plan_x_m;
  int pipelines = 0, members = 0, elbows = 0, flanges_checked = 0;
  for (const Object& line : model.objects) {
    if (line.object_class != ObjectClass::pipeline) continue;
    ++pipelines;
    ASSERT_FALSE(line.branches.empty()) << line.name;
    for (const Branch& branch : line.branches) {
      ASSERT_FALSE(branch.members.empty()) << branch.name;
      std::vector<const Object*> m;
      for (uint64_t id : branch.members) {
        auto it = by_id.find(id);
        ASSERT_NE(it, by_id.end()) << branch.name;
        const Object& o = *it->second;
        EXPECT_EQ(o.pipeline_id, line.id) << o.name;
        EXPECT_TRUE(o.object_class == ObjectClass::pipe ||
                    o.object_class == ObjectClass::component);
        ASSERT_GE(o.connections.size(), 1u) << o.name;
        m.push_back(&o);
      }
      members += int(m.size());
      for (size_t i = 0; i < m.size(); ++i) {
        const Object& o = *m[i];
        const std::string type = attribute(o, "Type");
        if (o.connections.size() == 1) {
          EXPECT_EQ(i + 1, m.size()) << o.name << ": a closure ends its branch";
          continue;
        }
        const glm::vec3 d0 = o.connections[0].direction, d1 = o.connections[1].direction;
        if (type == "ELBO") {
          ++elbows;
          EXPECT_LT(std::abs(glm::dot(d0, d1)), 1e-3f) << o.name << ": elbows turn 90 degrees";
        } else {
          EXPECT_LT(glm::dot(d0, d1), -0.999f) << o.name << ": only elbows change direction";
        }
        if (i + 1 < m.size()) {
          const Object& n = *m[i + 1];
          EXPECT_LT(glm::length(at(o, o.connections[1]) - at(n, n.connections[0])), 1e-3)
              << o.name << " -> " << n.name;
          EXPECT_LT(glm::dot(o.connections[1].direction, n.connections[0].direction), -0.999f)
              << o.name << " -> " << n.name;
        }
        // An inline flange sits on the centreline of the pipe it joins on a straight run.
        if (type == "FLAN") {
          for (int step : {-1, 1}) {
            for (int j = int(i) + step; j >= 0 && j < int(m.size()); j += step) {
              const Object& p = *m[size_t(j)];
              const std::string t = attribute(p, "Type");
              if (t == "ELBO" || t == "REDU" || t == "TEE" || t == "OLET") break;
              if (p.object_class != ObjectClass::pipe) continue;
              const glm::dvec3 a = p.origin_m + glm::dvec3(p.centreline[0].start_m);
              const glm::dvec3 b = p.origin_m + glm::dvec3(p.centreline[0].end_m);
              for (const ConnectionPoint& c : o.connections) {
                EXPECT_LT(distance_to_line(at(o, c), a, b), 1e-3) << o.name << " on " << p.name;
              }
              ++flanges_checked;
              break;
            }
          }
        }
      }
      // Branch ends: a nozzle, a tee or olet port, a battery limit at the plot's edge, or a
      // closure.
      auto is_end = [&](const glm::dvec3& p) {
        return ends.count(key(p)) > 0 || std::abs(p.x) < 0.1 || std::abs(p.x - plan_x) < 0.1;
      };
      EXPECT_TRUE(is_end(at(*m.front(), m.front()->connections[0])))
          << branch.name << " head " << m.front()->name << " at "
          << at(*m.front(), m.front()->connections[0]).x << " "
          << at(*m.front(), m.front()->connections[0]).y << " "
          << at(*m.front(), m.front()->connections[0]).z;
      if (m.back()->connections.size() > 1) {
        EXPECT_TRUE(is_end(at(*m.back(), m.back()->connections[1]))) << branch.name << " tail";
      }
    }
  }
  EXPECT_WITHIN(pipelines, preset_info('a')->pipelines, 0.10);
  EXPECT_GT(members, 10 * pipelines);
  EXPECT_GT(elbows, pipelines);
  EXPECT_GT(flanges_checked, 20);
}

TEST(GeneratePiping, PipesAreOneCylinderAlongTheirCentreline) {
  for (const Object& o : preset_a().objects) {
    if (o.object_class != ObjectClass::pipe) continue;
    ASSERT_EQ(o.primitives.size(), 1u) << o.name;
    ASSERT_EQ(o.primitives[0].kind(), PrimitiveKind::cylinder) << o.name;
    ASSERT_EQ(o.centreline.size(), 1u) << o.name;
    const CentrelineSegment& s = o.centreline[0];
    const float length = glm::length(s.end_m - s.start_m);
    EXPECT_NEAR(std::get<Cylinder>(o.primitives[0].shape).height_m, length, 1e-4f) << o.name;
    EXPECT_NEAR(std::get<Cylinder>(o.primitives[0].shape).radius_m, 0.5f * s.diameter_m, 1e-5f)
        << o.name;
    EXPECT_EQ(o.connections[0].position_m, glm::vec3(0.0f)) << o.name << ": origin at the inlet";
  }
}

TEST(GeneratePiping, NamesAndAttributesReadLikeAPlantModel) {
  int valves = 0;
  for (const Object& o : preset_a().objects) {
    ASSERT_FALSE(o.name.empty());
    EXPECT_EQ(o.name[0], '/') << o.name;
    EXPECT_EQ(o.id, object_id("gen:a:1:0", o.name)) << o.name;
    EXPECT_EQ(o.source, "gen:a");
    EXPECT_FALSE(attribute(o, "Type").empty() && o.object_class != ObjectClass::pipeline) << o.name;
    if (attribute(o, "Type") == "VALV") {
      ++valves;
      EXPECT_FALSE(attribute(o, "Tag").empty()) << o.name;
      EXPECT_FALSE(attribute(o, "Spec").empty()) << o.name;
      EXPECT_NE(attribute(o, "Bore").find("DN"), std::string::npos) << o.name;
    }
    if (o.object_class == ObjectClass::pipeline) {
      EXPECT_FALSE(attribute(o, "Line number").empty()) << o.name;
      EXPECT_TRUE(o.primitives.empty()) << o.name;
    }
  }
  EXPECT_GT(valves, 100);
}

// --- Geometry ------------------------------------------------------------------------------------

bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

TEST(GenerateGeometry, EveryPrimitiveTessellatesAndNothingIsNaN) {
  for (const Object& o : preset_a().objects) {
    ASSERT_TRUE(std::isfinite(o.origin_m.x) && std::isfinite(o.origin_m.y) &&
                std::isfinite(o.origin_m.z))
        << o.name;
    for (const Primitive& p : o.primitives) {
      for (int c = 0; c < 3; ++c) ASSERT_TRUE(finite(p.placement.linear[c])) << o.name;
      ASSERT_TRUE(finite(p.placement.translation_m)) << o.name;
      const Aabb local = local_bounds(p.shape);
      ASSERT_TRUE(finite(local.min) && finite(local.max)) << o.name;
      const MeshPlan plan = plan_mesh(p);
      EXPECT_GT(element_count(plan, 0), 0u) << o.name << " " << kind_name(p.kind());
      // Frames are rotations (lengths kept, not mirrored).
      EXPECT_NEAR(glm::determinant(p.placement.linear), 1.0f, 1e-4f) << o.name;
    }
    for (const ConnectionPoint& c : o.connections) {
      ASSERT_TRUE(finite(c.position_m) && finite(c.direction)) << o.name;
      EXPECT_NEAR(glm::length(c.direction), 1.0f, 1e-4f) << o.name;
      EXPECT_GT(c.diameter_m, 0.0f) << o.name;
    }
    for (const CentrelineSegment& s : o.centreline) {
      ASSERT_TRUE(finite(s.start_m) && finite(s.end_m)) << o.name;
    }
    if (o.object_class != ObjectClass::pipeline) {
      EXPECT_FALSE(object_bounds(o).empty()) << o.name;
    }
    EXPECT_GE(object_bounds(o).min.z, -0.5) << o.name << ": nothing below grade";
  }
}

}  // namespace
}  // namespace plantview
