// The service's loop: connections, HTTP parsing, routing, limits, metrics and shutdown.
#include "server/server.h"

#include <arpa/inet.h>
#include <http_parser.h>
#include <strings.h>
#include <uv.h>

#include <algorithm>
#include <climits>

#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <deque>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <unordered_map>
#include <unordered_set>

#include "plantview/render.h"
#include "plantview/store.h"
#include "server/http.h"
#include "server/objects_json.h"
#include "server/render_worker.h"

namespace plantview::service {

namespace {

using Clock = std::chrono::steady_clock;

struct Server;

// One request's place in its connection's response order.
struct Pending {
  bool ready = false;
  bool keep_alive = true;
  std::string bytes;
  std::string endpoint;  // for metrics
  Clock::time_point started = Clock::now();
};

struct Connection {
  uv_tcp_t tcp{};
  uv_timer_t timer{};
  Server* server = nullptr;
  uint64_t id = 0;
  http_parser parser{};
  // The request being parsed.
  std::string url, field, value;
  Fields headers;
  bool value_last = false, in_request = false;
  size_t header_bytes = 0, body_bytes = 0;
  int limit_status = 0;       // set by a callback that stopped the parser
  bool no_more = false;       // a request said Connection: close, or an error is being answered
  // Responses in request order; the front is written once ready.
  std::deque<std::shared_ptr<Pending>> pending;
  uint64_t unsent_bytes = 0;
  bool reading = false, closing = false;
  int open_handles = 0;
};

struct WriteRequest {
  uv_write_t req{};
  std::string data;
  Connection* connection = nullptr;
};

struct Ticket {
  Connection* connection = nullptr;  // null once the connection has closed
  std::shared_ptr<Pending> pending;
};

struct Metrics {
  std::map<std::pair<std::string, int>, uint64_t> requests;  // (endpoint, status)
  // Frame times (render + encode), as a histogram in milliseconds.
  static constexpr double kBuckets[] = {10, 25, 50, 100, 250, 500, 1000, 2500, 5000, 10000};
  uint64_t frame_buckets[std::size(kBuckets)] = {};
  uint64_t frames = 0;
  double frame_ms_sum = 0;
  uint64_t arena_bytes = 0, arena_budget = 0, evictions = 0, uploads_bytes = 0;
  uint64_t superseded = 0, rejected_busy = 0;
};

struct Server {
  ServerOptions options;
  uv_loop_t* loop = nullptr;
  uv_tcp_t listener{};
  uv_signal_t sigint{}, sigterm{};
  uv_timer_t shutdown_timer{};
  std::unique_ptr<Store> store;
  RenderWorker worker;
  std::unordered_set<Connection*> connections;
  std::unordered_map<uint64_t, Ticket> tickets;
  uint64_t next_ticket = 1, next_connection = 1;
  int works_in_flight = 0;
  bool shutting_down = false;
  std::string model_json;
  DAabb bounds;
  std::map<std::string, std::pair<std::string, std::string>> files;  // path -> (type, bytes)
  Metrics metrics;
  http_parser_settings settings{};
};

void close_connection(Connection* c);
void flush(Connection* c);
void start_reading(Connection* c);

void count(Server& s, const std::string& endpoint, int status) {
  s.metrics.requests[{endpoint, status}] += 1;
}

void on_written(uv_write_t* req, int status) {
  auto* w = reinterpret_cast<WriteRequest*>(req);
  Connection* c = w->connection;
  c->unsent_bytes -= w->data.size();
  delete w;
  if (status < 0) {
    close_connection(c);
    return;
  }
  // A slow reader has caught up: read its next requests.
  if (!c->reading && !c->closing && !c->no_more && c->unsent_bytes <= c->server->options.max_unsent_bytes / 4 &&
      c->pending.size() < 16 && !c->server->shutting_down)
    start_reading(c);
  if (c->no_more && c->pending.empty() && c->unsent_bytes == 0) close_connection(c);
  if (c->server->shutting_down && c->pending.empty() && c->unsent_bytes == 0) close_connection(c);
}

void write(Connection* c, std::string data) {
  auto* w = new WriteRequest;
  w->data = std::move(data);
  w->connection = c;
  c->unsent_bytes += w->data.size();
  uv_buf_t buf = uv_buf_init(w->data.data(), unsigned(w->data.size()));
  if (uv_write(&w->req, reinterpret_cast<uv_stream_t*>(&c->tcp), &buf, 1, on_written) != 0) {
    c->unsent_bytes -= w->data.size();
    delete w;
    close_connection(c);
  }
}

// Writes the ready responses at the front, in order.
void flush(Connection* c) {
  if (c->closing) return;
  while (!c->pending.empty() && c->pending.front()->ready) {
    auto p = c->pending.front();
    c->pending.pop_front();
    if (!p->keep_alive) c->no_more = true;
    write(c, std::move(p->bytes));
    if (c->closing) return;
    if (!p->keep_alive) {
      // Nothing after a closing response: later pipelined requests are dropped.
      for (auto& later : c->pending) later->ready = false;
      c->pending.clear();
      break;
    }
  }
  // Stop reading a connection that does not read its answers, or floods requests.
  if (c->reading && (c->unsent_bytes > c->server->options.max_unsent_bytes || c->pending.size() >= 16)) {
    uv_read_stop(reinterpret_cast<uv_stream_t*>(&c->tcp));
    c->reading = false;
  }
}

void finish(Connection* c, const std::shared_ptr<Pending>& p, std::string bytes, int status) {
  count(*c->server, p->endpoint, status);
  p->bytes = std::move(bytes);
  p->ready = true;
  flush(c);
}

void respond_error(Connection* c, const std::shared_ptr<Pending>& p, int status,
                   const std::string& message, bool close = false, const Fields& headers = {}) {
  if (close) p->keep_alive = false;
  finish(c, p, http_error(status, message, p->keep_alive, headers), status);
}

void on_closed(uv_handle_t* handle) {
  auto* c = static_cast<Connection*>(handle->data);
  if (--c->open_handles == 0) delete c;
}

void close_connection(Connection* c) {
  if (c->closing) return;
  c->closing = true;
  Server& s = *c->server;
  s.connections.erase(c);
  for (auto& [ticket, t] : s.tickets)
    if (t.connection == c) t.connection = nullptr;
  c->pending.clear();
  uv_timer_stop(&c->timer);
  uv_close(reinterpret_cast<uv_handle_t*>(&c->timer), on_closed);
  uv_close(reinterpret_cast<uv_handle_t*>(&c->tcp), on_closed);
}

// --- parameters ---------------------------------------------------------------------------------

bool parse_u32(const std::string& text, uint32_t& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return !text.empty() && ec == std::errc() && end == text.data() + text.size();
}

bool parse_double(const std::string& text, double& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return !text.empty() && ec == std::errc() && end == text.data() + text.size() && std::isfinite(out);
}

// The camera, size and LOD parameters shared by frame, stats and pick; `allowed` lists the
// further keys the endpoint takes. False with a message for the 400 answer.
bool parse_view(const Server& s, const Fields& query, std::initializer_list<std::string_view> allowed,
                RenderJob& job, std::string& error) {
  static const std::unordered_set<std::string_view> common = {"eye", "target", "up", "fov", "w",
                                                              "h", "lod", "px", "client"};
  std::string eye, target, up = "0,0,1", fov = "50";
  job.width = 1280;
  job.height = 720;
  for (const auto& [key, value] : query) {
    if (!common.count(key) && std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      error = "unknown parameter '" + key + "'";
      return false;
    }
    if (key == "eye") eye = value;
    else if (key == "target") target = value;
    else if (key == "up") up = value;
    else if (key == "fov") fov = value;
    else if (key == "client") job.client = value.substr(0, 128);
    else if (key == "w" || key == "h") {
      uint32_t v = 0;
      if (!parse_u32(value, v) || v == 0 || v > 4096) {
        error = "'" + key + "' must be a whole number of pixels in 1..4096, got '" + value.substr(0, 32) + "'";
        return false;
      }
      (key == "w" ? job.width : job.height) = v;
    } else if (key == "lod") {
      if (!parse_lod_policy(value, job.policy)) {
        error = "'lod' must be screen-space, distance or none";
        return false;
      }
    } else if (key == "px") {
      if (!parse_double(value, job.pixel_error) || job.pixel_error <= 0 || job.pixel_error > 1000) {
        error = "'px' must be a pixel error in (0, 1000]";
        return false;
      }
    }
  }
  if (eye.empty() != target.empty()) {
    error = "give both 'eye' and 'target', or neither (the default view)";
    return false;
  }
  if (eye.empty()) {
    job.camera = default_camera(s.bounds, double(job.width) / job.height);
    return true;
  }
  return parse_camera("eye=" + eye + ",target=" + target + ",up=" + up + ",fov=" + fov,
                      job.camera, error);
}

// --- routes -------------------------------------------------------------------------------------

std::string metrics_text(Server& s) {
  std::ostringstream o;
  o << "# HELP plantview_requests_total HTTP requests answered, by endpoint and status.\n"
       "# TYPE plantview_requests_total counter\n";
  for (const auto& [key, n] : s.metrics.requests)
    o << "plantview_requests_total{endpoint=\"" << key.first << "\",status=\"" << key.second
      << "\"} " << n << "\n";
  o << "# HELP plantview_frame_milliseconds Time to render (and encode) a frame.\n"
       "# TYPE plantview_frame_milliseconds histogram\n";
  uint64_t cumulative = 0;
  for (size_t i = 0; i < std::size(Metrics::kBuckets); ++i) {
    cumulative += s.metrics.frame_buckets[i];
    o << "plantview_frame_milliseconds_bucket{le=\"" << Metrics::kBuckets[i] << "\"} " << cumulative << "\n";
  }
  o << "plantview_frame_milliseconds_bucket{le=\"+Inf\"} " << s.metrics.frames << "\n";
  o << "plantview_frame_milliseconds_sum " << s.metrics.frame_ms_sum << "\n";
  o << "plantview_frame_milliseconds_count " << s.metrics.frames << "\n";
  const auto gauge = [&](const char* name, const char* help, const char* type, double v) {
    o << "# HELP " << name << " " << help << "\n# TYPE " << name << " " << type << "\n" << name << " " << v << "\n";
  };
  gauge("plantview_arena_bytes", "Vertex arena bytes resident after the last frame.", "gauge", double(s.metrics.arena_bytes));
  gauge("plantview_arena_budget_bytes", "The vertex arena's budget.", "gauge", double(s.worker.vertex_budget_bytes()));
  gauge("plantview_evictions_total", "Objects evicted from the vertex arena.", "counter", double(s.metrics.evictions));
  gauge("plantview_uploaded_bytes_total", "Bytes tessellated into the vertex arena.", "counter", double(s.metrics.uploads_bytes));
  gauge("plantview_queue_depth", "Render requests waiting.", "gauge", double(s.worker.queue_depth()));
  gauge("plantview_superseded_total", "Render requests replaced by a newer one of the same client.", "counter", double(s.metrics.superseded));
  gauge("plantview_busy_total", "Render requests refused with 503 because the queue was full.", "counter", double(s.metrics.rejected_busy));
  gauge("plantview_connections", "Open connections.", "gauge", double(s.connections.size()));
  return o.str();
}

struct ObjectWork {
  uv_work_t req{};
  Server* server = nullptr;
  uint64_t id = 0, ticket = 0;
  bool found = false;
  std::string json, error;
};

void handle(Connection* c, const std::string& method, const std::string& url,
            const std::shared_ptr<Pending>& p) {
  Server& s = *c->server;
  const size_t q = url.find('?');
  const std::string path = url.substr(0, q);
  const std::string query = q == std::string::npos ? "" : url.substr(q + 1);
  p->endpoint = path.rfind("/api/objects/", 0) == 0 ? "objects" : path == "/" ? "page" : path.substr(path.rfind('/') + 1);
  if (p->endpoint.empty() || p->endpoint.size() > 16) p->endpoint = "other";

  if (s.shutting_down) return respond_error(c, p, 503, "the server is shutting down", true);
  if (!s.options.token.empty()) {
    std::string auth;
    for (const auto& [k, v] : c->headers)
      if (strcasecmp(k.c_str(), "authorization") == 0) auth = v;
    const std::string expected = "Bearer " + s.options.token;
    // Compare in constant time over the expected length.
    unsigned diff = unsigned(auth.size() ^ expected.size());
    for (size_t i = 0; i < expected.size(); ++i) diff |= unsigned(uint8_t(expected[i]) ^ uint8_t(i < auth.size() ? auth[i] : 0));
    if (diff != 0)
      return respond_error(c, p, 401, "a valid 'Authorization: Bearer' token is required", false,
                           {{"WWW-Authenticate", "Bearer"}});
  }
  if (method != "GET") return respond_error(c, p, 405, "only GET is served", false, {{"Allow", "GET"}});

  Fields fields;
  std::string error;
  if (!parse_query(query, fields, error)) return respond_error(c, p, 400, error);

  if (const auto f = s.files.find(path); f != s.files.end()) {
    if (!fields.empty()) return respond_error(c, p, 400, "the page takes no parameters");
    return finish(c, p, http_response(200, f->second.first, f->second.second, p->keep_alive), 200);
  }
  if (path == "/api/model") {
    if (!fields.empty()) return respond_error(c, p, 400, "/api/model takes no parameters");
    return finish(c, p, http_response(200, "application/json", s.model_json, p->keep_alive), 200);
  }
  if (path == "/metrics") {
    count(s, p->endpoint, 200);  // counted before rendering, so that this request shows
    p->bytes = http_response(200, "text/plain; version=0.0.4", metrics_text(s), p->keep_alive);
    p->ready = true;
    return flush(c);
  }
  if (path.rfind("/api/objects/", 0) == 0) {
    const std::string id_text = path.substr(13);
    uint64_t id = 0;
    const auto [end, ec] = std::from_chars(id_text.data(), id_text.data() + id_text.size(), id);
    if (id_text.empty() || ec != std::errc() || end != id_text.data() + id_text.size() || id == 0)
      return respond_error(c, p, 400, "an object id is a decimal number, got '" + id_text.substr(0, 32) + "'");
    if (!fields.empty()) return respond_error(c, p, 400, "/api/objects takes no parameters");
    auto* work = new ObjectWork;
    work->server = &s;
    work->id = id;
    work->ticket = s.next_ticket++;
    work->req.data = work;
    s.tickets[work->ticket] = {c, p};
    ++s.works_in_flight;
    uv_queue_work(
        s.loop, &work->req,
        [](uv_work_t* req) {
          auto* w = static_cast<ObjectWork*>(req->data);
          w->found = object_json(*w->server->store, w->id, w->json, w->error);
        },
        [](uv_work_t* req, int) {
          auto* w = static_cast<ObjectWork*>(req->data);
          Server& server = *w->server;
          --server.works_in_flight;
          const auto it = server.tickets.find(w->ticket);
          if (it != server.tickets.end()) {
            Ticket t = it->second;
            server.tickets.erase(it);
            if (t.connection) {
              if (w->found)
                finish(t.connection, t.pending, http_response(200, "application/json", w->json, t.pending->keep_alive), 200);
              else
                respond_error(t.connection, t.pending, w->error.rfind("no object", 0) == 0 ? 404 : 500, w->error);
            }
          }
          delete w;
        });
    return;
  }

  RenderJob job;
  if (path == "/api/frame") {
    job.kind = RenderJob::Kind::frame;
    if (!parse_view(s, fields, {"format", "quality"}, job, error)) return respond_error(c, p, 400, error);
    for (const auto& [key, value] : fields) {
      if (key == "format" && !image_format_from_name(value, job.format))
        return respond_error(c, p, 400, "'format' must be jpeg or png");
      if (key == "quality") {
        uint32_t quality = 0;
        if (!parse_u32(value, quality) || quality < 1 || quality > 100)
          return respond_error(c, p, 400, "'quality' must be 1..100");
        job.quality = int(quality);
      }
    }
  } else if (path == "/api/stats") {
    job.kind = RenderJob::Kind::stats;
    if (!parse_view(s, fields, {}, job, error)) return respond_error(c, p, 400, error);
  } else if (path == "/api/pick") {
    job.kind = RenderJob::Kind::pick;
    if (!parse_view(s, fields, {"x", "y"}, job, error)) return respond_error(c, p, 400, error);
    bool have_x = false, have_y = false;
    for (const auto& [key, value] : fields) {
      if (key == "x" || key == "y") {
        uint32_t v = 0;
        if (!parse_u32(value, v)) return respond_error(c, p, 400, "'" + key + "' must be a pixel position");
        (key == "x" ? job.x : job.y) = v;
        (key == "x" ? have_x : have_y) = true;
      }
    }
    if (!have_x || !have_y || job.x >= job.width || job.y >= job.height)
      return respond_error(c, p, 400, "'x' and 'y' must lie inside the w x h image");
  } else {
    return respond_error(c, p, 404, "no such resource: " + path.substr(0, 128));
  }
  // Latest wins per client and kind of request: a newer frame replaces a waiting frame, not a
  // waiting pick.
  if (job.client.empty()) job.client = "connection:" + std::to_string(c->id);
  job.client += job.kind == RenderJob::Kind::frame ? "/frame" : job.kind == RenderJob::Kind::stats ? "/stats" : "/pick";
  job.ticket = s.next_ticket++;
  uint64_t dropped = 0;
  const uint64_t ticket = job.ticket;
  const auto result = s.worker.submit(std::move(job), dropped);
  if (result == RenderWorker::Submitted::busy) {
    s.metrics.rejected_busy += 1;
    return respond_error(c, p, 503, "too many frames waiting; retry shortly", false, {{"Retry-After", "1"}});
  }
  s.tickets[ticket] = {c, p};
  if (result == RenderWorker::Submitted::replaced) {
    s.metrics.superseded += 1;
    const auto it = s.tickets.find(dropped);
    if (it != s.tickets.end()) {
      Ticket t = it->second;
      s.tickets.erase(it);
      if (t.connection) respond_error(t.connection, t.pending, 409, "superseded by a newer request of the same client");
    }
  }
}

struct EncodeWork {
  uv_work_t req{};
  Server* server = nullptr;
  RenderResult result;
  std::string error;
};

void deliver(Server& s, RenderResult& r) {
  if (r.rendered) {
    const double ms = r.stats.ms.total + r.stats.ms.encode;
    s.metrics.frames += 1;
    s.metrics.frame_ms_sum += ms;
    for (size_t i = 0; i < std::size(Metrics::kBuckets); ++i)
      if (ms <= Metrics::kBuckets[i]) {
        s.metrics.frame_buckets[i] += 1;
        break;
      }
    s.metrics.arena_bytes = r.stats.arena_bytes_resident;
    s.metrics.evictions += r.stats.objects_evicted;
    s.metrics.uploads_bytes += r.stats.arena_bytes_uploaded;
  }
  const auto it = s.tickets.find(r.ticket);
  if (it == s.tickets.end()) return;
  Ticket t = it->second;
  s.tickets.erase(it);
  if (!t.connection) return;  // the client went away
  finish(t.connection, t.pending,
         http_response(r.status, r.content_type, r.body, t.pending->keep_alive, r.headers), r.status);
}

void on_render_done(Server& s, RenderResult&& r) {
  if (!r.needs_encoding) return deliver(s, r);
  // Encode on libuv's pool: the render thread goes on with the next frame meanwhile.
  auto* work = new EncodeWork;
  work->server = &s;
  work->result = std::move(r);
  work->req.data = work;
  ++s.works_in_flight;
  uv_queue_work(
      s.loop, &work->req,
      [](uv_work_t* req) {
        auto* w = static_cast<EncodeWork*>(req->data);
        RenderResult& result = w->result;
        const auto t = Clock::now();
        std::vector<uint8_t> bytes;
        if (!encode_image(result.image, result.format, result.quality, bytes, w->error)) {
          result.status = 500;
          result.content_type = "application/json";
          result.body = "{\"error\":" + json_string(w->error) + "}\n";
        } else {
          result.body.assign(bytes.begin(), bytes.end());
        }
        result.image = Image{};
        result.stats.ms.encode = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
        char ms[32];
        std::snprintf(ms, sizeof ms, "%.1f", result.stats.ms.encode);
        result.headers.emplace_back("X-Encode-Ms", ms);
      },
      [](uv_work_t* req, int) {
        auto* w = static_cast<EncodeWork*>(req->data);
        --w->server->works_in_flight;
        deliver(*w->server, w->result);
        delete w;
      });
}

// --- HTTP parsing -------------------------------------------------------------------------------

Connection* of(http_parser* p) { return static_cast<Connection*>(p->data); }

bool over_header_limit(Connection* c, size_t n) {
  c->header_bytes += n;
  if (c->header_bytes > c->server->options.max_header_bytes) {
    c->limit_status = 431;
    return true;
  }
  return false;
}

void store_header(Connection* c) {
  if (!c->field.empty()) c->headers.emplace_back(std::move(c->field), std::move(c->value));
  c->field.clear();
  c->value.clear();
}

void restart_timer(Connection* c, uint32_t ms);

void setup_parser_settings(http_parser_settings& s) {
  http_parser_settings_init(&s);
  s.on_message_begin = [](http_parser* p) {
    Connection* c = of(p);
    if (c->no_more) return 1;
    c->url.clear();
    c->headers.clear();
    c->field.clear();
    c->value.clear();
    c->value_last = false;
    c->header_bytes = c->body_bytes = 0;
    c->in_request = true;
    restart_timer(c, c->server->options.request_timeout_ms);
    return 0;
  };
  s.on_url = [](http_parser* p, const char* at, size_t n) {
    Connection* c = of(p);
    if (over_header_limit(c, n)) return 1;
    c->url.append(at, n);
    return 0;
  };
  s.on_header_field = [](http_parser* p, const char* at, size_t n) {
    Connection* c = of(p);
    if (over_header_limit(c, n)) return 1;
    if (c->value_last) store_header(c);
    c->value_last = false;
    c->field.append(at, n);
    return 0;
  };
  s.on_header_value = [](http_parser* p, const char* at, size_t n) {
    Connection* c = of(p);
    if (over_header_limit(c, n)) return 1;
    c->value_last = true;
    c->value.append(at, n);
    return 0;
  };
  s.on_headers_complete = [](http_parser* p) {
    Connection* c = of(p);
    store_header(c);
    if (p->content_length != ULLONG_MAX && p->content_length > c->server->options.max_body_bytes) {
      c->limit_status = 413;
      return -1;  // http-parser: -1 = error here (1 would mean "no body")
    }
    return 0;
  };
  s.on_body = [](http_parser* p, const char*, size_t n) {
    Connection* c = of(p);
    c->body_bytes += n;
    if (c->body_bytes > c->server->options.max_body_bytes) {
      c->limit_status = 413;
      return 1;
    }
    return 0;
  };
  s.on_message_complete = [](http_parser* p) {
    Connection* c = of(p);
    c->in_request = false;
    restart_timer(c, c->server->options.idle_timeout_ms);
    auto pending = std::make_shared<Pending>();
    pending->keep_alive = http_should_keep_alive(p) != 0;
    c->pending.push_back(pending);
    const std::string method = http_method_str(static_cast<http_method>(p->method));
    handle(c, method, c->url, pending);
    if (!pending->keep_alive) c->no_more = true;
    return 0;
  };
}

void on_timer(uv_timer_t* timer) {
  auto* c = static_cast<Connection*>(timer->data);
  if (c->closing) return;
  if (c->in_request) {
    // Too slow to send its request: answer and close.
    c->in_request = false;
    c->no_more = true;
    auto p = std::make_shared<Pending>();
    p->endpoint = "timeout";
    c->pending.push_back(p);
    uv_read_stop(reinterpret_cast<uv_stream_t*>(&c->tcp));
    c->reading = false;
    respond_error(c, p, 408, "the request did not arrive in time", true);
  } else if (c->pending.empty() && c->unsent_bytes == 0) {
    close_connection(c);  // idle keep-alive connection
  } else {
    restart_timer(c, c->server->options.idle_timeout_ms);
  }
}

void restart_timer(Connection* c, uint32_t ms) { uv_timer_start(&c->timer, on_timer, ms, 0); }

void on_read(uv_stream_t* stream, ssize_t n, const uv_buf_t* buf) {
  auto* c = static_cast<Connection*>(stream->data);
  std::unique_ptr<char[]> owned(buf->base);
  if (c->closing) return;
  if (n < 0) {
    // EOF or reset: answers still owed are dropped with the connection.
    close_connection(c);
    return;
  }
  if (n == 0 || c->no_more) return;
  const size_t parsed = http_parser_execute(&c->parser, &c->server->settings, buf->base, size_t(n));
  if (c->closing) return;
  const auto err = HTTP_PARSER_ERRNO(&c->parser);
  if ((err != HPE_OK || parsed != size_t(n)) && !(c->no_more && err == HPE_CB_message_begin)) {
    if (c->no_more && c->limit_status == 0) return;
    c->no_more = true;
    uv_read_stop(stream);
    c->reading = false;
    auto p = std::make_shared<Pending>();
    p->endpoint = "malformed";
    c->pending.push_back(p);
    if (c->limit_status == 431)
      respond_error(c, p, 431, "request headers larger than " + std::to_string(c->server->options.max_header_bytes) + " bytes", true);
    else if (c->limit_status == 413)
      respond_error(c, p, 413, "request body larger than " + std::to_string(c->server->options.max_body_bytes) + " bytes", true);
    else
      respond_error(c, p, 400, std::string("malformed HTTP: ") + http_errno_description(err), true);
  }
}

void start_reading(Connection* c) {
  c->reading = true;
  uv_read_start(
      reinterpret_cast<uv_stream_t*>(&c->tcp),
      [](uv_handle_t*, size_t suggested, uv_buf_t* buf) {
        *buf = uv_buf_init(new char[suggested], unsigned(suggested));
      },
      on_read);
}

void on_connection(uv_stream_t* listener, int status) {
  auto* s = static_cast<Server*>(listener->data);
  if (status < 0) return;
  auto* c = new Connection;
  c->server = s;
  c->id = s->next_connection++;
  uv_tcp_init(s->loop, &c->tcp);
  uv_timer_init(s->loop, &c->timer);
  c->open_handles = 2;
  c->tcp.data = c;
  c->timer.data = c;
  if (uv_accept(listener, reinterpret_cast<uv_stream_t*>(&c->tcp)) != 0) {
    c->closing = true;
    uv_close(reinterpret_cast<uv_handle_t*>(&c->timer), on_closed);
    uv_close(reinterpret_cast<uv_handle_t*>(&c->tcp), on_closed);
    return;
  }
  uv_tcp_nodelay(&c->tcp, 1);
  s->connections.insert(c);
  http_parser_init(&c->parser, HTTP_REQUEST);
  c->parser.data = c;
  if (s->connections.size() > s->options.max_clients || s->shutting_down) {
    c->no_more = true;
    auto p = std::make_shared<Pending>();
    p->endpoint = "refused";
    c->pending.push_back(p);
    respond_error(c, p, 503, "too many connections", true, {{"Retry-After", "1"}});
    return;
  }
  restart_timer(c, s->options.idle_timeout_ms);
  start_reading(c);
}

void begin_shutdown(Server& s) {
  if (s.shutting_down) return;
  s.shutting_down = true;
  std::fprintf(stderr, "plantview serve: shutting down (finishing %zu requests)\n", s.tickets.size());
  uv_close(reinterpret_cast<uv_handle_t*>(&s.listener), nullptr);
  std::vector<Connection*> idle;
  for (Connection* c : s.connections) {
    uv_read_stop(reinterpret_cast<uv_stream_t*>(&c->tcp));
    c->reading = false;
    if (c->pending.empty() && c->unsent_bytes == 0) idle.push_back(c);
  }
  for (Connection* c : idle) close_connection(c);
  uv_timer_start(
      &s.shutdown_timer,
      [](uv_timer_t* t) {
        Server& server = *static_cast<Server*>(t->data);
        std::vector<Connection*> done;
        for (Connection* c : server.connections)
          if (c->pending.empty() && c->unsent_bytes == 0) done.push_back(c);
        for (Connection* c : done) close_connection(c);
        if (!server.connections.empty() || server.works_in_flight > 0 || !server.worker.idle()) return;
        server.worker.stop();
        uv_timer_stop(t);
        uv_close(reinterpret_cast<uv_handle_t*>(t), nullptr);
        // Everything is finished; only the store's clean close remains. A repeated signal
        // (a second Ctrl-C, a supervisor's retry) must not cut that short.
        std::signal(SIGINT, SIG_IGN);
        std::signal(SIGTERM, SIG_IGN);
        uv_close(reinterpret_cast<uv_handle_t*>(&server.sigint), nullptr);
        uv_close(reinterpret_cast<uv_handle_t*>(&server.sigterm), nullptr);
      },
      50, 50);
}

bool load_web_files(Server& s) {
  const std::pair<const char*, const char*> files[] = {
      {"index.html", "text/html; charset=utf-8"},
      {"viewer.js", "text/javascript; charset=utf-8"},
      {"viewer.css", "text/css; charset=utf-8"}};
  for (const auto& [name, type] : files) {
    std::ifstream in(s.options.web_directory + "/" + name, std::ios::binary);
    if (!in) continue;
    std::ostringstream bytes;
    bytes << in.rdbuf();
    s.files["/" + std::string(name)] = {type, bytes.str()};
  }
  if (const auto it = s.files.find("/index.html"); it != s.files.end()) s.files["/"] = it->second;
  return s.files.count("/") != 0;
}

bool is_loopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

}  // namespace

int run_server(const ServerOptions& options, std::string& error) {
  auto server = std::make_unique<Server>();
  Server& s = *server;
  s.options = options;
  if (!is_loopback(options.host) && options.token.empty()) {
    error = "serve: listening on " + options.host + " (not loopback) requires --token";
    return 1;
  }
  s.store = Store::open(options.store_directory, Store::Mode::read_only, error);
  if (!s.store) return 1;
  {
    auto view = s.store->read(error);
    if (!view) return 1;
    const StoreInfo info = view->info();
    s.bounds = info.statistics.bounds;
    const Camera camera = default_camera(s.bounds, 16.0 / 9.0);
    nlohmann::json model = {{"objects", info.objects},
                            {"statistics", nlohmann::json::parse(statistics_json(info.statistics))},
                            {"camera",
                             {{"eye", {camera.eye_m.x, camera.eye_m.y, camera.eye_m.z}},
                              {"target", {camera.target_m.x, camera.target_m.y, camera.target_m.z}},
                              {"up", {camera.up.x, camera.up.y, camera.up.z}},
                              {"fov", camera.fov_deg}}}};
    if (!s.bounds.empty())
      model["bounds"] = {{"min", {s.bounds.min.x, s.bounds.min.y, s.bounds.min.z}},
                         {"max", {s.bounds.max.x, s.bounds.max.y, s.bounds.max.z}}};
    s.model_json = model.dump() + "\n";
  }
  if (!load_web_files(s))
    std::fprintf(stderr, "plantview serve: no viewer page in %s (the API still works)\n",
                 options.web_directory.c_str());

  // Encoding and object look-ups run on libuv's pool: one thread per core (at least 4), unless
  // the operator chose otherwise. Must be set before the pool first starts.
  if (!std::getenv("UV_THREADPOOL_SIZE"))
    setenv("UV_THREADPOOL_SIZE", std::to_string(std::max(4u, std::thread::hardware_concurrency())).c_str(), 1);
  uv_loop_t loop;
  uv_loop_init(&loop);
  s.loop = &loop;
  setup_parser_settings(s.settings);
  if (!s.worker.start(*s.store, options.vertex_budget_bytes, options.device, options.max_queue, &loop,
                      [&s](RenderResult&& r) { on_render_done(s, std::move(r)); }, error)) {
    uv_run(&loop, UV_RUN_NOWAIT);
    uv_loop_close(&loop);
    return 1;
  }
  std::fprintf(stderr, "plantview serve: rendering on %s\n", s.worker.device_description().c_str());
  // Frames are encoded through the image module: it loads while the server listens. Not earlier:
  // the render thread's EGL initialisation loads its drivers under the same loader lock.
  preload_image_io();

  sockaddr_storage address{};
  if (uv_ip4_addr(options.host.c_str(), options.port, reinterpret_cast<sockaddr_in*>(&address)) != 0 &&
      uv_ip6_addr(options.host.c_str(), options.port, reinterpret_cast<sockaddr_in6*>(&address)) != 0) {
    error = "serve: '" + options.host + "' is not an IP address";
    s.worker.stop();
    uv_run(&loop, UV_RUN_DEFAULT);
    uv_loop_close(&loop);
    return 1;
  }
  uv_tcp_init(&loop, &s.listener);
  s.listener.data = &s;
  int rc = uv_tcp_bind(&s.listener, reinterpret_cast<const sockaddr*>(&address), 0);
  if (rc == 0) rc = uv_listen(reinterpret_cast<uv_stream_t*>(&s.listener), 256, on_connection);
  if (rc != 0) {
    error = "serve: cannot listen on " + options.host + ":" + std::to_string(options.port) + ": " + uv_strerror(rc);
    uv_close(reinterpret_cast<uv_handle_t*>(&s.listener), nullptr);
    s.worker.stop();
    uv_run(&loop, UV_RUN_DEFAULT);
    uv_loop_close(&loop);
    return 1;
  }
  sockaddr_storage bound{};
  int length = sizeof bound;
  uv_tcp_getsockname(&s.listener, reinterpret_cast<sockaddr*>(&bound), &length);
  const int port = bound.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port)
                                               : ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  const bool v6 = options.host.find(':') != std::string::npos;
  std::printf("listening on http://%s%s%s:%d/\n", v6 ? "[" : "", options.host.c_str(), v6 ? "]" : "", port);
  std::fflush(stdout);

  uv_signal_init(&loop, &s.sigint);
  uv_signal_init(&loop, &s.sigterm);
  s.sigint.data = s.sigterm.data = &s;
  const auto on_signal = [](uv_signal_t* h, int) { begin_shutdown(*static_cast<Server*>(h->data)); };
  uv_signal_start(&s.sigint, on_signal, SIGINT);
  uv_signal_start(&s.sigterm, on_signal, SIGTERM);
  uv_timer_init(&loop, &s.shutdown_timer);
  s.shutdown_timer.data = &s;
  std::signal(SIGPIPE, SIG_IGN);

  uv_run(&loop, UV_RUN_DEFAULT);
  uv_loop_close(&loop);
  s.store.reset();
  std::fprintf(stderr, "plantview serve: stopped\n");
  return 0;
}

}  // namespace plantview::service
