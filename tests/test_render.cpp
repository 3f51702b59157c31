// The headless renderer on whatever EGL offers (llvmpipe in CI): reference images, culling,
// level choice, the vertex budget and its eviction order, picking, far-from-origin precision,
// cameras, paths and image files.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <optional>
#include <random>
#include <set>

#include "gl/backend.h"
#include "hlod.h"
#include "lod.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "streaming/residency.h"
#include "support/gl_context.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

Object make_object(const std::string& name, ObjectClass cls, glm::dvec3 origin, Shape shape,
                   Colour colour = {200, 120, 40, 255}) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = cls;
  o.colour = colour;
  o.origin_m = origin;
  o.primitives.push_back(Primitive{Placement{}, std::move(shape)});
  return o;
}

std::unique_ptr<Store> make_store(const TempDir& dir, const std::vector<Object>& objects) {
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  EXPECT_TRUE(store) << error;
  const IngestResult result = ingest_objects(*store, objects);
  EXPECT_TRUE(result) << result.error().message;
  return store;
}

struct Frame {
  Image image;
  FrameStats stats;
};

Frame render(Renderer& r, const Camera& camera, uint32_t w = 160, uint32_t h = 120) {
  Frame f;
  std::string error;
  EXPECT_TRUE(r.render(camera, w, h, true, f.image, f.stats, error)) << error;
  return f;
}

// Tests use a small arena unless they say otherwise: allocating it is most of a renderer's start.
RenderOptions small(LodPolicy policy = LodPolicy::screen_space) {
  RenderOptions o;
  o.lod_policy = policy;
  o.vertex_budget_bytes = 16u << 20;
  return o;
}

std::unique_ptr<Renderer> make_renderer(const Store& store, RenderOptions options = small()) {
  test::gl_context();
  std::string error;
  auto r = Renderer::create(store, options, error);
  EXPECT_TRUE(r) << error;
  return r;
}

Camera look(glm::dvec3 eye, glm::dvec3 target) {
  Camera c;
  c.eye_m = eye;
  c.target_m = target;
  return c;
}

// 400 large spheres, 20 x 20, 4 m apart: more than a small arena holds at once.
std::vector<Object> sphere_field() {
  std::vector<Object> objects;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j)
      objects.push_back(make_object("S" + std::to_string(i) + "_" + std::to_string(j),
                                    ObjectClass::equipment, {i * 4.0, j * 4.0, 0},
                                    Sphere{1.5f + 0.1f * float(j % 5)}));
  return objects;
}

std::set<uint64_t> ids_in(const Image& image) {
  std::set<uint64_t> ids(image.object_ids.begin(), image.object_ids.end());
  ids.erase(0);
  return ids;
}

// --- images -----------------------------------------------------------------------------------

TEST(RenderImage, OneCylinderMatchesTheReferenceImage) {
  TempDir dir;
  auto store = make_store(dir, {make_object("C", ObjectClass::pipe, {0, 0, 0},
                                            Cylinder{0.5f, 2.0f})});
  auto r = make_renderer(*store, small(LodPolicy::none));
  Camera cam = look({3, -4, 2}, {0, 0, 0});
  cam.fov_deg = 40;
  Frame f = render(*r, cam, 200, 150);
  const std::string reference = std::string(PLANTVIEW_TEST_DATA) + "/reference/cylinder.png";
  Image expected;
  std::string error;
  if (std::getenv("PLANTVIEW_UPDATE_REFERENCES")) {
    ASSERT_TRUE(write_image(reference, f.image, 90, error)) << error;
  }
  ASSERT_TRUE(read_image(reference, expected, error)) << error;
  ImageComparison c;
  ASSERT_TRUE(compare_images(f.image, expected, c, error)) << error;
  if (c.psnr_db < 30.0 || c.differing_share > 0.02) {
    const fs::path out = fs::temp_directory_path() / "plantview-cylinder-actual.png";
    const fs::path diff = fs::temp_directory_path() / "plantview-cylinder-diff.png";
    write_image(out.string(), f.image, 90, error);
    write_difference_image(f.image, expected, diff.string(), error);
    ADD_FAILURE() << "PSNR " << c.psnr_db << " dB, " << 100 * c.differing_share
                  << "% differing; actual " << out << ", difference " << diff;
  }
}

TEST(RenderImage, EncodesPngLosslesslyAndJpegCloseToIt) {
  Image image;
  image.width = 64;
  image.height = 48;
  image.rgba.resize(64 * 48 * 4);
  for (size_t i = 0; i < image.rgba.size(); ++i) image.rgba[i] = (i % 4 == 3) ? 255 : uint8_t((i * 7) / 13);
  TempDir dir;
  fs::create_directories(dir.path());
  std::string error;
  const std::string png = (dir.path() / "a.png").string();
  ASSERT_TRUE(write_image(png, image, 90, error)) << error;
  Image back;
  ASSERT_TRUE(read_image(png, back, error)) << error;
  EXPECT_EQ(back.rgba, image.rgba);
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(encode_image(image, ImageFormat::jpeg, 95, jpeg, error)) << error;
  ASSERT_GT(jpeg.size(), 100u);
  EXPECT_EQ(jpeg[0], 0xff);
  EXPECT_EQ(jpeg[1], 0xd8);
  EXPECT_FALSE(encode_image(image, ImageFormat::jpeg, 0, jpeg, error));
  EXPECT_FALSE(write_image((dir.path() / "a.tiff").string(), image, 90, error));
  EXPECT_NE(error.find("a.tiff"), std::string::npos);
}

TEST(RenderImage, ComparisonReportsIdenticalAndDifferentImages) {
  Image a;
  a.width = 10;
  a.height = 10;
  a.rgba.assign(400, 100);
  Image b = a;
  ImageComparison c;
  std::string error;
  ASSERT_TRUE(compare_images(a, b, c, error)) << error;
  EXPECT_TRUE(std::isinf(c.psnr_db));
  EXPECT_EQ(c.differing_share, 0.0);
  b.rgba[0] = 200;  // one pixel's red
  ASSERT_TRUE(compare_images(a, b, c, error));
  EXPECT_NEAR(c.differing_share, 0.01, 1e-9);
  EXPECT_NEAR(c.max_difference, 100.0 / 255.0, 1e-3);
  EXPECT_GT(c.psnr_db, 20.0);
  b.width = 5;
  b.rgba.resize(200);
  EXPECT_FALSE(compare_images(a, b, c, error));
  EXPECT_NE(error.find("sizes differ"), std::string::npos);
}

TEST(RenderImage, ACaptionDrawsTextInAStripAlongTheBottomAndKeepsTheSize) {
  Image image;
  image.width = 320;
  image.height = 180;
  image.rgba.assign(size_t(320) * 180 * 4, 0);
  for (size_t i = 3; i < image.rgba.size(); i += 4) image.rgba[i] = 255;  // opaque black
  image.object_ids.assign(size_t(320) * 180, 7);
  const Image before = image;
  std::string error;
  ASSERT_TRUE(add_caption(image, "Pump P-101A", {"Tag P-101A", "Type PUMP"}, error)) << error;
  EXPECT_EQ(image.width, 320u);
  EXPECT_EQ(image.height, 180u);
  ASSERT_EQ(image.rgba.size(), before.rgba.size());
  EXPECT_EQ(image.object_ids, before.object_ids);
  // The top half is untouched; the strip below is light, with dark glyph pixels on it, in the
  // rows of each of the three lines of text.
  const auto pixel = [&](uint32_t x, uint32_t y) { return &image.rgba[(size_t(y) * 320 + x) * 4]; };
  for (uint32_t y = 0; y < 90; ++y)
    for (uint32_t x = 0; x < 320; ++x) ASSERT_EQ(pixel(x, y)[0], 0) << x << "," << y;
  std::vector<uint32_t> dark_per_row(180, 0), light_per_row(180, 0);
  for (uint32_t y = 90; y < 180; ++y)
    for (uint32_t x = 0; x < 320; ++x) {
      const uint8_t v = pixel(x, y)[1];
      dark_per_row[y] += v < 80;
      light_per_row[y] += v > 200;
    }
  EXPECT_GT(light_per_row[179], 300u);  // the strip reaches the bottom row
  // Rows with ink, grouped into runs: one run per line of text.
  int runs = 0;
  bool in_run = false;
  for (uint32_t y = 90; y < 180; ++y) {
    const bool ink = dark_per_row[y] > 0 && light_per_row[y] > 100;
    if (ink && !in_run) ++runs;
    in_run = ink;
  }
  EXPECT_GE(runs, 3);  // (a descender's thin tail may make a run of its own)
  // Fewer lines, a lower strip: its top is the first row that changed.
  Image title_only = before;
  ASSERT_TRUE(add_caption(title_only, "Pump P-101A", {}, error)) << error;
  const auto first_changed = [&](const Image& im) {
    for (uint32_t y = 0; y < 180; ++y)
      if (!std::equal(im.rgba.begin() + y * 320 * 4, im.rgba.begin() + (y + 1) * 320 * 4,
                      before.rgba.begin() + y * 320 * 4))
        return y;
    return 180u;
  };
  EXPECT_LT(first_changed(image), first_changed(title_only));
  EXPECT_LT(first_changed(title_only), 180u);
  if (runs < 3) {
    const fs::path out = fs::temp_directory_path() / "plantview-caption-actual.png";
    write_image(out.string(), image, 90, error);
    ADD_FAILURE() << "see " << out;
  }
  uint32_t ink_total = 0;
  for (uint32_t y = 90; y < 180; ++y) ink_total += dark_per_row[y];
  EXPECT_GT(ink_total, 200u);  // glyphs, not a rule or two
}

