// Sections (plantview/view_filters.h) in the renderer, review views and the command line: a plan
// slab of preset c draws only the slab (objects_clipped counted, every drawn object meeting it,
// nothing above it on screen); a cut closed solid is capped in its own hue, darker, with its id
// under the cap, and shows nothing (no id) there uncapped; a view cut open with
// `views --section subject` shows its subject through the walls of its room; usage errors of
// --clip and --section-box exit 2 naming the option.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/review.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

struct Rgb {
  int r, g, b;
};
Rgb pixel(const Image& image, uint32_t x, uint32_t y) {
  const uint8_t* p = image.rgba.data() + (size_t(y) * image.width + x) * 4;
  return {p[0], p[1], p[2]};
}
uint64_t id_at(const Image& image, uint32_t x, uint32_t y) {
  return image.object_ids[size_t(y) * image.width + x];
}

using test::make_object;
using test::make_store;

bool render(Renderer& r, const Camera& camera, uint32_t w, uint32_t h, Image& image,
            FrameStats& stats) {
  std::string error;
  const bool ok = r.render(camera, w, h, true, image, stats, error);
  EXPECT_TRUE(ok) << error;
  return ok;
}

// ---- a 2 m plan slab of preset c

class PresetCSlab : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    std::string error;
    store_ = Store::open(dir_->str(), Store::Mode::read_write, error).release();
    ASSERT_TRUE(store_) << error;
    GenerateOptions options;
    options.preset = 'c';
    const IngestResult result = ingest_generated(*store_, options);
    ASSERT_TRUE(result) << result.error().message;
  }
  static void TearDownTestSuite() {
    delete store_;
    delete dir_;
  }
  static TempDir* dir_;
  static Store* store_;
};
TempDir* PresetCSlab::dir_ = nullptr;
Store* PresetCSlab::store_ = nullptr;

