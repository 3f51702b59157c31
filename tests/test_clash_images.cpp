// Clash images (clash.h: clash_views with the store; render.h: see-through subject colours): a
// pipe buried wholly inside a vessel is found as a clash; its view draws the vessel see-through
// in its colour and the pipe opaque, so the pipe's pixels show in its red blended with the
// vessel's cyan where it projects; drawn with the vessel opaque (as before see-through
// subjects), nothing of the pipe is seen. The legend says which is see-through.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "plantview/clash.h"
#include "plantview/render.h"
#include "plantview/review.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

using test::TempDir;

constexpr Colour kGrey{150, 150, 150, 255};

Object make_object(const std::string& name, ObjectClass cls, glm::dvec3 origin, Primitive primitive) {
  return test::make_object(name, cls, origin, kGrey, std::move(primitive));
}

class BuriedClash : public ::testing::Test {
 protected:
  void SetUp() override {
    // A vertical vessel 2 m across, 4 m tall; a pipe 0.2 m across, 1.2 m long, wholly inside
    // it, along x; a beam beside the vessel as context.
    Primitive vessel{Placement{}, Cylinder{1.0f, 4.0f}};
    Primitive pipe{Placement{}, Cylinder{0.1f, 1.2f}};
    pipe.placement.linear = glm::mat3(glm::vec3(0, 0, -1), glm::vec3(0, 1, 0), glm::vec3(1, 0, 0));
    Primitive beam{Placement{}, Box{0.3f, 6.0f, 0.3f}};
    objects_ = {make_object("/V-1", ObjectClass::equipment, {50, 60, 3}, vessel),
                make_object("/P-1", ObjectClass::pipe, {50, 60, 3.3}, pipe),
                make_object("/BEAM-1", ObjectClass::structure, {48, 60, 1}, beam)};
    store_ = test::make_store(dir_, objects_);
    ASSERT_TRUE(store_);
  }
  // The one clash's view, made as `views --per clash` makes it.
  ReviewView clash_view() {
    std::string error;
    const auto view = store_->read(error);
    EXPECT_TRUE(view) << error;
    ClashSettings settings;
    settings.include_connected = true;  // (a store without pipelines)
    ClashReport report;
    EXPECT_TRUE(find_clashes(*view, dir_.str(), settings, report, error)) << error;
    EXPECT_EQ(report.clashes.size(), 1u);
    if (!report.clashes.empty()) first_point_ = report.clashes[0].points_m.front();
    std::vector<ReviewView> views;
    EXPECT_TRUE(clash_views(report, 16.0 / 9.0, *view, views, error)) << error;
    EXPECT_EQ(views.size(), 1u);
    return views.empty() ? ReviewView{} : views[0];
  }
  // The view drawn as `render --views` draws it (render_views.cpp), 320 x 180, with ids.
  Image draw(const ReviewView& view, FrameStats& stats) {
    test::gl_context();
    RenderOptions options;
    options.pixel_error = kStillPixelError;
    options.highlight_ids = view.subject;
    options.subject_colours = view.colours;
    options.section = view.section;
    std::string error;
    auto r = Renderer::create(*store_, options, error);
    EXPECT_TRUE(r) << error;
    Image image;
    if (r) {
      EXPECT_TRUE(r->render(view.camera, 320, 180, true, image, stats, error)) << error;
    }
    return image;
  }
  uint64_t vessel_id() const { return objects_[0].id; }
  uint64_t pipe_id() const { return objects_[1].id; }

  TempDir dir_;
  std::vector<Object> objects_;
  std::unique_ptr<Store> store_;
  glm::dvec3 first_point_{0.0};
};