TEST(RenderImage, ACaptionTooLongForTheWidthIsCutAndExtraLinesAreLeftOut) {
  Image image;
  image.width = 120;
  image.height = 60;
  image.rgba.assign(size_t(120) * 60 * 4, 255);
  std::string error;
  const std::vector<std::string> many(40, "Description: a very long line of text that cannot fit");
  ASSERT_TRUE(add_caption(image, "A title much longer than one hundred and twenty pixels", many, error))
      << error;
  // At most half the image is strip: the top rows stay white.
  for (size_t i = 0; i < size_t(120) * 29 * 4; ++i) ASSERT_EQ(image.rgba[i], 255) << i;
  Image tiny;
  tiny.width = 8;
  tiny.height = 8;
  tiny.rgba.assign(8 * 8 * 4, 255);
  EXPECT_FALSE(add_caption(tiny, "T", {}, error));
  EXPECT_NE(error.find("too small"), std::string::npos) << error;
}

// Every image call with PLANTVIEW_IMAGE_MODULE pointing at nothing; prints each error on
// stderr. 0 when each call failed and wrote nothing.
int image_calls_without_the_module(const fs::path& png) {
  ::setenv("PLANTVIEW_IMAGE_MODULE", "/nonexistent/plantview_image_oiio.so", 1);
  preload_image_io();
  preload_image_io();  // harmless twice
  Image image;
  image.width = 4;
  image.height = 2;
  image.rgba.assign(32, 128);
  std::string error;
  std::vector<uint8_t> bytes{1, 2, 3};
  const bool encoded = encode_image(image, ImageFormat::png, 90, bytes, error);
  std::fprintf(stderr, "encode_image: %s\n", error.c_str());
  error.clear();
  const bool written = write_image(png.string(), image, 90, error);
  std::fprintf(stderr, "write_image: %s\n", error.c_str());
  error.clear();
  Image back;
  const bool read = read_image(png.string(), back, error);
  std::fprintf(stderr, "read_image: %s\n", error.c_str());
  return !encoded && bytes.empty() && !written && !fs::exists(png) && !read ? 0 : 1;
}

// The image module is loaded once per process, so this runs in a child process of its own
// (re-executed: "threadsafe" death-test style).
TEST(RenderImage, AMissingImageModuleFailsEachCallNamingThePathTried) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  // Not a TempDir: the child exits without unwinding.
  const fs::path png = fs::temp_directory_path() /
                       ("plantview-render-test-no-module-" + std::to_string(::getpid()) + ".png");
  EXPECT_EXIT(std::exit(image_calls_without_the_module(png)), ::testing::ExitedWithCode(0),
              "encode_image: image: cannot load the image module \\(OpenImageIO\\); tried "
              "PLANTVIEW_IMAGE_MODULE=/nonexistent/plantview_image_oiio.so: .*No such file.*\n"
              "write_image: image: cannot load the image module.*/nonexistent/.*\n"
              "read_image: image: cannot load the image module.*/nonexistent/");
}

// --- culling and picking ----------------------------------------------------------------------

TEST(RenderCull, ObjectsOutsideTheFrustumAreNotDrawnAndVisibleOnesAre) {
  TempDir dir;
  const auto front = make_object("front", ObjectClass::equipment, {0, 5, 0}, Box{1, 1, 1});
  const auto behind = make_object("behind", ObjectClass::equipment, {0, -5, 0}, Box{1, 1, 1});
  const auto aside = make_object("aside", ObjectClass::equipment, {50, 5, 0}, Box{1, 1, 1});
  auto store = make_store(dir, {front, behind, aside});
  auto r = make_renderer(*store);
  Frame f = render(*r, look({0, 0, 0}, {0, 1, 0}));
  EXPECT_EQ(f.stats.objects_visible, 1u);
  EXPECT_EQ(f.stats.objects_culled, 2u);
  EXPECT_EQ(f.stats.triangles, 12u);
  EXPECT_EQ(ids_in(f.image), std::set<uint64_t>{front.id});
  // Turning round shows the other one.
  f = render(*r, look({0, 0, 0}, {0, -1, 0}));
  EXPECT_EQ(ids_in(f.image), std::set<uint64_t>{behind.id});
}

TEST(RenderPick, TheIdUnderAPixelIsTheObjectDrawnThere) {
  TempDir dir;
  const auto left = make_object("left", ObjectClass::equipment, {-1.5, 10, 0}, Box{1, 1, 1}, {255, 0, 0, 255});
  const auto right = make_object("right", ObjectClass::equipment, {1.5, 10, 0}, Sphere{0.6f}, {0, 0, 255, 255});
  auto store = make_store(dir, {left, right});
  auto r = make_renderer(*store);
  Frame f = render(*r, look({0, 0, 0}, {0, 10, 0}), 200, 100);
  const auto at = [&](uint32_t x, uint32_t y) { return f.image.object_ids[size_t(y) * 200 + x]; };
  const auto rgb = [&](uint32_t x, uint32_t y) { return &f.image.rgba[(size_t(y) * 200 + x) * 4]; };
  // x = 1.5 m at 10 m with a 50 degree fov spans 1.5 / (10 tan 25) of the half height (50 px).
  const uint32_t offset = uint32_t(std::lround(1.5 / (10 * std::tan(25 * M_PI / 180)) * 50));
  EXPECT_EQ(at(100 - offset, 50), left.id);
  EXPECT_EQ(at(100 + offset, 50), right.id);
  EXPECT_EQ(at(100, 50), 0u);   // the gap between them
  EXPECT_EQ(at(5, 5), 0u);      // the sky
  EXPECT_GT(rgb(100 - offset, 50)[0], rgb(100 - offset, 50)[2]);  // red box
  EXPECT_GT(rgb(100 + offset, 50)[2], rgb(100 + offset, 50)[0]);  // blue sphere
}

// --- level choice -----------------------------------------------------------------------------

TEST(RenderLod, TheChosenLevelIsTheCoarsestWhoseProjectedErrorIsUnderThePixelError) {
  const float error_m[4] = {0.001f, 0.004f, 0.016f, 0.064f};
  // 1000 px per metre: 1 mm is 1 px, 4 mm 4 px.
  EXPECT_EQ(detail::choose_level_screen_space(error_m, 4, 1000.0, 1.0), 0u);
  EXPECT_EQ(detail::choose_level_screen_space(error_m, 4, 1000.0, 4.5), 1u);
  EXPECT_EQ(detail::choose_level_screen_space(error_m, 4, 10.0, 1.0), 3u);
  EXPECT_EQ(detail::choose_level_screen_space(error_m, 4, 100.0, 1.0), 1u);  // 1.6 px at level 2
  EXPECT_EQ(detail::choose_level_screen_space(error_m, 4, 50.0, 1.0), 2u);
  EXPECT_NEAR(detail::pixels_per_metre(10.0, 90.0, 1000), 50.0, 1e-9);
  EXPECT_EQ(detail::choose_level_distance(4, 1.0, 1.0), 0u);
  EXPECT_EQ(detail::choose_level_distance(4, 12.0, 1.0), 1u);
  EXPECT_EQ(detail::choose_level_distance(4, 20.0, 1.0), 2u);
  EXPECT_EQ(detail::choose_level_distance(4, 1000.0, 1.0), 3u);
}

TEST(RenderLod, ARenderedCylinderCoarsensWithDistanceAsItsErrorProjects) {
  TempDir dir;
  const Primitive cyl{Placement{}, Cylinder{0.4f, 1.0f}};
  const MeshPlan plan = plan_mesh(cyl);
  ASSERT_GT(plan.level_count, 2);
  auto store = make_store(dir, {make_object("C", ObjectClass::pipe, {0, 0, 0}, Cylinder{0.4f, 1.0f})});
  auto r = make_renderer(*store);
  const uint32_t h = 400;
  uint32_t previous = UINT32_MAX;
  for (double d : {2.0, 8.0, 30.0, 120.0}) {
    Frame f = render(*r, look({0, -d, 0}, {0, 0, 0}), 400, h);
    uint32_t level = 0;
    for (uint32_t l = 0; l < 8; ++l)
      if (f.stats.triangles_by_level[l]) level = l;
    // The bounds' nearest point is 0.4 m closer than the axis.
    const double px_per_m = detail::pixels_per_metre(d - 0.4, 50.0, h);
    EXPECT_LE(plan.error_m[level] * px_per_m, 1.0) << "at " << d << " m";
    if (level + 1u < plan.level_count) {
      EXPECT_GT(plan.error_m[level + 1] * px_per_m, 1.0) << d;
    }
    EXPECT_LE(f.stats.triangles, previous);
    previous = uint32_t(f.stats.triangles);
  }
  // At 500 m the whole cylinder spans under a pixel: it is left out.
  Frame gone = render(*r, look({0, -500, 0}, {0, 0, 0}), 400, h);
  EXPECT_EQ(gone.stats.objects_subpixel, 1u);
  EXPECT_EQ(gone.stats.triangles, 0u);
  // Policy none draws level 0 everywhere.
  r->set_options(small(LodPolicy::none));
  Frame f = render(*r, look({0, -500, 0}, {0, 0, 0}), 400, h);
  EXPECT_EQ(f.stats.triangles, element_count(plan, 0));
}

TEST(RenderLod, PipesUnderAPixelAndThePixelErrorAreDrawnAsTheirCentreline) {
  TempDir dir;
  Object pipe = make_object("P", ObjectClass::pipe, {0, 0, 0}, Cylinder{0.05f, 4.0f});
  pipe.centreline = {{{0, 0, -2}, {0, 0, 2}, 0.1f}};
  auto store = make_store(dir, {pipe});
  auto r = make_renderer(*store);
  Frame near = render(*r, look({0, -3, 0}, {0, 0, 0}));
  EXPECT_EQ(near.stats.centreline_pipes, 0u);
  EXPECT_GT(near.stats.triangles, 0u);
  Frame far = render(*r, look({0, -400, 0}, {0, 0, 0}));
  EXPECT_EQ(far.stats.centreline_pipes, 1u);
  EXPECT_EQ(far.stats.triangles, 0u);
  EXPECT_EQ(far.stats.lines, 1u);
  EXPECT_EQ(ids_in(far.image), std::set<uint64_t>{pipe.id});  // still drawn, as a line

  // A finer pixel error than a pixel (stills) keeps a pipe solid down to that error: at 25 m
  // its diameter spans half a pixel (a line at 1 px, a cylinder at 0.25 px); at 100 m an
  // eighth (a line at both).
  RenderOptions fine = small();
  fine.pixel_error = 0.25;
  auto still = make_renderer(*store, fine);
  const double half_px = 0.1 * detail::pixels_per_metre(25.0 - 0.05, 50.0, 120);
  ASSERT_GT(half_px, 0.25);
  ASSERT_LT(half_px, 1.0);
  EXPECT_EQ(render(*r, look({0, -25, 0}, {0, 0, 0})).stats.centreline_pipes, 1u);
  const Frame solid = render(*still, look({0, -25, 0}, {0, 0, 0}));
  EXPECT_EQ(solid.stats.centreline_pipes, 0u);
  EXPECT_GT(solid.stats.triangles, 0u);
  EXPECT_EQ(ids_in(solid.image), std::set<uint64_t>{pipe.id});
  const Frame line = render(*still, look({0, -100, 0}, {0, 0, 0}));
  EXPECT_EQ(line.stats.centreline_pipes, 1u);
  EXPECT_EQ(line.stats.triangles, 0u);
}

