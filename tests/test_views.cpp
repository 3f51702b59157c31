// Review views: camera fitting, the views file, subjects from a store, the views command,
// default cameras and walkthroughs that stay in the plant (judged on rendered images).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "plantview/camera.h"
#include "plantview/review.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/image_fill.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

// The box's projection, found independently of fit_camera: points sampled densely along the
// box's 12 edges, projected with glm's own lookAt and perspective. Normalised device
// coordinates, -1..1 across the frame.
struct Projected {
  double min_x = INFINITY, max_x = -INFINITY, min_y = INFINITY, max_y = -INFINITY;
  double fill_x() const { return 0.5 * (max_x - min_x); }
  double fill_y() const { return 0.5 * (max_y - min_y); }
  double centre_x() const { return 0.5 * (max_x + min_x); }
  double centre_y() const { return 0.5 * (max_y + min_y); }
  bool behind = false;  // some point was at or behind the eye
};

Projected project_box(const DAabb& b, const Camera& c, double aspect) {
  const glm::dmat4 view = glm::lookAt(c.eye_m, c.target_m, c.up);
  const glm::dmat4 projection = glm::perspective(glm::radians(c.fov_deg), aspect, 0.01, 1e7);
  Projected out;
  const int steps = 64;
  for (int edge = 0; edge < 12; ++edge) {
    const int axis = edge / 4;  // the axis the edge runs along; the other two at min or max
    for (int s = 0; s <= steps; ++s) {
      glm::dvec3 p;
      const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
      p[axis] = glm::mix(b.min[axis], b.max[axis], double(s) / steps);
      p[a1] = edge & 1 ? b.max[a1] : b.min[a1];
      p[a2] = edge & 2 ? b.max[a2] : b.min[a2];
      const glm::dvec4 clip = projection * view * glm::dvec4(p, 1.0);
      if (clip.w <= 0) {
        out.behind = true;
        continue;
      }
      out.min_x = std::min(out.min_x, clip.x / clip.w);
      out.max_x = std::max(out.max_x, clip.x / clip.w);
      out.min_y = std::min(out.min_y, clip.y / clip.w);
      out.max_y = std::max(out.max_y, clip.y / clip.w);
    }
  }
  return out;
}

DAabb box(glm::dvec3 min, glm::dvec3 max) {
  DAabb b;
  b.extend(min);
  b.extend(max);
  return b;
}

// ---- fit_camera ----

TEST(FitCamera, SubjectFillsTheAskedShareOfTheBindingAxisAndIsCentred) {
  const std::vector<DAabb> subjects = {
      box({0, 0, 0}, {1, 1, 1}),            // a cube
      box({-40, 3, 0}, {60, 5, 2}),         // a long low pipe rack
      box({10, 10, 0}, {11, 11, 30}),       // a tall column
      box({1000, -2000, 5}, {1003, -1990, 6}),  // far from the origin
      box({0, 0, 0}, {20, 20, 0}),          // flat: no height
  };
  const std::vector<glm::dvec3> directions = {
      {-1, -1, -0.8}, {1, 0, -0.3}, {0, 1, -0.3}, {-0.2, 0.1, -1}, {0, 0, -1}};
  for (const double aspect : {16.0 / 9.0, 1.0, 0.5}) {
    for (size_t s = 0; s < subjects.size(); ++s) {
      for (size_t d = 0; d < directions.size(); ++d) {
        SCOPED_TRACE("aspect " + std::to_string(aspect) + " subject " + std::to_string(s) +
                     " direction " + std::to_string(d));
        const Camera c = fit_camera(subjects[s], directions[d], aspect, 50.0, 0.75);
        std::string error;
        ASSERT_TRUE(validate_camera(c, error)) << error;
        const Projected p = project_box(subjects[s], c, aspect);
        ASSERT_FALSE(p.behind);
        // The corners bound the edges' projection, so the sampled fill is exact (to the
        // sampling) on the binding axis, and never more elsewhere.
        EXPECT_NEAR(std::max(p.fill_x(), p.fill_y()), 0.75, 0.003);
        EXPECT_LE(std::min(p.fill_x(), p.fill_y()), 0.7501);
        EXPECT_NEAR(p.centre_x(), 0.0, 0.003);
        EXPECT_NEAR(p.centre_y(), 0.0, 0.003);
        // It looks the way it was asked to.
        const glm::dvec3 view = glm::normalize(c.target_m - c.eye_m);
        EXPECT_GT(glm::dot(view, glm::normalize(directions[d])), 0.999999);
      }
    }
  }
}

TEST(FitCamera, AWiderFrameMovesTheEyeNoFartherThanTheTallerOne) {
  const DAabb b = box({0, 0, 0}, {10, 2, 3});
  const glm::dvec3 direction(-1, -1, -0.8);
  const Camera wide = fit_camera(b, direction, 16.0 / 9.0, 50.0, 0.75);
  const Camera tall = fit_camera(b, direction, 9.0 / 16.0, 50.0, 0.75);
  const glm::dvec3 centre(5, 1, 1.5);
  EXPECT_LE(glm::length(wide.eye_m - centre), glm::length(tall.eye_m - centre));
}

// ---- the views file ----

