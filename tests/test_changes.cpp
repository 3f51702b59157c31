// Change images (render.h: RenderOptions::changes; docs/changes.md) on a small store of boxes
// seen from straight above, whose second revision removes one box, moves one, recolours one,
// adds one and moves a pipe of a pipeline: what a reviewer sees (pixels checked at the places a
// pinhole projection of the boxes' centres gives, independently of the renderer), the picks,
// the counts and legend, the errors (CLI, service), and `views --per change`'s views and
// their fitting.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "plantview/camera.h"
#include "plantview/image.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/review.h"
#include "plantview/store.h"
#include "server/render_worker.h"
#include "server/routes.h"
#include "support/gl_context.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;

constexpr uint32_t kWidth = 320, kHeight = 180;
constexpr Colour kGrey{150, 150, 150, 255};

Object box_at(const std::string& name, glm::dvec3 centre, Colour colour = kGrey,
              ObjectClass cls = ObjectClass::equipment, uint64_t pipeline_id = 0) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = cls;
  o.colour = colour;
  o.origin_m = centre;
  o.pipeline_id = pipeline_id;
  o.primitives.push_back(Primitive{Placement{}, Box{1.5f, 1.5f, 1.0f}});
  o.attributes = {{"Tag", name.substr(1)}};
  return o;
}

// Revision 1: /GONE at (0,0), /MOVED at (4,0), /SAME at (8,0), /RECOLOURED at (12,0), a
// pipeline /LINE-1 (no geometry) with a pipe /PIPE-1 at (0,-4). Revision 2: /GONE removed,
// /MOVED at (4,4), /RECOLOURED blue, /NEW at (8,4), /PIPE-1 at (4,-4).
std::vector<Object> revision_1() {
  Object line;
  line.name = "/LINE-1";
  line.source = "test";
  line.id = object_id(line.source, line.name);
  line.object_class = ObjectClass::pipeline;
  line.attributes = {{"Line number", "LINE-1"}};
  return {box_at("/GONE", {0, 0, 0}), box_at("/MOVED", {4, 0, 0}), box_at("/SAME", {8, 0, 0}),
          box_at("/RECOLOURED", {12, 0, 0}), line,
          box_at("/PIPE-1", {0, -4, 0}, kGrey, ObjectClass::pipe, line.id)};
}
std::vector<Object> revision_2() {
  std::vector<Object> objects = revision_1();
  objects.erase(objects.begin());                        // /GONE
  objects[0].origin_m = {4, 4, 0};                       // /MOVED
  objects[2].colour = Colour{40, 60, 200, 255};          // /RECOLOURED
  objects[4].origin_m = {4, -4, 0};                      // /PIPE-1
  objects.push_back(box_at("/NEW", {8, 4, 0}));
  return objects;
}
uint64_t id_of(const char* name) { return object_id("test", name); }

// Straight down onto the middle of the scene: +x to the right, +y up in the image.
const glm::dvec3 kCentre{6, 0, 0};
constexpr double kEyeHeightM = 30.0;
Camera top_camera() {
  Camera c;
  c.eye_m = kCentre + glm::dvec3(0, 0, kEyeHeightM);
  c.target_m = kCentre;
  c.up = {0, 1, 0};
  c.fov_deg = 50.0;
  return c;
}
// The pixel (column, row from the top) a point of the ground plane z = 0.5 (the boxes' tops)
// projects to: a pinhole of vertical field of view fov.
std::pair<uint32_t, uint32_t> pixel_of(glm::dvec2 p) {
  const double half_h = (kEyeHeightM - 0.5) * std::tan(glm::radians(25.0));
  const double half_w = half_h * double(kWidth) / kHeight;
  const double x = (p.x - kCentre.x) / half_w, y = (p.y - kCentre.y) / half_h;
  return {uint32_t(std::lround((x + 1) * 0.5 * kWidth)), uint32_t(std::lround((1 - y) * 0.5 * kHeight))};
}

