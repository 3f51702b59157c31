// Ordered tasks: work that runs on background threads while the caller goes on (encoding and
// writing review images while the next view renders), with each task's completion handed back
// on the caller's thread in the order the tasks were submitted.
//
// Rules
//   - submit(work, done): `work` runs on one of the threads; `done` runs later on the caller's
//     thread, inside submit() or finish(), after its own work and after every earlier task's
//     done. So what `done` writes (a stats line, a manifest, progress) needs no lock and comes
//     out in submission order whatever order the work finished in.
//   - At most max_in_flight tasks are submitted and not yet done: submit() waits for the
//     oldest before taking another, so what the tasks hold (images) stays bounded.
//   - `work` must not throw; it must not touch what the caller uses until its `done` runs
//     (pass it what it owns, and hand results back through what `done` reads).
//   - The destructor lets the tasks already submitted run to their end and joins the threads;
//     their done calls are dropped (a caller that stops on an error still leaves every file it
//     started written whole).
// Threads: submit() and finish() from one thread (the owner's).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace plantview::cli {

class OrderedTasks {
 public:
  // `threads` >= 1 workers; `max_in_flight` >= 1 tasks at once.
  OrderedTasks(unsigned threads, size_t max_in_flight);
  ~OrderedTasks();
  OrderedTasks(const OrderedTasks&) = delete;
  OrderedTasks& operator=(const OrderedTasks&) = delete;

  void submit(std::function<void()> work, std::function<void()> done);
  // Waits for every task submitted and runs their done calls, in order.
  void finish();

  // Threads for writing images on this machine: half its cores (the other half renders, or
  // is the software renderer's), at least 1, at most 4.
  static unsigned default_threads();

 private:
  struct Task {
    std::function<void()> work, done;
    bool finished = false;  // guarded by mutex_
  };
  void run_worker();
  // Runs the done call of the oldest task once its work has finished.
  void retire_oldest();

  const size_t max_in_flight_;
  std::mutex mutex_;
  std::condition_variable queued_, finished_;
  std::deque<std::shared_ptr<Task>> in_flight_;  // submission order; the caller's alone
  std::deque<std::shared_ptr<Task>> waiting_;    // not yet taken by a worker (mutex_)
  bool stopping_ = false;                        // mutex_
  std::vector<std::thread> threads_;
};

}  // namespace plantview::cli
