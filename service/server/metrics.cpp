#include "server/metrics.h"

#include <sstream>

namespace plantview::service {

namespace {

constexpr const char* kKindNames[] = {"frame", "stats", "pick"};  // RenderJob::Kind order

}  // namespace

void RenderHistogram::observe(double ms) {
  count += 1;
  sum_ms += ms;
  for (size_t i = 0; i < std::size(kBucketsMs); ++i)
    if (ms <= kBucketsMs[i]) {
      buckets[i] += 1;
      break;
    }
}

void Metrics::count_rendered(RenderJob::Kind kind, const FrameStats& stats) {
  render_ms[size_t(kind)].observe(stats.ms.total + stats.ms.encode);
  arena_bytes = stats.arena_bytes_resident;
  evictions += stats.objects_evicted;
  uploaded_bytes += stats.arena_bytes_uploaded;
}

std::string escape_label_value(std::string_view value) {
  std::string out;
  out.reserve(value.size());
  for (const char c : value) {
    if (c == '\\') out += "\\\\";
    else if (c == '"') out += "\\\"";
    else if (c == '\n') out += "\\n";
    else out += c;
  }
  return out;
}

std::string metrics_text(const Metrics& m, const MetricsGauges& g) {
  std::ostringstream o;
  o.precision(15);  // sums of milliseconds in full; everything else is an integer
  o << "# HELP plantview_requests_total HTTP requests answered, by endpoint and status.\n"
       "# TYPE plantview_requests_total counter\n";
  for (const auto& [key, n] : m.requests)
    o << "plantview_requests_total{endpoint=\"" << escape_label_value(key.first) << "\",status=\""
      << key.second << "\"} " << n << "\n";
  o << "# HELP plantview_render_milliseconds Time to render (and encode) a frame, statistics or pick.\n"
       "# TYPE plantview_render_milliseconds histogram\n";
  for (size_t k = 0; k < std::size(kKindNames); ++k) {
    const RenderHistogram& h = m.render_ms[k];
    const std::string kind = std::string("kind=\"") + kKindNames[k] + "\"";
    uint64_t cumulative = 0;
    for (size_t i = 0; i < std::size(RenderHistogram::kBucketsMs); ++i) {
      cumulative += h.buckets[i];
      o << "plantview_render_milliseconds_bucket{" << kind << ",le=\"" << RenderHistogram::kBucketsMs[i]
        << "\"} " << cumulative << "\n";
    }
    o << "plantview_render_milliseconds_bucket{" << kind << ",le=\"+Inf\"} " << h.count << "\n";
    o << "plantview_render_milliseconds_sum{" << kind << "} " << h.sum_ms << "\n";
    o << "plantview_render_milliseconds_count{" << kind << "} " << h.count << "\n";
  }
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
  gauge("plantview_refused_connections_total",
        "Connections refused at accept: too many in all, from one address, or from addresses not yet served.",
        "counter", m.refused_connections);
  gauge("plantview_timed_out_connections_total",
        "Connections closed because a request, write or shutdown deadline passed.", "counter",
        m.timed_out_connections);
  gauge("plantview_streams", "Open frame streams (WebSocket /api/stream).", "gauge", g.streams);
  gauge("plantview_streams_opened_total", "Frame streams opened.", "counter", m.streams_opened);
  gauge("plantview_stream_frames_total", "Frames sent on streams.", "counter", m.stream_frames);
  gauge("plantview_stream_bytes_total", "Bytes of frames sent on streams.", "counter", m.stream_bytes);
  gauge("plantview_stream_drops_total",
        "Stream views replaced before they were rendered, and frames whose stream closed first.", "counter",
        m.stream_drops);
  gauge("plantview_ready", "1 when /readyz answers 200 (store open, renderer warm, not draining).", "gauge",
        g.ready ? 1 : 0);
  return o.str();
}

}  // namespace plantview::service
