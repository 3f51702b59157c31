// The renderer's frontend without GL: the view from a camera, cull and level choice from a store
// (frame_plan.h, decoded_objects.h). No GpuContext is made: these run where EGL is absent.
// Oracles are independent of the code under test: points projected through a camera basis
// built here, and pixels per metre from H / (2 tan(fov / 2) d).
#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <set>

#include "decoded_objects.h"
#include "frame_plan.h"
#include "lod.h"
#include "radix_sort.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using detail::Draw;
using detail::FramePlan;
using detail::FrameView;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("plantview-frame-plan-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::remove_all(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
  static inline int counter_ = 0;
};

Object make_object(const std::string& name, glm::dvec3 origin, Shape shape) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = ObjectClass::equipment;
  o.origin_m = origin;
  o.primitives.push_back(Primitive{Placement{}, std::move(shape)});
  return o;
}

Camera look(glm::dvec3 eye, glm::dvec3 target, double fov_deg = 50.0) {
  Camera c;
  c.eye_m = eye;
  c.target_m = target;
  c.fov_deg = fov_deg;
  return c;
}

// A store, its snapshot, and the frontend's state over it: what Renderer::frame runs before
// streaming, with no GL.
class Frontend {
 public:
  explicit Frontend(const std::vector<Object>& objects) {
    std::string error;
    store_ = Store::open(dir_.str(), Store::Mode::read_write, error);
    EXPECT_TRUE(store_) << error;
    auto import = store_->begin_import(error);
    EXPECT_TRUE(import) << error;
    for (const auto& o : objects) EXPECT_TRUE(import->put(o, error)) << error;
    EXPECT_TRUE(import->commit(error)) << error;
    view_ = store_->read(error);
    EXPECT_TRUE(view_) << error;
    objects_.reset(*view_);
    for (const auto& o : objects) slot_of_[o.name] = *view_->slot_of(o.id);
  }

  // Culls and chooses one frame; the draws by object name, their levels and the statistics.
  struct Planned {
    std::map<std::string, uint8_t> level;  // object name -> chosen level
    std::set<std::string> centreline;      // drawn as their centreline
    FrameStats stats;
  };
  Planned plan(const Camera& camera, uint32_t w, uint32_t h, const RenderOptions& options) {
    Planned out;
    const FrameView view = detail::make_frame_view(camera, w, h, view_->spatial_origin());
    std::string error;
    EXPECT_TRUE(plan_.cull(*view_, view, options, out.stats, error)) << error;
    EXPECT_TRUE(objects_.decode(plan_.visible(), options.hlod, error)) << error;
    plan_.choose(objects_, view, options, ++frame_, out.stats);
    for (const Draw& d : plan_.draws()) {
      const std::string& name = name_of(d.key);
      out.level[name] = d.level;
      if (d.centreline) out.centreline.insert(name);
    }
    return out;
  }

 private:
  const std::string& name_of(uint32_t slot) const {
    for (const auto& [name, s] : slot_of_)
      if (s == slot) return name;
    static const std::string none = "?";
    ADD_FAILURE() << "slot " << slot << " is no object of the scene";
    return none;
  }

  TempDir dir_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<ReadView> view_;
  detail::DecodedObjects objects_;
  FramePlan plan_;
  uint64_t frame_ = 0;
  std::map<std::string, uint32_t> slot_of_;
};

RenderOptions options(LodPolicy policy = LodPolicy::screen_space) {
  RenderOptions o;
  o.lod_policy = policy;
  return o;
}

// Where a model-space point lands on the image: x, y in pixels from the centre (y up) and the
// depth along the view; through a camera basis built here, not by the code under test.
struct Projected {
  double x_px, y_px, depth_m;
};
Projected project(const Camera& c, uint32_t w, uint32_t h, const glm::dvec3& p) {
  const glm::dvec3 forward = glm::normalize(c.target_m - c.eye_m);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
  const glm::dvec3 up = glm::cross(right, forward);
  const glm::dvec3 d = p - c.eye_m;
  const double depth = glm::dot(d, forward);
  const double pixels_at_1m = h / (2.0 * std::tan(c.fov_deg * M_PI / 360.0));
  (void)w;
  return {glm::dot(d, right) * pixels_at_1m / depth, glm::dot(d, up) * pixels_at_1m / depth, depth};
}

