// Clash detection (plantview/clash.h): planted pairs of every kind moved into one another by
// known depths and apart by known gaps, found exactly and measured within 1 mm; a pipeline's own
// parts and supports never reported; a revision that moves a pipe into a beam makes exactly one
// new clash, active on the next run; --between; shards merged equal one run; the command's bad
// input.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <sstream>
#include <tuple>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "plantview/clash.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/review.h"
#include "plantview/store.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

constexpr double kMm = 0.001;

Primitive at(Shape shape, const glm::vec3& t, const glm::mat3& linear = glm::mat3(1.0f)) {
  Primitive p;
  p.shape = std::move(shape);
  p.placement.linear = linear;
  p.placement.translation_m = t;
  return p;
}

Object object_of(const std::string& name, ObjectClass c, std::vector<Primitive> primitives, const glm::dvec3& origin_m) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = c;
  o.origin_m = origin_m;
  o.primitives = std::move(primitives);
  return o;
}

glm::mat3 rotation(double angle_rad, const glm::vec3& axis) {
  return glm::mat3(glm::rotate(glm::mat4(1.0f), float(angle_rad), axis));
}

// A cube of facets (a facet group of 6 quads), side s, centred.
FacetGroup facet_cube(float s) {
  FacetGroup g;
  const float h = s / 2;
  const glm::vec3 corners[8] = {{-h, -h, -h}, {h, -h, -h}, {h, h, -h}, {-h, h, -h},
                                {-h, -h, h},  {h, -h, h},  {h, h, h},  {-h, h, h}};
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  for (const auto& f : faces) {
    const glm::vec3 n = glm::normalize(glm::cross(corners[f[1]] - corners[f[0]], corners[f[2]] - corners[f[0]]));
    for (int k = 0; k < 4; ++k) g.vertices.push_back({corners[f[k]], n});
    g.contour_ends.push_back(uint32_t(g.vertices.size()));
    g.polygon_ends.push_back(uint32_t(g.contour_ends.size()));
  }
  g.triangulate();
  return g;
}

// One planted case: two objects whose overlap (depth > 0) or gap (depth < 0) is `depth_m`, at
// `origin` (cases lie 20 m apart).
struct Planted {
  std::string kind;
  double depth_m;
  Object a, b;
};

Planted planted(const std::string& kind, int index, double depth_m) {
  const glm::dvec3 o(20.0 * index, 0, 5);
  const std::string n = kind + "-" + std::to_string(index);
  const float d = float(depth_m);
  Planted p{kind, depth_m, {}, {}};
  if (kind == "box-box") {
    p.a = object_of(n + "-A", ObjectClass::structure, {at(Box{1, 1, 1}, {0, 0, 0})}, o);
    p.b = object_of(n + "-B", ObjectClass::structure, {at(Box{0.6f, 0.6f, 0.6f}, {0.8f - d, 0.1f, 0.05f})}, o);
  } else if (kind == "cylinder-box") {  // a pipe along x, its end into a box face
    p.a = object_of(n + "-A", ObjectClass::structure, {at(Box{1, 1, 1}, {0, 0, 0})}, o);
    p.b = object_of(n + "-B", ObjectClass::pipe,
                    {at(Cylinder{0.1f, 2}, {0.5f + 1 - d, 0, 0}, rotation(std::numbers::pi / 2, {0, 1, 0}))}, o);
  } else if (kind == "cylinder-cylinder") {  // crossing at 60 degrees, axes 0.2 - d apart
    p.a = object_of(n + "-A", ObjectClass::pipe, {at(Cylinder{0.1f, 3}, {0, 0, 0}, rotation(std::numbers::pi / 2, {0, 1, 0}))}, o);
    const glm::mat3 r = rotation(std::numbers::pi / 3, {0, 0, 1}) * rotation(std::numbers::pi / 2, {0, 1, 0});
    p.b = object_of(n + "-B", ObjectClass::pipe, {at(Cylinder{0.1f, 3}, {0, 0, 0.2f - d}, r)}, o);
  } else if (kind == "pipe-along-pipe") {  // two lines laid along one route, 1 m apart lengthwise
    const glm::mat3 along_x = rotation(std::numbers::pi / 2, {0, 1, 0});
    p.a = object_of(n + "-A", ObjectClass::pipe, {at(Cylinder{0.1f, 3}, {0, 0, 0}, along_x)}, o);
    p.b = object_of(n + "-B", ObjectClass::pipe, {at(Cylinder{0.15f, 3}, {1, 0.25f - d, 0}, along_x)}, o);
  } else if (kind == "torus-cylinder") {  // an elbow's outer side into a vertical pipe
    p.a = object_of(n + "-A", ObjectClass::component, {at(CircularTorus{0.5f, 0.1f, float(std::numbers::pi / 2)}, {0, 0, 0})}, o);
    const float r = 0.6f + 0.1f - d, c = float(std::cos(std::numbers::pi / 4));
    p.b = object_of(n + "-B", ObjectClass::pipe, {at(Cylinder{0.1f, 2}, {r * c, r * c, 0})}, o);
  } else if (kind == "dish-box") {  // a box pressed onto a vessel head's crown
    p.a = object_of(n + "-A", ObjectClass::equipment, {at(EllipticalDish{0.5f, 0.25f}, {0, 0, 0})}, o);
    p.b = object_of(n + "-B", ObjectClass::structure, {at(Box{0.4f, 0.4f, 0.2f}, {0, 0, 0.25f + 0.1f - d})}, o);
  } else if (kind == "facets-box") {  // a box onto a facet cube's top face
    p.a = object_of(n + "-A", ObjectClass::other, {at(facet_cube(1), {0, 0, 0})}, o);
    p.b = object_of(n + "-B", ObjectClass::structure, {at(Box{1.4f, 1.4f, 0.4f}, {0.1f, 0, 0.5f + 0.2f - d})}, o);
  }
  return p;
}