TEST_F(PresetCSlab, DrawsOnlyTheSlabAndCountsWhatItClips) {
  test::gl_context();
  std::string error;
  RenderOptions options;
  options.ground = false;
  auto r = Renderer::create(*store_, options, error);
  ASSERT_TRUE(r) << error;
  const DAabb bounds = r->model_bounds();
  const double bottom = bounds.min.z + 2.0, top = bottom + 2.0;
  Section slab;
  slab.planes.push_back({{0, 0, top}, {0, 0, 1}});
  slab.planes.push_back({{0, 0, bottom}, {0, 0, -1}});

  // From the side, level with the slab's middle, outside the plant.
  const glm::dvec3 centre = 0.5 * (bounds.min + bounds.max);
  const double reach = glm::length(bounds.max - bounds.min);
  Camera side;
  side.eye_m = {centre.x, bounds.min.y - 0.6 * reach, 0.5 * (bottom + top)};
  side.target_m = {centre.x, centre.y, side.eye_m.z};
  side.up = {0, 0, 1};
  side.fov_deg = 60;
  const uint32_t w = 320, h = 180;
  Image whole, cut;
  FrameStats whole_stats, cut_stats;
  ASSERT_TRUE(render(*r, side, w, h, whole, whole_stats));
  options.section = slab;
  r->set_options(options);
  ASSERT_TRUE(render(*r, side, w, h, cut, cut_stats));
  EXPECT_EQ(whole_stats.objects_clipped, 0u);
  EXPECT_GT(cut_stats.objects_clipped, 0u);
  EXPECT_LT(cut_stats.objects_visible, whole_stats.objects_visible);
  EXPECT_NE(cut_stats.to_json().find("\"objects_clipped\":"), std::string::npos);

  // Nothing above the slab's top on screen: the top projects at most focal * 1 m / nearest
  // distance above the image's middle row.
  const double nearest_m = side.eye_m.y < bounds.min.y ? bounds.min.y - side.eye_m.y : 1.0;
  const double focal_px = 0.5 * h / std::tan(glm::radians(side.fov_deg / 2));
  const int top_row = int(std::floor(0.5 * h - focal_px * (top - side.eye_m.z) / nearest_m)) - 2;
  ASSERT_GT(top_row, 0);
  uint64_t above_whole = 0, above_cut = 0, ids_cut = 0;
  std::set<uint64_t> drawn;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      if (id_at(cut, x, y)) {
        ++ids_cut;
        drawn.insert(id_at(cut, x, y));
      }
      if (int(y) >= top_row) continue;
      above_whole += id_at(whole, x, y) != 0;
      above_cut += id_at(cut, x, y) != 0;
    }
  EXPECT_GT(above_whole, 100u) << "the plant rises above the slab in this view";
  EXPECT_EQ(above_cut, 0u);
  EXPECT_GT(ids_cut, 100u);

  // Every object drawn (in the id buffer) and every object the plan draws meets the slab.
  auto read = store_->read(error);
  ASSERT_TRUE(read) << error;
  for (const uint64_t id : drawn) {
    const auto slot = read->slot_of(id);
    ASSERT_TRUE(slot);
    Object o;
    ASSERT_TRUE(read->object(*slot, o, false, error)) << error;
    const DAabb b = object_bounds(o);
    if (b.empty()) continue;  // a pipeline: a merged run of its pipes (they are checked below)
    EXPECT_TRUE(b.min.z <= top + 1e-3 && b.max.z >= bottom - 1e-3)
        << o.name << " " << b.min.z << ".." << b.max.z << " slab " << bottom << ".." << top
        << " class " << int(o.object_class);
  }
  ViewPlan plan;
  ASSERT_TRUE(plan_view(*read, side, w, h, options, plan, error)) << error;
  ASSERT_FALSE(plan.objects.empty());
  // (Bounds in the spatial index are rounded outwards to float: an object within a few tenths of
  // a millimetre of a plane is kept there and clipped whole on the GPU.)
  Section grown = slab;
  grown.planes[0].point_m.z += 0.01;
  grown.planes[1].point_m.z -= 0.01;
  for (const PlannedObject& p : plan.objects) {
    Object o;
    ASSERT_TRUE(read->object(p.slot, o, false, error)) << error;
    const DAabb b = object_bounds(o);
    EXPECT_FALSE(section_removes_all(grown, b)) << o.name << " " << b.min.z << ".." << b.max.z;
  }
}

// ---- caps

// A red vessel (a closed cylinder, 2 m across, 4 m tall) cut at 2 m, seen from above, and a
// box wholly above the cut over it.
class Caps : public ::testing::Test {
 protected:
  void SetUp() override {
    test::gl_context();
    Primitive vessel{Placement{}, Cylinder{1.0f, 4.0f}};
    Primitive lid{Placement{}, Box{3.0f, 3.0f, 0.5f}};
    objects_ = {make_object("/V-1", ObjectClass::equipment, {100, 200, 2}, kRed, vessel),
                make_object("/LID", ObjectClass::structure, {100, 200, 6}, kBlue, lid)};
    store_ = make_store(dir_, objects_);
    ASSERT_TRUE(store_);
    camera_.eye_m = {100.0, 199.5, 14.0};
    camera_.target_m = {100.0, 200.0, 2.0};
    camera_.up = {0, 0, 1};
    camera_.fov_deg = 30;
  }
  Image draw(bool capped) {
    RenderOptions options;
    options.ambient_occlusion = false;
    options.section.planes.push_back({{0, 0, 2.0}, {0, 0, 1}});
    options.section.capped = capped;
    std::string error;
    auto r = Renderer::create(*store_, options, error);
    EXPECT_TRUE(r) << error;
    Image image;
    FrameStats stats;
    if (r) {
      render(*r, camera_, kSide, kSide, image, stats);
      EXPECT_EQ(stats.objects_clipped, 1u);  // the lid
    }
    return image;
  }
  static constexpr Colour kRed{200, 40, 30, 255}, kBlue{40, 60, 220, 255};
  static constexpr uint32_t kSide = 200;
  TempDir dir_;
  std::vector<Object> objects_;
  std::unique_ptr<Store> store_;
  Camera camera_;
};