// --- the view ---------------------------------------------------------------------------------

TEST(FramePlanView, AMetreProjectsToThePixelsPerMetreThatLevelChoiceUses) {
  const Camera camera = look({3, -7, 2}, {5, 20, 4}, 40.0);
  const uint32_t w = 640, h = 480;
  const FrameView view = detail::make_frame_view(camera, w, h, glm::dvec3(0.0));
  // Two points 1 m apart across the view, 12 m in front of the eye, through the view's own
  // matrix (eye-relative) to window pixels.
  const glm::dvec3 forward = glm::normalize(camera.target_m - camera.eye_m);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, camera.up));
  const auto to_window_y = [&](const glm::dvec3& p) {
    const glm::vec4 clip = view.view_projection * glm::vec4(glm::vec3(p - camera.eye_m), 1.0f);
    return double(clip.y / clip.w) * h / 2.0;
  };
  const auto to_window_x = [&](const glm::dvec3& p) {
    const glm::vec4 clip = view.view_projection * glm::vec4(glm::vec3(p - camera.eye_m), 1.0f);
    return double(clip.x / clip.w) * w / 2.0;
  };
  const glm::dvec3 a = camera.eye_m + 12.0 * forward;
  const double drawn_px = to_window_x(a + 0.5 * right) - to_window_x(a - 0.5 * right);
  EXPECT_NEAR(drawn_px, detail::pixels_per_metre(12.0, view.focal_px), 1e-3);
  EXPECT_NEAR(std::abs(to_window_y(a)), 0.0, 1e-3);
  // And the same figure from the fov by the textbook formula.
  EXPECT_NEAR(view.focal_px / 12.0, h / (2.0 * std::tan(40.0 * M_PI / 360.0) * 12.0), 1e-4);
  EXPECT_EQ(detail::pixels_per_metre(12.0, 40.0, h), detail::pixels_per_metre(12.0, view.focal_px));
}

// --- cull -------------------------------------------------------------------------------------

TEST(FramePlanCull, ObjectsOutsideTheFrustumAreNotChosenAndThoseInsideAre) {
  // Spheres scattered all around a camera looking along +y.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-60.0, 60.0);
  std::vector<Object> objects;
  for (int i = 0; i < 400; ++i)
    objects.push_back(make_object("s" + std::to_string(i), {coord(rng), coord(rng), coord(rng)}, Sphere{0.5f}));
  Frontend frontend(objects);
  const Camera camera = look({0, 0, 0}, {0, 1, 0.2});
  const uint32_t w = 320, h = 200;
  RenderOptions o = options();
  o.subpixel_culling = false;  // here only the frustum decides
  const auto planned = frontend.plan(camera, w, h, o);
  size_t inside = 0, outside = 0;
  for (const Object& s : objects) {
    // The sphere's bounds' corners, projected independently: wholly inside the image and in
    // front of the eye, or wholly beyond one side of it.
    bool all_in = true, all_left = true, all_right = true, all_below = true, all_above = true,
         all_behind = true;
    for (int c = 0; c < 8; ++c) {
      // (5 cm beyond the bounds: the store rounds them outward by millimetres)
      const glm::dvec3 p = s.origin_m + glm::dvec3(c & 1 ? 0.55 : -0.55, c & 2 ? 0.55 : -0.55, c & 4 ? 0.55 : -0.55);
      const Projected q = project(camera, w, h, p);
      all_behind &= q.depth_m < 0.0;
      if (q.depth_m <= 0.1) {
        all_in = all_left = all_right = all_below = all_above = false;
        continue;
      }
      all_in &= std::abs(q.x_px) < w / 2.0 && std::abs(q.y_px) < h / 2.0;
      all_left &= q.x_px < -(w / 2.0);
      all_right &= q.x_px > w / 2.0;
      all_below &= q.y_px < -(h / 2.0);
      all_above &= q.y_px > h / 2.0;
    }
    const bool chosen = planned.level.count(s.name) != 0;
    if (all_in) {
      ++inside;
      EXPECT_TRUE(chosen) << s.name << " is inside the view";
    } else if (all_behind || all_left || all_right || all_below || all_above) {
      ++outside;
      EXPECT_FALSE(chosen) << s.name << " is outside the view";
    }
  }
  EXPECT_GT(inside, 10u);   // the scene tests both sides
  EXPECT_GT(outside, 200u);
  EXPECT_EQ(planned.stats.objects_visible, planned.level.size());
  EXPECT_EQ(planned.stats.objects_visible + planned.stats.objects_culled, objects.size());
}