// A thin far pipe's centreline covers what its diameter covers: half the diameter on screen,
// half the darkening across it (a 1-pixel line would darken alike at both distances), in the
// pipe's colour.
TEST(RenderLook, ACentrelineCoversItsProjectedDiameter) {
  TempDir dir;
  Object pipe = make_object("P", ObjectClass::pipe, {0, 0, 0}, Cylinder{0.05f, 4.0f});
  pipe.centreline = {{{0, 0, -2}, {0, 0, 2}, 0.1f}};
  auto store = make_store(dir, {pipe});
  RenderOptions options = small();
  options.ground = false;
  options.ambient_occlusion = false;
  for (const bool antialias : {false, true}) {
    options.antialias = antialias;
    auto r = make_renderer(*store, options);
    // Darkening across the rows through the middle of the pipe, summed, per row (in units of
    // the background-to-pipe difference of the red-blue balance, which only the pipe moves).
    const auto coverage = [&](double distance_m) {
      Frame f = render(*r, look({0, -distance_m, 0}, {0, 0, 0}));
      EXPECT_EQ(f.stats.centreline_pipes, 1u) << distance_m;
      double sum = 0;
      for (uint32_t y = 55; y < 65; ++y)  // (the pipe spans rows 54-66 at 40 m)
        for (uint32_t x = 0; x < 160; ++x) {
          const uint8_t* p = &f.image.rgba[(size_t(y) * 160 + x) * 4];
          sum += std::max(0.0, double(p[0]) - double(p[2]) - (204.0 - 224.0));
        }
      return sum / 10;
    };
    // 128.7 px a metre at 1 m (160x120, 50 degrees): 0.64 px at 20 m, 0.32 px at 40 m.
    const double near = coverage(20), far = coverage(40);
    EXPECT_GT(near, 0.0);
    EXPECT_NEAR(near / far, 2.0, 0.5) << "antialias " << antialias << ": " << near << " " << far;
  }
}

// --- the look of stills -------------------------------------------------------------------------

// A red box and a blue sphere against the sky, drawn aliased and antialiased.
struct EdgeScene {
  TempDir dir;
  Object box = make_object("box", ObjectClass::equipment, {-1.2, 10, 0}, Box{1.6f, 1.6f, 1.6f},
                           {220, 40, 30, 255});
  Object ball = make_object("ball", ObjectClass::equipment, {1.3, 10, 0.3}, Sphere{0.9f},
                            {40, 60, 220, 255});
  std::unique_ptr<Store> store = make_store(dir, {box, ball});
};

RenderOptions plain_look(bool antialias, AntialiasMethod method = AntialiasMethod::automatic) {
  RenderOptions o = small(LodPolicy::none);
  o.antialias = antialias;
  o.antialias_method = method;
  o.ground = false;
  o.ambient_occlusion = false;
  return o;
}

// Antialiasing puts intermediate values on edges, and changes nothing away from them: pixels
// more than two pixels from any change of object in the aliased frame's id buffer stay within
// a few levels. Every method.
TEST(RenderLook, AntialiasingChangesOnlyEdgePixelsToIntermediateValues) {
  EdgeScene scene;
  const uint32_t w = 200, h = 100;
  auto aliased_renderer = make_renderer(*scene.store, plain_look(false));
  const Camera camera = look({0, 0, 0.5}, {0, 10, 0});
  Frame aliased = render(*aliased_renderer, camera, w, h);
  const auto id = [&](int x, int y) {
    return aliased.image.object_ids[size_t(std::clamp(y, 0, int(h) - 1)) * w + size_t(std::clamp(x, 0, int(w) - 1))];
  };
  const auto near_edge = [&](int x, int y) {
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx)
        if (id(x + dx, y + dy) != id(x, y)) return true;
    return false;
  };
  // Pixels whose red lies strictly between the sky's and the box's, on the box's outline.
  const auto blended_on_box_edge = [&](const Image& image) {
    int n = 0;
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        if (!near_edge(int(x), int(y))) continue;
        const uint8_t* p = &image.rgba[(size_t(y) * w + x) * 4];
        const uint8_t* a = &aliased.image.rgba[(size_t(y) * w + x) * 4];
        n += p[0] != a[0] && p[2] > 70 && p[2] < 215;  // between the box's blue and the sky's
      }
    return n;
  };
  for (const AntialiasMethod method : {AntialiasMethod::supersampling,
                                       AntialiasMethod::multisampling,
                                       AntialiasMethod::edge_filter}) {
    auto r = make_renderer(*scene.store, plain_look(true, method));
    Frame smooth = render(*r, camera, w, h);
    int far_from_edges = 0, changed = 0;
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        if (near_edge(int(x), int(y))) continue;
        ++far_from_edges;
        for (int c = 0; c < 3; ++c) {
          const size_t i = (size_t(y) * w + x) * 4 + size_t(c);
          if (std::abs(int(smooth.image.rgba[i]) - int(aliased.image.rgba[i])) > 4) {
            ++changed;
            break;
          }
        }
      }
    const std::string name(antialias_method_name(method));
    EXPECT_GT(far_from_edges, int(w * h / 2)) << name;
    EXPECT_EQ(changed, 0) << name;
    EXPECT_GT(blended_on_box_edge(smooth.image), 40) << name;
    EXPECT_EQ(ids_in(smooth.image), ids_in(aliased.image)) << name;
  }
}

// A renderer makes its id buffer only when a frame first asks for ids (stills never do): frames
// without ids, then with, then without again give the same colours, and the frame with ids the
// same ids as a renderer that always drew them. Every method (multisampling resolves ids too).
TEST(RenderLook, FramesWithAndWithoutIdsAlternateOnOneRenderer) {
  EdgeScene scene;
  const uint32_t w = 200, h = 100;
  const Camera camera = look({0, 0, 0.5}, {0, 10, 0});
  for (const AntialiasMethod method : {AntialiasMethod::supersampling,
                                       AntialiasMethod::multisampling,
                                       AntialiasMethod::edge_filter}) {
    const std::string name(antialias_method_name(method));
    const Frame reference = render(*make_renderer(*scene.store, plain_look(true, method)), camera, w, h);
    ASSERT_EQ(ids_in(reference.image), (std::set<uint64_t>{scene.box.id, scene.ball.id})) << name;
    auto r = make_renderer(*scene.store, plain_look(true, method));
    std::string error;
    Frame before, after;
    ASSERT_TRUE(r->render(camera, w, h, false, before.image, before.stats, error)) << error;
    EXPECT_TRUE(before.image.object_ids.empty()) << name;
    const Frame with_ids = render(*r, camera, w, h);
    ASSERT_TRUE(r->render(camera, w, h, false, after.image, after.stats, error)) << error;
    EXPECT_EQ(before.image.rgba, reference.image.rgba) << name;
    EXPECT_EQ(with_ids.image.rgba, reference.image.rgba) << name;
    EXPECT_EQ(after.image.rgba, reference.image.rgba) << name;
    EXPECT_EQ(with_ids.image.object_ids, reference.image.object_ids) << name;
  }
}

// The ground lies at the model's lowest level: seen from above, the rays that meet that plane
// near the plant show it (no object id), those that rise above the horizon show the sky; from
// below it, or without it, there is none.
TEST(RenderLook, TheGroundIsDrawnBelowThePlantAndNotAboveTheHorizon) {
  TempDir dir;
  const auto tank = make_object("tank", ObjectClass::equipment, {0, 0, 3}, Cylinder{2.0f, 6.0f});
  auto store = make_store(dir, {tank});  // its bounds reach down to z = 0
  RenderOptions options = small();
  options.ambient_occlusion = false;
  auto r = make_renderer(*store, options);
  const uint32_t w = 160, h = 120;
  // Level with the tank's middle, looking along y: the horizon is the middle row.
  Frame f = render(*r, look({0, -20, 3}, {0, 0, 3}), w, h);
  const auto rgb = [&](const Frame& frame, uint32_t x, uint32_t y) {
    const uint8_t* p = &frame.image.rgba[(size_t(y) * w + x) * 4];
    return std::array<int, 3>{p[0], p[1], p[2]};
  };
  const std::array<int, 3> sky = {204, 214, 224};
  const auto is_sky = [&](const Frame& frame, uint32_t x, uint32_t y) {
    const auto p = rgb(frame, x, y);
    return std::abs(p[0] - sky[0]) <= 1 && std::abs(p[1] - sky[1]) <= 1 && std::abs(p[2] - sky[2]) <= 1;
  };
  // Bottom corners: rays 45 degrees down-ish meet z = 0 some 3-10 m ahead, beside the tank.
  for (const uint32_t x : {2u, w - 3}) {
    EXPECT_FALSE(is_sky(f, x, h - 3)) << x;
    EXPECT_EQ(f.image.object_ids[size_t(h - 3) * w + x], 0u);
    EXPECT_TRUE(is_sky(f, x, 3)) << x;  // above the horizon
  }
  EXPECT_EQ(ids_in(f.image), std::set<uint64_t>{tank.id});
  // Without the ground, or from below it: sky.
  options.ground = false;
  r->set_options(options);
  Frame bare = render(*r, look({0, -20, 3}, {0, 0, 3}), w, h);
  EXPECT_TRUE(is_sky(bare, 2, h - 3));
  options.ground = true;
  r->set_options(options);
  Frame below = render(*r, look({0, -20, -3}, {0, 0, 3}), w, h);
  EXPECT_TRUE(is_sky(below, 2, h - 3));
  EXPECT_TRUE(is_sky(below, 2, 3));
}

