// Pipelines analysed for runs on the renderer's workers (render/src/decoded_objects.h), each
// worker reading through a sibling view of the renderer's: the runs are exactly those one thread
// finds, and where no sibling can be had the renderer's thread reads alone; and occlusion's
// occluders and tests on the workers drop what one thread drops. Built into the service unit
// tests so that the ThreadSanitizer pass (scripts/test.sh) runs it: the render workers of the
// service decode and cull on their pools.
#include <gtest/gtest.h>
#include <lmdb.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <unordered_map>
#include <vector>

#include "decoded_objects.h"
#include "frame_plan.h"
#include "hlod.h"
#include "occlusion/occlusion.h"
#include "plantview/camera.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/store.h"
#include "support/temp_dir.h"
#include "worker_pool.h"

namespace plantview {
namespace {

using test::TempDir;

std::unique_ptr<Store> generated_store(const TempDir& dir) {
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  EXPECT_TRUE(store) << error;
  if (!store) return nullptr;
  GenerateOptions options;
  options.preset = 'a';
  const IngestResult result = ingest_generated(*store, options);
  EXPECT_TRUE(result) << result.error().message;
  return store;
}

// Decodes every slot of `view` in frames of `frame_slots`, with HLOD, on one thread and on a
// pool of `threads`, and checks that both find the same runs for the same objects. Returns the
// objects found in runs.
size_t compare_runs(const ReadView& view, unsigned threads, size_t& reading_views) {
  std::string error;
  detail::WorkerPool pool(threads);
  detail::DecodedObjects alone, shared(&pool);
  alone.reset(view);
  shared.reset(view);
  std::vector<detail::VisibleObject> frame;
  size_t in_runs = 0;
  const uint32_t slots = view.slot_count();
  for (uint32_t slot = 0; slot < slots; ++slot) {
    frame.push_back(detail::VisibleObject{slot, {}, {}, 0.0, 0.0, 0, 0});
    if (frame.size() < 2000 && slot + 1 < slots) continue;
    EXPECT_TRUE(alone.decode(frame, true, error)) << error;
    EXPECT_TRUE(shared.decode(frame, true, error)) << error;
    for (size_t i = 0; i < frame.size(); ++i) {
      const detail::Known& a = *alone.decoded()[i];
      const detail::Known& b = *shared.decoded()[i];
      EXPECT_EQ(a.run, b.run) << "slot " << frame[i].slot;
      if (a.run < 0 || a.run != b.run) continue;
      in_runs += 1;
      const detail::PipelineRun& ra = alone.run(uint32_t(a.run));
      const detail::PipelineRun& rb = shared.run(uint32_t(b.run));
      EXPECT_EQ(ra.members, rb.members) << "slot " << frame[i].slot;
      EXPECT_EQ(ra.merge_error_m, rb.merge_error_m);
      EXPECT_EQ(ra.start_m, rb.start_m);
      EXPECT_EQ(ra.end_m, rb.end_m);
    }
    frame.clear();
  }
  EXPECT_EQ(alone.runs_count(), shared.runs_count());
  EXPECT_EQ(alone.reading_views(), 1u);
  reading_views = shared.reading_views();
  return in_runs;
}

// A generated plant and a view of it.
class PipelineWorkers : public ::testing::Test {
 protected:
  void SetUp() override {
    store_ = generated_store(dir_);
    ASSERT_TRUE(store_);
    std::string error;
    view_ = store_->read(error);
    ASSERT_TRUE(view_) << error;
  }
  TempDir dir_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<ReadView> view_;
};

TEST_F(PipelineWorkers, RunsFoundOnWorkersAreThoseOfOneThread) {
  size_t reading_views = 0;
  EXPECT_GT(compare_runs(*view_, 3, reading_views), 1000u) << "the plant must have pipeline runs";
  EXPECT_EQ(reading_views, 3u) << "every worker reads through a view of its own";
}

// A renderer analyses only the stretch of a branch about each member it meets (up to the
// members that end runs): meeting the plant's objects a few at a time, in any order, on the
// workers, it finds for every member the run that its whole branch, analysed at once, gives.
TEST_F(PipelineWorkers, RunsFoundStretchByStretchInAnyOrderAreThoseOfWholeBranches) {
  std::string error;
  const uint32_t slots = view_->slot_count();
  std::unordered_map<uint32_t, std::vector<uint32_t>> expected;  // member slot -> its run
  size_t pipelines = 0;
  for (uint32_t slot = 0; slot < slots; ++slot) {
    Object pipeline;
    ASSERT_TRUE(view_->object(slot, pipeline, false, error)) << error;
    if (pipeline.object_class != ObjectClass::pipeline) continue;
    pipelines += 1;
    for (const Branch& b : pipeline.branches) {
      std::vector<Object> members(b.members.size());
      std::vector<std::pair<uint32_t, const Object*>> branch;
      for (size_t i = 0; i < b.members.size(); ++i) {
        const auto s = view_->slot_of(b.members[i]);
        ASSERT_TRUE(s) << "member " << b.members[i];
        ASSERT_TRUE(view_->object(*s, members[i], false, error)) << error;
        branch.emplace_back(*s, &members[i]);
      }
      std::vector<detail::PipelineRun> runs;
      detail::find_runs(branch, runs);
      for (const auto& run : runs)
        for (const uint32_t m : run.members) expected[m] = run.members;
    }
  }
  ASSERT_GT(pipelines, 10u);
  ASSERT_GT(expected.size(), 1000u) << "the plant must have pipeline runs";

  std::vector<uint32_t> order(slots);
  for (uint32_t s = 0; s < slots; ++s) order[s] = s;
  std::mt19937 random(7);
  std::shuffle(order.begin(), order.end(), random);
  detail::WorkerPool pool(3);
  detail::DecodedObjects objects(&pool);
  objects.reset(*view_);
  std::vector<detail::VisibleObject> frame;
  for (size_t i = 0; i < order.size(); ++i) {
    frame.push_back(detail::VisibleObject{order[i], {}, {}, 0.0, 0.0, 0, 0});
    if (frame.size() < 37 && i + 1 < order.size()) continue;
    ASSERT_TRUE(objects.decode(frame, true, error)) << error;
    frame.clear();
  }
  size_t in_runs = 0;
  for (uint32_t slot = 0; slot < slots; ++slot) {
    const detail::Known* k = objects.find(slot);
    ASSERT_TRUE(k) << "slot " << slot;
    const auto it = expected.find(slot);
    if (it == expected.end()) {
      EXPECT_LT(k->run, 0) << "slot " << slot << " is in no run of its branch";
      continue;
    }
    ASSERT_GE(k->run, 0) << "slot " << slot << " is in a run of its branch";
    EXPECT_EQ(objects.run(uint32_t(k->run)).members, it->second) << "slot " << slot;
    in_runs += 1;
  }
  EXPECT_EQ(in_runs, expected.size());
}

TEST_F(PipelineWorkers, AfterAnImportCommittedTheRenderersThreadReadsAloneAndFindsTheSameRuns) {
  std::string error;
  // The store moves on: the view's snapshot cannot be read again by a sibling.
  {
    auto import = store_->begin_import(error);
    ASSERT_TRUE(import) << error;
    Object o;
    o.id = 1;
    o.name = "/added";
    o.source = "added";
    ASSERT_TRUE(import->put(o, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  size_t reading_views = 0;
  EXPECT_GT(compare_runs(*view_, 3, reading_views), 1000u);
  EXPECT_EQ(reading_views, 1u);
}

// A damaged record among a frame's new objects: decoding stops there with the store's message
// naming the slot, on the workers as on one thread, and what came before it is known, its
// pipelines analysed.
TEST_F(PipelineWorkers, ACorruptRecordStopsDecodingAtItsSlotWithTheObjectsBeforeItKnown) {
  view_.reset();
  store_.reset();
  const TempDir& dir = dir_;
  // The object chunk holding slot 1280 (the greatest key not above it; chunks.h) overwritten
  // with a frame that is not zstd, for as many slots as it held.
  uint32_t first = 0;
  {
    MDB_env* env = nullptr;
    ASSERT_EQ(mdb_env_create(&env), MDB_SUCCESS);
    mdb_env_set_maxdbs(env, 12);
    ASSERT_EQ(mdb_env_open(env, dir.str().c_str(), 0, 0644), MDB_SUCCESS);
    MDB_txn* txn = nullptr;
    MDB_dbi dbi;
    MDB_cursor* cursor = nullptr;
    ASSERT_EQ(mdb_txn_begin(env, nullptr, 0, &txn), MDB_SUCCESS);
    ASSERT_EQ(mdb_dbi_open(txn, "objects", 0, &dbi), MDB_SUCCESS);
    ASSERT_EQ(mdb_cursor_open(txn, dbi, &cursor), MDB_SUCCESS);
    unsigned char key[4] = {0, 0, 1280 >> 8, 1280 & 255};
    MDB_val k{4, key}, v;
    int rc = mdb_cursor_get(cursor, &k, &v, MDB_SET_RANGE);
    if (rc != MDB_SUCCESS || std::memcmp(k.mv_data, key, 4) != 0) {
      rc = mdb_cursor_get(cursor, &k, &v, MDB_PREV);
    }
    ASSERT_EQ(rc, MDB_SUCCESS);
    ASSERT_EQ(k.mv_size, 4u);
    const auto* got = static_cast<const unsigned char*>(k.mv_data);
    first = uint32_t(got[0]) << 24 | uint32_t(got[1]) << 16 | uint32_t(got[2]) << 8 | got[3];
    uint8_t value[8] = {0, 0, 0, 0, 'X', 'X', 'X', 'X'};
    std::memcpy(value, v.mv_data, 4);  // the chunk's slot count
    std::memcpy(key, got, 4);
    mdb_cursor_close(cursor);
    MDB_val put_k{4, key}, put_v{8, value};
    ASSERT_EQ(mdb_put(txn, dbi, &put_k, &put_v, 0), MDB_SUCCESS);
    ASSERT_EQ(mdb_txn_commit(txn), MDB_SUCCESS);
    mdb_env_close(env);
  }
  ASSERT_GT(first, 1000u);
  ASSERT_LE(first, 1280u);
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  const auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  detail::WorkerPool pool(3);
  detail::DecodedObjects alone, shared(&pool);
  alone.reset(*view);
  shared.reset(*view);
  std::vector<detail::VisibleObject> frame;
  for (uint32_t slot = 0; slot < 3000; ++slot)
    frame.push_back(detail::VisibleObject{slot, {}, {}, 0.0, 0.0, 0, 0});
  std::string alone_error, shared_error;
  EXPECT_FALSE(alone.decode(frame, true, alone_error));
  EXPECT_FALSE(shared.decode(frame, true, shared_error));
  EXPECT_EQ(shared_error, alone_error);
  EXPECT_NE(shared_error.find(dir.str()), std::string::npos) << shared_error;
  EXPECT_NE(shared_error.find("object slot " + std::to_string(first)), std::string::npos)
      << shared_error;
  EXPECT_GT(shared.reading_views(), 1u) << "the objects must have been read on the workers";
  size_t in_runs = 0;
  for (uint32_t slot = 0; slot < first; ++slot) {
    const detail::Known* a = alone.find(slot);
    const detail::Known* b = shared.find(slot);
    ASSERT_TRUE(a && b) << "slot " << slot << " precedes the damage and must be known";
    EXPECT_EQ(a->run, b->run) << "slot " << slot;
    in_runs += a->run >= 0;
  }
  // (59 of these slots are in runs: the plant lists its equipment first.)
  EXPECT_GT(in_runs, 20u) << "the pipelines of the objects known must have been analysed";
  EXPECT_FALSE(shared.find(first));
}

// Occlusion's CPU form on the pool (the occluders rasterised by each worker into a buffer of
// its own, merged; the tests in parts) keeps and drops exactly what it does on one thread.
TEST_F(PipelineWorkers, OcclusionOnWorkersDropsWhatOneThreadDrops) {
  std::string error;
  detail::WorkerPool pool(3);
  detail::DecodedObjects alone_objects, shared_objects(&pool);
  alone_objects.reset(*view_);
  shared_objects.reset(*view_);
  detail::FramePlan alone, shared(&pool);
  RenderOptions options;
  const DAabb bounds = view_->info().statistics.bounds;
  const glm::dvec3 centre = 0.5 * (bounds.min + bounds.max), size = bounds.max - bounds.min;
  size_t most_occluders = 0, occluded = 0;
  for (int i = 0; i < 8; ++i) {
    // Around the plant at a fifth of its size from its middle, a little above its floor.
    const double angle = 0.8 * i;
    Camera camera;
    camera.eye_m = centre + glm::dvec3(0.2 * size.x * std::cos(angle), 0.2 * size.y * std::sin(angle),
                                       -0.3 * size.z);
    camera.target_m = centre + glm::dvec3(0.0, 0.0, -0.3 * size.z);
    camera.fov_deg = 60;
    const detail::FrameView fv = detail::make_frame_view(camera, 640, 360, view_->spatial_origin());
    FrameStats a, b;
    ASSERT_TRUE(alone.find_visible(*view_, fv, options, a, error)) << error;
    ASSERT_TRUE(alone.occlude(*view_, alone_objects, fv, options, a, error)) << error;
    ASSERT_TRUE(shared.find_visible(*view_, fv, options, b, error)) << error;
    ASSERT_TRUE(shared.occlude(*view_, shared_objects, fv, options, b, error)) << error;
    SCOPED_TRACE("view " + std::to_string(i));
    EXPECT_EQ(a.occluders, b.occluders);
    EXPECT_EQ(a.objects_occluded, b.objects_occluded);
    EXPECT_EQ(a.nodes_occluded, b.nodes_occluded);
    ASSERT_EQ(alone.visible().size(), shared.visible().size());
    for (size_t v = 0; v < alone.visible().size(); ++v)
      ASSERT_EQ(alone.visible()[v].slot, shared.visible()[v].slot);
    most_occluders = std::max<size_t>(most_occluders, b.occluders);
    occluded += b.objects_occluded;
  }
  // Views with more occluders than one part of the pool takes, hiding something.
  EXPECT_GT(most_occluders, 2 * detail::kOccludersPerPart);
  EXPECT_GT(occluded, 0u);
}

}  // namespace
}  // namespace plantview