std::vector<ReviewView> sample_views() {
  ReviewView a;
  a.name = "P-101A";
  a.title = "Pump P-101A";
  a.kind = "equipment";
  a.camera.eye_m = {1.5, -2.25, 3.125};
  a.camera.target_m = {0.1, 0.2, 0.3};
  a.camera.up = {0, 0, 1};
  a.camera.fov_deg = 42.5;
  a.aspect = 16.0 / 9.0;
  a.subject = {12, 13, 14, uint64_t(1) << 60};
  a.attributes = {{"type", "PUMP"}, {"tag", "P-101A"}, {"description", "Feed pump, \"A\" side"}};
  a.section.planes = {ClipPlane{{0.5, 1.25, 12.0}, {0, 0, 1}}, ClipPlane{{3, 0, 0}, {-1, 0, 0}}};
  a.section.has_box = true;
  a.section.box.min = {-1, -2, -3};
  a.section.box.max = {4, 5, 6.5};
  a.style.colour_by = "Material";
  a.style.hide = {"structure", "HV-*"};
  a.style.only = {"P-1*"};
  ReviewView b;
  b.name = "unit_2.zone-B";
  b.title = "Zone B of unit 2";
  b.kind = "area";
  b.camera.eye_m = {-100, 50, 20};
  b.camera.target_m = {0, 0, 0};
  b.aspect = 1.0;
  b.subject = {};
  return {a, b};
}

void expect_same(const std::vector<ReviewView>& a, const std::vector<ReviewView>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].name, b[i].name);
    EXPECT_EQ(a[i].title, b[i].title);
    EXPECT_EQ(a[i].kind, b[i].kind);
    EXPECT_EQ(a[i].camera, b[i].camera);  // exact: the writer keeps every bit
    EXPECT_EQ(a[i].aspect, b[i].aspect);
    EXPECT_EQ(a[i].subject, b[i].subject);
    EXPECT_EQ(a[i].attributes, b[i].attributes);  // in order
    EXPECT_EQ(a[i].section, b[i].section);
    EXPECT_EQ(a[i].style, b[i].style);
  }
}

TEST(ViewsFile, WhatIsWrittenReadsBackTheSameInTheSameOrder) {
  const std::string json = review_views_json(sample_views(), "equipment");
  std::vector<ReviewView> read;
  std::string error;
  ASSERT_TRUE(parse_review_views(json, read, error)) << error;
  expect_same(sample_views(), read);
}

TEST(ViewsFile, AttributesThatAreNotUtf8AreWrittenWithReplacementCharacters) {
  std::vector<ReviewView> views = sample_views();
  views[0].attributes = {{"description", "Pumpe f\xfcr K\xfchlwasser"}};  // Latin-1 bytes
  std::vector<ReviewView> read;
  std::string error;
  ASSERT_TRUE(parse_review_views(review_views_json(views, "equipment"), read, error)) << error;
  EXPECT_EQ(read[0].attributes[0].second, "Pumpe f\xef\xbf\xbdr K\xef\xbf\xbdhlwasser");
}

TEST(ViewsFile, MatchesTheAgreedLayout) {
  const std::string json = R"({"version": 1, "per": "equipment", "views": [
    {"name": "P-101A", "title": "Pump P-101A", "kind": "equipment",
     "camera": {"eye": [1, 2, 3], "target": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 50},
     "aspect": 1.7778, "subject": [12, 13, 14],
     "attributes": {"tag": "P-101A", "type": "PUMP", "description": "Feed"}}]})";
  std::vector<ReviewView> read;
  std::string error;
  ASSERT_TRUE(parse_review_views(json, read, error)) << error;
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].camera.eye_m, glm::dvec3(1, 2, 3));
  EXPECT_EQ(read[0].camera.fov_deg, 50.0);
  EXPECT_EQ(read[0].aspect, 1.7778);
  EXPECT_EQ(read[0].subject, (std::vector<uint64_t>{12, 13, 14}));
  ASSERT_EQ(read[0].attributes.size(), 3u);
  EXPECT_EQ(read[0].attributes[0], (std::pair<std::string, std::string>{"tag", "P-101A"}));
  EXPECT_EQ(read[0].attributes[2].first, "description");
}

TEST(ViewsFile, EveryTruncationIsRejectedAndLeavesTheOutputAlone) {
  const std::string json = review_views_json(sample_views(), "area");
  const std::vector<ReviewView> before = {ReviewView{}};
  const size_t whole = json.rfind('}') + 1;  // what follows is the final newline
  for (size_t n = 0; n < whole; ++n) {
    std::vector<ReviewView> out = before;
    std::string error;
    EXPECT_FALSE(parse_review_views(std::string_view(json).substr(0, n), out, error)) << n;
    EXPECT_FALSE(error.empty()) << n;
    EXPECT_EQ(out.size(), 1u) << n;
  }
}

// The sample file changed by `edit` (on its JSON), and the parser's error for it.
std::string error_after(const std::function<void(nlohmann::ordered_json&)>& edit) {
  auto json = nlohmann::ordered_json::parse(review_views_json(sample_views(), "equipment"));
  edit(json);
  std::vector<ReviewView> out;
  std::string error;
  EXPECT_FALSE(parse_review_views(json.dump(), out, error)) << json.dump();
  return error;
}