// A see-through object (alpha under 255) standing on the ground is seen: its colour blends
// over the ground behind it, and the ground is not drawn over it.
TEST(RenderLook, ASeeThroughObjectOverTheGroundKeepsItsColour) {
  TempDir dir;
  const auto pad = make_object("pad", ObjectClass::structure, {0, 0, 0.05}, Box{20, 20, 0.1f}, {120, 120, 120, 255});
  const auto glass = make_object("glass", ObjectClass::equipment, {0, 0, 2}, Box{3, 3, 3}, {30, 60, 230, 128});
  auto store = make_store(dir, {pad, glass});
  RenderOptions options = small();
  options.ambient_occlusion = false;
  const uint32_t w = 160, h = 120;
  // From above and beside: the glass box's upper part is seen against the ground beyond the pad.
  const Camera camera = look({0, -14, 6}, {0, 0, 1.5});
  for (const bool ground : {false, true}) {
    options.ground = ground;
    auto r = make_renderer(*store, options);
    Frame f = render(*r, camera, w, h);
    size_t blue = 0, glass_pixels = 0;
    for (size_t i = 0; i < size_t(w) * h; ++i) {
      if (f.image.object_ids[i] != glass.id) continue;
      ++glass_pixels;
      const uint8_t* p = &f.image.rgba[4 * i];
      blue += p[2] > p[0] + 40;
    }
    EXPECT_GT(glass_pixels, 200u) << "ground " << ground;
    EXPECT_GT(blue, glass_pixels * 9 / 10) << "ground " << ground;
  }
}

// A highlight: the id buffer holds the subject's id and 0 only; the subject shows through the
// object in front of it; the others are ghosted (lighter, greyer than drawn plainly); a plain
// frame after it is as before it.
TEST(RenderLook, AHighlightShowsOnlyTheSubjectsIdsAndSeesThroughWhatHidesIt) {
  TempDir dir;
  const auto pump = make_object("pump", ObjectClass::equipment, {0, 10, 0}, Box{1, 1, 1}, {230, 40, 30, 255});
  const auto wall = make_object("wall", ObjectClass::structure, {0, 6, 0}, Box{3, 0.2f, 3}, {60, 160, 60, 255});
  const auto aside = make_object("aside", ObjectClass::equipment, {3.5, 10, 0}, Box{1, 1, 1}, {40, 60, 220, 255});
  auto store = make_store(dir, {pump, wall, aside});
  RenderOptions options = small();
  auto r = make_renderer(*store, options);
  const uint32_t w = 200, h = 100;
  const Camera camera = look({0, 0, 0}, {0, 10, 0});
  Frame plain = render(*r, camera, w, h);
  const size_t centre = size_t(h / 2) * w + w / 2;
  EXPECT_EQ(plain.image.object_ids[centre], wall.id);  // the wall hides the pump
  EXPECT_EQ(ids_in(plain.image), (std::set<uint64_t>{wall.id, aside.id}));
  options.highlight_ids = {pump.id};
  r->set_options(options);
  Frame lit = render(*r, camera, w, h);
  EXPECT_EQ(ids_in(lit.image), std::set<uint64_t>{pump.id});
  EXPECT_EQ(lit.image.object_ids[centre], pump.id);
  // Seen through the wall: the pump's red dominates the centre.
  const uint8_t* c = &lit.image.rgba[centre * 4];
  EXPECT_GT(int(c[0]), int(c[1]) + 60) << int(c[0]) << " " << int(c[1]) << " " << int(c[2]);
  // The box aside: its blue, ghosted, is lighter and less saturated.
  const uint32_t aside_x = w / 2 + uint32_t(std::lround(3.5 / (10 * std::tan(25 * M_PI / 180)) * (h / 2)));
  const uint8_t* a0 = &plain.image.rgba[(size_t(h / 2) * w + aside_x) * 4];
  const uint8_t* a1 = &lit.image.rgba[(size_t(h / 2) * w + aside_x) * 4];
  const auto spread = [](const uint8_t* p) { return std::max({p[0], p[1], p[2]}) - std::min({p[0], p[1], p[2]}); };
  EXPECT_GT(int(a1[0]) + a1[1] + a1[2], int(a0[0]) + a0[1] + a0[2]);
  EXPECT_LT(spread(a1), spread(a0));
  // An unknown id highlights nothing: no ids at all.
  options.highlight_ids = {12345};
  r->set_options(options);
  EXPECT_TRUE(ids_in(render(*r, camera, w, h).image).empty());
  // Plain again (the framebuffers keep the stencil that highlighting made): as the first.
  options.highlight_ids.clear();
  r->set_options(options);
  Frame again = render(*r, camera, w, h);
  EXPECT_EQ(again.image.object_ids, plain.image.object_ids);
  EXPECT_EQ(again.image.rgba, plain.image.rgba);
}

// --- pipeline HLOD -----------------------------------------------------------------------------

// A pipeline along x: pipe, flange, pipe (one straight run), a tee, then one more pipe.
struct PipelineScene {
  Object pipeline, a, flange, b, tee, c;
  std::vector<Object> all() const { return {pipeline, a, flange, b, tee, c}; }
};

