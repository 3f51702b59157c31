// A frame's picture depends on its camera and options only, not on the frames rendered before
// it: the renderer keeps decoded objects, merged runs, residency and chosen levels from frame to
// frame, and none of that may show. The same view rendered fresh and after a walkthrough (with
// every policy, occlusion on and off) gives equal object-id buffers and equal colours; with
// occlusion on, but for at most kEdgeSamplesAllowed pixels at an edge. Occlusion draws a frame
// in phases whose make-up follows the frame before (occlusion.h), and llvmpipe's vertex
// processing rounds a vertex differently in draws of a different make-up (measured: the same
// vertices, offsets and indices, one sample of a 2x2 supersampled pixel covered in one and not
// the other): an edge may move by a sample. Such a pixel shows, within a pixel of it, the
// object the other shows there. What history would change (a level, an object lost or
// doubled) moves whole edges and outlines, far more than that.
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

std::unique_ptr<Renderer> make_renderer(const Store& store, LodPolicy policy, bool occlusion,
                                        OcclusionTest test) {
  test::gl_context();
  RenderOptions options;
  options.lod_policy = policy;
  options.occlusion = occlusion;
  options.occlusion_test = test;
  std::string error;
  auto r = Renderer::create(store, options, error);
  EXPECT_TRUE(r) << error;
  return r;
}

constexpr size_t kEdgeSamplesAllowed = 4;

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

// Pixels whose object id differs and is not explained by an edge moved by up to a pixel: that
// of an object either shows there and the other shows within a pixel of it.
size_t unexplained_ids(const Image& a, const Image& b) {
  const auto near = [&](const Image& in, uint32_t x, uint32_t y, uint64_t id) {
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int64_t nx = int64_t(x) + dx, ny = int64_t(y) + dy;
        if (nx < 0 || ny < 0 || nx >= int64_t(in.width) || ny >= int64_t(in.height)) continue;
        if (in.object_ids[size_t(ny) * in.width + size_t(nx)] == id) return true;
      }
    return false;
  };
  size_t n = 0;
  for (uint32_t y = 0; y < a.height; ++y)
    for (uint32_t x = 0; x < a.width; ++x) {
      const size_t p = size_t(y) * a.width + x;
      if (a.object_ids[p] == b.object_ids[p]) continue;
      n += !near(b, x, y, a.object_ids[p]) && !near(a, x, y, b.object_ids[p]);
    }
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
  for (const int mode : {0, 1, 2}) {
    const bool occlusion = mode != 0;
    const OcclusionTest test = mode == 2 ? OcclusionTest::exact : OcclusionTest::coarse;
    SCOPED_TRACE(std::string(lod_policy_name(policy)) +
                 (occlusion ? ", occlusion on, " + std::string(occlusion_test_name(test)) + " test"
                            : ", occlusion off"));
    auto walked = make_renderer(*store, policy, occlusion, test);
    Image image;
    FrameStats stats;
    for (size_t v = 0; v < walk.size(); ++v) {
      ASSERT_TRUE(walked->render(walk[v], w, h, true, image, stats, error)) << error;
      if (v != 5 && v != 7) continue;
      auto fresh = make_renderer(*store, policy, occlusion, test);
      Image alone;
      ASSERT_TRUE(fresh->render(walk[v], w, h, true, alone, stats, error)) << error;
      ASSERT_EQ(image.object_ids.size(), alone.object_ids.size());
      const size_t allowed = occlusion ? kEdgeSamplesAllowed : 0;
      EXPECT_LE(differing_ids(image, alone), allowed) << "view " << v;
      EXPECT_EQ(unexplained_ids(image, alone), 0u) << "view " << v;
      EXPECT_LE(differing_colours(image, alone), allowed) << "view " << v;
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