TEST(ViewsFile, ErrorsNameTheViewAndTheField) {
  using Json = nlohmann::ordered_json;
  EXPECT_EQ(error_after([](Json& j) { j["version"] = 2; }), "views file: 'version' must be 1");
  EXPECT_EQ(error_after([](Json& j) { j["per"] = "valve"; }),
            "views file: 'per' must be one of overview, equipment, pipeline, area, change, clash");
  EXPECT_EQ(error_after([](Json& j) { j["views"][1]["kind"] = "zone"; }),
            "views file: view 1 ('unit_2.zone-B'): 'kind' is 'zone' (overview, equipment, pipeline, area, change, clash)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["name"] = "../P-101A"; }),
            "views file: view 0 ('../P-101A'): 'name' must be 1 to 200 of A-Z a-z 0-9 . _ - and not "
            "start with '.'");
  EXPECT_EQ(error_after([](Json& j) { j["views"][1]["name"] = "P-101A"; }),
            "views file: view 1 ('P-101A'): the name is used by an earlier view");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["camera"]["eye"][0] = "x"; }),
            "views file: view 0 ('P-101A'): 'camera.eye' must be a list of 3 numbers");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["camera"]["target"].get_ref<Json::array_t&>().pop_back(); }),
            "views file: view 0 ('P-101A'): 'camera.target' must be a list of 3 numbers");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["camera"].erase("target"); }),
            "views file: view 0 ('P-101A'): 'camera.target' is missing");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["camera"]["centre"] = Json::array({0, 0, 0}); }),
            "views file: view 0 ('P-101A'): unknown key 'camera.centre' (eye, target, up, fov_deg)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["camera"]["fov_deg"] = 200; }),
            "views file: view 0 ('P-101A'): camera: fov must be in (0, 179) degrees");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["camera"]["target"] = j["views"][0]["camera"]["eye"]; }),
            "views file: view 0 ('P-101A'): camera: the eye is on the target");
  EXPECT_EQ(error_after([](Json& j) { j["views"][1]["aspect"] = -1.0; }),
            "views file: view 1 ('unit_2.zone-B'): 'aspect' must be a positive number (width / height)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["subject"][0] = -12; }),
            "views file: view 0 ('P-101A'): 'subject[0]' must be an object id (an integer >= 0)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["subject"][1] = 1.5; }),
            "views file: view 0 ('P-101A'): 'subject[1]' must be an object id (an integer >= 0)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["attributes"]["tag"] = 7; }),
            "views file: view 0 ('P-101A'): 'attributes.tag' must be a string");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0].erase("title"); }),
            "views file: view 0 ('P-101A'): 'title' is missing");
  EXPECT_EQ(error_after([](Json& j) { j["views"][1]["aspekt"] = 1.0; }),
            "views file: view 1 ('unit_2.zone-B'): unknown key 'aspekt' (name, title, kind, camera, "
            "aspect, subject, attributes, section, style, changes, colours)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["changes"] = "5..3"; }),
            "views file: view 0 ('P-101A'): 'changes': '5..3': the first revision must come before "
            "the second");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["changes"] = 3; }),
            "views file: view 0 ('P-101A'): 'changes' must be a string (R1 or R1..R2)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["section"]["planes"][1]["normal"] = Json::array({0, 0, 0}); }),
            "views file: view 0 ('P-101A'): 'section.planes[1].normal' has no direction (zero length)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["section"]["box"]["min"][2] = 7.0; }),
            "views file: view 0 ('P-101A'): 'section.box' has min above max on an axis");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["section"]["slab"] = 2; }),
            "views file: view 0 ('P-101A'): unknown key 'section.slab' (planes, box, capped)");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["style"]["hide"][0] = 3; }),
            "views file: view 0 ('P-101A'): 'style.hide[0]' must be a non-empty string");
  EXPECT_EQ(error_after([](Json& j) { j["views"][0]["style"]["colour"] = "x"; }),
            "views file: view 0 ('P-101A'): unknown key 'style.colour' (colour_by, hide, only)");
  EXPECT_EQ(error_after([](Json& j) { j["extra"] = 1; }),
            "views file: unknown key 'extra' (version, per, views)");
}

TEST(ViewFilters, ClipPlanesAndBoxesParseAndRejectWhatCannotCut) {
  ClipPlane plane;
  std::string error;
  ASSERT_TRUE(parse_clip_plane("1,2,3,0,0,2", "--clip", plane, error)) << error;
  EXPECT_EQ(plane.point_m, glm::dvec3(1, 2, 3));
  EXPECT_EQ(plane.normal, glm::dvec3(0, 0, 1));
  EXPECT_FALSE(parse_clip_plane("1,2,3,0,0,0", "--clip", plane, error));
  EXPECT_EQ(error, "--clip: the plane's normal (0.000000, 0.000000, 0.000000) has no direction, in '1,2,3,0,0,0'");
  EXPECT_FALSE(parse_clip_plane("1,2,3,0,0", "clip", plane, error));
  EXPECT_EQ(error, "clip: expected PX,PY,PZ,NX,NY,NZ (6 numbers separated by commas), got '1,2,3,0,0'");
  EXPECT_FALSE(parse_clip_plane("1,2,3,0,0,1,", "clip", plane, error));
  EXPECT_FALSE(parse_clip_plane("1,2,nan,0,0,1", "clip", plane, error));
  DAabb box;
  ASSERT_TRUE(parse_section_box("-1,-2,-3,1,2,3", "--section-box", box, error)) << error;
  EXPECT_EQ(box.max, glm::dvec3(1, 2, 3));
  EXPECT_FALSE(parse_section_box("0,0,5,1,1,4", "--section-box", box, error));
  EXPECT_EQ(error, "--section-box: the box's min z (5.000000) is above its max (4.000000), in '0,0,5,1,1,4'");
  std::vector<std::string> words;
  ASSERT_TRUE(parse_word_list(" structure, P-*,,", "--hide", words, error)) << error;
  EXPECT_EQ(words, (std::vector<std::string>{"structure", "P-*"}));
  EXPECT_FALSE(parse_word_list(",", "--hide", words, error));
}