TEST_F(Caps, TheCutFaceIsFilledInTheObjectsHueDarkerAndPicksIt) {
  const Image image = draw(true);
  ASSERT_EQ(image.object_ids.size(), size_t(kSide) * kSide);
  const Rgb c = pixel(image, kSide / 2, kSide / 2);
  EXPECT_EQ(id_at(image, kSide / 2, kSide / 2), objects_[0].id);
  EXPECT_GT(c.r, c.g + 40) << c.r << " " << c.g << " " << c.b;
  EXPECT_GT(c.r, c.b + 40);
  EXPECT_LT(c.r, kRed.r);  // darker than the object's colour
  EXPECT_GT(c.r, 40);      // not background, not black
}

TEST_F(Caps, UncappedTheInsideShowsNothingAndNothingIsPickedWhereClipped) {
  const Image image = draw(false);
  ASSERT_EQ(image.object_ids.size(), size_t(kSide) * kSide);
  // The vessel's top half and the lid are clipped; its inside (back faces) is not drawn.
  EXPECT_EQ(id_at(image, kSide / 2, kSide / 2), 0u);
  // Seen from above, its side's outward faces turn away from the eye: nothing of it has an id.
  for (const uint64_t id : image.object_ids) EXPECT_NE(id, objects_[1].id);
}

// A section box holding the whole model cuts nothing: the frame is the one without a section
// (the plain programs draw it: no face of the box cuts the model).
TEST_F(Caps, ABoxAroundEverythingChangesNothing) {
  RenderOptions options;
  std::string error;
  auto r = Renderer::create(*store_, options, error);
  ASSERT_TRUE(r) << error;
  Image plain, boxed;
  FrameStats stats;
  ASSERT_TRUE(render(*r, camera_, kSide, kSide, plain, stats));
  options.section.has_box = true;
  options.section.box = {{90, 190, -5}, {110, 210, 20}};
  r->set_options(options);
  ASSERT_TRUE(render(*r, camera_, kSide, kSide, boxed, stats));
  EXPECT_EQ(stats.objects_clipped, 0u);
  EXPECT_TRUE(plain.rgba == boxed.rgba);
  EXPECT_TRUE(plain.object_ids == boxed.object_ids);
}

// Whatever lies inside a cut solid (a pipe through a vessel) is under its cap, not seen through
// it: the cap is drawn before the uncut solids, whose depth would otherwise hide the back faces
// that mark where it goes.
TEST_F(Caps, WhatLiesInsideACutSolidIsUnderItsCap) {
  const TempDir dir;
  std::vector<Object> objects = objects_;
  // A pipe inside the vessel, wholly below the cut (uncut), off its axis.
  objects.push_back(make_object("/P-1", ObjectClass::pipe, {100.4, 200, 1.0}, kBlue,
                                Primitive{Placement{}, Cylinder{0.25f, 1.0f}}));
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  RenderOptions options;
  options.ambient_occlusion = false;
  options.section.planes.push_back({{0, 0, 2.0}, {0, 0, 1}});
  std::string error;
  auto r = Renderer::create(*store, options, error);
  ASSERT_TRUE(r) << error;
  Image image;
  FrameStats stats;
  ASSERT_TRUE(render(*r, camera_, kSide, kSide, image, stats));
  uint64_t vessel = 0, pipe = 0;
  for (const uint64_t id : image.object_ids) {
    vessel += id == objects[0].id;
    pipe += id == objects.back().id;
  }
  EXPECT_GT(vessel, 1000u);
  EXPECT_EQ(pipe, 0u) << "pixels of the pipe inside the vessel seen through its cap";
}