struct Rgb {
  double r = 0, g = 0, b = 0;
};
// The mean colour of the 5 x 5 pixels about a place.
Rgb colour_at(const Image& image, glm::dvec2 p) {
  const auto [cx, cy] = pixel_of(p);
  Rgb sum;
  for (uint32_t y = cy - 2; y <= cy + 2; ++y)
    for (uint32_t x = cx - 2; x <= cx + 2; ++x) {
      const size_t i = 4 * (size_t(y) * image.width + x);
      sum.r += image.rgba[i] / 25.0;
      sum.g += image.rgba[i + 1] / 25.0;
      sum.b += image.rgba[i + 2] / 25.0;
    }
  return sum;
}
uint64_t id_at(const Image& image, glm::dvec2 p) {
  const auto [x, y] = pixel_of(p);
  return image.object_ids[size_t(y) * image.width + x];
}
std::string text(const Rgb& c) {
  return "(" + std::to_string(int(c.r)) + ", " + std::to_string(int(c.g)) + ", " + std::to_string(int(c.b)) + ")";
}
bool greenish(const Rgb& c) { return c.g > c.r + 40 && c.g > c.b + 40; }
bool reddish(const Rgb& c) { return c.r > c.g + 40 && c.r > c.b + 40; }
double saturation(const Rgb& c) {
  const double hi = std::max({c.r, c.g, c.b});
  return hi > 0 ? (hi - std::min({c.r, c.g, c.b})) / hi : 0;
}
// Orange-yellow and saturated; amber-grey (a previous shape's ghost) is the same hue, greyer.
bool amber(const Rgb& c) { return c.r > c.b + 60 && c.g > c.b + 30 && c.r >= c.g && saturation(c) > 0.6; }
bool amber_grey(const Rgb& c) { return c.r > c.b + 20 && c.r >= c.g && saturation(c) < 0.5; }
bool neutral(const Rgb& c) {
  return std::max({c.r, c.g, c.b}) - std::min({c.r, c.g, c.b}) < 30;
}

class Changes : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    store_ = test::make_store(*dir_, revision_1()).release();
    ASSERT_TRUE(store_);
    const IngestResult second = ingest_objects(*store_, revision_2());
    ASSERT_TRUE(second) << second.error().message;
  }
  static void TearDownTestSuite() {
    delete store_;
    delete dir_;
  }
  static RenderOptions change_options(uint32_t from = 1, uint32_t to = 0) {
    RenderOptions o;
    o.changes = ChangeRange{from, to};
    o.ground = false;
    o.ambient_occlusion = false;
    o.antialias = false;
    return o;
  }
  struct Frame {
    Image image;
    FrameStats stats;
  };
  static Frame render(const RenderOptions& options, bool ok = true, std::string* why = nullptr) {
    test::gl_context();
    std::string error;
    auto r = Renderer::create(*store_, options, error);
    EXPECT_TRUE(r) << error;
    Frame f;
    if (!r) return f;
    const bool rendered = r->render(top_camera(), kWidth, kHeight, true, f.image, f.stats, error);
    EXPECT_EQ(rendered, ok) << error;
    if (why) *why = error;
    return f;
  }
  static test::TempDir* dir_;
  static Store* store_;
};
test::TempDir* Changes::dir_ = nullptr;
Store* Changes::store_ = nullptr;

TEST(ChangeRanges, ParseOneRevisionOrAnIncreasingPair) {
  ChangeRange r;
  std::string error;
  ASSERT_TRUE(parse_change_range("3", r, error)) << error;
  EXPECT_EQ(r, (ChangeRange{3, 0}));
  ASSERT_TRUE(parse_change_range("3..5", r, error)) << error;
  EXPECT_EQ(r, (ChangeRange{3, 5}));
  EXPECT_EQ(change_range_text(r), "3..5");
  EXPECT_EQ(change_range_text(ChangeRange{0, 0}), "0");
  for (const char* bad : {"", "a", "5..3", "3..3", "3..", "..3", "-1", "1.5", "3...5", "99999999999"}) {
    EXPECT_FALSE(parse_change_range(bad, r, error)) << bad;
    EXPECT_NE(error.find(bad), std::string::npos) << error;
  }
}