TEST(ViewFilters, BoundsWhollyOnTheClippedSideAreRemovedAndOthersKept) {
  Section plan;  // cut away all above 12 m
  plan.planes.push_back(ClipPlane{{0, 0, 12}, {0, 0, 1}});
  const auto box = [](glm::dvec3 min, glm::dvec3 max) {
    DAabb b;
    b.min = min;
    b.max = max;
    return b;
  };
  EXPECT_TRUE(section_removes_all(plan, box({0, 0, 12.5}, {1, 1, 14})));
  EXPECT_FALSE(section_removes_all(plan, box({0, 0, 11}, {1, 1, 14})));
  EXPECT_FALSE(section_keeps_all(plan, box({0, 0, 11}, {1, 1, 14})));
  EXPECT_TRUE(section_keeps_all(plan, box({0, 0, 1}, {1, 1, 12})));
  EXPECT_TRUE(section_removes(plan, {0, 0, 12.001}));
  EXPECT_FALSE(section_removes(plan, {0, 0, 12}));
  Section slab;  // a 2 m slab kept by a box
  slab.has_box = true;
  slab.box = box({-100, -100, 4}, {100, 100, 6});
  EXPECT_TRUE(section_removes_all(slab, box({0, 0, 7}, {1, 1, 8})));
  EXPECT_FALSE(section_removes_all(slab, box({0, 0, 5}, {1, 1, 8})));
  EXPECT_TRUE(section_keeps_all(slab, box({0, 0, 4.5}, {1, 1, 5.5})));
  Section oblique;  // 45 degrees: a box touching the plane by its corner is not wholly removed
  oblique.planes.push_back(ClipPlane{{0, 0, 0}, glm::normalize(glm::dvec3(1, 1, 0))});
  EXPECT_FALSE(section_removes_all(oblique, box({0, 0, 0}, {1, 1, 1})));
  EXPECT_TRUE(section_removes_all(oblique, box({0.01, 0.01, 0}, {1, 1, 1})));
  EXPECT_FALSE(section_removes_all(oblique, box({-1, 0.1, 0}, {0, 1, 1})));
}

TEST(ViewsFile, AnEmptyListOrANonObjectIsRejected) {
  std::vector<ReviewView> out;
  std::string error;
  EXPECT_FALSE(parse_review_views(R"({"version": 1, "per": "area", "views": []})", out, error));
  EXPECT_EQ(error, "views file: the list of views is empty");
  EXPECT_FALSE(parse_review_views("[]", out, error));
  EXPECT_EQ(error, "views file: not a JSON object");
  EXPECT_FALSE(parse_review_views(R"({"version": 1, "per": "area", "views": [3]})", out, error));
  EXPECT_EQ(error, "views file: view 0 is not an object");
}

TEST(ViewNames, OnlyFileNameSafeNamesPass) {
  for (const char* ok : {"P-101A", "a", "unit_2.zone-B", "3"}) EXPECT_TRUE(is_safe_view_name(ok)) << ok;
  for (const char* bad : {"", ".", "..", ".hidden", "a/b", "a b", "a\\b", "P\xc3\xa9"})
    EXPECT_FALSE(is_safe_view_name(bad)) << bad;
  EXPECT_TRUE(is_safe_view_name(std::string(200, 'x')));
  EXPECT_FALSE(is_safe_view_name(std::string(201, 'x')));
}

// ---- review views of a store ----

namespace fs = std::filesystem;
using test::TempDir;

Object box_object(const std::string& name, ObjectClass cls, glm::dvec3 centre, glm::vec3 size,
                  std::vector<Attribute> attributes = {}) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = cls;
  o.origin_m = centre;
  o.primitives.push_back(Primitive{Placement{}, Box{size.x, size.y, size.z}});
  o.attributes = std::move(attributes);
  return o;
}

using test::make_store;

std::vector<ReviewView> views_of(const Store& store, ReviewViewOptions options,
                                 ReviewViewsSummary* summary = nullptr) {
  std::vector<ReviewView> views;
  ReviewViewsSummary ignored;
  std::string error;
  EXPECT_TRUE(make_review_views(store, options, views, summary ? *summary : ignored, error)) << error;
  return views;
}

ReviewViewOptions per(const std::string& kind, int sides = 1) {
  ReviewViewOptions o;
  o.per = kind;
  o.sides = sides;
  return o;
}

bool inside(const DAabb& b, const glm::dvec3& p) {
  return p.x > b.min.x && p.x < b.max.x && p.y > b.min.y && p.y < b.max.y && p.z > b.min.z &&
         p.z < b.max.z;
}

// Whether the segment a-b passes through box `b` (dense sampling: an oracle apart from the
// placement's slab test).
bool crosses(const DAabb& box, const glm::dvec3& a, const glm::dvec3& b) {
  for (int i = 0; i <= 2000; ++i)
    if (inside(box, glm::mix(a, b, i / 2000.0))) return true;
  return false;
}

// An RVM equipment item without a tag ("/-ART1105BA-", as PDMS names it) has one name in its
// view's file name, title and caption: the plant's name without the path's '/'.
TEST(ReviewViews, AnUntaggedItemIsNamedAsThePlantNamesItEverywhere) {
  TempDir dir;
  auto store = make_store(dir, {box_object("/-ART1105BA-", ObjectClass::equipment, {0, 0, 1}, {1, 1, 2}),
                                box_object("/PS/WD1/E 7", ObjectClass::equipment, {9, 0, 1}, {1, 1, 2})});
  ASSERT_TRUE(store);
  const auto views = views_of(*store, per("equipment"));
  ASSERT_EQ(views.size(), 2u);
  EXPECT_EQ(views[0].name, "-ART1105BA-");
  EXPECT_EQ(views[0].title, "Equipment -ART1105BA-");
  EXPECT_EQ(views[0].attributes[0], (std::pair<std::string, std::string>{"tag", "-ART1105BA-"}));
  EXPECT_TRUE(is_safe_view_name(views[0].name));
  EXPECT_EQ(views[1].name, "PS-WD1-E-7");
  EXPECT_EQ(views[1].attributes[0], (std::pair<std::string, std::string>{"tag", "PS/WD1/E 7"}));
}