const char* const kKinds[] = {"box-box",        "cylinder-box", "cylinder-cylinder", "pipe-along-pipe",
                              "torus-cylinder", "dish-box",     "facets-box"};

ClashReport run(const Store& store, const std::string& dir, ClashSettings settings = {}) {
  std::string error;
  const auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  ClashReport report;
  EXPECT_TRUE(find_clashes(*view, dir, settings, report, error)) << error;
  return report;
}

std::pair<uint64_t, uint64_t> key(uint64_t x, uint64_t y) { return {std::min(x, y), std::max(x, y)}; }

TEST(Clash, PlantedDepthsAndGapsFoundExactly) {
  // Each kind at 5, 20 and 50 mm deep (found), 0.3 mm deep (under the tolerance) and 30 mm apart.
  const double depths[] = {0.005, 0.020, 0.050, 0.0003, -0.030};
  std::vector<Object> objects;
  std::map<std::pair<uint64_t, uint64_t>, Planted> cases;
  int index = 0;
  for (const char* kind : kKinds)
    for (double depth : depths) {
      Planted p = planted(kind, index++, depth);
      objects.push_back(p.a);
      objects.push_back(p.b);
      cases.emplace(key(p.a.id, p.b.id), std::move(p));
    }
  const test::TempDir dir;
  const auto store = test::make_store(dir, objects);
  ASSERT_TRUE(store);

  const ClashReport hard = run(*store, dir.str());
  std::set<std::pair<uint64_t, uint64_t>> found;
  for (const Clash& c : hard.clashes) {
    const auto it = cases.find(key(c.a.id, c.b.id));
    ASSERT_NE(it, cases.end()) << "unplanted clash " << c.a.tag << " x " << c.b.tag;
    const Planted& p = it->second;
    EXPECT_EQ(c.kind, ClashKind::hard);
    EXPECT_NEAR(c.depth_m, p.depth_m, 1 * kMm) << p.kind << " at " << p.depth_m;
    EXPECT_FALSE(c.points_m.empty());
    EXPECT_EQ(c.status, ClashStatus::new_clash);
    found.insert(it->first);
  }
  for (const auto& [k, p] : cases)
    EXPECT_EQ(found.count(k), p.depth_m > 1 * kMm ? 1u : 0u) << p.kind << " at depth " << p.depth_m;

  // Clearance 50 mm: the 30 mm gaps too (distance within 1 mm), the shallow overlaps as touching.
  ClashSettings settings;
  settings.clearance_m = 0.050;
  const ClashReport near = run(*store, dir.str(), settings);
  size_t clearance = 0;
  for (const Clash& c : near.clashes) {
    const Planted& p = cases.at(key(c.a.id, c.b.id));
    if (c.kind != ClashKind::clearance) continue;
    ++clearance;
    // Within 1 mm, or the tessellation error the clash states (a large dish's finest mesh).
    EXPECT_NEAR(c.distance_m, std::max(0.0, -p.depth_m), std::max(1 * kMm, c.error_m)) << p.kind;
    EXPECT_LE(c.error_m, 3 * kMm) << p.kind;
  }
  EXPECT_EQ(clearance, 2 * std::size(kKinds));
  EXPECT_EQ(near.clashes.size(), cases.size());

  // --between a class --and a glob: only the pipe-structure case of cylinder-box.
  settings = {};
  settings.between.word = "pipe";
  settings.with.word = "box-box-*";
  EXPECT_TRUE(run(*store, dir.str(), settings).clashes.empty());
  settings.with.word = "cylinder-box-*";
  const ClashReport between = run(*store, dir.str(), settings);
  EXPECT_EQ(between.clashes.size(), 3u);
  for (const Clash& c : between.clashes) EXPECT_EQ(cases.at(key(c.a.id, c.b.id)).kind, "cylinder-box");
}

// A pipeline of two pipes, a flange pair between them and a support under it, on a beam; and a
// beam beside it. `moved`: the second pipe lowered into the beam beside.
std::vector<Object> piping_case(bool moved) {
  std::vector<Object> out;
  Object line;
  line.name = "/P-1";
  line.source = "test";
  line.id = object_id("test", line.name);
  line.object_class = ObjectClass::pipeline;
  const auto piece = [&](const std::string& name, ObjectClass c, Primitive p, const glm::dvec3& origin,
                         glm::vec3 in, glm::vec3 out_at) {
    Object o = object_of("/P-1/" + name, c, {p}, origin);
    o.pipeline_id = line.id;
    o.connections = {{in, {-1, 0, 0}, 0.2f}, {out_at, {1, 0, 0}, 0.2f}};
    o.centreline = {{in, out_at, 0.2f}};
    return o;
  };
  const glm::mat3 along_x = rotation(std::numbers::pi / 2, {0, 1, 0});
  out.push_back(piece("PIPE-1", ObjectClass::pipe, at(Cylinder{0.1f, 2}, {1, 0, 0}, along_x), {0, 100, 2}, {0, 0, 0}, {2, 0, 0}));
  out.push_back(piece("FLAN-1", ObjectClass::component, at(Cylinder{0.15f, 0.1f}, {0.05f, 0, 0}, along_x), {2, 100, 2}, {0, 0, 0}, {0.1f, 0, 0}));
  // The other line's flange, bolted face to face (another pipeline: the connection rule).
  Object other = object_of("/P-2/FLAN-1", ObjectClass::component, {at(Cylinder{0.15f, 0.1f}, {0.05f, 0, 0}, along_x)}, {2.1, 100, 2});
  other.pipeline_id = object_id("test", "/P-2");
  other.connections = {{{0, 0, 0}, {-1, 0, 0}, 0.2f}};
  // Overlaps the first flange by 2 mm: a gasket's squeeze.
  other.origin_m.x -= 0.002;
  other.connections[0].position_m.x += 0.002f;
  out.push_back(other);
  Object pipe2 = piece("PIPE-2", ObjectClass::pipe, at(Cylinder{0.1f, 2}, {1, 0, 0}, along_x), {2.2, 100, 2}, {0, 0, 0}, {2, 0, 0});
  pipe2.pipeline_id = other.pipeline_id;
  if (moved) pipe2.origin_m = {2.2, 110, 0.6};  // into the beam beside, 50 mm deep
  out.push_back(pipe2);
  // A support of another line's make-up (no pipeline id): carries PIPE-1 by its connection point.
  Object support = object_of("/P-3/SUPP-1", ObjectClass::component, {at(Box{0.2f, 0.2f, 0.21f}, {0, 0, -0.095f})}, {1, 100, 1.9});
  support.attributes = {{"Type", "SUPP"}};
  support.connections = {{{0, 0, 0}, {0, 0, -1}, 0.2f}};
  out.push_back(support);
  out.push_back(object_of("/BEAM-1", ObjectClass::structure, {at(Box{6, 0.3f, 0.4f}, {0, 0, 0})}, {2, 100, 1.5}));
  out.push_back(object_of("/BEAM-2", ObjectClass::structure, {at(Box{6, 0.3f, 0.4f}, {0, 0, 0})}, {2, 110, 0.35}));
  // An equipment item whose nozzle P-1 starts from, 20 mm into PIPE-1 (the nozzle rule; the
  // nozzle's direction is not opposite the pipe's, so that the connection rule does not apply).
  Object item = object_of("/E-1", ObjectClass::equipment, {at(Box{1, 0.5f, 0.5f}, {0, 0, 0})}, {-0.48, 100, 2});
  item.connections = {{{0.48f, 0, 0}, {-1, 0, 0}, 0.2f}};
  out.push_back(item);
  line.branches = {{"/P-1-B1", {out[0].id, out[1].id}}};
  out.push_back(line);
  return out;
}

