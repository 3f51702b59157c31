// The looks a reviewer sees, as golden images: preset c's default overview, a still inside the
// plant, an equipment item's highlighted review view and a plan slab (a section), each rendered
// by a fresh renderer with the stills' defaults (antialiasing, ambient occlusion, ground) and
// compared with a reference PNG in tests/data/reference/looks/ (PSNR >= 30 dB and at most 2% of pixels differing; on
// failure the actual image and a difference image are written to the temporary directory and
// named). PLANTVIEW_UPDATE_REFERENCES=1 rewrites the references: look at them before committing.
// And what a highlight means, checked on the pixels: the subject keeps its own hue, in the
// first frame of a renderer and in every frame after, whatever came before; the rest is
// desaturated. And a change image (a generated plant's second revision). And each look (and a
// clash view's: two colours, see-through, a section box) the same image on a renderer that drew
// the others before it as on a fresh one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include "plantview/camera.h"
#include "plantview/review.h"
#include "plantview/generate.h"
#include "plantview/image.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;

constexpr uint32_t kWidth = 320, kHeight = 180;

// Preset c (40,746 objects), generated once for every test of this file.
class Looks : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    store_ = test::generated_store(*dir_, 'c').release();
    ASSERT_TRUE(store_);
  }
  static void TearDownTestSuite() {
    delete store_;
    delete dir_;
  }

  static std::unique_ptr<Renderer> renderer(const RenderOptions& options = RenderOptions{}) {
    test::gl_context();
    std::string error;
    auto r = Renderer::create(*store_, options, error);
    EXPECT_TRUE(r) << error;
    return r;
  }

  static Image render(Renderer& r, const Camera& camera) {
    Image image;
    FrameStats stats;
    std::string error;
    EXPECT_TRUE(r.render(camera, kWidth, kHeight, true, image, stats, error)) << error;
    return image;
  }

  // The review view of one equipment item (as `plantview views --per equipment` fits it).
  static ReviewView equipment_view(const std::string& tag) {
    ReviewViewOptions options;
    options.per = "equipment";
    options.select = tag;
    options.aspect = double(kWidth) / kHeight;
    std::vector<ReviewView> views;
    ReviewViewsSummary summary;
    std::string error;
    EXPECT_TRUE(make_review_views(*store_, options, views, summary, error)) << error;
    EXPECT_EQ(views.size(), 1u) << tag;
    return views.empty() ? ReviewView{} : views.front();
  }

  // A golden look: its reference's name, the renderer's options and the camera.
  struct Look {
    std::string name;
    RenderOptions options;
    Camera camera;
  };
  static Look look(const std::string& name) {
    Look l{name, RenderOptions{}, Camera{}};
    std::string error;
    auto view = store_->read(error);
    EXPECT_TRUE(view) << error;
    if (name == "overview" || name == "colour_by") {
      // Categories (view_filters.h: colour_by): each material a palette colour, objects without
      // one grey. (The legend is the caption's, drawn by the CLI, not here.)
      if (name == "colour_by") l.options.style.colour_by = "Material";
      l.camera = default_camera(overview_boxes(*view), double(kWidth) / kHeight);
    } else if (name == "interior") {
      // Among the pumps and exchangers of unit 01, under the pipe rack: curved shells, elbows and
      // contact shadows, where half-resolution ambient occlusion once left blocks.
      l.camera.eye_m = {8.0, 16.0, 3.0};
      l.camera.target_m = {16.0, 24.0, 1.0};
    } else if (name == "highlight") {
      const ReviewView v = equipment_view("P-01-001A");
      EXPECT_FALSE(v.subject.empty());
      l.options.highlight_ids = v.subject;
      l.camera = v.camera;
    } else if (name == "clash") {
      // A clash view's look (clash.h: clash_views; not a golden): the subject in its own colour,
      // see-through, the rest ghosted, cut to a box around it.
      const ReviewView v = equipment_view("P-01-001A");
      EXPECT_FALSE(v.subject.empty());
      l.options.highlight_ids = v.subject;
      for (const uint64_t id : v.subject) l.options.subject_colours.push_back({id, Colour{225, 35, 35, 255}, "", true});
      l.options.section.has_box = true;
      l.options.section.box = {v.camera.target_m - glm::dvec3(1.5), v.camera.target_m + glm::dvec3(1.5)};
      l.camera = v.camera;
    } else if (name == "section") {
      // A 2 m plan slab (clip planes 1 m and 3 m above the plant's lowest point), seen from
      // above at an angle: vessels, a pipe rack's legs, pumps of unit 01.
      const double bottom = view->info().statistics.bounds.min.z + 1.0, top = bottom + 2.0;
      l.options.section.planes.push_back({{0, 0, top}, {0, 0, 1}});
      l.options.section.planes.push_back({{0, 0, bottom}, {0, 0, -1}});
      l.camera.target_m = {12.0, 14.0, bottom};
      l.camera.eye_m = {4.0, 6.0, bottom + 8.3};
    } else {
      ADD_FAILURE() << "no look " << name;
    }
    return l;
  }

  // Renders the look on a fresh renderer and compares it with its reference.
  static void expect_look_matches_reference(const std::string& name);

  static Colour colour_of(uint64_t id) {
    std::string error;
    auto view = store_->read(error);
    EXPECT_TRUE(view) << error;
    std::optional<uint32_t> slot;
    EXPECT_TRUE(view->slot_of(id, slot, error)) << error;
    Object o;
    EXPECT_TRUE(slot && view->object(*slot, o, false, error)) << error;
    return o.colour;
  }

  static test::TempDir* dir_;
  static Store* store_;
};
test::TempDir* Looks::dir_ = nullptr;
Store* Looks::store_ = nullptr;