TEST(FramePlanCull, ObjectsUnderThePixelErrorAreLeftOutOnlyWithSubpixelCulling) {
  Frontend frontend({make_object("near", {0, 20, 0}, Sphere{0.5f}),
                     make_object("speck", {0, 3000, 0}, Sphere{0.05f})});
  const Camera camera = look({0, 0, 0}, {0, 1, 0});
  auto planned = frontend.plan(camera, 320, 200, options());
  EXPECT_EQ(planned.level.count("speck"), 0u);
  EXPECT_EQ(planned.level.count("near"), 1u);
  EXPECT_EQ(planned.stats.objects_subpixel, 1u);
  RenderOptions all = options();
  all.subpixel_culling = false;
  planned = frontend.plan(camera, 320, 200, all);
  EXPECT_EQ(planned.level.count("speck"), 1u);
  EXPECT_EQ(planned.stats.objects_subpixel, 0u);
}

// --- choose -----------------------------------------------------------------------------------

// The frame's sorts (largest on screen first, nearest first) order (key, index) pairs as
// std::sort does: by key, equal keys by index. Keys like the frame's (float bits over a slot),
// many equal, some bytes the same in every key; sizes on both sides of the small-sort cut.
TEST(FramePlanOrder, TheRadixSortOrdersPairsAsStdSortDoes) {
  std::mt19937_64 rng(3);
  std::vector<detail::SortPair> items, expected, scratch;
  for (const size_t n : {size_t(0), size_t(1), size_t(2), size_t(255), size_t(256), size_t(257),
                         size_t(5000), size_t(40000)}) {
    for (int kind = 0; kind < 3; ++kind) {
      items.clear();
      for (uint32_t i = 0; i < n; ++i) {
        uint64_t key;
        if (kind == 0) key = rng();                                  // every byte varies
        else if (kind == 1) key = uint64_t(rng() % 7) << 40 | 5;     // few keys, many ties
        else key = uint64_t(std::bit_cast<uint32_t>(float(rng() % 100000) * 0.01f)) << 32 | (rng() % 300);
        items.push_back({key, i});
      }
      expected = items;
      std::sort(expected.begin(), expected.end());
      detail::radix_sort(items, scratch);
      ASSERT_EQ(items, expected) << n << " pairs, kind " << kind;
    }
  }
}