TEST(ReviewViews, NamesAreSafeUniqueAndTheSameOnEveryRun) {
  TempDir dir;
  std::vector<Object> objects;
  // Three tags that make the same safe name, one with a path in it, and one without a tag.
  for (const char* tag : {"P 101", "P/101", "P-101", "../etc/passwd"})
    objects.push_back(box_object(std::string("/EQ-") + tag, ObjectClass::equipment,
                                 {10.0 * objects.size(), 0, 1}, {1, 1, 2}, {{"Tag", tag}, {"Type", "Pump"}}));
  objects.push_back(box_object("/V-1", ObjectClass::equipment, {60, 0, 1}, {2, 2, 2}));
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  const auto views = views_of(*store, per("equipment"));
  std::vector<std::string> names;
  for (const auto& v : views) names.push_back(v.name);
  // Sorted by tag (a name without a tag as the plant names it, without the path's '/'):
  // "../etc/passwd" < "P 101" < "P-101" < "P/101" < "V-1".
  EXPECT_EQ(names, (std::vector<std::string>{"etc-passwd", "P-101", "P-101-2", "P-101-3", "V-1"}));
  EXPECT_EQ(views[1].title, "Pump P 101");
  EXPECT_EQ(views[1].attributes[0], (std::pair<std::string, std::string>{"tag", "P 101"}));
  EXPECT_EQ(views[4].title, "Equipment V-1");
  EXPECT_EQ(views[4].attributes[0], (std::pair<std::string, std::string>{"tag", "V-1"}));
  EXPECT_EQ(views_of(*store, per("equipment"))[3].camera, views[3].camera);

  const auto sides = views_of(*store, per("equipment", 4));
  ASSERT_EQ(sides.size(), 4 * views.size());
  std::set<std::string> unique;
  for (const auto& v : sides) {
    EXPECT_TRUE(is_safe_view_name(v.name)) << v.name;
    unique.insert(v.name);
  }
  EXPECT_EQ(unique.size(), sides.size());
  EXPECT_EQ(sides[0].name, "etc-passwd-N");
  EXPECT_EQ(sides[19].name, "V-1-W");
  // What the file says reads back.
  std::vector<ReviewView> read;
  std::string error;
  ASSERT_TRUE(parse_review_views(review_views_json(sides, "equipment"), read, error)) << error;
  EXPECT_EQ(read.size(), sides.size());
}

TEST(ReviewViews, SelectMatchingNothingIsAnErrorThatSaysSo) {
  TempDir dir;
  auto store = make_store(dir, {box_object("/P-1", ObjectClass::equipment, {0, 0, 1}, {1, 1, 2})});
  ASSERT_TRUE(store);
  ReviewViewOptions options = per("equipment");
  options.select = "K-*";
  std::vector<ReviewView> views;
  ReviewViewsSummary summary;
  std::string error;
  EXPECT_FALSE(make_review_views(*store, options, views, summary, error));
  EXPECT_EQ(error, "--select 'K-*' matches none of the 1 equipment in " + dir.str());
  options.select = "P-*";
  EXPECT_TRUE(make_review_views(*store, options, views, summary, error)) << error;
  EXPECT_EQ(views.size(), 1u);
  EXPECT_FALSE(make_review_views(*store, per("pipeline"), views, summary, error));
  EXPECT_EQ(error, dir.str() + ": the store has no pipelines");
}

// A pump on the ground, and walls and columns where its views would stand or look through.
TEST(ReviewViews, TheEyeStandsOutsideOtherObjectsWithAnOpenLineToTheSubject) {
  const DAabb pump_box{{-1, -0.5, 0}, {1, 0.5, 1.5}};
  const glm::dvec3 pump_centre(0, 0, 0.75);
  const Camera first = fit_camera(pump_box, isometric_direction(), 16.0 / 9.0, 50.0, kReviewFill);

  TempDir dir;
  std::vector<Object> objects = {box_object("/P-1", ObjectClass::equipment, pump_centre, {2, 1, 1.5})};
  // A wall 0.4 m thick around the first fit's eye, and a column on the line halfway to it.
  objects.push_back(box_object("/WALL", ObjectClass::structure, first.eye_m, {8, 0.4f, 12}));
  const glm::dvec3 halfway = pump_centre + 0.5 * (first.eye_m - pump_centre);
  objects.push_back(box_object("/COLUMN", ObjectClass::structure, {halfway.x, halfway.y, 4}, {1.5, 1.5, 8}));
  // The mirror quadrant (eye at +x, -y) walled off too: the placement must look further.
  objects.push_back(box_object("/WALL-2", ObjectClass::structure,
                               {-first.eye_m.x, first.eye_m.y, first.eye_m.z}, {0.4f, 8, 12}));
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  ReviewViewsSummary summary;
  const auto views = views_of(*store, per("equipment"), &summary);
  ASSERT_EQ(views.size(), 1u);
  EXPECT_EQ(summary.moved, 1u);
  EXPECT_EQ(summary.obstructed, 0u);
  const Camera& c = views[0].camera;
  EXPECT_GT(glm::length(c.eye_m - first.eye_m), 1.0);  // it did move
  for (const Object& o : objects) {
    if (o.name == "/P-1") continue;
    const DAabb b = object_bounds(o);
    EXPECT_FALSE(inside(b, c.eye_m)) << o.name;
    EXPECT_FALSE(crosses(b, c.eye_m, pump_centre)) << o.name;
  }
  // Still framed by the rule.
  const Projected p = project_box(pump_box, c, 16.0 / 9.0);
  EXPECT_NEAR(std::max(p.fill_x(), p.fill_y()), kReviewFill, 0.01);
}