// Compares with the reference (or writes it, with PLANTVIEW_UPDATE_REFERENCES set).
void expect_matches_reference(const Image& actual, const std::string& name) {
  const std::string reference = std::string(PLANTVIEW_TEST_DATA) + "/reference/looks/" + name + ".png";
  std::string error;
  if (std::getenv("PLANTVIEW_UPDATE_REFERENCES")) {
    fs::create_directories(fs::path(reference).parent_path());
    ASSERT_TRUE(write_image(reference, actual, 90, error)) << error;
  }
  Image expected;
  ASSERT_TRUE(read_image(reference, expected, error)) << error;
  ImageComparison c;
  ASSERT_TRUE(compare_images(actual, expected, c, error)) << error;
  if (c.psnr_db < 30.0 || c.differing_share > 0.02) {
    const fs::path out = fs::temp_directory_path() / ("plantview-look-" + name + "-actual.png");
    const fs::path diff = fs::temp_directory_path() / ("plantview-look-" + name + "-diff.png");
    write_image(out.string(), actual, 90, error);
    write_difference_image(actual, expected, diff.string(), error);
    ADD_FAILURE() << name << ": PSNR " << c.psnr_db << " dB, " << 100 * c.differing_share
                  << "% differing from " << reference << "; actual " << out << ", difference "
                  << diff;
  }
}

// Hue (degrees) and saturation (HSV, 0..1) of an RGB colour.
struct Hsv {
  double hue_deg = 0, saturation = 0;
};
Hsv hsv(double r, double g, double b) {
  const double hi = std::max({r, g, b}), lo = std::min({r, g, b}), d = hi - lo;
  Hsv out;
  out.saturation = hi > 0 ? d / hi : 0;
  if (d <= 0) return out;
  double h = hi == r ? std::fmod((g - b) / d, 6.0) : hi == g ? (b - r) / d + 2 : (r - g) / d + 4;
  out.hue_deg = std::fmod(60 * h + 360, 360);
  return out;
}
double hue_distance_deg(double a, double b) {
  const double d = std::fabs(a - b);
  return std::min(d, 360 - d);
}

// The mean colour of the pixels `where` selects, as hue and saturation.
template <class Where>
Hsv mean_hsv(const Image& image, Where where, size_t& count) {
  double r = 0, g = 0, b = 0;
  count = 0;
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
    if (!where(i)) continue;
    r += image.rgba[4 * i];
    g += image.rgba[4 * i + 1];
    b += image.rgba[4 * i + 2];
    ++count;
  }
  return count ? hsv(r / count, g / count, b / count) : Hsv{};
}

void Looks::expect_look_matches_reference(const std::string& name) {
  const Look l = look(name);
  auto r = renderer(l.options);
  ASSERT_TRUE(r);
  expect_matches_reference(render(*r, l.camera), name);
}