// The ground under a cut model is drawn from the cut frame's own camera, whatever the renderer
// drew before: the first frame of a fresh renderer and a frame after an uncut one from another
// camera are the same image (a served permalink renders on whichever renderer is free).
TEST_F(Caps, TheGroundUnderACutIsDrawnFromTheFramesOwnCamera) {
  RenderOptions options;
  options.ambient_occlusion = false;
  std::string error;
  auto warm = Renderer::create(*store_, options, error);
  ASSERT_TRUE(warm) << error;
  Camera elsewhere;
  elsewhere.eye_m = {60.0, 150.0, 30.0};
  elsewhere.target_m = {100.0, 200.0, 2.0};
  elsewhere.up = {0, 0, 1};
  Image before, after_uncut, fresh;
  FrameStats stats;
  ASSERT_TRUE(render(*warm, elsewhere, kSide, kSide, before, stats));
  options.section.planes.push_back({{0, 0, 2.0}, {0, 0, 1}});
  warm->set_options(options);
  ASSERT_TRUE(render(*warm, camera_, kSide, kSide, after_uncut, stats));
  auto cold = Renderer::create(*store_, options, error);
  ASSERT_TRUE(cold) << error;
  ASSERT_TRUE(render(*cold, camera_, kSide, kSide, fresh, stats));

  // Looking down from 12 m over a plant 3 m across, the ground fills the corners.
  for (const Image* image : {&fresh, &after_uncut}) {
    const Rgb corner = pixel(*image, 3, 3);
    EXPECT_FALSE(corner.r == 204 && corner.g == 214 && corner.b == 224)
        << "the background, not the ground, at a corner";
    EXPECT_LT(corner.b, 200) << corner.r << " " << corner.g << " " << corner.b;
  }
  ASSERT_EQ(fresh.rgba.size(), after_uncut.rgba.size());
  double difference = 0;
  for (size_t i = 0; i < fresh.rgba.size(); ++i)
    difference += std::abs(int(fresh.rgba[i]) - int(after_uncut.rgba[i]));
  EXPECT_LT(difference / double(fresh.rgba.size()), 0.5) << "mean difference per channel";
}

// ---- views --section subject

TEST(SectionViews, AWalledInSubjectIsCutOpenAndShowsItsColour) {
  test::gl_context();
  TempDir dir;
  const Colour orange{230, 120, 20, 255}, grey{150, 150, 150, 255};
  std::vector<Object> objects = {make_object("/P-1", ObjectClass::equipment, {0, 0, 0.75}, orange,
                                             Primitive{Placement{}, Box{2, 1, 1.5}})};
  // A tight room about the pump, walls and a roof half a metre and more from it: no clear place
  // for the eye, which stays outside.
  const auto wall = [&](const char* name, glm::dvec3 at, glm::vec3 size) {
    objects.push_back(make_object(name, ObjectClass::structure, at, grey,
                                  Primitive{Placement{}, Box{size.x, size.y, size.z}}));
  };
  wall("/WALL-E", {1.9, 0, 1.1}, {0.4f, 3.6f, 2.2f});
  wall("/WALL-W", {-1.9, 0, 1.1}, {0.4f, 3.6f, 2.2f});
  wall("/WALL-N", {0, 1.4, 1.1}, {4.2f, 0.4f, 2.2f});
  wall("/WALL-S", {0, -1.4, 1.1}, {4.2f, 0.4f, 2.2f});
  wall("/ROOF", {0, 0, 2.35}, {4.2f, 3.2f, 0.3f});
  auto store = make_store(dir, objects);
  ASSERT_TRUE(store);
  ReviewViewOptions vo;
  vo.per = "equipment";
  vo.aspect = 16.0 / 9.0;
  std::vector<ReviewView> plain, cut;
  ReviewViewsSummary summary;
  std::string error;
  ASSERT_TRUE(make_review_views(*store, vo, plain, summary, error)) << error;
  vo.section = "subject";
  vo.section_margin_m = 0.5;
  ASSERT_TRUE(make_review_views(*store, vo, cut, summary, error)) << error;
  ASSERT_EQ(cut.size(), 1u);
  ASSERT_TRUE(cut[0].section.has_box);
  EXPECT_EQ(summary.obstructed, 1u);
  EXPECT_EQ(cut[0].section.box.min, glm::dvec3(-1.5, -1, -0.5));
  EXPECT_EQ(cut[0].section.box.max, glm::dvec3(1.5, 1, 2));
  EXPECT_TRUE(plain[0].section.empty());
  EXPECT_EQ(plain[0].camera, cut[0].camera);
  // As render --views draws a view: its subject highlighted, its section applied.
  const auto draw = [&](const ReviewView& v) {
    RenderOptions options;
    options.highlight_ids = v.subject;
    options.section = v.section;
    auto r = Renderer::create(*store, options, error);
    EXPECT_TRUE(r) << error;
    Image image;
    FrameStats stats;
    if (r) render(*r, v.camera, 320, 180, image, stats);
    return image;
  };
  const Image before = draw(plain[0]), after = draw(cut[0]);
  ASSERT_FALSE(after.rgba.empty());
  ASSERT_FALSE(before.rgba.empty());
  const Rgb b = pixel(before, 160, 90), a = pixel(after, 160, 90);
  // The subject's own orange, no longer behind a see-through wall: more saturated.
  EXPECT_GT(a.r - a.b, b.r - b.b + 20) << "before " << b.r << "," << b.g << "," << b.b << " after "
                                         << a.r << "," << a.g << "," << a.b;
  EXPECT_GT(a.r, 2 * a.g - 10);  // orange: red over green over blue
  EXPECT_GT(a.g, a.b);
}

