// The renderer's worker pool (render/src/worker_pool.h): every part runs once, on a worker
// index no other thread uses at the same time, and run() returns only when all have. Built into
// the service unit tests so that the ThreadSanitizer pass (scripts/test.sh) runs it too: the
// render workers of the service use one pool each.
#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <vector>

#include "worker_pool.h"

namespace plantview {
namespace {

using detail::WorkerPool;

TEST(WorkerPool, RunsEveryPartOnceAndReturnsWhenAllAreDone) {
  for (const unsigned threads : {1u, 2u, 5u}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.size(), threads);
    for (const size_t parts : {size_t(0), size_t(1), size_t(3), size_t(1000)}) {
      std::vector<int> ran(parts, 0);  // each part writes only its own element
      pool.run(parts, [&](size_t part, unsigned worker) {
        ASSERT_LT(worker, threads);
        ran[part] += 1;
      });
      EXPECT_EQ(std::accumulate(ran.begin(), ran.end(), size_t(0)), parts)
          << threads << " threads, " << parts << " parts";
      for (size_t p = 0; p < parts; ++p) ASSERT_EQ(ran[p], 1) << "part " << p;
    }
  }
}

TEST(WorkerPool, AWorkersScratchIsNeverUsedByTwoPartsAtOnce) {
  WorkerPool pool(4);
  std::vector<std::atomic<int>> in_use(pool.size());
  std::vector<long> scratch(pool.size(), 0);  // plain: TSan reports any shared use
  std::atomic<int> clashes{0};
  for (int job = 0; job < 200; ++job) {
    pool.run(64, [&](size_t part, unsigned worker) {
      if (in_use[worker].fetch_add(1) != 0) clashes += 1;
      scratch[worker] += long(part);
      in_use[worker].fetch_sub(1);
    });
  }
  EXPECT_EQ(clashes.load(), 0);
  EXPECT_EQ(std::accumulate(scratch.begin(), scratch.end(), 0L), 200L * (63 * 64 / 2));
}

TEST(WorkerPool, ThePoolForThisMachineHasAtLeastOneAndAtMostTheCapWorkers) {
  const unsigned n = WorkerPool::default_size();
  EXPECT_GE(n, 1u);
  EXPECT_LE(n, WorkerPool::kMaxWorkers);
}

}  // namespace
}  // namespace plantview