PipelineScene pipeline_scene() {
  const glm::mat3 along_x(glm::vec3(0, 0, -1), glm::vec3(0, 1, 0), glm::vec3(1, 0, 0));
  const glm::mat3 along_y(glm::vec3(1, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
  PipelineScene s;
  s.pipeline.name = "/PL-1";
  s.pipeline.source = "test";
  s.pipeline.id = object_id("test", s.pipeline.name);
  s.pipeline.object_class = ObjectClass::pipeline;
  const auto part = [&](const std::string& name, ObjectClass cls, float x0, float x1, float radius) {
    Object o = make_object(name, cls, {0, 0, 0}, Cylinder{radius, x1 - x0}, {200, 180, 60, 255});
    o.primitives[0].placement.linear = along_x;
    o.primitives[0].placement.translation_m = {0.5f * (x0 + x1), 0, 0};
    o.pipeline_id = s.pipeline.id;
    o.connections = {{{x0, 0, 0}, {-1, 0, 0}, 0.1f}, {{x1, 0, 0}, {1, 0, 0}, 0.1f}};
    o.centreline = {{{x0, 0, 0}, {x1, 0, 0}, 0.1f}};
    return o;
  };
  s.a = part("A", ObjectClass::pipe, 0, 2, 0.05f);
  s.flange = part("F", ObjectClass::component, 2, 2.04f, 0.09f);
  s.b = part("B", ObjectClass::pipe, 2.04f, 4, 0.05f);
  s.tee = part("T", ObjectClass::component, 4, 4.3f, 0.05f);
  s.tee.primitives.push_back(Primitive{Placement{along_y, {4.15f, 0.15f, 0}}, Cylinder{0.05f, 0.3f}});
  s.tee.connections.push_back({{4.15f, 0.3f, 0}, {0, 1, 0}, 0.1f});
  s.tee.centreline.push_back({{4.15f, 0, 0}, {4.15f, 0.3f, 0}, 0.1f});
  s.c = part("C", ObjectClass::pipe, 4.3f, 6, 0.05f);
  s.pipeline.branches = {{"B1", {s.a.id, s.flange.id, s.b.id, s.tee.id, s.c.id}}};
  return s;
}

// At 20 m the flange's 4 cm collar is under a pixel: A, F and B become one cylinder (picked
// as the pipeline); the tee and the pipe after it stay.
void expect_far_run_merged(Renderer& r, const PipelineScene& s) {
  Frame far = render(r, look({3, -20, 0}, {3, 0, 0}), 400, 400);
  EXPECT_EQ(far.stats.hlod_merges, 1u);
  EXPECT_EQ(far.stats.hlod_members, 3u);
  const auto ids = ids_in(far.image);
  EXPECT_TRUE(ids.count(s.pipeline.id));
  EXPECT_TRUE(ids.count(s.tee.id));
  EXPECT_TRUE(ids.count(s.c.id));
  EXPECT_FALSE(ids.count(s.flange.id));
  EXPECT_FALSE(ids.count(s.a.id));
}

TEST(RenderHlod, FindsTheStraightRunUpToTheTee) {
  const PipelineScene s = pipeline_scene();
  std::vector<std::pair<uint32_t, const Object*>> branch = {
      {1, &s.a}, {2, &s.flange}, {3, &s.b}, {4, &s.tee}, {5, &s.c}};
  std::vector<detail::PipelineRun> runs;
  detail::find_runs(branch, runs);
  ASSERT_EQ(runs.size(), 1u);  // C alone after the tee is no run
  EXPECT_EQ(runs[0].members, (std::vector<uint32_t>{1, 2, 3}));
  EXPECT_NEAR(runs[0].start_m.x, 0.0, 1e-6);
  EXPECT_NEAR(runs[0].end_m.x, 4.0, 1e-6);
  EXPECT_NEAR(runs[0].diameter_m, 0.1, 1e-6);
  EXPECT_NEAR(runs[0].merge_error_m, 0.04, 1e-4);  // the flange's collar
  // A reducer (another diameter at one end) ends a run too.
  Object reducer = s.flange;
  reducer.connections[1].diameter_m = 0.2f;
  branch[1].second = &reducer;
  runs.clear();
  detail::find_runs(branch, runs);
  EXPECT_TRUE(runs.empty());
}

TEST(RenderHlod, AFarRunIsOneCylinderWithoutItsFlangeAndTheTeeStays) {
  TempDir dir;
  const PipelineScene s = pipeline_scene();
  auto store = make_store(dir, s.all());
  auto r = make_renderer(*store);
  // Near: every part drawn as itself.
  Frame near = render(*r, look({3, -3, 1}, {3, 0, 0}), 400, 400);
  EXPECT_EQ(near.stats.hlod_merges, 0u);
  for (const Object* o : {&s.a, &s.flange, &s.b, &s.tee, &s.c})
    EXPECT_TRUE(ids_in(near.image).count(o->id)) << o->name;
  expect_far_run_merged(*r, s);
  // Policy none never merges.
  r->set_options(small(LodPolicy::none));
  Frame none = render(*r, look({3, -20, 0}, {3, 0, 0}), 400, 400);
  EXPECT_EQ(none.stats.hlod_merges, 0u);
  EXPECT_TRUE(ids_in(none.image).count(s.flange.id));
}

// The renderer finds a pipeline and its members by looking through the slots about the member it
// meets first, then by the ids table: the run is the same wherever the importer put them.
TEST(RenderHlod, ARunIsFoundWhereverThePipelineAndItsMembersLieInTheStore) {
  const PipelineScene s = pipeline_scene();
  // Objects far to the side of the view, none of the pipeline's: 40 of them between two slots
  // are more than the renderer looks through.
  int fillers = 0;
  const auto filler = [&]() {
    Object o = make_object("/FILL-" + std::to_string(fillers), ObjectClass::structure,
                           {1000.0 + fillers, 0, 0}, Box{0.5f, 0.5f, 0.5f});
    fillers += 1;
    return o;
  };
  std::vector<std::pair<std::string, std::vector<Object>>> layouts;
  layouts.push_back({"pipeline first", s.all()});
  layouts.push_back({"pipeline last, members reversed", {s.c, s.tee, s.b, s.flange, s.a, s.pipeline}});
  std::vector<Object> apart;
  for (const Object* o : {&s.b, &s.pipeline, &s.tee, &s.a, &s.c, &s.flange}) {
    for (int i = 0; i < 40; ++i) apart.push_back(filler());
    apart.push_back(*o);
  }
  layouts.push_back({"each 40 slots apart, shuffled", apart});
  for (const auto& [name, objects] : layouts) {
    SCOPED_TRACE(name);
    TempDir dir;
    auto store = make_store(dir, objects);
    auto r = make_renderer(*store);
    expect_far_run_merged(*r, s);
  }
}

// --- the vertex arena -------------------------------------------------------------------------

TEST(RenderArena, EvictsTheLargestVisibilityCounterFirst) {
  detail::Residency res(100);
  std::vector<std::pair<uint32_t, uint64_t>> evicted;
  res.begin_frame();
  ASSERT_TRUE(res.admit(1, 30, evicted));
  ASSERT_TRUE(res.admit(2, 30, evicted));
  ASSERT_TRUE(res.admit(3, 30, evicted));
  res.end_frame();
  // Frame 2: only 3 visible. Frame 3: only 2 visible. Counters: 1 -> 2, 2 -> 0, 3 -> 1.
  res.begin_frame();
  res.mark_visible(3);
  res.end_frame();
  res.begin_frame();
  res.mark_visible(2);
  res.end_frame();
  EXPECT_EQ(res.counter(1), 2u);
  EXPECT_EQ(res.counter(2), 0u);
  EXPECT_EQ(res.counter(3), 1u);
  res.begin_frame();
  res.mark_visible(2);
  ASSERT_TRUE(res.admit(4, 20, evicted));  // needs one eviction: the oldest, 1
  ASSERT_EQ(evicted.size(), 1u);
  EXPECT_EQ(evicted[0].first, 1u);
  ASSERT_TRUE(res.admit(5, 30, evicted));  // next: 3 (2 is visible)
  ASSERT_EQ(evicted.size(), 2u);
  EXPECT_EQ(evicted[1].first, 3u);
  EXPECT_FALSE(res.admit(6, 30, evicted));  // only visible objects are left: nothing fits
  EXPECT_TRUE(res.resident(2));
  EXPECT_LE(res.used_units(), res.capacity_units());
}

// admit() keeps its eviction order in per-frame buckets instead of sorting every resident
// object: along random frames of marks, admissions and drops it evicts exactly what the rule
// (longest unseen, then largest, then lowest key; never one visible this frame) picks from all
// of them, and its bookkeeping follows the resident count however many frames pass.
TEST(RenderArena, EvictionFollowsTheRuleOverAllResidentObjectsAlongRandomFrames) {
  struct Reference {
    detail::RangeAllocator allocator{5000};
    struct Entry {
      uint64_t offset, units, visible_frame;
    };
    std::map<uint32_t, Entry> entries;
    uint64_t frame = 0;
    std::optional<uint64_t> admit(uint32_t key, uint64_t units, std::vector<uint32_t>& evicted) {
      auto place = allocator.allocate(units);
      while (!place) {
        auto best = entries.end();
        for (auto it = entries.begin(); it != entries.end(); ++it) {
          if (it->second.visible_frame == frame) continue;
          if (best == entries.end() || it->second.visible_frame < best->second.visible_frame ||
              (it->second.visible_frame == best->second.visible_frame &&
               it->second.units > best->second.units))
            best = it;  // keys ascend: the lowest key wins the remaining ties
        }
        if (best == entries.end()) return std::nullopt;
        allocator.release(best->second.offset, best->second.units);
        evicted.push_back(best->first);
        entries.erase(best);
        place = allocator.allocate(units);
      }
      entries[key] = {*place, units, frame};
      return place;
    }
  } ref;
  detail::Residency res(5000);
  std::mt19937 rng(11);
  std::vector<std::pair<uint32_t, uint64_t>> evicted;
  std::vector<uint32_t> ref_evicted;
  uint32_t next_key = 0;
  size_t evictions = 0;
  for (int frame = 0; frame < 400; ++frame) {
    res.begin_frame();
    ++ref.frame;
    // Mark a random share of the resident objects visible (some twice).
    std::vector<uint32_t> keys;
    for (const auto& [k, e] : ref.entries) keys.push_back(k);
    for (const uint32_t k : keys)
      if (rng() % 3 == 0) {
        res.mark_visible(k);
        ref.entries[k].visible_frame = ref.frame;
        if (rng() % 4 == 0) res.mark_visible(k);
      }
    // Admit new objects (and now and then one dropped earlier this frame), drop a few.
    const int admits = int(rng() % 40);
    for (int i = 0; i < admits; ++i) {
      const uint32_t key = next_key++;
      const uint64_t units = 1 + rng() % 120;
      evicted.clear();
      ref_evicted.clear();
      const auto got = res.admit(key, units, evicted);
      const auto want = ref.admit(key, units, ref_evicted);
      ASSERT_EQ(got, want) << "frame " << frame << " key " << key;
      ASSERT_EQ(evicted.size(), ref_evicted.size()) << "frame " << frame;
      for (size_t j = 0; j < evicted.size(); ++j) ASSERT_EQ(evicted[j].first, ref_evicted[j]);
      evictions += evicted.size();
      if (got && rng() % 10 == 0) {  // dropped (its data could not be written), then again
        res.drop(key);
        ref.allocator.release(ref.entries[key].offset, ref.entries[key].units);
        ref.entries.erase(key);
        evicted.clear();
        ref_evicted.clear();
        ASSERT_EQ(res.admit(key, units, evicted), ref.admit(key, units, ref_evicted));
        ASSERT_EQ(evicted.size(), ref_evicted.size());
      }
    }
    res.end_frame();
    ASSERT_EQ(res.resident_count(), ref.entries.size());
    for (const auto& [k, e] : ref.entries) ASSERT_EQ(res.offset(k), std::optional<uint64_t>(e.offset));
  }
  EXPECT_GT(evictions, 1000u) << "the arena must have been full most of the time";

  // Without evictions, every object seen every frame: the records do not pile up.
  detail::Residency roomy(1u << 20);
  roomy.begin_frame();
  for (uint32_t k = 0; k < 2000; ++k) ASSERT_TRUE(roomy.admit(k, 10, evicted));
  roomy.end_frame();
  const size_t bytes_at_start = roomy.bookkeeping_bytes();
  for (int frame = 0; frame < 1000; ++frame) {
    roomy.begin_frame();
    for (uint32_t k = 0; k < 2000; ++k) roomy.mark_visible(k);
    roomy.end_frame();
  }
  EXPECT_LE(roomy.bookkeeping_bytes(), 2 * bytes_at_start + 64 * 1024);
}

TEST(RenderArena, FreedRangesCoalesce) {
  detail::RangeAllocator a(100);
  const auto x = a.allocate(40), y = a.allocate(40), z = a.allocate(20);
  ASSERT_TRUE(x && y && z);
  EXPECT_FALSE(a.allocate(1));
  a.release(*x, 40);
  a.release(*z, 20);
  EXPECT_FALSE(a.allocate(60));
  a.release(*y, 40);
  EXPECT_EQ(a.largest_free(), 100u);
  EXPECT_TRUE(a.allocate(100));
}

// Objects of one template leave many free ranges of one size: best fit takes the smallest
// that fits, the lowest of equal ones, and every range freed is found again to coalesce.
TEST(RenderArena, BestFitAmongManyEqualFreeRangesTakesTheLowestAndAllCoalesce) {
  detail::RangeAllocator a(30000);
  std::vector<uint64_t> at;
  for (int i = 0; i < 3000; ++i) at.push_back(*a.allocate(10));
  for (int i = 2999; i >= 1; i -= 2) a.release(at[size_t(i)], 10);  // 1500 holes of 10
  a.release(at[0], 10);  // merges with the hole at 10: one of 20 at 0
  EXPECT_EQ(a.allocate(10), std::optional<uint64_t>(30)) << "the lowest range of the exact size";
  EXPECT_EQ(a.allocate(15), std::optional<uint64_t>(0)) << "the smallest that fits";
  EXPECT_EQ(a.allocate(10), std::optional<uint64_t>(50));
  a.release(0, 15);
  a.release(30, 10);
  a.release(50, 10);
  for (int i = 2; i < 3000; i += 2) a.release(at[size_t(i)], 10);
  EXPECT_EQ(a.used(), 0u);
  EXPECT_EQ(a.largest_free(), 30000u) << "every freed range coalesced";
}

TEST(RenderArena, StaysWithinBudgetOnARandomPathAndFallsBackToBoxes) {
  TempDir dir;
  auto store = make_store(dir, sphere_field());
  RenderOptions options = small(LodPolicy::none);
  options.vertex_budget_bytes = 1u << 20;  // a few dozen large spheres
  auto r = make_renderer(*store, options);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10, 90);
  uint64_t evictions = 0;
  for (int frame = 0; frame < 30; ++frame) {
    const glm::dvec3 eye(u(rng), u(rng), 3 + 0.2 * u(rng));
    const glm::dvec3 target(u(rng), u(rng), 0);
    if (glm::length(target - eye) < 1) continue;
    Frame f = render(*r, look(eye, target), 96, 64);
    EXPECT_LE(f.stats.arena_bytes_resident, options.vertex_budget_bytes) << frame;
    evictions += f.stats.objects_evicted;
    EXPECT_LE(ids_in(f.image).size(), f.stats.objects_visible);
  }
  EXPECT_GT(evictions, 0u);
  // The whole plant at full resolution cannot fit: objects are made resident at coarser
  // levels instead, and none is left out.
  Frame all = render(*r, look({40, -120, 80}, {40, 40, 0}), 320, 240);
  EXPECT_GT(all.stats.budget_coarsened, 0u);
  EXPECT_LE(all.stats.arena_bytes_resident, options.vertex_budget_bytes);
  EXPECT_EQ(ids_in(all.image).size(), 400u);
}

// Progressive refinement (RenderOptions::stream_budget_vertices): when every level of a view
// turns finer at once (the service's degradation lifting), a bounded frame streams about its
// budget and draws the rest coarser, leaving nothing out; the frames after refine it, budget by
// budget, to exactly what an unbounded renderer draws.
TEST(RenderArena, AStreamingBudgetRefinesOverFramesToTheUnboundedImage) {
  TempDir dir;
  auto store = make_store(dir, sphere_field());
  RenderOptions coarse = small();
  coarse.pixel_error = 16;
  RenderOptions fine = small();
  fine.pixel_error = 0.5;
  auto unbounded = make_renderer(*store, coarse);
  coarse.stream_budget_vertices = fine.stream_budget_vertices = 4000;
  auto bounded = make_renderer(*store, coarse);
  const Camera camera = look({40, -30, 30}, {40, 40, 0});
  render(*unbounded, camera, 320, 240);
  render(*bounded, camera, 320, 240);  // the coarse levels resident, within the budget or not
  RenderOptions unbounded_fine = fine;
  unbounded_fine.stream_budget_vertices = 0;
  unbounded->set_options(unbounded_fine);
  bounded->set_options(fine);
  const Frame want = render(*unbounded, camera, 320, 240);
  EXPECT_EQ(want.stats.objects_deferred, 0u);
  Frame got = render(*bounded, camera, 320, 240);
  EXPECT_GT(got.stats.objects_deferred, 0u);
  EXPECT_LT(got.stats.arena_bytes_uploaded, want.stats.arena_bytes_uploaded / 2);
  EXPECT_LT(got.stats.triangles, want.stats.triangles);
  EXPECT_EQ(got.stats.objects_visible, want.stats.objects_visible);
  EXPECT_EQ(ids_in(got.image), ids_in(want.image)) << "drawn coarser, none left out";
  int frames = 1;
  while (got.stats.objects_deferred > 0 && frames < 100) {
    got = render(*bounded, camera, 320, 240);
    frames += 1;
  }
  EXPECT_GT(frames, 2) << "refined over several frames";
  EXPECT_EQ(got.stats.objects_deferred, 0u);
  EXPECT_EQ(got.stats.triangles, want.stats.triangles);
  EXPECT_TRUE(got.image.rgba == want.image.rgba) << "the same image once refined";
}

// A model larger than the vertex budget is drawn in bounded pieces on a software renderer
// (GlBackend::draw_triangles): a view of more triangles than a piece, all of them resident,
// looks exactly as it does from a renderer whose budget holds the whole model.
TEST(RenderArena, AModelLargerThanTheBudgetIsDrawnInPiecesToTheSameImage) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 24; ++i)
    for (int j = 0; j < 24; ++j)
      objects.push_back(make_object("S" + std::to_string(i) + "_" + std::to_string(j),
                                    ObjectClass::equipment, {i * 1.0, 10 + j * 1.0, 0},
                                    Sphere{0.45f}, {uint8_t(40 + 8 * i), uint8_t(40 + 8 * j), 200, 255}));
  auto store = make_store(dir, objects);
  const Camera camera = look({11.5, -6, 14}, {11.5, 21.5, 0});
  RenderOptions roomy = small(LodPolicy::none);
  roomy.vertex_budget_bytes = 256u << 20;
  const Frame whole = render(*make_renderer(*store, roomy), camera, 240, 160);
  ASSERT_GT(whole.stats.triangles, 2 * detail::kSoftwarePieceTriangles) << "more than two pieces";
  ASSERT_EQ(ids_in(whole.image).size(), objects.size());
  // A budget that holds this view's vertices but not the model's triangles' worth.
  RenderOptions tight = roomy;
  tight.vertex_budget_bytes = ((whole.stats.arena_bytes_resident * 5 / 4) | ((1u << 20) - 1)) + 1;
  ASSERT_LT(tight.vertex_budget_bytes / detail::kBytesPerVertex, whole.stats.triangles)
      << "the model must be larger than the budget";
  const Frame pieces = render(*make_renderer(*store, tight), camera, 240, 160);
  EXPECT_EQ(pieces.stats.budget_proxies, 0u);
  EXPECT_EQ(pieces.stats.triangles, whole.stats.triangles);
  EXPECT_EQ(pieces.image.rgba, whole.image.rgba);
  EXPECT_EQ(pieces.image.object_ids, whole.image.object_ids);
}

