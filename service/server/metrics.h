// The service's metrics, as Prometheus text (exposition format 0.0.4): requests by endpoint and
// status, frame times as a histogram, the vertex arena, the render queue and connections.
// Counting and formatting are pure; the loop thread owns the one Metrics of a server (no locks).
#pragma once

#include <cstdint>
#include <iterator>
#include <map>
#include <string>
#include <utility>

#include "plantview/render.h"

namespace plantview::service {

struct Metrics {
  // Upper bounds of the frame-time histogram's buckets, in milliseconds (+Inf is implicit).
  static constexpr double kFrameBucketsMs[] = {10, 25, 50, 100, 250, 500, 1000, 2500, 5000, 10000};

  std::map<std::pair<std::string, int>, uint64_t> requests;  // (endpoint, status) -> answers
  uint64_t frame_buckets[std::size(kFrameBucketsMs)] = {};     // not cumulative
  uint64_t frames = 0;
  double frame_ms_sum = 0;
  uint64_t arena_bytes = 0, evictions = 0, uploaded_bytes = 0;
  uint64_t superseded = 0, rejected_busy = 0;

  void count_answer(const std::string& endpoint, int status) { requests[{endpoint, status}] += 1; }
  // A rendered frame, statistics or pick: its time (render and encode) and the arena after it.
  void count_rendered(const FrameStats& stats);
};

// What the metrics page shows besides the counters: values read at the moment it is asked for.
struct MetricsGauges {
  uint64_t arena_budget_bytes = 0;
  uint64_t queue_depth = 0;
  uint64_t connections = 0;
};

std::string metrics_text(const Metrics& metrics, const MetricsGauges& gauges);

}  // namespace plantview::service