// In a roofed courtyard that every fitted eye stands outside of: the eye comes in front of the
// first wall (or the roof) on its ray, the field of view widened to keep the fill.
TEST(ReviewViews, AnEyeBehindAWallMovesInFrontOfItAndWidensTheView) {
  const DAabb pump_box{{-1, -0.5, 0}, {1, 0.5, 1.5}};
  const glm::dvec3 pump_centre(0, 0, 0.75);
  const Camera first = fit_camera(pump_box, isometric_direction(), 16.0 / 9.0, 50.0, kReviewFill);
  const double distance_m = glm::length(first.eye_m - pump_centre);
  const double d = 0.8 * distance_m;  // the walls' inner faces, each way from the pump
  const double roof_m = 2.5;          // below every fitted eye
  TempDir dir;
  std::vector<Object> objects = {box_object("/P-1", ObjectClass::equipment, pump_centre, {2, 1, 1.5})};
  const float side = float(2 * d + 1);
  objects.push_back(box_object("/WALL-E", ObjectClass::structure, {d + 0.2, 0, roof_m / 2}, {0.4f, side, float(roof_m)}));
  objects.push_back(box_object("/WALL-W", ObjectClass::structure, {-d - 0.2, 0, roof_m / 2}, {0.4f, side, float(roof_m)}));
  objects.push_back(box_object("/WALL-N", ObjectClass::structure, {0, d + 0.2, roof_m / 2}, {side, 0.4f, float(roof_m)}));
  objects.push_back(box_object("/WALL-S", ObjectClass::structure, {0, -d - 0.2, roof_m / 2}, {side, 0.4f, float(roof_m)}));
  objects.push_back(box_object("/ROOF", ObjectClass::structure, {0, 0, roof_m + 0.15}, {side, side, 0.3f}));
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  ReviewViewsSummary summary;
  const auto views = views_of(*store, per("equipment"), &summary);
  ASSERT_EQ(views.size(), 1u);
  EXPECT_EQ(summary.moved, 1u);
  EXPECT_EQ(summary.obstructed, 0u);
  const Camera& c = views[0].camera;
  EXPECT_GT(c.fov_deg, 50.0);
  EXPECT_LE(c.fov_deg, 90.0);
  EXPECT_LT(std::abs(c.eye_m.x), d);
  EXPECT_LT(std::abs(c.eye_m.y), d);
  EXPECT_LT(c.eye_m.z, roof_m);
  for (const Object& o : objects) {
    if (o.name == "/P-1") continue;
    EXPECT_FALSE(inside(object_bounds(o), c.eye_m)) << o.name;
    EXPECT_FALSE(crosses(object_bounds(o), c.eye_m, pump_centre)) << o.name;
  }
  const Projected p = project_box(pump_box, c, 16.0 / 9.0);
  EXPECT_NEAR(std::max(p.fill_x(), p.fill_y()), kReviewFill, 0.01);
}

// Walled in on every side and from above: nowhere is clear, so the first fit stays (the
// renderer's highlight shows the subject through) and the summary says so.
TEST(ReviewViews, ASubjectWithNoClearViewKeepsItsFirstFitAndIsCounted) {
  TempDir dir;
  std::vector<Object> objects = {box_object("/P-1", ObjectClass::equipment, {0, 0, 0.75}, {2, 1, 1.5})};
  objects.push_back(box_object("/SHED", ObjectClass::structure, {0, 0, 0}, {300, 300, 300}));
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  ReviewViewsSummary summary;
  const auto views = views_of(*store, per("equipment"), &summary);
  ASSERT_EQ(views.size(), 1u);
  EXPECT_EQ(summary.obstructed, 1u);
  EXPECT_EQ(views[0].camera,
            fit_camera(DAabb{{-1, -0.5, 0}, {1, 0.5, 1.5}}, isometric_direction(), 16.0 / 9.0, 50.0, kReviewFill));
}

// Generated plants are kept per preset and seed for the whole program (generating is most of
// these tests' time).
const Store& generated(char preset, uint64_t seed, uint32_t scale = 1) {
  static std::map<std::tuple<char, uint64_t, uint32_t>, std::pair<std::unique_ptr<TempDir>, std::unique_ptr<Store>>> stores;
  auto& entry = stores[{preset, seed, scale}];
  if (!entry.second) {
    entry.first = std::make_unique<TempDir>();
    std::string error;
    entry.second = Store::open(entry.first->str(), Store::Mode::read_write, error);
    if (!entry.second) ADD_FAILURE() << error;
    GenerateOptions options;
    options.preset = preset;
    options.seed = seed;
    options.scale = scale;
    const IngestResult result = ingest_generated(*entry.second, options);
    if (!result) ADD_FAILURE() << result.error().message;
  }
  return *entry.second;
}

TEST(ReviewViews, AreasOfAGeneratedPlantAreItsUnitsAndPipelinesAreWholeLines) {
  const Store& store = generated('a', 1, 2);
  const auto areas = views_of(store, per("area"));
  ASSERT_EQ(areas.size(), 2u);
  EXPECT_EQ(areas[0].name, "Unit-01");
  EXPECT_EQ(areas[1].name, "Unit-02");
  EXPECT_EQ(areas[0].title, "Unit 01");

  // Every object is in one unit, and each pipeline view holds its line's every object.
  std::string error;
  auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  std::map<uint64_t, std::set<uint64_t>> lines;  // pipeline id -> its objects' ids
  uint64_t objects = 0;
  ASSERT_TRUE(view->for_each_object(
      [&](uint32_t, Object&& o) {
        ++objects;
        if (o.object_class == ObjectClass::pipeline) lines[o.id].insert(o.id);
        else if (o.pipeline_id != 0) lines[o.pipeline_id].insert(o.id);
        return true;
      },
      false, error)) << error;
  EXPECT_EQ(areas[0].subject.size() + areas[1].subject.size(), objects);
  const auto pipelines = views_of(store, per("pipeline"));
  ASSERT_EQ(pipelines.size(), lines.size());
  for (const auto& v : pipelines) {
    const std::set<uint64_t> subject(v.subject.begin(), v.subject.end());
    ASSERT_TRUE(lines.count(v.subject.front()) || !subject.empty());
    bool found = false;
    for (const auto& [line, members] : lines) {
      if (members.count(v.subject.front()) == 0) continue;
      EXPECT_EQ(subject, members) << v.name;
      found = true;
    }
    EXPECT_TRUE(found) << v.name;
    EXPECT_EQ(v.title, "Pipeline " + v.name);
  }
}