TEST(Clash, PipesLaidInOneAnotherReadTheirRadialDepth) {
  // Two lines along one route, one lying 5 cm off the other's axis and 1 m along it: the
  // shortest way apart is sideways, 0.2 - 0.05 m (the line between their centres runs along
  // them, and a depth measured there reads the length they share).
  const glm::mat3 along_x = rotation(std::numbers::pi / 2, {0, 1, 0});
  const glm::dvec3 o(0, 0, 5);
  const std::vector<Object> objects = {
      object_of("P-A", ObjectClass::pipe, {at(Cylinder{0.1f, 3}, {0, 0, 0}, along_x)}, o),
      object_of("P-B", ObjectClass::pipe, {at(Cylinder{0.1f, 3}, {1, 0.05f, 0}, along_x)}, o)};
  const test::TempDir dir;
  const auto store = test::make_store(dir, objects);
  ASSERT_TRUE(store);
  ClashSettings settings;
  settings.include_connected = true;
  const ClashReport report = run(*store, dir.str(), settings);
  ASSERT_EQ(report.clashes.size(), 1u);
  EXPECT_NEAR(report.clashes[0].depth_m, 0.15, 1 * kMm);
}

TEST(Clash, RulesKeepAPipelinesOwnPartsAndSupportsOut) {
  const test::TempDir dir;
  const auto store = test::make_store(dir, piping_case(false));
  ASSERT_TRUE(store);
  const ClashReport report = run(*store, dir.str());
  for (const Clash& c : report.clashes) ADD_FAILURE() << c.a.tag << " x " << c.b.tag << " " << c.depth_m;
  EXPECT_GT(report.counts.skipped_by_rule[int(ClashRule::connected)], 0u);
  EXPECT_GT(report.counts.skipped_by_rule[int(ClashRule::support)], 0u);
  EXPECT_EQ(report.counts.skipped_by_rule[int(ClashRule::nozzle)], 1u);
  ClashSettings all;
  all.include_connected = true;
  const ClashReport everything = run(*store, dir.str(), all);
  EXPECT_GE(everything.clashes.size(), 3u);  // the squeezed flanges, the support in the pipe, the nozzle
}