TEST_F(Changes, TheStoreRecordsTheRevisionItsChangeImagesRead) {
  std::string error;
  auto view = store_->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_EQ(view->info().revision, 2u);
  std::vector<ObjectChange> changes;
  ASSERT_TRUE(view->changes(1, 2, changes, error)) << error;
  std::set<std::pair<uint64_t, ChangeKind>> got;
  for (const ObjectChange& c : changes) got.insert({c.id, c.kind});
  const std::set<std::pair<uint64_t, ChangeKind>> expected = {
      {id_of("/GONE"), ChangeKind::removed},       {id_of("/MOVED"), ChangeKind::modified},
      {id_of("/RECOLOURED"), ChangeKind::modified}, {id_of("/NEW"), ChangeKind::added},
      {id_of("/PIPE-1"), ChangeKind::modified}};
  EXPECT_EQ(got, expected);
}

TEST_F(Changes, AddedIsGreenRemovedIsARedGhostMovedIsAmberWithAGhostAndTheRestIsGhosted) {
  const Frame f = render(change_options());
  if (const char* dir = std::getenv("PLANTVIEW_CHANGES_IMAGES")) {
    std::string error;
    write_image((fs::path(dir) / "changes-boxes.png").string(), f.image, 90, error);
  }
  const Rgb added = colour_at(f.image, {8, 4}), removed = colour_at(f.image, {0, 0}),
            moved_now = colour_at(f.image, {4, 4}), moved_before = colour_at(f.image, {4, 0}),
            recoloured = colour_at(f.image, {12, 0}), same = colour_at(f.image, {8, 0}),
            empty = colour_at(f.image, {0, 4});
  EXPECT_TRUE(greenish(added)) << text(added);
  EXPECT_TRUE(reddish(removed)) << text(removed);
  EXPECT_TRUE(amber(moved_now)) << text(moved_now);
  // The moved box's previous shape: amber-grey, see-through over the background.
  EXPECT_TRUE(amber_grey(moved_before)) << text(moved_before);
  EXPECT_GT(std::fabs(moved_before.r - empty.r) + std::fabs(moved_before.b - empty.b), 20) << text(moved_before)
                                                                                          << " over " << text(empty);
  // A recolour has no ghost: amber, as the modified box it is.
  EXPECT_TRUE(amber(recoloured)) << text(recoloured);
  // The unchanged box is ghosted: light and nearly grey.
  EXPECT_TRUE(neutral(same)) << text(same);
  EXPECT_GT(same.r, 150) << text(same);
}

TEST_F(Changes, PicksReturnTheChangedObjectsAndTheGhostsTheObjectsTheyWere) {
  const Frame f = render(change_options());
  EXPECT_EQ(id_at(f.image, {8, 4}), id_of("/NEW"));
  EXPECT_EQ(id_at(f.image, {4, 4}), id_of("/MOVED"));
  EXPECT_EQ(id_at(f.image, {12, 0}), id_of("/RECOLOURED"));
  EXPECT_EQ(id_at(f.image, {0, 0}), id_of("/GONE"));       // a removed object's ghost
  EXPECT_EQ(id_at(f.image, {4, 0}), id_of("/MOVED"));      // a moved one's previous shape
  EXPECT_EQ(id_at(f.image, {8, 0}), 0u);                   // the unchanged context
  const std::set<uint64_t> ids(f.image.object_ids.begin(), f.image.object_ids.end());
  const std::set<uint64_t> changed = {0, id_of("/NEW"), id_of("/MOVED"), id_of("/RECOLOURED"),
                                      id_of("/GONE"), id_of("/PIPE-1")};
  for (const uint64_t id : ids) EXPECT_TRUE(changed.count(id)) << id;
}

TEST_F(Changes, TheFrameSaysTheRangeAndItsCountsInItsStatisticsLegendAndCaption) {
  const Frame f = render(change_options());
  EXPECT_TRUE(f.stats.changes.shown);
  EXPECT_EQ(f.stats.changes.from, 1u);
  EXPECT_EQ(f.stats.changes.to, 2u);
  EXPECT_EQ(f.stats.changes.added, 1u);
  EXPECT_EQ(f.stats.changes.modified, 3u);
  EXPECT_EQ(f.stats.changes.removed, 1u);
  EXPECT_EQ(change_caption(f.stats.changes),
            "Changes since revision 1 (to 2): 1 added, 3 modified, 1 removed");
  ASSERT_EQ(f.stats.legend.key, "changes");
  ASSERT_EQ(f.stats.legend.entries.size(), 3u);
  EXPECT_EQ(f.stats.legend.entries[0].value, "added");
  EXPECT_EQ(f.stats.legend.entries[0].objects, 1u);
  EXPECT_EQ(f.stats.legend.entries[2].value, "removed");
  EXPECT_EQ(f.stats.legend.entries[2].colour, kRemovedColour);
  EXPECT_NE(f.stats.to_json().find("\"changes\":{\"from\":1,\"to\":2,\"added\":1,\"modified\":3,\"removed\":1}"),
            std::string::npos);
  // The same range to the store's revision, given explicitly, draws the same image.
  const Frame explicit_to = render(change_options(1, 2));
  EXPECT_EQ(explicit_to.image.rgba, f.image.rgba);
}