// The arena's two kinds of memory (gl/backend.h): grown GPU buffers report the time each
// growth took; on a software renderer that can draw from client memory, the whole budget is
// mapped at once and never grows.
TEST(RenderArena, AGrownArenaAtLeastDoublesAndReportsTheTimeItTook) {
  test::gl_context();
  detail::GlBackend backend;
  std::string error;
  const uint64_t budget_vertices = (64u << 20) / detail::kBytesPerVertex;
  ASSERT_TRUE(backend.init(budget_vertices, error, detail::ArenaMemory::grown)) << error;
  EXPECT_FALSE(backend.arena_mapped());
  const uint64_t initial = backend.arena_vertices();
  ASSERT_LT(initial, budget_vertices);
  backend.take_growth_ms();
  ASSERT_TRUE(backend.grow_arena(initial + 1, error)) << error;
  EXPECT_GE(backend.arena_vertices(), 2 * initial);
  EXPECT_GT(backend.take_growth_ms(), 0.0);
  ASSERT_TRUE(backend.grow_arena(initial + 1, error)) << error;
  EXPECT_EQ(backend.take_growth_ms(), 0.0) << "it holds that already";
  ASSERT_TRUE(backend.grow_arena(2 * budget_vertices, error)) << error;
  EXPECT_EQ(backend.arena_vertices(), budget_vertices) << "never more than the budget";
}

long resident_kb() {
  long pages = 0, resident = 0;
  FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return -1;
  if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = -1;
  std::fclose(f);
  return resident < 0 ? -1 : resident * (sysconf(_SC_PAGESIZE) / 1024);
}

TEST(RenderArena, ASoftwareRendererMapsItsWholeBudgetAndTakesMemoryOnlyForWhatItHolds) {
  test::gl_context();
  {
    detail::GlBackend probe;
    std::string error;
    ASSERT_TRUE(probe.init(1u << 16, error)) << error;
    if (!probe.arena_mapped())
      GTEST_SKIP() << "this renderer grows GPU buffers (no GL_AMD_pinned_memory, or a GPU)";
  }
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 40; ++i)
    objects.push_back(make_object("P" + std::to_string(i), ObjectClass::equipment, {i * 2.0, 0, 0},
                                  Cylinder{0.5f, 1.0f}));
  auto store = make_store(dir, objects);
  RenderOptions options = small(LodPolicy::none);
  options.vertex_budget_bytes = 4ull << 30;  // a sixth of this machine's memory
  const long before_kb = resident_kb();
  auto renderer = make_renderer(*store, options);
  const Frame first = render(*renderer, look({39, -90, 40}, {39, 0, 0}));
  EXPECT_EQ(ids_in(first.image).size(), objects.size());
  EXPECT_EQ(first.stats.ms.arena_growth, 0.0) << "mapped once: it never grows";
  const long taken_kb = resident_kb() - before_kb;
  EXPECT_LT(taken_kb, 256 * 1024) << "a 4 GB budget took " << taken_kb << " kB";
}

TEST(RenderArena, AnObjectLargerThanTheWholeBudgetIsDrawnAsItsBox) {
  FacetGroup mesh;  // 60,000 vertices in one level: more than a 1 MB arena holds
  for (uint32_t t = 0; t < 20000; ++t) {
    const float x = float(t % 200) * 0.01f, y = float(t / 200) * 0.01f;
    mesh.vertices.push_back({{x, y, 0}, {0, 0, 1}});
    mesh.vertices.push_back({{x + 0.01f, y, 0}, {0, 0, 1}});
    mesh.vertices.push_back({{x, y + 0.01f, 0}, {0, 0, 1}});
    mesh.contour_ends.push_back(uint32_t(mesh.vertices.size()));
    mesh.polygon_ends.push_back(uint32_t(mesh.contour_ends.size()));
  }
  mesh.triangulate();
  TempDir dir;
  const auto big = make_object("big", ObjectClass::structure, {0, 0, 0}, mesh);
  auto store = make_store(dir, {big});
  RenderOptions options = small();
  options.vertex_budget_bytes = 1u << 20;
  auto r = make_renderer(*store, options);
  Frame f = render(*r, look({1, 1, 3}, {1, 1, 0}));
  EXPECT_EQ(f.stats.budget_proxies, 1u);
  EXPECT_EQ(f.stats.triangles, 12u);
  EXPECT_EQ(ids_in(f.image), std::set<uint64_t>{big.id});
  EXPECT_LE(f.stats.arena_bytes_resident, options.vertex_budget_bytes);
}