TEST(Clash, ARevisionMovingAPipeIntoABeamMakesOneNewClash) {
  const test::TempDir dir;
  const auto store = test::make_store(dir, piping_case(false));
  ASSERT_TRUE(store);
  const ClashReport first = run(*store, dir.str());
  ASSERT_TRUE(first.clashes.empty());
  ASSERT_TRUE(ingest_objects(*store, piping_case(true)));
  ClashReport second = run(*store, dir.str());
  std::string error;
  ASSERT_TRUE(apply_previous(second, first, error)) << error;
  ASSERT_EQ(second.clashes.size(), 1u);
  EXPECT_EQ(second.clashes[0].status, ClashStatus::new_clash);
  EXPECT_EQ(second.clashes[0].a.tag == "/BEAM-2" || second.clashes[0].b.tag == "/BEAM-2", true);
  EXPECT_NEAR(second.clashes[0].depth_m, 0.05, 1 * kMm);
  {
    // The revision moved the pipe: the new clash names it (not the beam).
    const auto view = store->read(error);
    ASSERT_TRUE(view) << error;
    EXPECT_EQ(first.revision + 1, second.revision);
    std::string note;
    EXPECT_TRUE(name_changed_objects(second, *view, first.revision, note)) << note;
    EXPECT_TRUE(note.empty()) << note;
    ASSERT_NE(second.clashes[0].changed_id, 0u);
    EXPECT_EQ(second.clashes[0].changed_tag().view().rfind("/P-1/", 0), 0u) << second.clashes[0].changed_tag();
    EXPECT_NE(clash_report_json(second).find("\"changed_tag\""), std::string::npos);
    const std::vector<ReviewView> views = clash_views(second, 16.0 / 9.0);
    ASSERT_EQ(views.size(), 1u);
    EXPECT_EQ(views[0].attributes.back(),
              (std::pair<std::string, std::string>{"changed", second.clashes[0].changed_tag().str()}));
  }
  // Through the file, as --since reads it.
  ClashReport reread;
  ASSERT_TRUE(parse_clash_report(clash_report_json(second), reread, error)) << error;
  ClashReport third = run(*store, dir.str());
  ASSERT_TRUE(apply_previous(third, reread, error)) << error;
  ASSERT_EQ(third.clashes.size(), 1u);
  EXPECT_EQ(third.clashes[0].status, ClashStatus::active);
  EXPECT_EQ(third.clashes[0].id, second.clashes[0].id);
  EXPECT_EQ(third.clashes[0].changed_id, 0u);  // (named only when new)
  // Moved back: resolved.
  ASSERT_TRUE(ingest_objects(*store, piping_case(false)));
  ClashReport fourth = run(*store, dir.str());
  const ClashReport fourth_found = fourth;
  ASSERT_TRUE(apply_previous(fourth, third, error)) << error;
  ASSERT_EQ(fourth.clashes.size(), 1u);
  EXPECT_EQ(fourth.clashes[0].status, ClashStatus::resolved);
  {
    // The same from the file's keys, then the file again for the resolved ones (clash --since
    // on a file too large to hold): the same report.
    const std::string third_file = clash_report_json(third);
    std::istringstream keys_stream(third_file), again(third_file);
    PreviousClashes previous;
    ASSERT_TRUE(read_previous_clashes(keys_stream, previous, error)) << error;
    ASSERT_EQ(previous.keys.size(), 1u);
    EXPECT_EQ(previous.header.revision, third.revision);
    ClashReport streamed = fourth_found;
    std::vector<bool> matched;
    ASSERT_TRUE(match_previous(streamed, previous, matched, error)) << error;
    ASSERT_TRUE(append_resolved(streamed, again, matched, error)) << error;
    EXPECT_EQ(clash_report_json(streamed), clash_report_json(fourth));
    // A file that changed between the two reads is refused.
    std::istringstream empty_now(clash_report_json(fourth_found));
    ClashReport changed = fourth_found;
    EXPECT_FALSE(append_resolved(changed, empty_now, matched, error));
    EXPECT_NE(error.find("changed"), std::string::npos) << error;
  }
  // Another store's file is refused.
  ClashReport other = third;
  other.store_directory = "/elsewhere";
  EXPECT_FALSE(apply_previous(fourth, other, error));
  EXPECT_NE(error.find("another store"), std::string::npos) << error;
}

TEST(Clash, ViewsColourTheTwoObjectsAndRoundTrip) {
  ClashReport report;
  Clash c;
  c.id = 0x1234;
  c.a.id = 7;
  c.a.tag = ClashText("P-1");
  c.b.id = 9;  // no tag: named by id
  c.points_m = {{1, 2, 3}};
  c.depth_m = 0.01;
  report.clashes = {c};
  const std::vector<ReviewView> views = clash_views(report, 16.0 / 9.0);
  ASSERT_EQ(views.size(), 1u);
  ASSERT_EQ(views[0].colours.size(), 2u);
  EXPECT_EQ(views[0].colours[0].id, 7u);
  EXPECT_EQ(views[0].colours[0].colour, kClashFirstColour);
  EXPECT_EQ(views[0].colours[0].label, "first: P-1");
  EXPECT_EQ(views[0].colours[1].id, 9u);
  EXPECT_EQ(views[0].colours[1].colour, kClashSecondColour);
  EXPECT_EQ(views[0].colours[1].label, "second: 9");
  std::vector<ReviewView> reread;
  std::string error;
  const std::string text = review_views_json(views, "clash");
  ASSERT_TRUE(parse_review_views(text, reread, error)) << error;
  ASSERT_EQ(reread.size(), 1u);
  EXPECT_EQ(reread[0].colours, views[0].colours);
  // A colour for an object not in the subject, or a malformed colour, is refused.
  std::string bad = text;
  const std::string nine = "\"id\": 9";
  bad.replace(bad.find(nine), nine.size(), "\"id\": 5");
  EXPECT_FALSE(parse_review_views(bad, reread, error));
  EXPECT_NE(error.find("not in 'subject'"), std::string::npos) << error;
  bad = text;
  bad.replace(bad.find("#e12323"), 7, "#e1232");
  EXPECT_FALSE(parse_review_views(bad, reread, error));
  EXPECT_NE(error.find("colours[0].colour"), std::string::npos) << error;
}

TEST(Clash, APrunedSinceRevisionSkipsOnlyTheNaming) {
  const test::TempDir dir;
  const auto store = test::make_store(dir, piping_case(false));
  ASSERT_TRUE(store);
  const ClashReport first = run(*store, dir.str());
  IngestControl keep_one;
  keep_one.keep_revisions = 1;
  ASSERT_TRUE(ingest_objects(*store, piping_case(false), keep_one));  // (nothing changes)
  ASSERT_TRUE(ingest_objects(*store, piping_case(true), keep_one));
  ClashReport second = run(*store, dir.str());
  std::string error, note;
  ASSERT_TRUE(apply_previous(second, first, error)) << error;
  ASSERT_EQ(second.clashes.size(), 1u);
  EXPECT_EQ(second.clashes[0].status, ClashStatus::new_clash);
  const auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_FALSE(name_changed_objects(second, *view, first.revision, note));
  EXPECT_NE(note.find("not named"), std::string::npos) << note;
  EXPECT_EQ(second.clashes[0].changed_id, 0u);
}