// ---- the command line

struct Outcome {
  int status = -1;
  std::string out, err;
};
std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}
Outcome run(const std::string& args) {
  TempDir dir;
  fs::create_directories(dir.str());
  const fs::path out = fs::path(dir.str()) / "stdout", err = fs::path(dir.str()) / "stderr";
  const std::string cmd = std::string(PLANTVIEW_BIN) + " " + args + " >" + out.string() + " 2>" +
                          err.string();
  const int raw = std::system(cmd.c_str());
  Outcome o;
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  o.out = slurp(out);
  o.err = slurp(err);
  return o;
}
// The last "objects": N of an export's summary line.
uint64_t objects_written(const std::string& summary) {
  const size_t at = summary.rfind("\"objects\":");
  return at == std::string::npos ? 0 : std::stoull(summary.substr(at + 10));
}

// glTF export leaves out what the section removes wholly, and keeps what it cuts.
TEST(SectionCli, ExportLeavesOutWhatTheSectionRemoves) {
  TempDir dir;
  fs::create_directories(dir.str());
  const std::string store = dir.str() + "/a";
  ASSERT_EQ(run("gen --preset a --store " + store).status, 0);
  const Outcome all = run("export --store " + store + " --gltf " + dir.str() + "/all.glb");
  ASSERT_EQ(all.status, 0) << all.err;
  const Outcome slab = run("export --store " + store + " --gltf " + dir.str() +
                           "/slab.glb --clip 0,0,3,0,0,1 --clip=0,0,1,0,0,-1");
  ASSERT_EQ(slab.status, 0) << slab.err;
  const uint64_t n_all = objects_written(all.out), n_slab = objects_written(slab.out);
  EXPECT_GT(n_slab, 0u);
  EXPECT_LT(n_slab, n_all);
}

TEST(SectionCli, UsageErrorsExitTwoNamingTheOption) {
  const std::string render = "render --store /nonexistent --out /tmp/x.png ";
  Outcome o = run(render + "--clip 0,0,12,0,0,0");
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--clip"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("no direction"), std::string::npos) << o.err;
  o = run(render + "--section-box 0,0,0,1,-1,1");
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--section-box"), std::string::npos) << o.err;
  std::string seven;
  for (int i = 0; i < 7; ++i) seven += "--clip 0,0," + std::to_string(i) + ",0,0,1 ";
  o = run(render + seven);
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--clip: at most 6"), std::string::npos) << o.err;
  o = run(render + "--clip 1,2,3");
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--clip"), std::string::npos) << o.err;
  o = run("views --store /nonexistent --per equipment --out /tmp/v.json --section walls");
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--section"), std::string::npos) << o.err;
  o = run("export --store /nonexistent --gltf /tmp/x.glb --section-box 1,1,1,0,0,0");
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--section-box"), std::string::npos) << o.err;
}

}  // namespace
}  // namespace plantview