TEST(RenderArena, AResidentObjectIsNotTessellatedAgain) {
  TempDir dir;
  auto store = make_store(dir, {make_object("C", ObjectClass::pipe, {0, 0, 0}, Cylinder{0.5f, 2.0f})});
  auto r = make_renderer(*store);
  Frame a = render(*r, look({0, -5, 0}, {0, 0, 0}));
  EXPECT_EQ(a.stats.objects_tessellated, 1u);
  EXPECT_GT(a.stats.arena_bytes_uploaded, 0u);
  Frame b = render(*r, look({0, -50, 0}, {0, 0, 0}));  // another level: same vertices
  EXPECT_EQ(b.stats.objects_tessellated, 0u);
  EXPECT_EQ(b.stats.arena_bytes_uploaded, 0u);
  EXPECT_LT(b.stats.triangles, a.stats.triangles);
}

// --- statistics and snapshots -------------------------------------------------------------------

TEST(RenderStatistics, CountWhatRenderingTheSameViewDraws) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 30; ++i)
    objects.push_back(make_object("C" + std::to_string(i), ObjectClass::equipment,
                                  {(i % 6) * 3.0, (i / 6) * 4.0, 0}, Cylinder{0.5f, 2.0f}));
  auto store = make_store(dir, objects);
  auto drawing = make_renderer(*store);
  auto counting = make_renderer(*store);
  for (const double d : {6.0, 25.0, 120.0}) {
    const Camera camera = look({7.5, -d, 3}, {7.5, 8, 0});
    Frame f = render(*drawing, camera, 320, 240);
    FrameStats counted;
    std::string error;
    ASSERT_TRUE(counting->statistics(camera, 320, 240, counted, error)) << error;
    f.stats.ms = counted.ms = {};
    // statistics() finds what is hidden on the CPU, render() in two phases on the GPU
    // (render/src/occlusion.h): their occluders and draw commands are not alike (nothing here
    // is hidden by either).
    f.stats.occluders = counted.occluders = 0;
    f.stats.draw_commands = counted.draw_commands = 0;
    EXPECT_EQ(counted.to_json(), f.stats.to_json()) << "at " << d << " m";
    EXPECT_GT(counted.triangles, 0u);
  }
}

// Renderer::expect(): a path whose next view is known draws the same images, ids and counts as
// one rendered view by view; the frame after takes the cull made while the one before drew,
// unless its camera, size, policy or pixel error is not the one expected.
TEST(RenderPath, ExpectingTheNextViewChangesNoImageAndItsCullIsTakenOnlyIfItComes) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      objects.push_back(make_object("C" + std::to_string(i) + "_" + std::to_string(j),
                                    ObjectClass::equipment, {i * 3.0, j * 3.0, 0},
                                    Cylinder{0.4f + 0.05f * float(j % 4), 2.0f}));
  auto store = make_store(dir, objects);
  auto ahead = make_renderer(*store);
  auto plain = make_renderer(*store);
  std::vector<Camera> path;
  for (int v = 0; v < 8; ++v)
    path.push_back(look({-6.0 + 5.0 * v, -8.0 + 2.0 * v, 2.5}, {16.0, 16.0 + v, 0}));
  const Camera surprise = look({40, 40, 6}, {16, 16, 0});
  std::string error;
  for (size_t v = 0; v < path.size(); ++v) {
    SCOPED_TRACE("view " + std::to_string(v));
    // View 5 is expected but another comes (the expectation is dropped); at view 6 the pixel
    // error changes after it was expected (culled again, as the options say).
    const bool surprised = v == 5;
    const Camera& camera = surprised ? surprise : path[v];
    if (v == 6) {
      RenderOptions o = small();
      o.pixel_error = 2.0;
      ahead->set_options(o);
      plain->set_options(o);
    }
    if (v + 1 < path.size()) ahead->expect(path[v + 1]);
    Frame a = render(*ahead, camera, 200, 150);
    Frame b = render(*plain, camera, 200, 150);
    EXPECT_EQ(a.image.rgba, b.image.rgba);
    EXPECT_EQ(a.image.object_ids, b.image.object_ids);
    EXPECT_FALSE(ids_in(a.image).empty());
    EXPECT_EQ(a.stats.made_ahead, v > 0 && !surprised && v != 6);
    EXPECT_FALSE(b.stats.made_ahead);
    EXPECT_EQ(a.stats.ms.ahead > 0, v + 1 < path.size());
    EXPECT_EQ(b.stats.ms.ahead, 0.0);
    a.stats.ms = b.stats.ms = {};
    if (v < 5) {
      EXPECT_EQ(a.stats.to_json(), b.stats.to_json());
    } else {
      // Once an expected view did not come, the arena also holds what its first phase was
      // streamed with: what is drawn is the same, what is resident may not be.
      EXPECT_EQ(a.stats.objects_visible, b.stats.objects_visible);
      EXPECT_EQ(a.stats.objects_occluded, b.stats.objects_occluded);
      EXPECT_EQ(a.stats.triangles, b.stats.triangles);
      EXPECT_EQ(a.stats.triangles_by_level, b.stats.triangles_by_level);
    }
  }
  // An expectation applies to the next frame alone: a statistics() frame in between spends it.
  ahead->expect(path[0]);
  FrameStats counted;
  ASSERT_TRUE(ahead->statistics(path[1], 200, 150, counted, error)) << error;
  Frame after = render(*ahead, path[0], 200, 150);
  EXPECT_FALSE(after.stats.made_ahead);
}

// The first phase streamed ahead (its objects made resident, evicting others, while the frame
// before still draws from the arena) draws what a renderer without the look ahead draws, and
// nothing the frame before drew is overwritten before it is read back, when the arena is too
// small for the path and evicts frame after frame.
TEST(RenderPath, ExpectingTheNextViewUnderATightBudgetChangesNoImage) {
  TempDir dir;
  auto store = make_store(dir, sphere_field());
  RenderOptions options = small();
  options.pixel_error = 0.25;
  options.vertex_budget_bytes = 1u << 20;
  auto ahead = make_renderer(*store, options);
  auto plain = make_renderer(*store, options);
  std::vector<Camera> path;
  for (int v = 0; v < 16; ++v) {
    const double a = 0.4 * v;
    const glm::dvec3 eye(38 + 30 * std::cos(a), 38 + 30 * std::sin(a), 4 + 0.5 * v);
    path.push_back(look(eye, {38 - 10 * std::sin(a), 38 + 10 * std::cos(a), 0}));
  }
  uint64_t evicted = 0, streamed_ahead = 0;
  for (size_t v = 0; v < path.size(); ++v) {
    SCOPED_TRACE("view " + std::to_string(v));
    if (v + 1 < path.size()) ahead->expect(path[v + 1]);
    Frame a = render(*ahead, path[v], 200, 150);
    Frame b = render(*plain, path[v], 200, 150);
    EXPECT_EQ(a.image.rgba, b.image.rgba);
    EXPECT_EQ(a.image.object_ids, b.image.object_ids);
    EXPECT_EQ(a.stats.made_ahead, v > 0);
    evicted += b.stats.objects_evicted;
    streamed_ahead += a.stats.made_ahead ? a.stats.objects_tessellated : 0;
    a.stats.ms = b.stats.ms = {};
    a.stats.made_ahead = false;
    EXPECT_EQ(a.stats.to_json(), b.stats.to_json());
  }
  EXPECT_GT(evicted, 0u) << "the arena holds the path: nothing checks eviction";
  EXPECT_GT(streamed_ahead, 0u);
}

TEST(RenderSnapshot, FramesAndTheReadViewSeeOneCommitUntilRefresh) {
  TempDir dir;
  const Object first = make_object("first", ObjectClass::equipment, {0, 0, 0}, Box{1, 1, 1});
  const Object second = make_object("second", ObjectClass::equipment, {2, 0, 0}, Box{1, 1, 1});
  auto store = make_store(dir, {first});
  auto r = make_renderer(*store);
  const Camera camera = look({1, -8, 1}, {1, 0, 0});
  EXPECT_EQ(ids_in(render(*r, camera).image), std::set<uint64_t>{first.id});
  std::string error;
  auto import = store->begin_import(error);
  ASSERT_TRUE(import) << error;
  ASSERT_TRUE(import->put(second, error)) << error;
  ASSERT_TRUE(import->commit(error)) << error;
  // The renderer's snapshot predates the import: neither frames nor its view see `second`.
  EXPECT_EQ(ids_in(render(*r, camera).image), std::set<uint64_t>{first.id});
  EXPECT_FALSE(r->read_view().slot_of(second.id));
  EXPECT_TRUE(r->read_view().slot_of(first.id));
  ASSERT_TRUE(r->refresh(error)) << error;
  EXPECT_TRUE(r->read_view().slot_of(second.id));
  EXPECT_EQ(ids_in(render(*r, camera).image), (std::set<uint64_t>{first.id, second.id}));
}

// --- precision --------------------------------------------------------------------------------