TEST_F(Changes, ARangeTheStoreCannotDrawFailsTheFrameNamingIt) {
  std::string why;
  render(change_options(2), false, &why);  // nothing after the store's revision
  EXPECT_EQ(why.rfind("changes 2: ", 0), 0u) << why;
  EXPECT_TRUE(service::is_change_range_error(why)) << why;
  render(change_options(7), false, &why);
  EXPECT_EQ(why.rfind("changes 7: ", 0), 0u) << why;
  render(change_options(0, 1), false, &why);  // not the snapshot's revision
  EXPECT_NE(why.find("the store is at revision 2"), std::string::npos) << why;
  EXPECT_TRUE(service::is_change_range_error(why)) << why;
}

TEST(ChangesPruned, ARangeWhoseChangesWerePrunedFailsWithTheStoresMessage) {
  test::TempDir dir;
  auto store = test::make_store(dir, revision_1());
  ASSERT_TRUE(store);
  ASSERT_TRUE(ingest_objects(*store, revision_2()));
  IngestControl keep_one;
  keep_one.keep_revisions = 1;
  std::vector<Object> third = revision_2();
  third.pop_back();  // /NEW removed again
  ASSERT_TRUE(ingest_objects(*store, third, keep_one));
  test::gl_context();
  std::string error;
  RenderOptions options;
  options.changes = ChangeRange{1, 0};
  auto r = Renderer::create(*store, options, error);
  ASSERT_TRUE(r) << error;
  Image image;
  FrameStats stats;
  EXPECT_FALSE(r->render(top_camera(), 64, 36, false, image, stats, error));
  EXPECT_EQ(error.rfind("changes 1: ", 0), 0u) << error;
  EXPECT_NE(error.find("pruned"), std::string::npos) << error;
  // The last revision's changes are kept.
  options.changes = ChangeRange{2, 0};
  r->set_options(options);
  EXPECT_TRUE(r->render(top_camera(), 64, 36, false, image, stats, error)) << error;
  EXPECT_EQ(stats.changes.removed, 1u);
}

TEST(ChangeRoutes, AMalformedRangeIs400NamingTheParameter) {
  service::RouteConfig c;
  c.bounds = {{-1, -1, -1}, {16, 1, 1}};
  service::Request request;
  request.method = "GET";
  request.path = "/api/frame";
  request.query = {{"changes", "3..1"}};
  service::Routed routed = service::route(request, c, false, 1);
  const auto* reply = std::get_if<service::Reply>(&routed.decision);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, 400);
  EXPECT_NE(reply->body.find("'changes'"), std::string::npos) << reply->body;
  request.query = {{"changes", "3..5"}};
  routed = service::route(request, c, false, 1);
  const auto* job = std::get_if<service::RenderJob>(&routed.decision);
  ASSERT_TRUE(job);
  ASSERT_TRUE(job->changes);
  EXPECT_EQ(*job->changes, (ChangeRange{3, 5}));
}

