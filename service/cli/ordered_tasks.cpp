// Ordered tasks (rules in ordered_tasks.h).
#include "cli/ordered_tasks.h"

#include <algorithm>
#include <cassert>

namespace plantview::cli {

OrderedTasks::OrderedTasks(unsigned threads, size_t max_in_flight)
    : max_in_flight_(std::max<size_t>(max_in_flight, 1)) {
  assert(threads >= 1);
  threads_.reserve(threads);
  for (unsigned t = 0; t < std::max(threads, 1u); ++t) threads_.emplace_back([this] { run_worker(); });
}

OrderedTasks::~OrderedTasks() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;  // workers drain what is waiting, then stop
  }
  queued_.notify_all();
  for (std::thread& t : threads_) t.join();
}

unsigned OrderedTasks::default_threads() {
  return std::clamp(std::thread::hardware_concurrency() / 2, 1u, 4u);
}

void OrderedTasks::submit(std::function<void()> work, std::function<void()> done) {
  while (in_flight_.size() >= max_in_flight_) retire_oldest();
  auto task = std::make_shared<Task>();
  task->work = std::move(work);
  task->done = std::move(done);
  in_flight_.push_back(task);
  {
    std::lock_guard lock(mutex_);
    waiting_.push_back(std::move(task));
  }
  queued_.notify_one();
}

void OrderedTasks::finish() {
  while (!in_flight_.empty()) retire_oldest();
}

void OrderedTasks::retire_oldest() {
  const std::shared_ptr<Task> task = std::move(in_flight_.front());
  in_flight_.pop_front();
  {
    std::unique_lock lock(mutex_);
    finished_.wait(lock, [&] { return task->finished; });
  }
  task->done();
}

void OrderedTasks::run_worker() {
  for (;;) {
    std::shared_ptr<Task> task;
    {
      std::unique_lock lock(mutex_);
      queued_.wait(lock, [&] { return stopping_ || !waiting_.empty(); });
      if (waiting_.empty()) return;  // stopping, and nothing left to run
      task = std::move(waiting_.front());
      waiting_.pop_front();
    }
    task->work();
    {
      std::lock_guard lock(mutex_);
      task->finished = true;
    }
    finished_.notify_all();
  }
}

}  // namespace plantview::cli