TEST(FramePlanChoose, TheChosenLevelIsTheCoarsestWhoseErrorProjectsUnderThePixelError) {
  const float radius = 0.4f;
  const Primitive cylinder{Placement{}, Cylinder{radius, 1.0f}};
  const MeshPlan mesh = plan_mesh(cylinder);
  ASSERT_GT(mesh.level_count, 2);
  Frontend frontend({make_object("c", {0, 0, 0}, Cylinder{radius, 1.0f})});
  const uint32_t h = 480;
  std::set<uint32_t> levels_seen;
  for (double pixel_error : {0.5, 1.0, 3.0}) {
    RenderOptions o = options();
    o.pixel_error = pixel_error;
    o.subpixel_culling = false;  // chosen however far
    for (double d = 1.5; d < 400.0; d *= 1.17) {
      const auto planned = frontend.plan(look({0, -d, 0}, {0, 0, 0}), 640, h, o);
      if (!planned.level.count("c")) {
        ADD_FAILURE() << "not chosen at " << d << " m";
        continue;
      }
      const uint32_t level = planned.level.at("c");
      levels_seen.insert(level);
      // Pixels a metre spans at the cylinder's nearest point (its radius nearer than its axis).
      const double px_per_m = h / (2.0 * std::tan(50.0 * M_PI / 360.0) * (d - radius));
      if (level > 0) {  // (level 0 is the finest there is, whatever its error)
        EXPECT_LE(mesh.error_m[level] * px_per_m, pixel_error * 1.01) << d << " m, level " << level;
      }
      if (level + 1u < mesh.level_count) {
        EXPECT_GT(mesh.error_m[level + 1] * px_per_m, pixel_error * 0.99) << d << " m: level "
                                                                          << level << " is not the coarsest";
      }
    }
  }
  EXPECT_GE(levels_seen.size(), 3u);  // the sweep crosses levels
}

TEST(FramePlanChoose, AFartherCameraNeverChoosesFinerLevels) {
  const std::vector<Object> objects = {
      make_object("cylinder", {0, 0, 0}, Cylinder{0.6f, 2.0f}),
      make_object("torus", {3, 0, 0}, CircularTorus{1.0f, 0.2f, float(M_PI)}),
      make_object("sphere", {-3, 0, 1}, Sphere{0.8f}),
      make_object("box", {0, 0, 3}, Box{1, 1, 1}),
  };
  Frontend frontend(objects);
  for (LodPolicy policy : {LodPolicy::screen_space, LodPolicy::distance}) {
    std::map<std::string, uint8_t> previous;
    for (double d = 4.0; d < 300.0; d *= 1.25) {
      const auto planned = frontend.plan(look({0, -d, 0.5}, {0, 0, 0.5}), 640, 480, options(policy));
      for (const auto& [name, level] : planned.level) {
        if (previous.count(name)) {
          EXPECT_GE(level, previous[name]) << name << " at " << d << " m, policy "
                                           << lod_policy_name(policy);
        }
        previous[name] = level;
      }
    }
    EXPECT_GT(previous.at("cylinder"), 0u) << lod_policy_name(policy);  // it did coarsen
  }
}

TEST(FramePlanChoose, PolicyNoneChoosesFullResolutionEverywhere) {
  Frontend frontend({make_object("near", {0, 5, 0}, Cylinder{0.5f, 1.0f}),
                     make_object("far", {0, 400, 0}, Cylinder{0.5f, 1.0f})});
  const auto planned = frontend.plan(look({0, 0, 0}, {0, 1, 0}), 640, 480, options(LodPolicy::none));
  ASSERT_EQ(planned.level.size(), 2u);
  EXPECT_EQ(planned.level.at("near"), 0u);
  EXPECT_EQ(planned.level.at("far"), 0u);
  EXPECT_TRUE(planned.centreline.empty());
}

// --- the level slack ----------------------------------------------------------------------------

TEST(FramePlanSlack, ObjectsAreResidentOneLevelFinerOnlyWhileTheArenaIsUnderHalfFull) {
  EXPECT_TRUE(detail::arena_roomy(49, 100));
  EXPECT_FALSE(detail::arena_roomy(50, 100));
  EXPECT_EQ(detail::resident_base(3, LodPolicy::screen_space, true), 2u);
  EXPECT_EQ(detail::resident_base(3, LodPolicy::screen_space, false), 3u);
  EXPECT_EQ(detail::resident_base(0, LodPolicy::screen_space, true), 0u);  // nothing finer
  EXPECT_EQ(detail::resident_base(2, LodPolicy::distance, true), 1u);
  EXPECT_EQ(detail::resident_base(2, LodPolicy::none, false), 0u);
}

}  // namespace
}  // namespace plantview