const fs::path kHuldra = fs::path(PLANTVIEW_SHARED_DIR) / "data" / "huldra";

// Huldra in a store of its own, for the whole program; null (after a skip message) without it.
const Store* huldra() {
  static std::unique_ptr<TempDir> dir;
  static std::unique_ptr<Store> store;
  if (!fs::exists(kHuldra)) return nullptr;
  if (!store) {
    dir = std::make_unique<TempDir>();
    std::string error;
    store = Store::open(dir->str(), Store::Mode::read_write, error);
    if (!store) ADD_FAILURE() << error;
    const std::vector<std::string> files = {(kHuldra / "WD1-PSUP.RVM").string()};
    const auto plan = plan_import(files, error);
    if (!plan) ADD_FAILURE() << error;
    const IngestResult result = ingest_files(*store, *plan);
    if (!result) ADD_FAILURE() << result.error().message;
  }
  return store.get();
}

TEST(ReviewViews, AreasOfAnRvmModelAreItsZones) {
  const Store* store = huldra();
  if (!store) GTEST_SKIP() << "no " << kHuldra;
  const auto areas = views_of(*store, per("area"));
  // The sample's 862 objects lie in 101 of its zones.
  ASSERT_EQ(areas.size(), 101u);
  size_t objects = 0;
  for (const auto& v : areas) {
    EXPECT_EQ(v.name.rfind("PS-WD1-", 0), 0u) << v.name;
    EXPECT_EQ(v.title.rfind("Zone /PS/WD1/", 0), 0u) << v.title;
    objects += v.subject.size();
  }
  EXPECT_EQ(objects, 862u);
}

// ---- the command ----