TEST(Clash, GeneratedPlantShardsEqualOneRunAndNoOwnPartsReported) {
  const test::TempDir dir;
  const auto store = test::generated_store(dir, 'a');
  ASSERT_TRUE(store);
  const ClashReport whole = run(*store, dir.str());
  for (const Clash& c : whole.clashes) {
    EXPECT_FALSE(c.a.pipeline_id != 0 && c.a.pipeline_id == c.b.pipeline_id) << c.a.tag << " x " << c.b.tag;
  }
  std::vector<ClashReport> shards;
  for (uint32_t i = 0; i < 3; ++i) {
    ClashSettings s;
    s.shard = {i, 3};
    shards.push_back(run(*store, dir.str(), s));
  }
  ClashReport merged;
  std::string error;
  ASSERT_TRUE(merge_reports(shards, merged, error)) << error;
  EXPECT_EQ(clash_report_json(merged), clash_report_json(whole));
  shards.pop_back();
  EXPECT_FALSE(merge_reports(shards, merged, error));
}

TEST(Clash, ReportIsWhatTheDocumentsDumpWrites) {
  // The writer appends each clash itself (no JSON value a clash): its bytes must be the
  // document's dump, for every field, kind and status, and for texts that need escaping.
  ClashReport report;
  report.store_directory = "/data/plant \"one\".store";
  Clash hard;
  hard.id = 0x0123456789abcdefull;
  hard.a = {7, ClashText("/P-1/\"quoted\" \\ tab\t \xc3\xa9"), ObjectClass::pipe, 99};
  hard.b = {9, ClashText(), ObjectClass::structure, 0};
  hard.depth_m = 0.1;
  hard.error_m = 1e-7;
  hard.points_m = {{1.5, -2.25, 1e20}, {0, 0, 0}};
  hard.group = ClashText("bad utf-8 \xff here");
  hard.changed_id = 7;
  Clash clearance;
  clearance.id = 1;
  clearance.kind = ClashKind::clearance;
  clearance.status = ClashStatus::resolved;
  clearance.a = {3, ClashText("A"), ObjectClass::equipment, 0};
  clearance.b = {4, ClashText("B"), ObjectClass::other, 0};
  clearance.distance_m = 0.0123456789;
  clearance.points_m = {{123456.789, 0.001, -0.0}};
  report.clashes = {hard, clearance};
  const std::string text = clash_report_json(report);
  const nlohmann::json document = nlohmann::json::parse(text, nullptr, false);
  ASSERT_FALSE(document.is_discarded());
  EXPECT_EQ(document.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n", text);
  ClashReport back;
  std::string error;
  ASSERT_TRUE(parse_clash_report(text, back, error)) << error;
  EXPECT_EQ(clash_report_json(back), text);
}

TEST(Clash, ReportRoundTripsAndRefusesTruncation) {
  const test::TempDir dir;
  const auto store = test::make_store(dir, piping_case(true));
  ASSERT_TRUE(store);
  const ClashReport report = run(*store, dir.str());
  const std::string text = clash_report_json(report);
  ClashReport back;
  std::string error;
  ASSERT_TRUE(parse_clash_report(text, back, error)) << error;
  EXPECT_EQ(clash_report_json(back), text);
  std::istringstream stream(text);
  ASSERT_TRUE(read_clash_report(stream, back, error)) << error;
  EXPECT_EQ(clash_report_json(back), text);
  ASSERT_GE(report.clashes.size(), 1u);
  // Cut anywhere before its closing brace, the file is refused with a reason, and the output is
  // left as it was.
  const size_t end = text.rfind('}');
  for (size_t cut = 0; cut < end; cut += std::max<size_t>(1, end / 97)) {
    ClashReport untouched;
    untouched.revision = 77;
    EXPECT_FALSE(parse_clash_report(std::string_view(text).substr(0, cut), untouched, error)) << cut;
    EXPECT_FALSE(error.empty());
    EXPECT_EQ(untouched.revision, 77u);
  }
  // A wrong field inside a clash names the clash and the field.
  std::string wrong = text;
  const size_t at = wrong.find("\"depth_m\"");
  ASSERT_NE(at, std::string::npos);
  wrong.replace(at, 9, "\"deep_m\" ");
  EXPECT_FALSE(parse_clash_report(wrong, back, error));
  EXPECT_NE(error.find("clash 0"), std::string::npos) << error;
  EXPECT_NE(error.find("depth_m"), std::string::npos) << error;
  // A count that is not a whole number in range is refused, naming it.
  for (const char* bad : {"-1", "1e30", "2.5", "4294967296"}) {
    std::string wrong_revision = text;
    const size_t r = wrong_revision.find("\"revision\": ");
    ASSERT_NE(r, std::string::npos);
    const size_t value = r + 12, end_of_value = wrong_revision.find_first_of(",\n}", value);
    wrong_revision.replace(value, end_of_value - value, bad);
    EXPECT_FALSE(parse_clash_report(wrong_revision, back, error)) << bad;
    EXPECT_NE(error.find("'revision'"), std::string::npos) << error;
  }
}

// `views --per clash` reads a clashes file keeping only the clashes it makes views of: the
// header as read whole, the selected clashes in the file's order.
TEST(Clash, ReadingKeepsOnlyTheSelectedClashes) {
  ClashReport report;
  report.store_directory = "/data/plant";
  report.revision = 4;
  const auto clash = [](uint64_t id, ClashStatus status, const char* a_tag, const char* group) {
    Clash c;
    c.id = id;
    c.status = status;
    c.a = {id * 2, ClashText(a_tag), ObjectClass::pipe, 0};
    c.b = {id * 2 + 1, ClashText(), ObjectClass::structure, 0};
    c.depth_m = 0.01;
    c.points_m = {{1, 2, 3}};
    c.group = ClashText(group);
    return c;
  };
  report.clashes = {clash(0x11, ClashStatus::new_clash, "/P-101/TUBE-1", "P-101 x B-7"),
                    clash(0x22, ClashStatus::active, "/P-202/TUBE-3", "P-202 x B-7"),
                    clash(0x33, ClashStatus::new_clash, "/P-303/ELBO-2", "P-303 x B-9"),
                    clash(0x44, ClashStatus::resolved, "/P-101/TUBE-9", "P-101 x B-7")};
  const std::string text = clash_report_json(report);
  const auto kept = [&](const ClashViewSelection& selection) {
    std::istringstream in(text);
    ClashReport read;
    std::string error;
    EXPECT_TRUE(read_clash_report(in, read, error, [&](const Clash& c) { return clash_view_selected(c, selection); }))
        << error;
    EXPECT_EQ(read.store_directory, report.store_directory);
    EXPECT_EQ(read.revision, 4u);
    std::vector<uint64_t> ids;
    for (const Clash& c : read.clashes) ids.push_back(c.id);
    return ids;
  };
  using Ids = std::vector<uint64_t>;
  EXPECT_EQ(kept({}), (Ids{0x11, 0x22, 0x33}));  // never a resolved one
  EXPECT_EQ(kept({true, false, ""}), (Ids{0x11, 0x33}));
  EXPECT_EQ(kept({false, true, ""}), (Ids{0x22}));
  EXPECT_EQ(kept({true, true, "/P-101/*"}), (Ids{0x11}));        // a tag
  EXPECT_EQ(kept({true, true, "* x B-7"}), (Ids{0x11, 0x22}));   // the group
  EXPECT_EQ(kept({true, true, "clash-0000000000000033"}), (Ids{0x33}));  // the view name
  EXPECT_EQ(kept({true, true, "103"}), (Ids{0x33}));  // b has no tag: its id (0x33 * 2 + 1)
  EXPECT_EQ(kept({false, true, "/P-101/*"}), (Ids{}));
}

// Runs the program; its exit status, stdout in `out`, stderr in `err`.
int run_plantview(const std::vector<std::string>& args, std::string& out, std::string& err) {
  const test::TempDir scratch;
  std::filesystem::create_directories(scratch.path());
  const std::string o = (scratch.path() / "out").string(), e = (scratch.path() / "err").string();
  std::string command = PLANTVIEW_BIN;
  for (const std::string& a : args) command += " '" + a + "'";
  const int status = std::system((command + " >" + o + " 2>" + e).c_str());
  const auto slurp = [](const std::string& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  out = slurp(o);
  err = slurp(e);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(ClashCommand, RunsSinceMergeAndRefusesBadInput) {
  const test::TempDir dir, scratch;
  std::filesystem::create_directories(scratch.path());
  ASSERT_TRUE(test::make_store(dir, piping_case(true)));
  const std::string s = dir.str(), first = (scratch.path() / "first.json").string(),
                    second = (scratch.path() / "second.json").string();
  std::string out, err;
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--out", first}, out, err), 0) << err;
  EXPECT_NE(out.find("1 clashes (1 hard, 0 clearance): 1 new"), std::string::npos) << out;
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--since", first, "--out", second}, out, err), 0) << err;
  EXPECT_NE(out.find("0 new, 1 active"), std::string::npos) << out;
  {
    // Its view, rendered: the two objects in the clash colours, named in the frame's legend.
    const std::string views = (scratch.path() / "views.json").string(), images = (scratch.path() / "images").string();
    ASSERT_EQ(run_plantview({"views", "--store", s, "--per", "clash", "--clashes", first, "--out", views}, out, err), 0)
        << err;
    ASSERT_EQ(run_plantview({"render", "--store", s, "--views", views, "--size", "160x90", "--out", images}, out, err), 0)
        << err;
    std::ifstream in(scratch.path() / "images" / "stats.jsonl");
    const std::string stats(std::istreambuf_iterator<char>(in), {});
    EXPECT_NE(stats.find("\"key\":\"subjects\""), std::string::npos) << stats;
    EXPECT_NE(stats.find("\"colour\":\"#e12323\",\"objects\":1,\"value\":\"first: "), std::string::npos) << stats;
    EXPECT_NE(stats.find("\"colour\":\"#14afeb\",\"objects\":1,\"value\":\"second: "), std::string::npos) << stats;
  }
  for (const char* shard : {"0/2", "1/2"})
    ASSERT_EQ(run_plantview({"clash", "--store", s, "--shard", shard, "--out",
                             (scratch.path() / (std::string("s") + shard[0] + ".json")).string()}, out, err), 0) << err;
  ASSERT_EQ(run_plantview({"clash", "merge", (scratch.path() / "s0.json").string(), (scratch.path() / "s1.json").string(),
                           "--json"}, out, err), 0) << err;
  std::ifstream f(first);
  EXPECT_EQ(out, std::string(std::istreambuf_iterator<char>(f), {}));

  const std::string never = (scratch.path() / "never.json").string();
  EXPECT_EQ(run_plantview({"clash", "--store", s, "--tolerance", "-1", "--out", never}, out, err), 2);
  EXPECT_EQ(run_plantview({"clash", "--store", s, "--tolerance", "50000", "--out", never}, out, err), 2);
  EXPECT_EQ(run_plantview({"clash", "--store", s, "--between", "NOPE-*", "--and", "pipe", "--out", never}, out, err), 2);
  EXPECT_NE(err.find("NOPE-*"), std::string::npos) << err;
  EXPECT_EQ(run_plantview({"clash", "--store", s, "--between", "pipe", "--out", never}, out, err), 2);
  EXPECT_EQ(run_plantview({"clash", "--store", s, "--shard", "2/2", "--out", never}, out, err), 2);
  // A truncated previous file, and one from another store.
  std::string text;
  {
    std::ifstream in(first);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::string cut = (scratch.path() / "cut.json").string();
  std::ofstream(cut) << text.substr(0, text.size() / 2);
  EXPECT_EQ(run_plantview({"clash", "--store", s, "--since", cut, "--out", never}, out, err), 1);
  EXPECT_NE(err.find("truncated"), std::string::npos) << err;
  const test::TempDir other;
  ASSERT_TRUE(test::make_store(other, piping_case(false)));
  EXPECT_EQ(run_plantview({"clash", "--store", other.str(), "--since", first, "--out", never}, out, err), 1);
  EXPECT_NE(err.find("another store"), std::string::npos) << err;
  // A store without topology (boxes alone): the rules cannot apply.
  const test::TempDir bare;
  ASSERT_TRUE(test::make_store(bare, {planted("box-box", 0, 0.01).a, planted("box-box", 0, 0.01).b}));
  EXPECT_EQ(run_plantview({"clash", "--store", bare.str(), "--out", never}, out, err), 2);
  EXPECT_NE(err.find("no piping topology"), std::string::npos) << err;
  EXPECT_EQ(run_plantview({"clash", "--store", bare.str(), "--include-connected"}, out, err), 0) << err;
  EXPECT_NE(out.find("1 clashes"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(never));
}

std::string slurp_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Every file under `dir` (logs too), by relative path -> bytes.
std::map<std::string, std::string> files_under(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[std::filesystem::relative(e.path(), dir).string()] = slurp_file(e.path());
  return files;
}

// `views --per clash --status ... --select ...`: the views of the clashes asked for; a status
// that is not new or active, or either option without --per clash, is a usage error; a glob
// matching no clash fails naming it.
TEST(ClashCommand, ViewsPerClashMakeViewsOfTheChosenStatusesAndTags) {
  const test::TempDir dir, scratch;
  std::filesystem::create_directories(scratch.path());
  ASSERT_TRUE(test::make_store(dir, piping_case(true)));
  const std::string s = dir.str(), first = (scratch.path() / "first.json").string(),
                    second = (scratch.path() / "second.json").string(),
                    views = (scratch.path() / "views.json").string();
  std::string out, err;
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--out", first}, out, err), 0) << err;
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--since", first, "--out", second}, out, err), 0) << err;
  ClashReport report;
  std::string error;
  std::ifstream in(second);
  ASSERT_TRUE(read_clash_report(in, report, error)) << error;
  ASSERT_EQ(report.clashes.size(), 1u);
  const Clash& clash = report.clashes[0];
  ASSERT_EQ(clash.status, ClashStatus::active);
  const auto views_of = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"views", "--store", s, "--per", "clash", "--clashes", second, "--out", views};
    args.insert(args.end(), extra.begin(), extra.end());
    std::filesystem::remove(views);
    const int status = run_plantview(args, out, err);
    EXPECT_EQ(status, 0) << err;
    const nlohmann::json written = nlohmann::json::parse(slurp_file(views), nullptr, false);
    EXPECT_TRUE(written.is_object() && written["views"].is_array()) << slurp_file(views);
    return written.is_object() && written["views"].is_array() ? written["views"].size() : size_t(99);
  };
  EXPECT_EQ(views_of({}), 1u);
  EXPECT_EQ(views_of({"--status", "new"}), 0u);  // (after a revision: nothing new to review)
  EXPECT_NE(err.find("no clash to review"), std::string::npos) << err;
  EXPECT_EQ(views_of({"--status", "active"}), 1u);
  EXPECT_EQ(views_of({"--status", "new,active", "--select", "clash-*"}), 1u);
  ASSERT_FALSE(clash.a.tag.empty());
  EXPECT_EQ(views_of({"--select", clash.a.tag.str()}), 1u);
  EXPECT_NE(out.find("\"views\":1,\"subjects\":1,"), std::string::npos) << out;

  const std::string never = (scratch.path() / "never.json").string();
  EXPECT_EQ(run_plantview({"views", "--store", s, "--per", "clash", "--clashes", second, "--select", "NOPE-*", "--out",
                           never}, out, err), 1);
  EXPECT_NE(err.find("'NOPE-*' matches none of the 1 unresolved clashes"), std::string::npos) << err;
  EXPECT_EQ(run_plantview({"views", "--store", s, "--per", "clash", "--clashes", second, "--status", "resolved",
                           "--out", never}, out, err), 2);
  EXPECT_NE(err.find("--status: 'resolved'"), std::string::npos) << err;
  EXPECT_EQ(run_plantview({"views", "--store", s, "--per", "equipment", "--status", "new", "--out", never}, out, err), 2);
  EXPECT_NE(err.find("--per clash"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(never));
}

TEST(ClashCommand, FarmSinceMarksARevisionsNewClashAsOneProcessDoes) {
  const test::TempDir dir, scratch;
  std::filesystem::create_directories(scratch.path());
  auto store = test::make_store(dir, piping_case(false));
  ASSERT_TRUE(store);
  const std::string s = dir.str(), first = (scratch.path() / "first.json").string(),
                    single = (scratch.path() / "single.json").string();
  const std::filesystem::path job = scratch.path() / "job";
  std::string out, err;
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--out", first}, out, err), 0) << err;
  // The revision moves the pipe into the beam.
  ASSERT_TRUE(ingest_objects(*store, piping_case(true)));
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--since", first, "--out", single}, out, err), 0) << err;
  ASSERT_EQ(run_plantview({"farm", "submit", "--clash", "--scheduler", "local", "--tasks", "2", "--store", s,
                           "--since", first, "--out", job.string()}, out, err), 0) << err;
  // (its summary: one JSON object, keys sorted)
  EXPECT_NE(out.find("{\"active\":0,\"clash\":true,\"clashes\":1,\"complete\":true,\"new\":1,\"resolved\":0,"
                     "\"shards_done\":2,\"since\":\"" + first + "\",\"tasks\":2}"), std::string::npos) << out;
  EXPECT_EQ(slurp_file(job / "clashes.json"), slurp_file(single));
  EXPECT_EQ(slurp_file(job / "clash-since.json"), slurp_file(first));
  ClashReport merged;
  std::string error;
  ASSERT_TRUE(parse_clash_report(slurp_file(job / "clashes.json"), merged, error)) << error;
  ASSERT_EQ(merged.clashes.size(), 1u);
  EXPECT_EQ(merged.clashes[0].status, ClashStatus::new_clash);
  EXPECT_EQ(merged.clashes[0].changed_tag().view().rfind("/P-1/", 0), 0u) << merged.clashes[0].changed_tag();
  // The next job in the same directory, since its own clashes.json: the same clash, active.
  ASSERT_EQ(run_plantview({"farm", "submit", "--clash", "--scheduler", "local", "--tasks", "2", "--store", s,
                           "--since", (job / "clashes.json").string(), "--out", job.string()}, out, err), 0) << err;
  EXPECT_NE(out.find("\"active\":1,"), std::string::npos) << out;
  EXPECT_NE(out.find("\"new\":0,"), std::string::npos) << out;
  ASSERT_TRUE(parse_clash_report(slurp_file(job / "clashes.json"), merged, error)) << error;
  ASSERT_EQ(merged.clashes.size(), 1u);
  EXPECT_EQ(merged.clashes[0].status, ClashStatus::active);
  ASSERT_EQ(run_plantview({"farm", "status", job.string()}, out, err), 0) << err;
  EXPECT_NE(out.find("2 of 2 shards done; clashes.json: 1 clashes (since "), std::string::npos) << out;
  EXPECT_NE(out.find(": 0 new, 1 active, 0 resolved)"), std::string::npos) << out;
  // A job without --since leaves no copy behind to be taken for one.
  ASSERT_EQ(run_plantview({"farm", "submit", "--clash", "--scheduler", "local", "--tasks", "2", "--store", s,
                           "--out", job.string()}, out, err), 0) << err;
  EXPECT_FALSE(std::filesystem::exists(job / "clash-since.json"));
  EXPECT_EQ(out.find("\"new\""), std::string::npos) << out;
}

TEST(ClashCommand, FarmSubmitRefusesWhatClashRefusesAndLeavesTheDirectoryAsItWas) {
  const test::TempDir dir, scratch, other, bare;
  std::filesystem::create_directories(scratch.path());
  ASSERT_TRUE(test::make_store(dir, piping_case(true)));
  ASSERT_TRUE(test::make_store(other, piping_case(false)));
  ASSERT_TRUE(test::make_store(bare, {planted("box-box", 0, 0.01).a, planted("box-box", 0, 0.01).b}));
  const std::string s = dir.str(), first = (scratch.path() / "first.json").string(),
                    elsewhere = (scratch.path() / "elsewhere.json").string(),
                    cut = (scratch.path() / "cut.json").string();
  const std::filesystem::path job = scratch.path() / "job", never = scratch.path() / "never";
  std::string out, err;
  ASSERT_EQ(run_plantview({"clash", "--store", s, "--out", first}, out, err), 0) << err;
  ASSERT_EQ(run_plantview({"clash", "--store", other.str(), "--out", elsewhere}, out, err), 0) << err;
  std::ofstream(cut) << slurp_file(first).substr(0, slurp_file(first).size() / 2);
  ASSERT_EQ(run_plantview({"farm", "submit", "--clash", "--scheduler", "local", "--tasks", "2", "--store", s,
                           "--since", first, "--out", job.string()}, out, err), 0) << err;
  const auto before = files_under(job);
  ASSERT_TRUE(before.count("clashes.json") && before.count("clash-job.json") && before.count("clash-since.json"));

  const std::vector<std::tuple<std::vector<std::string>, int, std::string>> cases = {
      {{"--tolerance", "-1"}, 2, "--tolerance must be from 0"},
      {{"--tolerance", "50000"}, 2, "--tolerance must be from 0"},
      {{"--tolerance", "1mm"}, 2, "--tolerance: expected millimetres, got '1mm'"},
      {{"--clearance", "nan"}, 2, "--clearance must be from 0"},
      {{"--threads", "two"}, 2, "--threads: expected a whole number, got 'two'"},
      {{"--between", "NOPE-*", "--and", "pipe"}, 2, "--between 'NOPE-*' matches no object"},
      {{"--between", "pipe", "--and", "NADA"}, 2, "--and 'NADA' matches no object"},
      {{"--between", "pipe"}, 2, "--between and --and go together"},
      {{"--since", cut}, 1, "truncated"},
      {{"--since", elsewhere}, 1, "another store"},
      {{"--since", first, "--tolerance", "5"}, 1, "other settings"},
      {{"--since", (scratch.path() / "missing.json").string()}, 1, "cannot read"},
  };
  for (const auto& [extra, status, message] : cases) {
    std::vector<std::string> args = {"farm", "submit", "--clash", "--scheduler", "local", "--tasks", "2",
                                     "--store", s, "--out", job.string()};
    args.insert(args.end(), extra.begin(), extra.end());
    EXPECT_EQ(run_plantview(args, out, err), status) << extra[0] << " " << extra[1] << ": " << err;
    EXPECT_NE(err.find("farm submit --clash: "), std::string::npos) << err;
    EXPECT_NE(err.find(message), std::string::npos) << err;
    EXPECT_EQ(files_under(job), before) << extra[0] << " " << extra[1] << " changed the job's directory";
  }
  // A store without topology; --since on a render job.
  EXPECT_EQ(run_plantview({"farm", "submit", "--clash", "--scheduler", "local", "--tasks", "2", "--store",
                           bare.str(), "--out", never.string()}, out, err), 2);
  EXPECT_NE(err.find("no piping topology"), std::string::npos) << err;
  EXPECT_EQ(run_plantview({"farm", "submit", "--scheduler", "local", "--tasks", "1", "--views", first, "--store", s,
                           "--since", first, "--out", never.string()}, out, err), 2);
  EXPECT_NE(err.find("--since is a clash job's option"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(never));
}

}  // namespace
}  // namespace plantview
