// Pipelines analysed for runs on the renderer's workers (render/src/decoded_objects.h), each
// worker reading through a sibling view of the renderer's: the runs are exactly those one thread
// finds, and where no sibling can be had the renderer's thread reads alone. Built into the
// service unit tests so that the ThreadSanitizer pass (scripts/test.sh) runs it: the render
// workers of the service decode on their pools.
#include <gtest/gtest.h>

#include <vector>

#include "decoded_objects.h"
#include "frame_plan.h"
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

TEST(PipelineWorkers, RunsFoundOnWorkersAreThoseOfOneThread) {
  TempDir dir;
  auto store = generated_store(dir);
  ASSERT_TRUE(store);
  std::string error;
  const auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  size_t reading_views = 0;
  EXPECT_GT(compare_runs(*view, 3, reading_views), 1000u) << "the plant must have pipeline runs";
  EXPECT_EQ(reading_views, 3u) << "every worker reads through a view of its own";
}

TEST(PipelineWorkers, AfterAnImportCommittedTheRenderersThreadReadsAloneAndFindsTheSameRuns) {
  TempDir dir;
  auto store = generated_store(dir);
  ASSERT_TRUE(store);
  std::string error;
  const auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  // The store moves on: the view's snapshot cannot be read again by a sibling.
  {
    auto import = store->begin_import(error);
    ASSERT_TRUE(import) << error;
    Object o;
    o.id = 1;
    o.name = "/added";
    o.source = "added";
    ASSERT_TRUE(import->put(o, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  size_t reading_views = 0;
  EXPECT_GT(compare_runs(*view, 3, reading_views), 1000u);
  EXPECT_EQ(reading_views, 1u);
}

}  // namespace
}  // namespace plantview