TEST_F(Looks, TheDefaultOverviewMatchesItsReference) { expect_look_matches_reference("overview"); }
TEST_F(Looks, AnOverviewColouredByMaterialMatchesItsReference) { expect_look_matches_reference("colour_by"); }
TEST_F(Looks, AStillInsideThePlantMatchesItsReference) { expect_look_matches_reference("interior"); }
TEST_F(Looks, AHighlightedReviewViewMatchesItsReference) { expect_look_matches_reference("highlight"); }
// Only the slab drawn, the cut faces of vessels, walls and pipes capped in their colours,
// darker, over the floor grid.
TEST_F(Looks, APlanSlabMatchesItsReference) { expect_look_matches_reference("section"); }

// A look is the same image whatever its renderer drew before: a server's renderers serve every
// client in turn and a farm's draw one view after another (a cut frame's ground once kept the
// camera of the renderer's last uncut frame). Each look drawn by one renderer after each of the
// others against a fresh renderer's first frame of it.
TEST_F(Looks, EachLookIsTheSameImageAfterAnyOther) {
  const std::vector<std::string> names = {"overview", "colour_by", "interior", "highlight", "section", "clash"};
  std::map<std::string, Image> first_frames;
  for (const std::string& name : names) {
    const Look l = look(name);
    auto r = renderer(l.options);
    ASSERT_TRUE(r);
    first_frames[name] = render(*r, l.camera);
  }
  auto r = renderer();
  ASSERT_TRUE(r);
  std::string after = "(none)";
  for (const char* name : {"section", "interior", "highlight", "colour_by", "overview", "clash", "section",
                           "highlight", "clash", "overview", "interior", "colour_by", "section", "colour_by",
                           "clash", "highlight", "interior", "overview", "clash"}) {
    const Look l = look(name);
    r->set_options(l.options);
    const Image image = render(*r, l.camera);
    ImageComparison c;
    std::string error;
    ASSERT_TRUE(compare_images(image, first_frames[name], c, error)) << error;
    std::printf("%s after %s: %.1f dB, %.3f%% differing\n", name, after.c_str(), c.psnr_db, 100 * c.differing_share);
    EXPECT_TRUE(c.psnr_db >= 50.0 && c.differing_share <= 0.0005)
        << name << " after " << after << ": PSNR " << c.psnr_db << " dB, " << 100 * c.differing_share
        << "% of pixels differing from a fresh renderer's";
    after = name;
  }
}

// The subject's pixels (where a plain frame of the same view draws it) keep its stored hue and
// most of its saturation; the pixels of other objects lose most of their saturation. Checked in
// a fresh renderer's first frame, in the frame after it, and after a plain frame.
TEST_F(Looks, AHighlightedSubjectKeepsItsHueAndTheRestIsDesaturated) {
  const ReviewView view = equipment_view("P-01-001A");
  ASSERT_EQ(view.subject.size(), 1u);
  const uint64_t subject = view.subject.front();
  const Colour stored = colour_of(subject);
  const Hsv own = hsv(stored.r, stored.g, stored.b);
  ASSERT_GT(own.saturation, 0.3) << "the check needs a subject of a saturated colour";

  const Image plain = render(*renderer(), view.camera);
  const auto on_subject = [&](size_t i) { return plain.object_ids[i] == subject; };
  const auto on_other = [&](size_t i) { return plain.object_ids[i] != 0 && plain.object_ids[i] != subject; };
  size_t n = 0;
  const Hsv plain_other = mean_hsv(plain, on_other, n);
  ASSERT_GT(n, 1000u);
  size_t subject_pixels = 0;
  ASSERT_GT(mean_hsv(plain, on_subject, subject_pixels).saturation, 0.3);
  ASSERT_GT(subject_pixels, 500u) << "the subject must be in view";

  RenderOptions options;
  options.highlight_ids = view.subject;
  auto lit = renderer(options);
  const auto expect_highlighted = [&](const Image& image, const char* when) {
    size_t count = 0;
    const Hsv s = mean_hsv(image, on_subject, count);
    EXPECT_LT(hue_distance_deg(s.hue_deg, own.hue_deg), 15.0) << when;
    EXPECT_GT(s.saturation, 0.6 * own.saturation) << when;
    const Hsv o = mean_hsv(image, on_other, count);
    EXPECT_LT(o.saturation, 0.6 * plain_other.saturation) << when;
    // The id buffer names the subject wherever the plain frame drew it (and where it is seen
    // through what hides it), and nothing else.
    size_t subject_ids = 0, others = 0;
    for (const uint64_t id : image.object_ids) {
      subject_ids += id == subject;
      others += id != 0 && id != subject;
    }
    EXPECT_GE(subject_ids, subject_pixels) << when;
    EXPECT_EQ(others, 0u) << when;
  };
  expect_highlighted(render(*lit, view.camera), "a fresh renderer's first frame");
  expect_highlighted(render(*lit, view.camera), "the frame after");
  RenderOptions plain_options;
  lit->set_options(plain_options);
  render(*lit, view.camera);
  lit->set_options(options);
  expect_highlighted(render(*lit, view.camera), "after a plain frame");
}