TEST_F(Changes, TheServiceAnswers422ForARangeTheStoreCannotDrawAndPicksAChangedObject) {
  test::gl_context();
  std::string error;
  auto r = Renderer::create(*store_, RenderOptions{}, error);
  ASSERT_TRUE(r) << error;
  service::RenderJob job;
  job.kind = service::RenderJob::Kind::pick;
  job.camera = top_camera();
  job.width = kWidth;
  job.height = kHeight;
  job.changes = ChangeRange{5, 0};
  service::RenderResult result = service::execute_job(job, {}, 0, *r);
  EXPECT_EQ(result.status, 422) << result.body;
  EXPECT_NE(result.body.find("changes 5"), std::string::npos) << result.body;
  job.changes = ChangeRange{1, 0};
  std::tie(job.x, job.y) = pixel_of({0, 0});
  result = service::execute_job(job, {}, 0, *r);
  EXPECT_EQ(result.status, 200) << result.body;
  EXPECT_NE(result.body.find(std::to_string(id_of("/GONE"))), std::string::npos) << result.body;
  // Answered as it was (it is no object of the store any more).
  EXPECT_NE(result.body.find("\"name\":\"/GONE\""), std::string::npos) << result.body;
  EXPECT_NE(result.body.find("\"revision\":1"), std::string::npos) << result.body;
  // Statistics say the range and its counts.
  job.kind = service::RenderJob::Kind::stats;
  result = service::execute_job(job, {}, 0, *r);
  EXPECT_EQ(result.status, 200) << result.body;
  EXPECT_NE(result.body.find("\"changes\":{\"from\":1,\"to\":2,"), std::string::npos) << result.body;
  // Frames carry the caption.
  job.kind = service::RenderJob::Kind::frame;
  result = service::execute_job(job, {}, 0, *r);
  EXPECT_EQ(result.status, 200) << result.body;
  bool captioned = false;
  for (const auto& [name, value] : result.headers)
    captioned = captioned || (name == "X-Plantview-Changes" &&
                              value == "Changes since revision 1 (to 2): 1 added, 3 modified, 1 removed");
  EXPECT_TRUE(captioned);
  // The next job without a range draws no change image.
  job.kind = service::RenderJob::Kind::pick;
  job.changes.reset();
  result = service::execute_job(job, {}, 0, *r);
  EXPECT_EQ(result.body, "{\"object\":null}\n");
}

std::vector<ReviewView> change_views(const Store& store, const std::string& group) {
  ReviewViewOptions options;
  options.per = "change";
  options.changes = ChangeRange{1, 0};
  options.group = group;
  options.aspect = double(kWidth) / kHeight;
  std::vector<ReviewView> views;
  ReviewViewsSummary summary;
  std::string error;
  EXPECT_TRUE(make_review_views(store, options, views, summary, error)) << error;
  return views;
}

// Whether a point lies in the view's image (in front of the eye and inside its frustum).
bool in_view(const ReviewView& v, const glm::dvec3& p) {
  const glm::dvec3 forward = glm::normalize(v.camera.target_m - v.camera.eye_m);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, v.camera.up));
  const glm::dvec3 up = glm::cross(right, forward);
  const glm::dvec3 d = p - v.camera.eye_m;
  const double z = glm::dot(d, forward);
  if (z <= 0) return false;
  const double t = std::tan(glm::radians(v.camera.fov_deg / 2));
  return std::fabs(glm::dot(d, up)) <= z * t && std::fabs(glm::dot(d, right)) <= z * t * v.aspect;
}