TEST(RenderPrecision, APlantTenKilometresFromTheOriginRendersAsAtTheOrigin) {
  const glm::dvec3 far_away(10000.0, -10000.0, 35.0);
  const auto scene = [](glm::dvec3 shift) {
    std::vector<Object> v;
    v.push_back(make_object("pipe", ObjectClass::pipe, shift + glm::dvec3(0, 0, 0), Cylinder{0.05f, 1.0f}));
    v.push_back(make_object("flange", ObjectClass::component, shift + glm::dvec3(0, 0, 0.52), Cylinder{0.09f, 0.04f}, {90, 90, 200, 255}));
    v.push_back(make_object("box", ObjectClass::equipment, shift + glm::dvec3(0.3, 0.2, 0), Box{0.1f, 0.1f, 0.1f}, {40, 160, 40, 255}));
    return v;
  };
  TempDir a, b;
  auto store_a = make_store(a, scene(glm::dvec3(0.0)));
  auto store_b = make_store(b, scene(far_away));
  auto ra = make_renderer(*store_a);
  auto rb = make_renderer(*store_b);
  const Camera cam = look({0.6, -0.9, 0.7}, {0, 0, 0.3});
  Camera cam_far = cam;
  cam_far.eye_m += far_away;
  cam_far.target_m += far_away;
  Frame fa = render(*ra, cam, 320, 240);
  Frame fb = render(*rb, cam_far, 320, 240);
  ImageComparison c;
  std::string error;
  ASSERT_TRUE(compare_images(fa.image, fb.image, c, error)) << error;
  EXPECT_GT(c.psnr_db, 40.0);
  EXPECT_LT(c.differing_share, 0.005);
  EXPECT_EQ(fa.stats.triangles, fb.stats.triangles);
}

// --- cameras and paths ------------------------------------------------------------------------

TEST(RenderCamera, ParsesTheCommandLineFormAndRejectsBadOnes) {
  Camera c;
  std::string error;
  ASSERT_TRUE(parse_camera("eye=1,2,3,target=4,5,6", c, error)) << error;
  EXPECT_EQ(c.eye_m, glm::dvec3(1, 2, 3));
  EXPECT_EQ(c.target_m, glm::dvec3(4, 5, 6));
  ASSERT_TRUE(parse_camera("eye=0,0,0,target=0,1,0,up=0,0,1,fov=35.5", c, error)) << error;
  EXPECT_EQ(c.fov_deg, 35.5);
  Camera back;
  ASSERT_TRUE(parse_camera(format_camera(c), back, error)) << error;
  EXPECT_EQ(back, c);
  for (const char* bad : {"", "eye=1,2,target=0,0,0", "eye=1,2,3", "eye=0,0,0,target=0,0,0",
                          "eye=0,0,0,target=1,0,0,fov=200", "eye=nan,0,0,target=1,0,0",
                          "eye=0,0,0,target=0,0,1,up=0,0,1", "eye=0,0,0,target=1,0,0,zoom=2",
                          "eye=1e999,0,0,target=1,0,0", "eye=0,0,0,target=1,0,0,fov=x"}) {
    EXPECT_FALSE(parse_camera(bad, c, error)) << bad;
    EXPECT_NE(error.find("camera"), std::string::npos);
  }
}

TEST(RenderCamera, APlanViewWithoutUpHasNorthAtTheTopOfTheImage) {
  // A reviewer's plan view: straight down, no up given. Every camera form takes +y as up there
  // (+z cannot orient a vertical view); an up given along the view is still refused.
  Camera c;
  std::string error;
  ASSERT_TRUE(parse_camera("eye=0,0,50,target=0,0,0", c, error)) << error;
  EXPECT_EQ(c.up, glm::dvec3(0, 1, 0));
  ASSERT_TRUE(parse_camera("eye=0,0,-50,target=0,0,0", c, error)) << error;  // from below
  EXPECT_EQ(c.up, glm::dvec3(0, 1, 0));
  ASSERT_TRUE(parse_camera("eye=0,0,50,target=0,0.5,0", c, error)) << error;  // slanted: +z
  EXPECT_EQ(c.up, glm::dvec3(0, 0, 1));
  EXPECT_FALSE(parse_camera("eye=0,0,50,target=0,0,0,up=0,0,1", c, error));
  std::vector<Camera> path;
  ASSERT_TRUE(parse_camera_path("[{\"eye\":[0,0,50],\"target\":[0,0,0]}]", path, error)) << error;
  EXPECT_EQ(path.at(0).up, glm::dvec3(0, 1, 0));

  // North at the top, east on the right, as on a plot plan.
  TempDir dir;
  const auto north = make_object("north", ObjectClass::equipment, {0, 4, 0}, Box{2, 2, 2});
  const auto east = make_object("east", ObjectClass::equipment, {4, 0, 0}, Sphere{1.0f});
  auto store = make_store(dir, {north, east});
  auto r = make_renderer(*store);
  ASSERT_TRUE(parse_camera("eye=0,0,30,target=0,0,0", c, error)) << error;
  Frame f = render(*r, c, 160, 120);
  double north_y = 0, east_x = 0, north_n = 0, east_n = 0;
  for (uint32_t y = 0; y < 120; ++y)
    for (uint32_t x = 0; x < 160; ++x) {
      const uint64_t id = f.image.object_ids[size_t(y) * 160 + x];
      if (id == north.id) north_y += y, ++north_n;
      if (id == east.id) east_x += x, ++east_n;
    }
  ASSERT_GT(north_n, 0);
  ASSERT_GT(east_n, 0);
  EXPECT_LT(north_y / north_n, 60 - 10);  // above the centre (rows count down)
  EXPECT_GT(east_x / east_n, 80 + 10);    // right of the centre
}

TEST(RenderCamera, ValidationRejectsWhatTheRendererCannotDraw) {
  std::string error;
  Camera c = look({0, -5, 1}, {0, 0, 1});
  EXPECT_TRUE(validate_camera(c, error)) << error;
  const auto rejected = [&](Camera bad, const char* why) {
    error.clear();
    EXPECT_FALSE(validate_camera(bad, error)) << why;
    EXPECT_NE(error.find("camera:"), std::string::npos) << why;
  };
  Camera bad = c;
  bad.target_m = bad.eye_m;
  rejected(bad, "eye on the target");
  bad = c;
  bad.up = {0, 1, 0};
  rejected(bad, "up along the view");
  bad = c;
  bad.up = {0, 0, 0};
  rejected(bad, "zero up");
  bad = c;
  bad.fov_deg = 179.0;
  rejected(bad, "fov too wide");
  bad = c;
  bad.eye_m.x = INFINITY;
  rejected(bad, "infinite eye");
  bad = c;
  bad.target_m.z = NAN;
  rejected(bad, "NaN target");
  bad = c;
  bad.fov_deg = NAN;
  rejected(bad, "NaN fov");
}

TEST(RenderCamera, PathsRoundTripThroughJsonAndWalkIntoThePlant) {
  DAabb plant;
  plant.extend(glm::dvec3(0, 0, 0));
  plant.extend(glm::dvec3(200, 100, 30));
  std::vector<DAabb> equipment;
  for (int i = 0; i < 20; ++i) {
    DAabb b;
    b.extend(glm::dvec3(10 + i * 9, 20 + (i % 2) * 50, 0));
    b.extend(glm::dvec3(14 + i * 9, 26 + (i % 2) * 50, 8));
    equipment.push_back(b);
  }
  const auto walk = make_camera_path(PathKind::walkthrough, 100, plant, equipment);
  ASSERT_EQ(walk.size(), 100u);
  // Starts outside the plant's bounds, ends at eye height, never inside equipment.
  const auto inside = [](const DAabb& b, glm::dvec3 p) {
    return p.x >= b.min.x && p.x <= b.max.x && p.y >= b.min.y && p.y <= b.max.y && p.z >= b.min.z && p.z <= b.max.z;
  };
  EXPECT_FALSE(inside(plant, walk.front().eye_m));
  EXPECT_LT(walk[60].eye_m.z, 3.0);
  bool went_in = false;
  for (const auto& c : walk) {
    went_in |= inside(plant, c.eye_m);
    for (const auto& e : equipment) EXPECT_FALSE(inside(e, c.eye_m));
  }
  EXPECT_TRUE(went_in);
  std::vector<Camera> back;
  std::string error;
  ASSERT_TRUE(parse_camera_path(camera_path_json(walk), back, error)) << error;
  ASSERT_EQ(back.size(), walk.size());
  for (size_t i = 0; i < back.size(); ++i) EXPECT_NEAR(glm::length(back[i].eye_m - walk[i].eye_m), 0, 1e-9);
  EXPECT_FALSE(parse_camera_path("[{\"eye\":[0,0],\"target\":[1,1,1]}]", back, error));
  EXPECT_NE(error.find("camera 0"), std::string::npos);
  EXPECT_FALSE(parse_camera_path("[]", back, error));
  EXPECT_FALSE(parse_camera_path("{", back, error));
  const auto orbit = make_camera_path(PathKind::orbit, 8, plant, equipment);
  ASSERT_EQ(orbit.size(), 8u);
  for (const auto& c : orbit) EXPECT_FALSE(inside(plant, c.eye_m));
}

TEST(RenderCamera, TheDefaultCameraSeesTheWholePlant) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 5; ++i)
    objects.push_back(make_object("B" + std::to_string(i), ObjectClass::equipment,
                                  {i * 30.0, (i % 2) * 40.0, 0}, Box{4, 4, 4}));
  auto store = make_store(dir, objects);
  auto r = make_renderer(*store);
  Frame f = render(*r, default_camera(r->model_bounds(), 320.0 / 240.0), 320, 240);
  EXPECT_EQ(f.stats.objects_visible, 5u);
  EXPECT_EQ(ids_in(f.image).size(), 5u);
}

TEST(RenderErrors, AbsurdSizesAndBudgetsAreRefused) {
  TempDir dir;
  auto store = make_store(dir, {make_object("C", ObjectClass::pipe, {0, 0, 0}, Cylinder{0.5f, 2.0f})});
  auto r = make_renderer(*store);
  Image image;
  FrameStats stats;
  std::string error;
  EXPECT_FALSE(r->render(look({0, -5, 0}, {0, 0, 0}), 0, 10, false, image, stats, error));
  EXPECT_FALSE(r->render(look({0, -5, 0}, {0, 0, 0}), 100000, 10, false, image, stats, error));
  EXPECT_NE(error.find("100000x10"), std::string::npos);
  RenderOptions tiny;
  tiny.vertex_budget_bytes = 1000;
  EXPECT_FALSE(Renderer::create(*store, tiny, error));
  EXPECT_NE(error.find("budget"), std::string::npos);
  EXPECT_FALSE(GpuContext::create(999, error));
  EXPECT_NE(error.find("999"), std::string::npos);
}

}  // namespace
}  // namespace plantview