// A change image (render.h: RenderOptions::changes) of preset a after a revision that removes
// two equipment items, moves two 3 m along x and adds three boxes beside them, seen as the
// view of those changes would be fitted: removed items as red ghosts, moved ones amber at their
// new place over an amber-grey ghost at the old, added ones green, the rest ghosted.
TEST(ChangeLooks, AChangeImageMatchesItsReference) {
  test::TempDir dir;
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  ASSERT_TRUE(store) << error;
  GenerateOptions generate;
  generate.preset = 'a';
  const PlantModel model = generate_model(generate);
  ASSERT_TRUE(ingest_objects(*store, model.objects));
  // Equipment within 30 m of the first item (all of unit 01), in model order.
  std::vector<size_t> near;
  glm::dvec3 anchor(0.0);
  for (size_t i = 0; i < model.objects.size(); ++i) {
    const Object& o = model.objects[i];
    if (o.object_class != ObjectClass::equipment) continue;
    if (near.empty()) anchor = o.origin_m;
    if (glm::length(o.origin_m - anchor) < 30.0) near.push_back(i);
  }
  ASSERT_GE(near.size(), 4u);
  std::vector<Object> next = model.objects;
  DAabb changed;
  for (int k = 0; k < 4; ++k) changed.extend(object_bounds(next[near[size_t(k)]]));
  for (int k = 2; k < 4; ++k) {
    next[near[size_t(k)]].origin_m.x += 3.0;
    changed.extend(object_bounds(next[near[size_t(k)]]));
  }
  for (int k = 0; k < 3; ++k) {
    Object added;
    added.name = "/NEW-" + std::to_string(k);
    added.source = next.front().source;
    added.id = object_id(added.source, added.name);
    added.object_class = ObjectClass::equipment;
    added.colour = {150, 150, 150, 255};
    added.origin_m = changed.max + glm::dvec3(2.0, -3.0 * k - 1.0, -changed.max.z + 1.0);
    added.primitives.push_back(Primitive{Placement{}, Box{1.5f, 1.5f, 2.0f}});
    changed.extend(object_bounds(added));
    next.push_back(std::move(added));
  }
  next.erase(next.begin() + std::ptrdiff_t(near[1]));
  next.erase(next.begin() + std::ptrdiff_t(near[0]));
  ASSERT_TRUE(ingest_objects(*store, next));

  test::gl_context();
  RenderOptions options;
  options.changes = ChangeRange{1, 0};
  auto r = Renderer::create(*store, options, error);
  ASSERT_TRUE(r) << error;
  const Camera camera = default_camera(changed, double(kWidth) / kHeight);
  Image image;
  FrameStats stats;
  ASSERT_TRUE(r->render(camera, kWidth, kHeight, false, image, stats, error)) << error;
  EXPECT_EQ(stats.changes.added, 3u);
  EXPECT_EQ(stats.changes.modified, 2u);
  EXPECT_EQ(stats.changes.removed, 2u);
  expect_matches_reference(image, "changes");
  if (const char* out = std::getenv("PLANTVIEW_CHANGES_IMAGES")) {
    // A larger copy to look at.
    ASSERT_TRUE(r->render(camera, 960, 540, false, image, stats, error)) << error;
    EXPECT_TRUE(write_image((fs::path(out) / "changes-look.png").string(), image, 90, error)) << error;
  }
}

}  // namespace
}  // namespace plantview
