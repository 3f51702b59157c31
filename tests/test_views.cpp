// Review views: camera fitting, the views file, subjects from a store, default cameras and
// walkthroughs that stay in the plant.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "plantview/camera.h"

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
  }
}

TEST(ViewsFile, WhatIsWrittenReadsBackTheSameInTheSameOrder) {
  const std::string json = review_views_json(sample_views(), "equipment");
  std::vector<ReviewView> read;
  std::string error;
  ASSERT_TRUE(parse_review_views(json, read, error)) << error;
  expect_same(sample_views(), read);
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
            "views file: 'per' must be one of overview, equipment, pipeline, area");
  EXPECT_EQ(error_after([](Json& j) { j["views"][1]["kind"] = "zone"; }),
            "views file: view 1 ('unit_2.zone-B'): 'kind' is 'zone' (overview, equipment, pipeline, area)");
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
            "aspect, subject, attributes)");
  EXPECT_EQ(error_after([](Json& j) { j["extra"] = 1; }),
            "views file: unknown key 'extra' (version, per, views)");
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

}  // namespace
}  // namespace plantview
