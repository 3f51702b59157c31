// The service's metrics, as Prometheus text (exposition format 0.0.4): requests by endpoint and
// status, render times as one histogram per kind of render (frame, stats, pick), the vertex
// arena, the render queue and connections.
//
// Rules
//   - Label values are escaped as the format requires (backslash, double quote, newline), and
//     endpoints come from a fixed set (routes.h: endpoint_of), so no client's bytes can break a
//     scrape or add a series.
//   - Counters, gauges and bucket counts are printed as integers; sums of milliseconds as
//     decimals.
// Threads: counting and formatting are pure; the loop thread owns the one Metrics of a server
// (no locks).
#pragma once

#include <cstdint>
#include <iterator>
#include <map>
#include <string>
#include <string_view>
#include <utility>

#include "plantview/render.h"
#include "server/render_job.h"

namespace plantview::service {

// Time spent on one kind of render, as a histogram.
struct RenderHistogram {
  // Upper bounds of the buckets, in milliseconds (+Inf is implicit).
  static constexpr double kBucketsMs[] = {10, 25, 50, 100, 250, 500, 1000, 2500, 5000, 10000};
  uint64_t buckets[std::size(kBucketsMs)] = {};  // not cumulative
  uint64_t count = 0;
  double sum_ms = 0;

  void observe(double ms);
};

struct Metrics {
  std::map<std::pair<std::string, int>, uint64_t> requests;  // (endpoint, status) -> answers
  RenderHistogram render_ms[3];  // indexed by RenderJob::Kind: frame, stats, pick
  uint64_t arena_bytes = 0, evictions = 0, uploaded_bytes = 0;
  uint64_t superseded = 0, rejected_busy = 0;
  uint64_t refused_connections = 0;  // at accept: too many in all, per address, or unproven
  uint64_t timed_out_connections = 0;  // request, write or shutdown deadline passed
  // Streams (/api/stream): opened, frames and bytes sent, views and frames dropped (a newer view
  // replaced one not yet rendered, or the stream closed before its frame was sent).
  uint64_t streams_opened = 0, stream_frames = 0, stream_bytes = 0, stream_drops = 0;

  void count_answer(const std::string& endpoint, int status) { requests[{endpoint, status}] += 1; }
  // A rendered frame, statistics or pick: its time (render and encode) and the arena after it.
  void count_rendered(RenderJob::Kind kind, const FrameStats& stats);
};

// What the metrics page shows besides the counters: values read at the moment it is asked for.
struct MetricsGauges {
  uint64_t arena_budget_bytes = 0;
  uint64_t queue_depth = 0;
  uint64_t connections = 0;
  uint64_t streams = 0;  // open streams (also counted in connections)
  bool ready = false;  // /readyz would answer 200
};

std::string metrics_text(const Metrics& metrics, const MetricsGauges& gauges);

// A label value as the text format writes it between its quotes: \ " and newline escaped.
std::string escape_label_value(std::string_view value);

}  // namespace plantview::service