struct Outcome {
  int status = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

Outcome run_plantview(const TempDir& dir, const std::string& args) {
  fs::create_directories(dir.path());
  const fs::path out = dir.path() / "stdout", err = dir.path() / "stderr";
  const std::string cmd = std::string(PLANTVIEW_BIN) + " " + args + " >" + out.string() + " 2>" + err.string();
  const int raw = std::system(cmd.c_str());
  Outcome r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

TEST(ViewsCommand, WritesTheViewsFileAndSaysWhatItMade) {
  TempDir store_dir, work;
  auto store = make_store(store_dir, {box_object("/P-1", ObjectClass::equipment, {0, 0, 1}, {1, 1, 2}),
                                      box_object("/P-2", ObjectClass::equipment, {9, 0, 1}, {1, 1, 2})});
  ASSERT_TRUE(store);
  store.reset();  // the command opens it
  const fs::path out = work.path() / "views.json";
  const Outcome r = run_plantview(work, "views --store " + store_dir.str() + " --per equipment --sides 4 --size 800x800 --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["views"], 8);
  EXPECT_EQ(summary["subjects"], 2);
  std::vector<ReviewView> views;
  std::string error;
  ASSERT_TRUE(parse_review_views(slurp(out), views, error)) << error;
  ASSERT_EQ(views.size(), 8u);
  EXPECT_EQ(views[0].name, "P-1-N");
  EXPECT_EQ(views[0].aspect, 1.0);
  const auto file = nlohmann::json::parse(slurp(out));
  EXPECT_EQ(file["per"], "equipment");
  // Nothing but the file is left beside it (the temporary was renamed).
  size_t entries = 0;
  for (const auto& e : fs::directory_iterator(work.path())) entries += e.path().filename().string().find(".tmp") != std::string::npos;
  EXPECT_EQ(entries, 0u);
}

TEST(ViewsCommand, UsageErrorsExitTwoAndRuntimeFailuresOne) {
  TempDir store_dir, work;
  auto store = make_store(store_dir, {box_object("/P-1", ObjectClass::equipment, {0, 0, 1}, {1, 1, 2})});
  ASSERT_TRUE(store);
  store.reset();
  const std::string base = "views --store " + store_dir.str() + " --out " + (work.path() / "v.json").string();
  EXPECT_EQ(run_plantview(work, base + " --per valve").status, 2);
  EXPECT_EQ(run_plantview(work, base).status, 2);  // --per is required
  EXPECT_EQ(run_plantview(work, base + " --per area --sides 3").status, 2);
  Outcome r = run_plantview(work, base + " --per area --size 16:9");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--size: expected WxH"), std::string::npos) << r.err;
  r = run_plantview(work, base + " --per equipment --select 'K-*'");
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.err, "plantview: --select 'K-*' matches none of the 1 equipment in " + store_dir.str() + "\n");
  r = run_plantview(work, base + " --per pipeline");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("the store has no pipelines"), std::string::npos) << r.err;
  r = run_plantview(work, "views --per area --store " + (work.path() / "nothing").string() + " --out x.json");
  EXPECT_EQ(r.status, 1);
  EXPECT_FALSE(fs::exists(work.path() / "v.json"));
}

// ---- on rendered images ----

std::unique_ptr<Renderer> make_renderer(const Store& store) {
  test::gl_context();
  RenderOptions options;
  options.vertex_budget_bytes = 64u << 20;
  std::string error;
  auto r = Renderer::create(store, options, error);
  EXPECT_TRUE(r) << error;
  return r;
}

Image render(Renderer& r, const Camera& camera, uint32_t w, uint32_t h, FrameStats* stats = nullptr) {
  Image image;
  FrameStats ignored;
  std::string error;
  EXPECT_TRUE(r.render(camera, w, h, true, image, stats ? *stats : ignored, error)) << error;
  return image;
}

TEST(ReviewViewImages, EachSubjectFillsSixtyToEightyFivePercentOfItsFrame) {
  TempDir dir;
  // A row of equipment of different shapes among a rack, and a pipeline of two pipes.
  std::vector<Object> objects = {
      box_object("/P-1", ObjectClass::equipment, {0, 0, 0.5}, {1.5, 0.8f, 1}),
      box_object("/C-1", ObjectClass::equipment, {8, 0, 12}, {2, 2, 24}),
      box_object("/E-1", ObjectClass::equipment, {16, 0, 1}, {6, 1.2f, 1.2f}),
      box_object("/RACK", ObjectClass::structure, {8, 8, 4}, {30, 4, 0.3f})};
  Object line = box_object("/L-1", ObjectClass::pipeline, {0, 0, 0}, {0, 0, 0});
  line.primitives.clear();
  for (int i = 0; i < 2; ++i) {
    Object pipe = box_object("/L-1/PIPE-" + std::to_string(i), ObjectClass::pipe,
                             {4.0 + 12.0 * i, 8, 5}, {12, 0.3f, 0.3f});
    pipe.pipeline_id = line.id;
    objects.push_back(pipe);
  }
  objects.push_back(line);
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  auto renderer = make_renderer(*store);
  ASSERT_TRUE(renderer);
  for (const std::string kind : {"equipment", "pipeline"}) {
    for (const int sides : {1, 4}) {
      for (const ReviewView& v : views_of(*store, per(kind, sides))) {
        const Image image = render(*renderer, v.camera, 320, 180);
        const test::ContentBox box =
            test::content_box_of(image, std::set<uint64_t>(v.subject.begin(), v.subject.end()));
        ASSERT_FALSE(box.empty) << v.name;
        EXPECT_GE(box.fill(), 0.60) << v.name;
        EXPECT_LE(box.fill(), 0.85) << v.name;
        // Centred: as much room left as right (a pixel or two of rounding).
        EXPECT_NEAR(double(box.min_x), double(image.width - 1 - box.max_x), 0.02 * image.width + 2)
            << v.name;
      }
    }
  }
}

TEST(ReviewViewImages, TheDefaultOverviewOfPresetCFillsSeventyPercentOfItsFrame) {
  const Store& store = generated('c', 1);
  auto renderer = make_renderer(store);
  ASSERT_TRUE(renderer);
  const Camera camera = default_camera(overview_boxes(renderer->read_view()), 16.0 / 9.0);
  const test::ContentBox box = test::content_box(render(*renderer, camera, 640, 360));
  std::printf("preset c overview: %.1f%% of the width, %.1f%% of the height\n",
              100 * box.width_share, 100 * box.height_share);
  EXPECT_GE(box.fill(), 0.70);
  EXPECT_LE(box.fill(), 0.90);
  // The views file's overview is the same camera.
  const auto overview = views_of(store, per("overview"));
  ASSERT_EQ(overview.size(), 1u);
  EXPECT_EQ(overview[0].camera, camera);
  EXPECT_TRUE(overview[0].subject.empty());
}

TEST(ReviewViewImages, TheDefaultOverviewOfHuldraFillsSeventyPercentOfItsFrame) {
  const Store* store = huldra();
  if (!store) GTEST_SKIP() << "no " << kHuldra;
  auto renderer = make_renderer(*store);
  ASSERT_TRUE(renderer);
  const Camera camera = default_camera(overview_boxes(renderer->read_view()), 16.0 / 9.0);
  const test::ContentBox box = test::content_box(render(*renderer, camera, 640, 360));
  std::printf("Huldra overview: %.1f%% of the width, %.1f%% of the height\n",
              100 * box.width_share, 100 * box.height_share);
  EXPECT_GE(box.fill(), 0.70);
  EXPECT_LE(box.fill(), 0.90);
}

// The issue's case: preset c's walkthrough of 10 views once ended looking out of the plant.
TEST(ReviewViewImages, EveryViewOfAWalkthroughSeesThePlant) {
  for (const auto& [preset, seed] : {std::pair{'a', 1}, std::pair{'a', 2}, std::pair{'a', 3},
                                     std::pair{'b', 1}, std::pair{'c', 1}}) {
    const Store& store = generated(preset, uint64_t(seed));
    auto renderer = make_renderer(store);
    ASSERT_TRUE(renderer);
    for (const int frames : {10, 25}) {
      std::vector<Camera> path;
      std::string error;
      ASSERT_TRUE(make_camera_path(PathKind::walkthrough, frames, store, path, error)) << error;
      ASSERT_EQ(path.size(), size_t(frames));
      for (size_t i = 0; i < path.size(); ++i) {
        FrameStats stats;
        const Image image = render(*renderer, path[i], 160, 90, &stats);
        const std::string where = std::string("preset ") + preset + " seed " + std::to_string(seed) +
                                  " view " + std::to_string(i) + " of " + std::to_string(frames) +
                                  " at " + format_camera(path[i]);
        EXPECT_GT(stats.objects_visible, 0u) << where;
        EXPECT_FALSE(test::is_one_colour(image)) << where;
        // Objects cover a part of the frame, not a speck on the horizon (thin piping seen
        // from afar covers a few percent; the view out of the plant covered none).
        EXPECT_GE(double(test::content_box(image).pixels) / (160.0 * 90.0), 0.02) << where;
      }
    }
  }
}

}  // namespace
}  // namespace plantview
