// Out-of-core rendering (issue 15): what the renderer keeps per object and per node follows what
// its frames touched, not the size of the plant; and the overview of a plant of thirty units
// draws about what the overview of one does (far nodes drawn as their stored far-field proxies).
// The residency key map against a standard map (an independent oracle), then a generated
// preset c at --scale 30 rendered by the real renderer (on whatever EGL offers: llvmpipe in CI).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <unordered_map>

#include "decoded_objects.h"
#include "frame_plan.h"
#include "lod.h"
#include "plantview/camera.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "streaming/residency.h"
#include "support/gl_context.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

using detail::FlatKeyMap;
using test::TempDir;

// --- the residency key map ------------------------------------------------------------------

TEST(ResidencyKeyMap, MemoryFollowsTheKeysPresentNotHowLargeTheyAre) {
  // Slots of a 40-million-object plant, merged runs and the largest key: an array indexed
  // by slot would hold 160 MB here.
  FlatKeyMap<uint64_t> map;
  const uint32_t keys[] = {0u, 39'999'999u, 20'000'000u, 0x80000000u | 5u, 0x80ffffffu, UINT32_MAX};
  for (const uint32_t k : keys) map.insert(k, uint64_t(k) * 3);
  EXPECT_EQ(map.size(), std::size(keys));
  for (const uint32_t k : keys) {
    ASSERT_NE(map.find(k), nullptr) << k;
    EXPECT_EQ(*map.find(k), uint64_t(k) * 3);
  }
  EXPECT_EQ(map.find(1), nullptr);
  EXPECT_LT(map.bytes(), 1024u);
}

// --- the decoded objects' directory -----------------------------------------------------------

