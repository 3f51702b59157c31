#include "server/metrics.h"

#include <sstream>

namespace plantview::service {

void Metrics::count_rendered(const FrameStats& stats) {
  const double ms = stats.ms.total + stats.ms.encode;
  frames += 1;
  frame_ms_sum += ms;
  for (size_t i = 0; i < std::size(kFrameBucketsMs); ++i)
    if (ms <= kFrameBucketsMs[i]) {
      frame_buckets[i] += 1;
      break;
    }
  arena_bytes = stats.arena_bytes_resident;
  evictions += stats.objects_evicted;
  uploaded_bytes += stats.arena_bytes_uploaded;
}

std::string metrics_text(const Metrics& m, const MetricsGauges& g) {
  std::ostringstream o;
  o.precision(15);  // the sum of frame times in full; counters and gauges are integers
  o << "# HELP plantview_requests_total HTTP requests answered, by endpoint and status.\n"
       "# TYPE plantview_requests_total counter\n";
  for (const auto& [key, n] : m.requests)
    o << "plantview_requests_total{endpoint=\"" << key.first << "\",status=\"" << key.second
      << "\"} " << n << "\n";
  o << "# HELP plantview_frame_milliseconds Time to render (and encode) a frame.\n"
       "# TYPE plantview_frame_milliseconds histogram\n";
  uint64_t cumulative = 0;
  for (size_t i = 0; i < std::size(Metrics::kFrameBucketsMs); ++i) {
    cumulative += m.frame_buckets[i];
    o << "plantview_frame_milliseconds_bucket{le=\"" << Metrics::kFrameBucketsMs[i] << "\"} "
      << cumulative << "\n";
  }
  o << "plantview_frame_milliseconds_bucket{le=\"+Inf\"} " << m.frames << "\n";
  o << "plantview_frame_milliseconds_sum " << m.frame_ms_sum << "\n";
  o << "plantview_frame_milliseconds_count " << m.frames << "\n";
  const auto gauge = [&](const char* name, const char* help, const char* type, uint64_t v) {
    o << "# HELP " << name << " " << help << "\n# TYPE " << name << " " << type << "\n"
      << name << " " << v << "\n";
  };
  gauge("plantview_arena_bytes", "Vertex arena bytes resident after the last frame.", "gauge", m.arena_bytes);
  gauge("plantview_arena_budget_bytes", "The vertex arena's budget.", "gauge", g.arena_budget_bytes);
  gauge("plantview_evictions_total", "Objects evicted from the vertex arena.", "counter", m.evictions);
  gauge("plantview_uploaded_bytes_total", "Bytes tessellated into the vertex arena.", "counter", m.uploaded_bytes);
  gauge("plantview_queue_depth", "Render requests waiting.", "gauge", g.queue_depth);
  gauge("plantview_superseded_total", "Render requests replaced by a newer one of the same client.", "counter", m.superseded);
  gauge("plantview_busy_total", "Render requests refused with 503 because the queue was full.", "counter", m.rejected_busy);
  gauge("plantview_connections", "Open connections.", "gauge", g.connections);
  return o.str();
}

}  // namespace plantview::service
