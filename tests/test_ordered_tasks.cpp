// Ordered tasks (service/cli/ordered_tasks.h): the images of a render run are written on other
// threads, and their stats lines and manifest records must still come out in view order,
// with a bounded number of images held.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "cli/ordered_tasks.h"

namespace plantview::cli {
namespace {

TEST(OrderedTasks, DoneCallsComeInSubmissionOrderWhenLaterWorkFinishesFirst) {
  OrderedTasks tasks(4, 8);
  std::vector<int> done_order;
  std::vector<std::atomic<bool>> worked(32);
  for (int i = 0; i < 32; ++i) {
    tasks.submit(
        [&worked, i] {
          // Earlier tasks take longer: their work finishes after later ones'.
          std::this_thread::sleep_for(std::chrono::microseconds(200 * (8 - i % 8)));
          worked[size_t(i)] = true;
        },
        [&done_order, &worked, i] {
          EXPECT_TRUE(worked[size_t(i)]) << "done " << i << " before its work";
          done_order.push_back(i);
        });
  }
  tasks.finish();
  ASSERT_EQ(done_order.size(), 32u);
  for (int i = 0; i < 32; ++i) EXPECT_EQ(done_order[size_t(i)], i);
}

TEST(OrderedTasks, HoldsAtMostMaxInFlightTasks) {
  OrderedTasks tasks(2, 3);
  int in_flight = 0, most = 0;  // on this thread only: submit and done
  std::atomic<int> running{0}, most_running{0};
  for (int i = 0; i < 40; ++i) {
    ++in_flight;
    most = std::max(most, in_flight);
    tasks.submit(
        [&] {
          const int now = ++running;
          int seen = most_running.load();
          while (now > seen && !most_running.compare_exchange_weak(seen, now)) {
          }
          std::this_thread::sleep_for(std::chrono::microseconds(300));
          --running;
        },
        [&] { --in_flight; });
    // submit() retires the oldest before taking a task beyond the bound.
    EXPECT_LE(in_flight, 3) << "after task " << i;
  }
  tasks.finish();
  EXPECT_EQ(in_flight, 0);
  EXPECT_EQ(most, 4) << "the fourth is counted here before submit() retires the oldest";
  EXPECT_LE(most_running.load(), 2) << "no more work at once than threads";
}

TEST(OrderedTasks, DestroyingRunsTheSubmittedWorkToItsEndWithoutDoneCalls) {
  std::atomic<int> worked{0};
  int done = 0;
  {
    OrderedTasks tasks(1, 5);
    for (int i = 0; i < 5; ++i)
      tasks.submit(
          [&] {
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
            ++worked;
          },
          [&] { ++done; });
  }
  EXPECT_EQ(worked.load(), 5) << "every file started is written whole";
  EXPECT_EQ(done, 0);
}

TEST(OrderedTasks, DefaultThreadsLeaveCoresToRender) {
  const unsigned threads = OrderedTasks::default_threads();
  EXPECT_GE(threads, 1u);
  EXPECT_LE(threads, 4u);
}

}  // namespace
}  // namespace plantview::cli