TEST(KnownDirectory, FindsWhatWasInsertedByResidencyKeyAndHoldsOnlyThePagesInUse) {
  detail::KnownDirectory directory;
  std::vector<detail::Known> known(6);
  // Slots far apart (a 40-million-object plant), two in one page, and merged runs.
  const uint32_t keys[] = {7u, 8u, 39'999'999u, 20'000'000u, detail::kRunKeyBit | 0u,
                           detail::kRunKeyBit | 70'000u};
  for (size_t i = 0; i < std::size(keys); ++i) directory.insert(keys[i], &known[i]);
  for (size_t i = 0; i < std::size(keys); ++i) EXPECT_EQ(directory.find(keys[i]), &known[i]);
  EXPECT_EQ(directory.find(9), nullptr);
  EXPECT_EQ(directory.find(40'000'000u), nullptr);
  EXPECT_EQ(directory.find(detail::kRunKeyBit | 1u), nullptr);
  EXPECT_EQ(directory.pages(), 3u);
  directory.erase(7);
  EXPECT_EQ(directory.pages(), 3u) << "slot 8 still holds its page";
  directory.erase(8);
  directory.erase(39'999'999u);
  EXPECT_EQ(directory.pages(), 1u);
  EXPECT_EQ(directory.find(8), nullptr);
  EXPECT_EQ(directory.find(20'000'000u), &known[3]);
  directory.erase(detail::kRunKeyBit | 70'000u);
  EXPECT_EQ(directory.find(detail::kRunKeyBit | 70'000u), nullptr);
  EXPECT_EQ(directory.find(detail::kRunKeyBit | 0u), &known[4]);
}

TEST(KnownDirectory, AgreesWithAStandardMapUnderRandomInsertsAndErases) {
  detail::KnownDirectory directory;
  std::unordered_map<uint32_t, detail::Known*> oracle;
  std::vector<detail::Known> known(64);
  std::mt19937 rng(13);
  for (int step = 0; step < 100000; ++step) {
    const uint32_t r = uint32_t(rng());
    const uint32_t key = r % 5 == 0 ? (detail::kRunKeyBit | (r >> 8) % 5000) : r % 20000;
    const auto it = oracle.find(key);
    ASSERT_EQ(directory.find(key), it == oracle.end() ? nullptr : it->second) << "step " << step;
    if (it != oracle.end()) {
      directory.erase(key);
      oracle.erase(it);
    } else {
      detail::Known* k = &known[rng() % known.size()];
      directory.insert(key, k);
      oracle[key] = k;
    }
  }
  for (const auto& [key, k] : oracle) ASSERT_EQ(directory.find(key), k) << key;
  size_t pages = 0;
  for (uint32_t p = 0; p * detail::KnownDirectory::kSlotsPerPage < 20000; ++p) {
    bool any = false;
    for (const auto& [key, k] : oracle)
      any |= !(key & detail::kRunKeyBit) && key / detail::KnownDirectory::kSlotsPerPage == p;
    pages += any;
  }
  EXPECT_EQ(directory.pages(), pages);
}

TEST(ResidencyKeyMap, AgreesWithAStandardMapUnderRandomInsertsAndErases) {
  FlatKeyMap<uint32_t> map;
  std::unordered_map<uint32_t, uint32_t> oracle;
  std::mt19937 rng(15);
  // Keys from a small range (many collisions and re-inserts) and from the whole range.
  const auto random_key = [&] {
    return rng() % 4 == 0 ? uint32_t(rng()) : uint32_t(rng() % 3000);
  };
  size_t peak = 0;
  for (int step = 0; step < 200000; ++step) {
    const uint32_t key = random_key();
    const bool present = oracle.count(key) > 0;
    ASSERT_EQ(map.find(key) != nullptr, present) << "step " << step << " key " << key;
    if (present && rng() % 2) {
      map.erase(key);
      oracle.erase(key);
    } else if (!present) {
      const uint32_t value = uint32_t(rng());
      map.insert(key, value);
      oracle[key] = value;
    } else {
      ASSERT_EQ(*map.find(key), oracle[key]);
    }
    ASSERT_EQ(map.size(), oracle.size());
    peak = std::max(peak, oracle.size());
  }
  size_t seen = 0;
  map.for_each([&](uint32_t k, uint32_t v) {
    ++seen;
    ASSERT_TRUE(oracle.count(k)) << k;
    EXPECT_EQ(oracle[k], v);
  });
  EXPECT_EQ(seen, oracle.size());
  // The table follows the most keys present at once (cells at most 4 per key, 8 bytes each;
  // dense entries 8 bytes, doubled by growth; free list and flags).
  EXPECT_LE(map.bytes(), 64 * peak + 1024);
}

// --- the renderer on a preset c of thirty units ----------------------------------------------

// A generated preset c, shared by the tests of this file (generating is most of their time).
const Store& preset_c(uint32_t scale) {
  static std::map<uint32_t, std::pair<std::unique_ptr<TempDir>, std::unique_ptr<Store>>> stores;
  auto& entry = stores[scale];
  if (!entry.second) {
    entry.first = std::make_unique<TempDir>();
    std::string error;
    entry.second = Store::open(entry.first->str(), Store::Mode::read_write, error);
    if (!entry.second) {
      ADD_FAILURE() << error;
      std::abort();
    }
    GenerateOptions options;
    options.preset = 'c';
    options.scale = scale;
    const IngestResult result = ingest_generated(*entry.second, options);
    if (!result) ADD_FAILURE() << result.error().message;
  }
  return *entry.second;
}

DAabb bounds_of(const Store& store) {
  std::string error;
  const auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  return view ? view->info().statistics.bounds : DAabb{};
}

// Eye-height views walking along an aisle of a box `region`: `frames` cameras from one end of
// its x extent towards the other, looking ahead and a little aside.
std::vector<Camera> walk(const DAabb& region, int frames) {
  std::vector<Camera> path;
  const double y = region.min.y + 0.45 * (region.max.y - region.min.y);
  const double z = region.min.z + 1.7;
  for (int i = 0; i < frames; ++i) {
    const double x = region.min.x + (0.1 + 0.8 * i / std::max(frames - 1, 1)) * (region.max.x - region.min.x);
    Camera c;
    c.eye_m = {x, y, z};
    c.target_m = {x + 20.0, y + 5.0 * ((i % 2) ? 1 : -1), z - 1.0};
    path.push_back(c);
  }
  return path;
}

TEST(OutOfCore, RendererMemoryFollowsWhatThePathSawNotThePlant) {
  const DAabb unit = bounds_of(preset_c(1));
  const Store& store = preset_c(30);
  std::string error;
  const auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  const uint64_t plant_objects = view->spatial_objects();
  const DAabb plant = view->info().statistics.bounds;
  ASSERT_GT(plant_objects, 1'000'000u);

  test::gl_context();
  RenderOptions options;
  options.vertex_budget_bytes = 64ull << 20;
  auto renderer = Renderer::create(store, options, error);
  ASSERT_TRUE(renderer) << error;

  // A walk through the first unit, then one through the first unit of the last row (units are
  // laid out row by row: its slots are among the plant's highest), then the overview.
  std::vector<Camera> path = walk(unit, 4);
  DAabb far_unit = unit;
  far_unit.min.y += plant.max.y - unit.max.y;
  far_unit.max.y += plant.max.y - unit.max.y;
  for (const Camera& c : walk(far_unit, 4)) path.push_back(c);
  path.push_back(default_camera(plant, 16.0 / 9.0));

  uint64_t max_visible = 0, max_resident = 0, max_walked = 0, max_held = 0;
  for (size_t i = 0; i < path.size(); ++i) {
    FrameStats stats;
    Image image;
    ASSERT_TRUE(renderer->render(path[i], 480, 270, false, image, stats, error)) << error;
    max_visible = std::max(max_visible, stats.objects_visible + stats.objects_occluded);
    max_resident = std::max(max_resident, stats.objects_resident);
    max_walked = std::max(max_walked, stats.spatial_blocks_walked);
    max_held = std::max(max_held, stats.spatial_blocks_held);
    SCOPED_TRACE("frame " + std::to_string(i));
    // Index blocks: only those holding this frame's visible objects (each holds one at least).
    EXPECT_LE(stats.spatial_blocks_held, stats.objects_visible + stats.objects_occluded);
    // Decoded objects: the resident ones, this frame's and a fixed number more.
    EXPECT_LE(stats.objects_known, detail::kKnownObjectsKept + max_resident + max_visible);
    // Residency bookkeeping: a few dozen bytes for each object resident at once, not 4 bytes
    // a slot up to the highest slot seen.
    EXPECT_LE(stats.residency_bytes, 160 * (max_resident + 1) + 4096);
  }
  std::printf("x30: %llu objects in %u blocks; path: at most %llu visible, %llu resident, "
              "%llu blocks walked, %llu held\n",
              (unsigned long long)plant_objects, view->spatial_block_count(),
              (unsigned long long)max_visible, (unsigned long long)max_resident,
              (unsigned long long)max_walked, (unsigned long long)max_held);
  // The path saw a small part of the plant, so the bounds above are not the plant's size.
  EXPECT_LT(detail::kKnownObjectsKept + max_resident + max_visible, plant_objects / 10);
}

TEST(OutOfCore, OverviewOfThirtyUnitsDrawsAtMostTwiceOneUnitsTriangles) {
  test::gl_context();
  const auto overview_triangles = [](const Store& store, FrameStats& stats) {
    std::string error;
    const auto view = store.read(error);
    EXPECT_TRUE(view) << error;
    auto renderer = Renderer::create(store, RenderOptions{}, error);
    EXPECT_TRUE(renderer) << error;
    if (!view || !renderer) return uint64_t(0);
    const Camera camera = default_camera(overview_boxes(*view), 16.0 / 9.0);
    EXPECT_TRUE(renderer->statistics(camera, 1280, 720, stats, error)) << error;
    return stats.triangles;
  };
  FrameStats one_stats, thirty_stats;
  const uint64_t one = overview_triangles(preset_c(1), one_stats);
  const uint64_t thirty = overview_triangles(preset_c(30), thirty_stats);
  std::printf("overview triangles: x1 %llu, x30 %llu (%llu node boxes for %llu objects)\n",
              (unsigned long long)one, (unsigned long long)thirty,
              (unsigned long long)thirty_stats.node_proxies,
              (unsigned long long)thirty_stats.objects_in_node_proxies);
  ASSERT_GT(one, 0u);
  EXPECT_LE(thirty, 2 * one);
  // Far nodes were drawn as proxies: the thirty units are there, as boxes where far.
  EXPECT_GT(thirty_stats.objects_in_node_proxies, 0u);
}

// Policy none draws every object, but not a million: beyond kMaxObjectsAnyPolicy the rest of the
// view is drawn as far-field proxies, so that its memory stays bounded on a plant seen whole.
TEST(OutOfCore, PolicyNoneOnAPlantOfMillionsStopsAtTheObjectCap) {
  test::gl_context();
  const Store& store = preset_c(30);
  std::string error;
  const auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  RenderOptions options;
  options.lod_policy = LodPolicy::none;
  options.occlusion = false;
  options.vertex_budget_bytes = 16u << 20;  // what does not fit is boxed: the cull is tested
  auto renderer = Renderer::create(store, options, error);
  ASSERT_TRUE(renderer) << error;
  FrameStats stats;
  ASSERT_TRUE(renderer->statistics(default_camera(overview_boxes(*view), 16.0 / 9.0), 1280, 720,
                                   stats, error)) << error;
  ASSERT_GT(view->spatial_objects(), 4 * detail::kMaxObjectsAnyPolicy);
  // The cap is checked before each block (at most kSpatialBlockObjects more).
  EXPECT_GE(stats.objects_visible, detail::kMaxObjectsAnyPolicy);
  EXPECT_LE(stats.objects_visible, detail::kMaxObjectsAnyPolicy + 2048);
  EXPECT_GT(stats.objects_in_node_proxies, 0u);
  EXPECT_GT(stats.node_proxies, 0u);
  EXPECT_EQ(stats.objects_visible + stats.objects_in_node_proxies + stats.objects_culled,
            view->spatial_objects());
}

// Pipeline runs are kept for the pipelines the known objects belong to, not for every pipeline
// a renderer has met: a service walking a whole site must not grow with it. Decodes the objects
// of twenty units in frames of 2,000 (as a walk would meet them), forgetting as a renderer does.
TEST(OutOfCore, PipelineRunsFollowTheObjectsKnownNotEveryPipelineMet) {
  const Store& store = preset_c(30);
  std::string error;
  const auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  detail::DecodedObjects objects;
  objects.reset(*view);
  const detail::Residency residency(1u << 20);  // nothing resident
  std::vector<detail::VisibleObject> frame;
  std::unordered_map<uint64_t, bool> pipelines_met;
  uint64_t frame_number = 0;
  size_t most_pipelines = 0, most_runs = 0;
  const uint32_t slots = uint32_t(view->spatial_objects() * 2 / 3);
  for (uint32_t slot = 0; slot < slots; ++slot) {
    frame.push_back(detail::VisibleObject{slot, {}, {}, 0.0, 0.0, 0, 0});
    if (frame.size() < 2000 && slot + 1 < slots) continue;
    ASSERT_TRUE(objects.decode(frame, true, error)) << error;
    for (detail::Known* k : objects.decoded())
      if (k->run >= 0) pipelines_met[k->pipeline_id] = true;
    objects.forget_old(++frame_number, residency);
    most_pipelines = std::max(most_pipelines, objects.pipelines_count());
    most_runs = std::max(most_runs, objects.runs_count());
    frame.clear();
  }
  const size_t bound = 2 * std::max(detail::kPipelinesKept, detail::kKnownObjectsKept + 2000);
  std::printf("pipelines met %zu, held at most %zu (%zu runs); bound %zu\n", pipelines_met.size(),
              most_pipelines, most_runs, bound);
  ASSERT_GT(pipelines_met.size(), bound) << "the walk must meet more pipelines than the bound";
  EXPECT_LE(most_pipelines, bound);
}

// Nodes are opened largest on screen first, and opening stops where the next would exceed the
// frame's items: so a view that cannot show every object reads only the blocks whose nodes span
// more than the size left boxed, once each, and the boxes are the finest that fit.
TEST(OutOfCore, CullOpensTheLargestNodesFirstAndReadsOnlyTheBlocksItOpens) {
  test::gl_context();
  const Store& store = preset_c(30);
  std::string error;
  const auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  RenderOptions options;
  options.occlusion = false;  // the items counted are then exactly what cull kept
  auto renderer = Renderer::create(store, options, error);
  ASSERT_TRUE(renderer) << error;
  const auto top = view->spatial_top();
  std::vector<Camera> cameras{default_camera(overview_boxes(*view), 16.0 / 9.0)};
  for (const Camera& c : walk(bounds_of(store), 4)) cameras.push_back(c);
  for (size_t i = 0; i < cameras.size(); ++i) {
    FrameStats stats;
    ASSERT_TRUE(renderer->statistics(cameras[i], 1280, 720, stats, error)) << error;
    SCOPED_TRACE("view " + std::to_string(i));
    // Beyond kMaxDrawnItems only where the view is opened whole (boxes only under the proxy
    // size).
    const size_t items = stats.objects_visible + stats.node_proxies;
    const double proxy_px = detail::kNodeProxyPixels * renderer->options().pixel_error;
    EXPECT_LE(items, detail::kMaxCompleteItems);
    if (items > detail::kMaxDrawnItems) {
      EXPECT_EQ(stats.node_proxy_pixels, proxy_px);
    }
    EXPECT_GE(stats.node_proxy_pixels, proxy_px);
    // The blocks under top leaves that span at least the boxed size, in the frustum.
    const detail::FrameView fv = detail::make_frame_view(cameras[i], 1280, 720, view->spatial_origin());
    uint64_t openable = 0;
    for (const SpatialNode& node : top) {
      if (node.count == 0 || fv.outside(node.min, node.max)) continue;
      const double extent_m = std::max({node.max[0] - node.min[0], node.max[1] - node.min[1], node.max[2] - node.min[2]});
      const double px = extent_m * fv.focal_px / std::max(fv.nearest_distance_m(node.min, node.max), detail::kNearPlaneM);
      openable += px >= stats.node_proxy_pixels;
    }
    EXPECT_LE(stats.spatial_blocks_walked, openable + 1);
    if (i == 0) {
      std::printf("overview of x30: %llu blocks read of %u, boxes under %.1f px\n",
                  (unsigned long long)stats.spatial_blocks_walked, unsigned(view->spatial_block_count()),
                  stats.node_proxy_pixels);
      EXPECT_GT(stats.objects_in_node_proxies, 0u);
    }
  }
}

// A snapshot's first cull reads up to kMaxFrameBlocksHeld index blocks: those it will read are
// read ahead on the workers (FramePlan::blocks_ahead, DecodedObjects::read_blocks). The blocks
// named are the ones the cull reads, largest first, where its bound does not stop it; later
// culls name none; the frame is the same with them read ahead.
TEST(OutOfCore, AFirstCullReadsAheadTheBlocksItWillRead) {
  const Store& store = preset_c(30);
  std::string error;
  const auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  RenderOptions options;
  std::vector<Camera> cameras{default_camera(overview_boxes(*view), 16.0 / 9.0)};
  for (const Camera& c : walk(bounds_of(store), 4)) cameras.push_back(c);
  for (size_t i = 0; i < cameras.size(); ++i) {
    SCOPED_TRACE("view " + std::to_string(i));
    const detail::FrameView fv = detail::make_frame_view(cameras[i], 1280, 720, view->spatial_origin());
    detail::FramePlan plan, unread;
    std::vector<uint32_t> ahead;
    plan.blocks_ahead(*view, fv, options, ahead);
    ASSERT_LE(ahead.size(), detail::kMaxFrameBlocksHeld);
    detail::DecodedObjects objects;
    objects.reset(*view);
    objects.read_blocks(ahead);
    FrameStats stats, unread_stats;
    ASSERT_TRUE(plan.find_visible(*view, fv, options, stats, error)) << error;
    ASSERT_TRUE(unread.find_visible(*view, fv, options, unread_stats, error)) << error;
    EXPECT_EQ(stats.to_json(), unread_stats.to_json());
    const std::span<const detail::VisibleObject> a = plan.visible(), b = unread.visible();
    ASSERT_EQ(a.size(), b.size());
    for (size_t o = 0; o < a.size(); ++o) ASSERT_EQ(a[o].slot, b[o].slot) << o;
    // Each block named is one the cull read (it holds those it took objects from); where the
    // bound did not stop the opening (no node boxed above the proxy size), it read those alone.
    std::set<uint32_t> named(ahead.begin(), ahead.end());
    EXPECT_EQ(named.size(), ahead.size());
    for (const detail::VisibleObject& v : a) EXPECT_TRUE(named.count(v.block)) << v.block;
    if (stats.node_proxy_pixels == detail::kNodeProxyPixels * options.pixel_error) {
      EXPECT_EQ(stats.spatial_blocks_walked, ahead.size());
    }
    plan.blocks_ahead(*view, fv, options, ahead);
    EXPECT_TRUE(ahead.empty());
  }
}

// A plant of one unit (40,746 objects) seen whole at the still pixel error needs more objects
// than kMaxDrawnItems: its nodes are still opened down to the proxy size (no node of several
// pixels drawn as a grey box for the bound), while the thirty units' overview keeps the bound.
TEST(OutOfCore, AViewOfOneUnitIsOpenedWholeWhereTheBoundWouldBoxIt) {
  test::gl_context();
  RenderOptions options;
  options.pixel_error = kStillPixelError;
  options.occlusion = false;  // the items counted are then exactly what cull kept
  const double proxy_px = detail::kNodeProxyPixels * options.pixel_error;
  const auto overview = [&](uint32_t units) {
    std::string error;
    auto renderer = Renderer::create(preset_c(units), options, error);
    EXPECT_TRUE(renderer) << error;
    FrameStats stats;
    if (renderer) {
      EXPECT_TRUE(renderer->statistics(default_camera(renderer->model_bounds(), 16.0 / 9.0), 1280,
                                       720, stats, error)) << error;
    }
    std::printf("overview of x%u: %llu objects, %llu boxes under %.2f px\n", units,
                (unsigned long long)stats.objects_visible, (unsigned long long)stats.node_proxies,
                stats.node_proxy_pixels);
    return stats;
  };
  const FrameStats one = overview(1);
  EXPECT_GT(one.objects_visible + one.node_proxies, detail::kMaxDrawnItems);
  EXPECT_EQ(one.node_proxy_pixels, proxy_px);
  const FrameStats thirty = overview(30);
  EXPECT_LE(thirty.objects_visible + thirty.node_proxies, detail::kMaxDrawnItems);
  EXPECT_GT(thirty.node_proxy_pixels, proxy_px);
}

}  // namespace
}  // namespace plantview