TEST_F(Changes, ViewsPerChangeFrameEachChangeBeforeAndAfterAndSayWhatChanged) {
  const std::vector<ReviewView> views = change_views(*store_, "object");
  ASSERT_EQ(views.size(), 5u);
  std::map<std::string, const ReviewView*> by_name;
  for (const ReviewView& v : views) {
    by_name[v.name] = &v;
    EXPECT_EQ(v.kind, "change");
    ASSERT_TRUE(v.changes);
    EXPECT_EQ(*v.changes, (ChangeRange{1, 2}));  // to the store's revision, explicitly
  }
  ASSERT_TRUE(by_name.count("MOVED"));
  const ReviewView& moved = *by_name["MOVED"];
  EXPECT_EQ(moved.title, "Modified equipment MOVED");
  EXPECT_EQ(moved.subject, std::vector<uint64_t>{id_of("/MOVED")});
  // Fitted on the box where it was and where it is.
  for (const glm::dvec3 corner : {glm::dvec3(3.25, -0.75, -0.5), glm::dvec3(4.75, 0.75, 0.5),
                                  glm::dvec3(3.25, 3.25, -0.5), glm::dvec3(4.75, 4.75, 0.5)})
    EXPECT_TRUE(in_view(moved, corner)) << corner.x << "," << corner.y << "," << corner.z;
  ASSERT_TRUE(by_name.count("GONE"));
  EXPECT_EQ(by_name["GONE"]->title, "Removed equipment GONE");
  EXPECT_TRUE(by_name["GONE"]->subject.empty());
  EXPECT_TRUE(in_view(*by_name["GONE"], {0, 0, 0}));
  const std::vector<std::string> lines = caption_lines(moved);
  EXPECT_NE(std::find(lines.begin(), lines.end(), "Change modified"), lines.end());
  EXPECT_NE(std::find(lines.begin(), lines.end(), "Revision since 1 (to 2)"), lines.end());
  // The views file keeps the range.
  std::vector<ReviewView> read;
  std::string error;
  ASSERT_TRUE(parse_review_views(review_views_json(views, "change"), read, error)) << error;
  ASSERT_EQ(read.size(), views.size());
  EXPECT_EQ(read[0].changes, views[0].changes);

  const std::vector<ReviewView> lines_views = change_views(*store_, "pipeline");
  ASSERT_EQ(lines_views.size(), 1u);
  EXPECT_EQ(lines_views[0].title, "Changed pipeline LINE-1: 1 modified");
  EXPECT_TRUE(in_view(lines_views[0], {0, -4, 0}));
  EXPECT_TRUE(in_view(lines_views[0], {4, -4, 0}));
  EXPECT_EQ(change_views(*store_, "equipment").size(), 4u);
}

// --- the command line ---------------------------------------------------------------------------

struct Outcome {
  int status = -1;
  std::string err;
};
Outcome run(const std::string& args, const fs::path& dir) {
  const fs::path err = dir / "stderr";
  const std::string cmd = std::string(PLANTVIEW_BIN) + " " + args + " >/dev/null 2>" + err.string();
  const int raw = std::system(cmd.c_str());
  Outcome r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::ifstream in(err);
  std::stringstream s;
  s << in.rdbuf();
  r.err = s.str();
  return r;
}

TEST_F(Changes, TheCommandLineDrawsAChangeImageAndRefusesBadRanges) {
  test::TempDir out;
  fs::create_directories(out.str());
  const std::string store = "--store " + dir_->str() + " ";
  const std::string png = (fs::path(out.str()) / "changes.png").string();
  Outcome r = run("render " + store + "--changes 3..1 --out " + png, fs::path(out.str()));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("--changes"), std::string::npos) << r.err;
  r = run("render " + store + "--changes 9 --size 160x90 --out " + png, fs::path(out.str()));
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find("changes 9"), std::string::npos) << r.err;
  r = run("render " + store + "--changes 1 --size 320x180 --out " + png, fs::path(out.str()));
  ASSERT_EQ(r.status, 0) << r.err;
  Image image;
  std::string error;
  ASSERT_TRUE(read_image(png, image, error)) << error;
  EXPECT_EQ(image.width, 320u);
  r = run("views " + store + "--per change --out " + (fs::path(out.str()) / "v.json").string(),
          fs::path(out.str()));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("--from"), std::string::npos) << r.err;
  // A view per change, rendered as the farm renders them: a change image each.
  const fs::path views = fs::path(out.str()) / "changes.json", sheet = fs::path(out.str()) / "sheet";
  r = run("views " + store + "--per change --from 1 --group equipment --size 320x180 --out " + views.string(),
          fs::path(out.str()));
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("render " + store + "--views " + views.string() + " --size 320x180 --out " + sheet.string(),
          fs::path(out.str()));
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* name : {"GONE", "MOVED", "NEW", "RECOLOURED"})
    EXPECT_TRUE(fs::is_regular_file(sheet / (std::string(name) + ".png"))) << name;
  std::ifstream stats(sheet / "stats.jsonl");
  std::string line;
  size_t lines = 0;
  while (std::getline(stats, line)) {
    ++lines;
    // (The manifest writes the statistics' keys sorted.)
    EXPECT_NE(line.find("\"changes\":{\"added\":1,\"from\":1,\"modified\":3,\"removed\":1,\"to\":2}"),
              std::string::npos) << line;
  }
  EXPECT_EQ(lines, 4u);
}

}  // namespace
}  // namespace plantview