TEST_F(BuriedClash, TheContainerIsSeeThroughAndTheBuriedPipeShowsThroughIt) {
  const ReviewView view = clash_view();
  ASSERT_EQ(view.colours.size(), 2u);
  const auto vessel = std::find_if(view.colours.begin(), view.colours.end(),
                                   [&](const SubjectColour& c) { return c.id == vessel_id(); });
  const auto pipe = std::find_if(view.colours.begin(), view.colours.end(),
                                 [&](const SubjectColour& c) { return c.id == pipe_id(); });
  ASSERT_NE(vessel, view.colours.end());
  ASSERT_NE(pipe, view.colours.end());
  EXPECT_TRUE(vessel->see_through);
  EXPECT_FALSE(pipe->see_through);
  EXPECT_NE(vessel->label.find("(see-through)"), std::string::npos) << vessel->label;
  // Framed on the pipe: a margin of three of its diameters, not the 1.5 m of a view without
  // sizes; the camera aimed at the deepest point.
  EXPECT_LT(view.section.box.max.x - view.section.box.min.x, 2 * (2 * kClashViewMarginM));
  EXPECT_LT(glm::distance(view.camera.target_m, first_point_), 1e-6);

  FrameStats stats;
  const Image image = draw(view, stats);
  ASSERT_EQ(image.object_ids.size(), size_t(320) * 180);
  // The pipe's pixels: its id (the see-through vessel writes none), its red tinted by the
  // vessel's cyan in front of it.
  uint64_t pipe_pixels = 0, vessel_tinted = 0;
  double r = 0, g = 0, b = 0;
  for (size_t i = 0; i < image.object_ids.size(); ++i) {
    const uint8_t* p = image.rgba.data() + 4 * i;
    if (image.object_ids[i] == pipe_id()) {
      ++pipe_pixels;
      r += p[0];
      g += p[1];
      b += p[2];
    } else if (image.object_ids[i] == 0 && p[2] > p[0] + 40) {
      ++vessel_tinted;  // cyan-blue: the see-through vessel over the background or context
    }
  }
  EXPECT_GT(pipe_pixels, 300u);  // (0.2 m x 1.2 m at this framing: about 2,000 pixels)
  ASSERT_GT(pipe_pixels, 0u);
  r /= double(pipe_pixels);
  g /= double(pipe_pixels);
  b /= double(pipe_pixels);
  EXPECT_GT(r, g + 30) << r << " " << g << " " << b;
  EXPECT_GT(r, b + 15) << r << " " << g << " " << b;
  EXPECT_GT(b, 40) << "tinted by the vessel in front: " << r << " " << g << " " << b;
  EXPECT_GT(vessel_tinted, 2000u);
  // The legend names both, the vessel see-through.
  ASSERT_EQ(stats.legend.key, "subjects");
  ASSERT_EQ(stats.legend.entries.size(), 2u);
  bool said = false;
  for (const FrameLegend::Entry& e : stats.legend.entries)
    said = said || e.value.find("see-through") != std::string::npos;
  EXPECT_TRUE(said);

  // The vessel opaque (both subjects as before see-through ones): the pipe is hidden.
  ReviewView opaque = view;
  for (SubjectColour& c : opaque.colours) c.see_through = false;
  FrameStats opaque_stats;
  const Image hidden = draw(opaque, opaque_stats);
  EXPECT_EQ(std::count(hidden.object_ids.begin(), hidden.object_ids.end(), pipe_id()), 0);
  EXPECT_GT(std::count(hidden.object_ids.begin(), hidden.object_ids.end(), vessel_id()), 2000);
}

// Two pipes of one size crossing: neither holds the other, both stay opaque; the section's
// margin comes from their size (3 diameters, at least 0.5 m), not the 1.5 m of a view without
// the store.
TEST(ClashViews, PartsOfOneSizeStayOpaque) {
  TempDir dir;
  Primitive along_x{Placement{}, Cylinder{0.1f, 3.0f}};
  along_x.placement.linear = glm::mat3(glm::vec3(0, 0, -1), glm::vec3(0, 1, 0), glm::vec3(1, 0, 0));
  Primitive along_y{Placement{}, Cylinder{0.1f, 3.0f}};
  along_y.placement.linear = glm::mat3(glm::vec3(1, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
  const std::vector<Object> objects = {make_object("/P-1", ObjectClass::pipe, {10, 10, 2}, along_x),
                                       make_object("/P-2", ObjectClass::pipe, {10, 10, 2.1}, along_y)};
  const auto store = test::make_store(dir, objects);
  ASSERT_TRUE(store);
  std::string error;
  const auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  ClashSettings settings;
  settings.include_connected = true;
  ClashReport report;
  ASSERT_TRUE(find_clashes(*view, dir.str(), settings, report, error)) << error;
  ASSERT_EQ(report.clashes.size(), 1u);
  std::vector<ReviewView> views;
  ASSERT_TRUE(clash_views(report, 16.0 / 9.0, *view, views, error)) << error;
  ASSERT_EQ(views.size(), 1u);
  for (const SubjectColour& c : views[0].colours) {
    EXPECT_FALSE(c.see_through) << c.label;
    EXPECT_EQ(c.label.find("see-through"), std::string::npos) << c.label;
  }
  const glm::dvec3 box = views[0].section.box.max - views[0].section.box.min;
  const glm::dvec3 plain = clash_views(report, 16.0 / 9.0)[0].section.box.max -
                           clash_views(report, 16.0 / 9.0)[0].section.box.min;
  EXPECT_LT(box.x, plain.x - 1.0);
}

// The views file carries the flag: written only when set, read back, a bad value refused.
TEST_F(BuriedClash, TheViewsFileKeepsSeeThrough) {
  const ReviewView view = clash_view();
  const std::string text = review_views_json({view}, "clash");
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n') > 0, true);
  size_t flags = 0;
  for (size_t at = text.find("\"see_through\""); at != std::string::npos; at = text.find("\"see_through\"", at + 1))
    ++flags;
  EXPECT_EQ(flags, 1u);
  std::vector<ReviewView> reread;
  std::string error;
  ASSERT_TRUE(parse_review_views(text, reread, error)) << error;
  ASSERT_EQ(reread.size(), 1u);
  EXPECT_EQ(reread[0].colours, view.colours);
  std::string bad = text;
  const size_t at = bad.find("\"see_through\": true");
  ASSERT_NE(at, std::string::npos) << text;
  bad.replace(at, std::string("\"see_through\": true").size(), "\"see_through\": 1");
  EXPECT_FALSE(parse_review_views(bad, reread, error));
  EXPECT_NE(error.find("see_through' must be true or false"), std::string::npos) << error;
}

}  // namespace
}  // namespace plantview
