// A frame's picture depends on its camera and options only, not on the frames rendered before
// it: the renderer keeps decoded objects, merged runs, residency and chosen levels from frame to
// frame, and none of that may show. The same view rendered fresh and after a walkthrough (with
// every policy, occlusion on and off) gives equal object-id buffers and equal colours.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

using test::TempDir;

std::unique_ptr<Renderer> make_renderer(const Store& store, LodPolicy policy, bool occlusion) {
  test::gl_context();
  RenderOptions options;
  options.lod_policy = policy;
  options.occlusion = occlusion;
  std::string error;
  auto r = Renderer::create(store, options, error);
  EXPECT_TRUE(r) << error;
  return r;
}

// Pixels whose object id (or colour) differs.
size_t differing_ids(const Image& a, const Image& b) {
  size_t n = 0;
  for (size_t p = 0; p < a.object_ids.size(); ++p) n += a.object_ids[p] != b.object_ids[p];
  return n;
}
size_t differing_colours(const Image& a, const Image& b) {
  size_t n = 0;
  for (size_t p = 0; p + 3 < a.rgba.size(); p += 4)
    n += a.rgba[p] != b.rgba[p] || a.rgba[p + 1] != b.rgba[p + 1] || a.rgba[p + 2] != b.rgba[p + 2];
  return n;
}

// Renders a walkthrough of preset a with `policy`, occlusion on and off; at two views of its
// second half it also renders the view with a fresh renderer and compares.
void expect_views_independent_of_history(LodPolicy policy) {
  TempDir dir;
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  ASSERT_TRUE(store) << error;
  GenerateOptions g;
  g.preset = 'a';
  const IngestResult result = ingest_generated(*store, g);
  ASSERT_TRUE(result) << result.error().message;
  std::vector<Camera> walk;
  ASSERT_TRUE(make_camera_path(PathKind::walkthrough, 8, *store, walk, error)) << error;
  const uint32_t w = 320, h = 180;
  for (const bool occlusion : {true, false}) {
    SCOPED_TRACE(std::string(lod_policy_name(policy)) + (occlusion ? ", occlusion on" : ", occlusion off"));
    auto walked = make_renderer(*store, policy, occlusion);
    Image image;
    FrameStats stats;
    for (size_t v = 0; v < walk.size(); ++v) {
      ASSERT_TRUE(walked->render(walk[v], w, h, true, image, stats, error)) << error;
      if (v != 5 && v != 7) continue;
      auto fresh = make_renderer(*store, policy, occlusion);
      Image alone;
      ASSERT_TRUE(fresh->render(walk[v], w, h, true, alone, stats, error)) << error;
      ASSERT_EQ(image.object_ids.size(), alone.object_ids.size());
      EXPECT_EQ(differing_ids(image, alone), 0u) << "view " << v;
      EXPECT_EQ(differing_colours(image, alone), 0u) << "view " << v;
    }
  }
}

TEST(FrameHistory, AViewLooksTheSameFreshAndAfterAWalkthroughWithPolicyNone) {
  expect_views_independent_of_history(LodPolicy::none);
}

TEST(FrameHistory, AViewLooksTheSameFreshAndAfterAWalkthroughWithPolicyDistance) {
  expect_views_independent_of_history(LodPolicy::distance);
}

TEST(FrameHistory, AViewLooksTheSameFreshAndAfterAWalkthroughWithPolicyScreenSpace) {
  expect_views_independent_of_history(LodPolicy::screen_space);
}

}  // namespace
}  // namespace plantview
