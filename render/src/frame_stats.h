// Frame statistics: timing a frame's stages, and how the times are reported. The counts are
// filled by the stage that knows them (frame_plan.h: cull and choose; arena_streaming.h:
// streaming); FrameStats itself is in render.h, its JSON form in frame_stats.cpp.
// Units: milliseconds, from the steady clock.
// Threads: a Stopwatch belongs to the thread that uses it.
#pragma once

#include <chrono>

#include "plantview/render.h"

namespace plantview::detail {

// Laps of a frame: each lap() is the time since the previous one (or the start).
class Stopwatch {
 public:
  double lap() {
    const Clock::time_point now = Clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - last_).count();
    last_ = now;
    return ms;
  }
  double total() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_ = Clock::now(), last_ = start_;
};

// The time of each stage of a frame, as measured.
struct StageTimes {
  double cull = 0, occlusion = 0, depth_reduction = 0, decode = 0, choose = 0, stream = 0,
         arena_growth = 0, index_lists = 0, draw = 0, ahead = 0, read_back = 0;
};
// Into FrameStats::Times: decoding newly visible objects counts as streaming (reading the
// store), and writing the index lists as choosing (the chosen levels' indices); cpu is the sum
// of cull, occlusion, choose and stream (not the depth reduction: GPU work).
void report_times(const StageTimes& stages, double total_ms, FrameStats::Times& ms);

}  // namespace plantview::detail
