// The service's loop: joins connections, routes, the render worker, encoding and object
// look-ups, and runs the shutdown.
//
// Rules
//   - Threads: everything here runs on the loop thread except the bodies of pool work (object
//     look-ups, frame encoding), which touch only their own work item and the store (read-only,
//     each with its own view).
//   - Tickets: an answer that waits for other threads (render job, look-up) is a ticket: the
//     connection and its Pending. When a connection closes its tickets lose the connection, and
//     the answer is dropped when it comes.
//   - Ownership: the Server owns its handles (listener, signals, shutdown timer, the worker's
//     async) and closes each before the loop ends; connections own themselves (connection.h);
//     pool work items are deleted in their after-work callbacks.
//   - Admission (at accept): max_clients in all, max_clients_per_address from one address, and
//     addresses not yet served only up to max_clients - reserved_clients. An address counts as
//     served once a request of its has completed (and not been refused for its token); the
//     server remembers at most
//     kMaxServedAddresses of them (the oldest are forgotten first).
//   - Readiness: the store is open before the loop runs; a warm-up frame is queued first, and
//     /readyz says 200 once it has been drawn, until the shutdown begins.
//   - Following imports: the render threads move to each new commit between jobs
//     (render_worker.h); object look-ups and measurements read a view begun for the request; and
//     every kFollowIntervalMs the loop compares Store::last_commit() with the commit /api/model
//     was described from, and on a change describes it again on the pool (the answer, bounds and
//     default view swapped in on the loop). Answers say which revision their data came from
//     (X-Plantview-Revision): a render job's, its renderer's snapshot; a look-up's, its view; an
//     answer of the routes alone (/api/model, refusals), the revision /api/model describes.
//   - Streams (/api/stream, docs/stream.md): a Stream per upgraded connection, on the loop
//     thread. Its views become render jobs of the stream's own latest-wins slot
//     ("stream:<connection>"), so they take part in the round-robin and the degradation like
//     HTTP frames; at most one job of a stream renders or encodes at a time, and at most
//     kStreamWindow frames are sent and not acknowledged; a newer view replaces one not yet
//     submitted. Its frames are encoded on libuv's pool with the stream's encoder (one frame at a
//     time). One timer (kStreamTickMs) serves every stream: the still at rest, pings (stream_ping_ms),
//     the idle close (3 pings unanswered) and the close of a stream whose frames go unacknowledged past the write timeout.
//   - Shutdown: stop accepting and reading; streams get a close frame (1001); answer what was read; close connections as they
//     finish, or all of them at the shutdown deadline; once no connection, pool work or render
//     job is left, stop the render thread and close the handles, so that uv_run returns and the
//     store closes.
#include "plantview/server.h"

#include <arpa/inet.h>
#include <uv.h>

#include <algorithm>
#include <chrono>
#include <deque>
#include <optional>
#include <csignal>
#include <ctime>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <unordered_map>
#include <unordered_set>

#include "plantview/measure.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "server/connection.h"
#include "server/encoding.h"
#include "server/metrics.h"
#include "server/objects_json.h"
#include "server/render_worker.h"
#include "server/routes.h"
#include "server/stream.h"

namespace plantview::service {

namespace {

constexpr size_t kMaxServedAddresses = 16384;

// Streams (docs/stream.md).
constexpr size_t kStreamWindow = 2;          // frames sent and not acknowledged, at most
constexpr uint64_t kStreamTickMs = 50;
constexpr uint64_t kStreamRestMs = 300;      // no view for this long after a moving frame: a still
constexpr uint16_t kUnsupportedData = 1003;  // a binary message from the client

struct Ticket {
  Connection* connection = nullptr;  // null once the connection has closed
  std::shared_ptr<Pending> pending;
  RenderJob::Kind kind = RenderJob::Kind::frame;  // render tickets: for the metrics
  bool stream = false;                            // a stream's frame (no pending)
};

struct Stream {
  Connection* connection = nullptr;  // null once it has closed
  bool authenticated = false, said_ready = false, seen_message = false;
  StreamCodec codec = StreamCodec::jpeg;
  BitrateControl bitrate;
  std::unique_ptr<VideoEncoder> encoder;  // used by one pool thread at a time (while busy)
  bool want_key = true;
  // The latest view not yet submitted (a newer one replaces it; the still is a view with
  // mode=still) and its seq.
  std::optional<RenderJob> next;
  uint64_t next_seq = 0;
  bool busy = false;  // a job of this stream renders or encodes
  uint64_t pending_seq = 0;  // the view seq of that job
  std::optional<RenderJob> last_view;  // the newest view accepted: what the still shows
  uint64_t last_view_seq = 0;
  uint64_t last_view_ms = 0;
  bool still_due = false;  // a moving frame of last_view went out, and no still since
  uint64_t moving_sent_ms = 0;  // when that frame went out: the rest counts from it too
  struct Sent {
    uint64_t frame = 0, sent_ms = 0;
  };
  std::deque<Sent> unacked;
  uint64_t next_frame = 1;
  uint64_t last_ping_ms = 0;
};

class Server final : public ConnectionHost {
 public:
  ServerOptions options;
  ConnectionLimits limits;
  RouteConfig routes;
  uv_loop_t* loop = nullptr;
  uv_tcp_t listener{};
  uv_signal_t sigint{}, sigterm{};
  uv_timer_t shutdown_timer{};
  uv_timer_t follow_timer{};   // looks for a new commit to describe (/api/model)
  uv_async_t results_ready{};  // the render thread's results, delivered on the loop
  std::unique_ptr<Store> store;
  RenderWorker worker;
  std::unordered_set<Connection*> connections;
  std::unordered_set<Connection*> admitted;  // started (not refused): count against the limits
  std::unordered_map<std::string, uint32_t> admitted_by_address;
  std::unordered_map<std::string, uint64_t> served_addresses;  // address -> when last served (uv_now, ms)
  std::unordered_map<uint64_t, Ticket> tickets;
  std::unordered_map<Connection*, std::shared_ptr<Stream>> streams;
  uv_timer_t stream_timer{};
  bool stream_timer_running = false;
  uint64_t next_ticket = 1, next_connection = 1;
  uint64_t warm_up_ticket = 0;  // the first frame's: readiness waits for it
  int works_in_flight = 0;
  bool ready = false;           // the renderer has drawn its first frame
  bool stopping = false;
  uint64_t shutdown_started_ms = 0;
  Metrics metrics;
  // The commit and revision /api/model (routes) describes; a description on the pool.
  uint64_t model_commit = 0;
  uint32_t model_revision = 0;
  bool describing = false;

  const ConnectionLimits& connection_limits() const override { return limits; }
  bool shutting_down() const override { return stopping; }
  void on_request(Connection& c, const Request& request, const std::shared_ptr<Pending>& p) override;
  void on_answered(const std::string& endpoint, int status) override { metrics.count_answer(endpoint, status); }
  void on_timed_out() override { metrics.timed_out_connections += 1; }
  void on_closing(Connection& c) override {
    connections.erase(&c);
    if (admitted.erase(&c)) {
      const auto it = admitted_by_address.find(c.address());
      if (it != admitted_by_address.end() && --it->second == 0) admitted_by_address.erase(it);
    }
    for (auto& [number, t] : tickets)
      if (t.connection == &c) t.connection = nullptr;
    if (const auto it = streams.find(&c); it != streams.end()) {
      it->second->connection = nullptr;
      streams.erase(it);
    }
  }
  void on_ws_message(Connection& c, bool text, std::string& payload) override;
  void open_stream(Connection& c, const std::shared_ptr<Pending>& p, StreamUpgrade upgrade);
  void stream_send_text(Stream& s, const std::string& text) { s.connection->send_ws(ws::Opcode::text, text); }
  void stream_ready(Stream& s);
  void stream_pump(Stream& s);
  void stream_rendered(Ticket& t, RenderResult&& r);
  void stream_tick();
  // Why a new connection from `address` is refused, or "" to admit it.
  std::string admission(const std::string& address) const;
  void remember_served(const std::string& address);
  bool health_check(Connection& c, const Request& request, const std::shared_ptr<Pending>& p);
  void queue_warm_up();

  uint64_t add_ticket(Connection& c, const std::shared_ptr<Pending>& p,
                      RenderJob::Kind kind = RenderJob::Kind::frame) {
    tickets[next_ticket] = {&c, p, kind};
    return next_ticket++;
  }
  // The ticket's connection and Pending, forgotten; connection null if it has gone.
  Ticket take_ticket(uint64_t number) {
    const auto it = tickets.find(number);
    if (it == tickets.end()) return {};
    Ticket t = it->second;
    tickets.erase(it);
    return t;
  }
  void submit_render(Connection& c, const std::shared_ptr<Pending>& p, RenderJob job);
  void look_up_object(Connection& c, const std::shared_ptr<Pending>& p, ObjectLookup lookup);
  void measure(Connection& c, const std::shared_ptr<Pending>& p, MeasureLookup lookup);
  void answer_from_store(Connection& c, const std::shared_ptr<Pending>& p,
                         std::function<ObjectAnswer(const ReadView&)> answer);
  void on_render_done(RenderResult&& r);
  void follow_commits();
  void deliver(RenderResult& r);
  void begin_shutdown();
  bool finish_shutdown();
};

Reply text_reply(std::string content_type, std::string body, int status = 200, Fields headers = {}) {
  Reply r;
  r.status = status;
  r.content_type = std::move(content_type);
  r.body = std::move(body);
  r.headers = std::move(headers);
  return r;
}

std::string Server::admission(const std::string& address) const {
  if (admitted.size() >= options.max_clients) return "too many connections";
  const auto open = admitted_by_address.find(address);
  if (open != admitted_by_address.end() && open->second >= options.max_clients_per_address)
    return "too many connections from " + address;
  const uint32_t unreserved = options.max_clients - std::min(options.reserved_clients, options.max_clients);
  if (admitted.size() >= unreserved && !served_addresses.count(address))
    return "too many connections (the rest are kept for clients already served)";
  return {};
}

void Server::remember_served(const std::string& address) {
  const uint64_t now = uv_now(loop);
  if (served_addresses.size() >= kMaxServedAddresses && !served_addresses.count(address)) {
    // Forget the older half (a scan over at most kMaxServedAddresses, once per that many new
    // addresses).
    std::vector<uint64_t> times;
    times.reserve(served_addresses.size());
    for (const auto& [a, t] : served_addresses) times.push_back(t);
    std::nth_element(times.begin(), times.begin() + times.size() / 2, times.end());
    const uint64_t median = times[times.size() / 2];
    std::erase_if(served_addresses, [&](const auto& entry) { return entry.second <= median; });
  }
  served_addresses[address] = now;
}

// /healthz and /readyz: for probes and balancers, before the token and the routes.
bool Server::health_check(Connection& c, const Request& request, const std::shared_ptr<Pending>& p) {
  const bool live = request.path == "/healthz", readiness = request.path == "/readyz";
  if (!live && !readiness) return false;
  p->endpoint = live ? "healthz" : "readyz";
  Reply reply;
  reply.content_type = "text/plain; charset=utf-8";
  if (request.method != "GET") {
    reply = error_reply(405, "only GET is served", {{"Allow", "GET"}});
  } else if (!request.query.empty() || !request.query_error.empty()) {
    reply = error_reply(400, request.path + " takes no parameters");
  } else if (live) {
    reply.body = "alive\n";
  } else if (stopping) {
    reply.status = 503;
    reply.body = "draining\n";
  } else if (!ready) {
    reply.status = 503;
    reply.body = "starting: the renderer has not drawn its first frame yet\n";
  } else {
    reply.body = "ready\n";
  }
  c.answer(p, std::move(reply));
  return true;
}

void Server::on_request(Connection& c, const Request& request, const std::shared_ptr<Pending>& p) {
  if (health_check(c, request, p)) return remember_served(c.address());
  // While draining, what has been read is still answered (the connection reads no more).
  Routed routed = route(request, routes, false, c.id());
  p->endpoint = routed.endpoint;
  const auto* refused = std::get_if<Reply>(&routed.decision);
  if (!refused || refused->status != 401) remember_served(c.address());  // a wrong token earns no slot
  if (auto* reply = std::get_if<Reply>(&routed.decision)) {
    if (reply->status != 401) reply->headers.emplace_back("X-Plantview-Revision", std::to_string(model_revision));
    c.answer(p, std::move(*reply));
  } else if (std::holds_alternative<MetricsPage>(routed.decision)) {
    metrics.count_answer(p->endpoint, 200);  // counted before it is written, so that it shows
    MetricsGauges gauges{worker.vertex_budget_bytes(), worker.queue_depth(), connections.size()};
    gauges.streams = streams.size();
    gauges.ready = ready && !stopping;
    c.answer(p, text_reply("text/plain; version=0.0.4", metrics_text(metrics, gauges)), false);
  } else if (auto* lookup = std::get_if<ObjectLookup>(&routed.decision)) {
    look_up_object(c, p, std::move(*lookup));
  } else if (auto* pair = std::get_if<MeasureLookup>(&routed.decision)) {
    measure(c, p, std::move(*pair));
  } else if (auto* upgrade = std::get_if<StreamUpgrade>(&routed.decision)) {
    open_stream(c, p, std::move(*upgrade));
  } else {
    submit_render(c, p, std::move(std::get<RenderJob>(routed.decision)));
  }
}

void Server::submit_render(Connection& c, const std::shared_ptr<Pending>& p, RenderJob job) {
  job.ticket = next_ticket;
  const RenderJob::Kind kind = job.kind;
  uint64_t dropped = 0;
  const auto submitted = worker.submit(std::move(job), dropped);
  if (submitted == RenderWorker::Submitted::busy) {
    metrics.rejected_busy += 1;
    return c.answer(p, error_reply(503, "too many frames waiting; retry shortly", {{"Retry-After", "1"}}));
  }
  add_ticket(c, p, kind);
  if (submitted == RenderWorker::Submitted::replaced) {
    metrics.superseded += 1;
    const Ticket t = take_ticket(dropped);
    if (t.connection) t.connection->answer(t.pending, error_reply(409, "superseded by a newer request of the same client"));
  }
}

// Object look-ups and measurements run on libuv's pool, each in a read view of its own: the
// render thread's view belongs to the render thread, and neither must wait behind frames (two
// objects of 5,000 primitives take tens of milliseconds to measure). `answer` runs on the pool
// and makes the JSON reply; the loop thread sends it if the connection is still there.
struct StoreWork {
  uv_work_t req{};
  Server* server = nullptr;
  const Store* store = nullptr;
  std::function<ObjectAnswer(const ReadView&)> answer;
  uint64_t ticket = 0;
  ObjectAnswer result;
  uint32_t revision = 0;  // of the view the answer read
};

void Server::answer_from_store(Connection& c, const std::shared_ptr<Pending>& p,
                               std::function<ObjectAnswer(const ReadView&)> answer) {
  auto* work = new StoreWork;
  work->server = this;
  work->store = store.get();
  work->answer = std::move(answer);
  work->ticket = add_ticket(c, p);
  work->req.data = work;
  ++works_in_flight;
  uv_queue_work(
      loop, &work->req,
      [](uv_work_t* req) {
        auto* w = static_cast<StoreWork*>(req->data);
        std::string error;
        const auto view = w->store->read(error);
        w->result = view ? w->answer(*view) : ObjectAnswer{500, error_body(error)};
        if (view) w->revision = view->info().revision;
      },
      [](uv_work_t* req, int) {
        const std::unique_ptr<StoreWork> w(static_cast<StoreWork*>(req->data));
        --w->server->works_in_flight;
        const Ticket t = w->server->take_ticket(w->ticket);
        if (!t.connection) return;
        t.connection->answer(t.pending, text_reply("application/json", std::move(w->result.body), w->result.status,
                                                   {{"X-Plantview-Revision", std::to_string(w->revision)}}));
      });
}

void Server::look_up_object(Connection& c, const std::shared_ptr<Pending>& p, ObjectLookup lookup) {
  answer_from_store(c, p, [lookup = std::move(lookup)](const ReadView& view) {
    return object_answer(view, lookup.id, lookup.name);
  });
}

void Server::measure(Connection& c, const std::shared_ptr<Pending>& p, MeasureLookup lookup) {
  answer_from_store(c, p, [lookup = std::move(lookup)](const ReadView& view) {
    const StoreMeasurement m = measure_in_store(view, lookup.a, lookup.b);
    using Outcome = StoreMeasurement::Outcome;
    int status = 500;
    switch (m.outcome) {
      case Outcome::measured: return ObjectAnswer{200, clearance_json(m.a, m.b, m.clearance) + "\n"};
      case Outcome::unknown: status = 404; break;
      case Outcome::ambiguous: status = 409; break;
      case Outcome::no_geometry: status = 422; break;
      case Outcome::failed: status = 500; break;
    }
    return ObjectAnswer{status, error_body(m.message)};
  });
}

// The first frame after start-up: the renderer is warm, and the server ready.
void Server::queue_warm_up() {
  RenderJob job;
  job.kind = RenderJob::Kind::frame;
  job.width = job.height = 64;
  job.camera = default_camera(routes.bounds, 1.0);
  job.client = "server/warm-up";
  job.ticket = warm_up_ticket = next_ticket++;
  uint64_t dropped = 0;
  worker.submit(std::move(job), dropped);
}

void Server::deliver(RenderResult& r) {
  const Ticket t = take_ticket(r.ticket);
  if (r.rendered) metrics.count_rendered(t.kind, r.stats);
  if (!t.connection) return;  // the client went away
  t.connection->answer(t.pending, text_reply(r.content_type, std::move(r.body), r.status, std::move(r.headers)));
}

struct EncodeWork {
  uv_work_t req{};
  Server* server = nullptr;
  RenderResult result;
};

void Server::on_render_done(RenderResult&& r) {
  if (r.ticket == warm_up_ticket) {
    if (stopping) return;  // drawn after the signal: never ready
    ready = r.status == 200;
    if (ready) std::fprintf(stderr, "plantview serve: ready (first frame drawn)\n");
    else std::fprintf(stderr, "plantview serve: not ready: the first frame failed: %s\n", r.body.c_str());
    return;
  }
  const auto ticket = tickets.find(r.ticket);
  if (ticket != tickets.end() && ticket->second.stream) {
    Ticket t = ticket->second;
    tickets.erase(ticket);
    return stream_rendered(t, std::move(r));
  }
  if (ticket == tickets.end() || !ticket->second.connection) return deliver(r);  // nobody to encode for
  if (!r.needs_encoding) return deliver(r);
  // Encode on libuv's pool: the render thread goes on with the next frame meanwhile.
  auto* work = new EncodeWork;
  work->server = this;
  work->result = std::move(r);
  work->req.data = work;
  ++works_in_flight;
  uv_queue_work(
      loop, &work->req, [](uv_work_t* req) { encode_frame(static_cast<EncodeWork*>(req->data)->result); },
      [](uv_work_t* req, int) {
        const std::unique_ptr<EncodeWork> w(static_cast<EncodeWork*>(req->data));
        --w->server->works_in_flight;
        w->server->deliver(w->result);
      });
}

// --- streams ------------------------------------------------------------------------------------

void Server::open_stream(Connection& c, const std::shared_ptr<Pending>& p, StreamUpgrade upgrade) {
  auto stream = std::make_shared<Stream>();
  stream->connection = &c;
  stream->authenticated = upgrade.authenticated;
  stream->last_ping_ms = uv_now(loop);
  streams[&c] = stream;
  metrics.streams_opened += 1;
  c.accept_websocket(p, std::move(upgrade.response));
  if (!stream_timer_running) {
    stream_timer_running = true;
    uv_timer_start(
        &stream_timer, [](uv_timer_t* t) { static_cast<Server*>(t->data)->stream_tick(); }, kStreamTickMs,
        kStreamTickMs);
  }
}

void Server::stream_ready(Stream& s) {
  if (s.said_ready) return;
  s.said_ready = true;
  const nlohmann::json message = {{"type", "ready"}, {"codec", codec_name(s.codec)}, {"protocol", 1}};
  stream_send_text(s, message.dump());
}

void Server::on_ws_message(Connection& c, bool text, std::string& payload) {
  const auto found = streams.find(&c);
  if (found == streams.end()) return;
  const std::shared_ptr<Stream> keep = found->second;
  Stream& s = *keep;
  const bool first = !s.seen_message;
  s.seen_message = true;
  if (!text) return c.close_ws(kUnsupportedData, "the stream takes text (JSON) messages only");
  ClientMessage m;
  std::string error;
  if (!parse_client_message(payload, m, error)) {
    if (!s.authenticated) return c.close_ws(ws::policy, "a token is required: send hello with it first");
    return stream_send_text(s, error_message(error, m.has_seq ? &m.seq : nullptr));
  }
  if (m.type == ClientMessage::Type::hello) {
    if (!first) return stream_send_text(s, error_message("hello must be the first message"));
    if (!routes.token.empty() && !s.authenticated) {
      const std::string& expected = routes.token;
      unsigned diff = unsigned(m.token.size() ^ expected.size());
      for (size_t i = 0; i < expected.size(); ++i)
        diff |= unsigned(uint8_t(expected[i]) ^ uint8_t(i < m.token.size() ? m.token[i] : 0));
      if (!m.has_token || diff != 0) return c.close_ws(ws::policy, "the token is missing or wrong");
      s.authenticated = true;
    }
    StreamCodec codec = StreamCodec::jpeg;
    if (!m.codec.empty() && codec_from_name(m.codec, codec) && codec_available(codec)) s.codec = codec;
    s.bitrate = BitrateControl(m.max_kbps);
    return stream_ready(s);
  }
  if (!s.authenticated) return c.close_ws(ws::policy, "a token is required: send hello with it first");
  const uint64_t now = uv_now(loop);
  switch (m.type) {
    case ClientMessage::Type::view: {
      Request request;
      request.method = "GET";
      request.path = "/api/frame";
      request.query = std::move(m.params);
      // A view is a moving camera unless it says otherwise: interactive (degradable) frames.
      if (std::none_of(request.query.begin(), request.query.end(), [](const auto& f) { return f.first == "mode"; }))
        request.query.emplace_back("mode", "interactive");
      if (!routes.token.empty()) request.authorization = "Bearer " + routes.token;
      Routed routed = route(request, routes, false, c.id());
      if (auto* refused = std::get_if<Reply>(&routed.decision)) {
        const auto body = nlohmann::json::parse(refused->body, nullptr, false);
        const std::string message = body.is_object() && body.contains("error") && body["error"].is_string()
                                        ? body["error"].get<std::string>()
                                        : "the view was refused";
        return stream_send_text(s, error_message(message, &m.seq));
      }
      RenderJob job = std::move(std::get<RenderJob>(routed.decision));
      job.client = "stream:" + std::to_string(c.id());
      stream_ready(s);
      if (s.next) metrics.stream_drops += 1;  // replaced before it was rendered
      s.last_view = job;
      s.last_view_seq = m.seq;
      s.last_view_ms = now;
      s.still_due = false;
      s.next = std::move(job);
      s.next_seq = m.seq;
      return stream_pump(s);
    }
    case ClientMessage::Type::ack: {
      while (!s.unacked.empty() && s.unacked.front().frame <= m.frame) {
        s.bitrate.on_ack(double(now - s.unacked.front().sent_ms), now);
        s.unacked.pop_front();
      }
      return stream_pump(s);
    }
    case ClientMessage::Type::key: s.want_key = true; return;
    case ClientMessage::Type::hello: return;
  }
}

// Submits the stream's next view when nothing of it renders and the window has room.
void Server::stream_pump(Stream& s) {
  if (!s.connection || s.busy || !s.next || s.unacked.size() >= kStreamWindow || stopping) return;
  RenderJob job = std::move(*s.next);
  job.ticket = next_ticket;
  uint64_t dropped = 0;
  RenderJob copy = job;  // kept to retry if the queue is full
  if (worker.submit(std::move(job), dropped) == RenderWorker::Submitted::busy) {
    s.next = std::move(copy);  // retried at the next tick
    return;
  }
  s.busy = true;
  Ticket& t = tickets[next_ticket++];
  t.connection = s.connection;
  t.stream = true;
  t.kind = RenderJob::Kind::frame;
  s.pending_seq = s.next_seq;
  s.next.reset();
}

struct StreamEncodeWork {
  uv_work_t req{};
  Server* server = nullptr;
  std::shared_ptr<Stream> stream;
  RenderResult result;
  StreamCodec codec = StreamCodec::jpeg;
  bool still = false, key = false;
  uint32_t kbps = 0;
  uint64_t seq = 0;
  std::string payload, encoding, error;
  uint32_t width = 0, height = 0;
  double encode_ms = 0;
};

void Server::stream_rendered(Ticket& t, RenderResult&& r) {
  if (r.rendered) metrics.count_rendered(t.kind, r.stats);
  const auto found = t.connection ? streams.find(t.connection) : streams.end();
  if (found == streams.end()) {
    metrics.stream_drops += 1;
    return;
  }
  const std::shared_ptr<Stream>& stream = found->second;
  auto* work = new StreamEncodeWork;
  work->server = this;
  work->stream = stream;
  work->result = std::move(r);
  work->codec = stream->codec;
  work->still = work->result.headers.end() !=
                std::find(work->result.headers.begin(), work->result.headers.end(),
                          std::pair<std::string, std::string>("X-Plantview-Mode", "still"));
  work->key = stream->want_key;
  work->kbps = stream->bitrate.target_kbps();
  work->seq = stream->pending_seq;
  work->req.data = work;
  ++works_in_flight;
  uv_queue_work(
      loop, &work->req,
      [](uv_work_t* req) {
        // On the pool: the stream's encoder is used by this thread alone (the stream is busy).
        auto& w = *static_cast<StreamEncodeWork*>(req->data);
        RenderResult& result = w.result;
        if (!result.needs_encoding) return;
        w.width = result.image.width;
        w.height = result.image.height;
        const auto start = std::chrono::steady_clock::now();
        if (w.codec == StreamCodec::jpeg || w.still) {
          encode_frame(result);
          w.encoding = result.format == ImageFormat::png ? "png" : "jpeg";
          w.payload = std::move(result.body);
        } else {
          if (!w.stream->encoder) w.stream->encoder = VideoEncoder::create(w.codec, w.error);
          if (w.stream->encoder &&
              w.stream->encoder->encode(result.image, w.kbps, w.key, w.payload, w.error)) {
            w.encoding = codec_name(w.codec);
            w.width = w.stream->encoder->width();
            w.height = w.stream->encoder->height();
          }
          result.image = Image{};
          result.needs_encoding = false;
        }
        w.encode_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      },
      [](uv_work_t* req, int) {
        const std::unique_ptr<StreamEncodeWork> w(static_cast<StreamEncodeWork*>(req->data));
        Server& server = *w->server;
        --server.works_in_flight;
        Stream& s = *w->stream;
        s.busy = false;
        if (!s.connection) {
          server.metrics.stream_drops += 1;
          return;
        }
        RenderResult& result = w->result;
        if (result.status != 200 || !w->error.empty()) {
          std::string message = w->error;
          if (message.empty()) {
            const auto body = nlohmann::json::parse(result.body, nullptr, false);
            message = body.is_object() && body.contains("error") && body["error"].is_string()
                          ? body["error"].get<std::string>()
                          : "the frame failed (" + std::to_string(result.status) + ")";
          }
          server.stream_send_text(s, error_message(message, &w->seq));
          if (!w->still) s.still_due = false;
          return server.stream_pump(s);
        }
        if (w->encoding != "jpeg" && w->encoding != "png" && w->key) s.want_key = false;
        nlohmann::json stats = nlohmann::json::object();
        for (const auto& [name, value] : result.headers)
          if (name.rfind("X-", 0) == 0 && name != "X-Plantview-Client") stats[name] = value;
        const uint64_t frame = s.next_frame++;
        nlohmann::json header = {{"frame", frame},
                                 {"seq", w->seq},
                                 {"encoding", w->encoding},
                                 {"key", w->encoding == "jpeg" || w->encoding == "png" || w->key},
                                 {"width", w->width},
                                 {"height", w->height},
                                 {"still", w->still},
                                 {"render_ms", result.stats.ms.total},
                                 {"encode_ms", w->encode_ms},
                                 {"stats", stats},
                                 {"kbps", w->kbps}};
        const std::string message =
            pack_frame(header.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), w->payload);
        server.metrics.stream_frames += 1;
        server.metrics.stream_bytes += message.size();
        s.connection->send_ws(ws::Opcode::binary, message);
        s.unacked.push_back({frame, uv_now(server.loop)});
        // A moving frame of the newest view: its still follows once the camera rests.
        if (!w->still && w->seq == s.last_view_seq) {
          s.still_due = true;
          s.moving_sent_ms = uv_now(server.loop);
        }
        if (w->still) s.still_due = false;
        server.stream_pump(s);
      });
}

// Every kStreamTickMs: stills at rest, retries of a full queue, pings, idle and unacknowledged
// closes.
void Server::stream_tick() {
  const uint64_t now = uv_now(loop);
  std::vector<std::shared_ptr<Stream>> all;
  for (const auto& [c, stream] : streams) all.push_back(stream);
  if (all.empty()) {
    uv_timer_stop(&stream_timer);
    stream_timer_running = false;
    return;
  }
  for (const auto& stream : all) {
    Stream& s = *stream;
    if (!s.connection || s.connection->ws_closing()) continue;
    Connection& c = *s.connection;
    // Nothing from the client (not even a pong) for 3 pings: closed.
    if (now - c.last_read_ms() >= 3 * uint64_t(options.stream_ping_ms)) {
      metrics.timed_out_connections += 1;
      c.close_ws(ws::going_away, "no message or pong for 3 pings");
      continue;
    }
    if (!s.unacked.empty() && now - s.unacked.front().sent_ms >= limits.write_timeout_ms) {
      metrics.timed_out_connections += 1;
      metrics.stream_drops += 1;
      c.close_ws(ws::policy, "frames not acknowledged within the write timeout");
      continue;
    }
    if (now - s.last_ping_ms >= options.stream_ping_ms) {
      s.last_ping_ms = now;
      c.send_ws(ws::Opcode::ping, {});
    }
    // At rest: no view since the newest one's moving frame went out, for kStreamRestMs after
    // both (a slow render must not make its own frame look like a camera at rest).
    if (s.still_due && !s.next && !s.busy && s.last_view &&
        now - std::max(s.last_view_ms, s.moving_sent_ms) >= kStreamRestMs) {
      RenderJob still = *s.last_view;
      still.mode = FrameMode::still;
      still.format = ImageFormat::png;
      s.next = std::move(still);
      s.next_seq = s.last_view_seq;
      s.still_due = false;
    }
    stream_pump(s);
  }
}

// --- shutdown -----------------------------------------------------------------------------------

void Server::begin_shutdown() {
  if (stopping) return;
  stopping = true;
  uv_timer_stop(&follow_timer);
  shutdown_started_ms = uv_now(loop);
  std::fprintf(stderr, "plantview serve: shutting down (finishing %zu requests)\n", tickets.size());
  uv_close(reinterpret_cast<uv_handle_t*>(&listener), nullptr);
  for (Connection* c : connections) c->stop_reading();
  std::vector<Connection*> open_streams;
  for (const auto& [c, stream] : streams) open_streams.push_back(c);
  for (Connection* c : open_streams) c->close_ws(ws::going_away, "the server is shutting down");
  // Every 50 ms until the work in flight is done.
  uv_timer_start(
      &shutdown_timer,
      [](uv_timer_t* t) { static_cast<Server*>(t->data)->finish_shutdown(); },
      0, 50);
}

// Closes finished connections; once nothing is left in flight, stops the render thread and
// closes the server's handles, this timer's too (true).
bool Server::finish_shutdown() {
  const bool deadline = uv_now(loop) - shutdown_started_ms >= options.shutdown_timeout_ms;
  std::vector<Connection*> done;
  for (Connection* c : connections)
    if (c->finished() || deadline) done.push_back(c);
  if (deadline && !done.empty()) {
    std::fprintf(stderr, "plantview serve: shutdown deadline: closing %zu connections\n", done.size());
    metrics.timed_out_connections += done.size();
  }
  for (Connection* c : done) c->close();
  if (!connections.empty() || works_in_flight > 0 || !worker.idle()) return false;
  worker.stop();
  uv_close(reinterpret_cast<uv_handle_t*>(&results_ready), nullptr);
  uv_close(reinterpret_cast<uv_handle_t*>(&shutdown_timer), nullptr);
  uv_close(reinterpret_cast<uv_handle_t*>(&follow_timer), nullptr);
  uv_close(reinterpret_cast<uv_handle_t*>(&stream_timer), nullptr);
  // Everything is finished; only the store's clean close remains. A repeated signal (a second
  // Ctrl-C, a supervisor's retry) must not cut that short.
  std::signal(SIGINT, SIG_IGN);
  std::signal(SIGTERM, SIG_IGN);
  uv_close(reinterpret_cast<uv_handle_t*>(&sigint), nullptr);
  uv_close(reinterpret_cast<uv_handle_t*>(&sigterm), nullptr);
  return true;
}

// --- start-up -----------------------------------------------------------------------------------

bool load_web_files(const std::string& directory, std::map<std::string, StaticFile>& files) {
  const std::pair<const char*, const char*> names[] = {
      {"index.html", "text/html; charset=utf-8"},
      {"viewer.js", "text/javascript; charset=utf-8"},
      {"viewer.css", "text/css; charset=utf-8"}};
  for (const auto& [name, type] : names) {
    std::ifstream in(directory + "/" + name, std::ios::binary);
    if (!in) continue;
    std::ostringstream bytes;
    bytes << in.rdbuf();
    files["/" + std::string(name)] = {type, bytes.str()};
  }
  if (const auto it = files.find("/index.html"); it != files.end()) files["/"] = it->second;
  return files.count("/") != 0;
}

// What the routes know of one commit of the store: the /api/model answer, the bounds and what
// the default view is fitted to.
struct ModelDescription {
  std::string model_json;
  DAabb bounds;
  std::vector<DAabb> overview_boxes;
  uint64_t commit = 0;    // the view's (ReadView::commit)
  uint32_t revision = 0;  // StoreInfo::revision
};

// "2026-12-06T09:30:00.123Z" (UTC).
std::string iso8601_utc(int64_t unix_ms) {
  const time_t seconds = time_t(unix_ms / 1000);
  tm utc{};
  gmtime_r(&seconds, &utc);
  char text[40];
  const size_t n = std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%S", &utc);
  std::snprintf(text + n, sizeof text - n, ".%03dZ", int(unix_ms % 1000));
  return text;
}

// The /api/model answer and the model's bounds, from a snapshot of the store. Any thread.
bool describe_model(const Store& store, ModelDescription& out, std::string& error) {
  auto view = store.read(error);
  if (!view) return false;
  const StoreInfo info = view->info();
  out.commit = view->commit();
  out.revision = info.revision;
  out.bounds = info.statistics.bounds;
  out.overview_boxes = overview_boxes(*view);
  const Camera camera = default_camera(out.overview_boxes, 16.0 / 9.0);
  nlohmann::json model = {{"objects", info.objects},
                          {"revision", info.revision},
                          {"revision_time", info.revision_time_unix_ms > 0
                                                ? nlohmann::json(iso8601_utc(info.revision_time_unix_ms))
                                                : nlohmann::json(nullptr)},
                          {"statistics", nlohmann::json::parse(statistics_json(info.statistics))},
                          {"camera",
                           {{"eye", {camera.eye_m.x, camera.eye_m.y, camera.eye_m.z}},
                            {"target", {camera.target_m.x, camera.target_m.y, camera.target_m.z}},
                            {"up", {camera.up.x, camera.up.y, camera.up.z}},
                            {"fov", camera.fov_deg}}}};
  // What the revision changed (ReadView::revisions: kept for ever, a few hundred bytes each).
  std::vector<Revision> revisions;
  if (!view->revisions(revisions, error)) return false;
  for (const Revision& r : revisions) {
    if (r.number != info.revision) continue;
    model["changes"] = {{"added", r.added}, {"removed", r.removed}, {"modified", r.modified}};
    model["note"] = r.note;
    model["sources"] = r.sources;
  }
  const DAabb& b = out.bounds;
  if (!b.empty()) model["bounds"] = {{"min", {b.min.x, b.min.y, b.min.z}}, {"max", {b.max.x, b.max.y, b.max.z}}};
  out.model_json = model.dump() + "\n";
  return true;
}

void use_description(Server& s, ModelDescription&& d) {
  s.routes.model_json = std::move(d.model_json);
  s.routes.bounds = d.bounds;
  s.routes.overview_boxes = std::move(d.overview_boxes);
  s.model_commit = d.commit;
  s.model_revision = d.revision;
}

struct DescribeWork {
  uv_work_t req{};
  Server* server = nullptr;
  uint64_t newest = 0;  // Store::last_commit() when it was queued
  ModelDescription description;
  bool ok = false;
  std::string error;
};

// On the loop, every kFollowIntervalMs: a new commit is described on the pool, then swapped in.
void Server::follow_commits() {
  if (stopping || describing) return;
  const uint64_t newest = store->last_commit();
  if (newest == model_commit) return;
  describing = true;
  ++works_in_flight;
  auto* work = new DescribeWork;
  work->server = this;
  work->newest = newest;
  work->req.data = work;
  uv_queue_work(
      loop, &work->req,
      [](uv_work_t* req) {
        auto* w = static_cast<DescribeWork*>(req->data);
        w->ok = describe_model(*w->server->store, w->description, w->error);
      },
      [](uv_work_t* req, int) {
        const std::unique_ptr<DescribeWork> w(static_cast<DescribeWork*>(req->data));
        Server& s = *w->server;
        --s.works_in_flight;
        s.describing = false;
        if (!w->ok) {
          s.model_commit = w->newest;  // tried again at the next commit
          std::fprintf(stderr, "plantview serve: still describing revision %u: %s\n", s.model_revision,
                       w->error.c_str());
          return;
        }
        if (w->description.commit == s.model_commit) return;
        use_description(s, std::move(w->description));
        std::fprintf(stderr, "plantview serve: following revision %u (commit %llu)\n", s.model_revision,
                     static_cast<unsigned long long>(s.model_commit));
      });
}


bool is_loopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

void on_connection(uv_stream_t* listener, int status) {
  auto& s = *static_cast<Server*>(listener->data);
  if (status < 0) return;
  Connection* c = Connection::accept(listener, s, s.next_connection++);
  if (!c) return;
  s.connections.insert(c);
  const std::string refused = s.stopping ? "the server is shutting down" : s.admission(c->address());
  if (!refused.empty()) {
    s.metrics.refused_connections += 1;
    c->refuse(error_reply(503, refused, {{"Retry-After", "1"}}));
    return;
  }
  s.admitted.insert(c);
  s.admitted_by_address[c->address()] += 1;
  c->start();
}

// Binds and listens; prints the address. False with `error` set.
bool listen_on(Server& s, std::string& error) {
  const ServerOptions& options = s.options;
  sockaddr_storage address{};
  if (uv_ip4_addr(options.host.c_str(), options.port, reinterpret_cast<sockaddr_in*>(&address)) != 0 &&
      uv_ip6_addr(options.host.c_str(), options.port, reinterpret_cast<sockaddr_in6*>(&address)) != 0) {
    error = "serve: '" + options.host + "' is not an IP address";
    return false;
  }
  uv_tcp_init(s.loop, &s.listener);
  s.listener.data = &s;
  int rc = uv_tcp_bind(&s.listener, reinterpret_cast<const sockaddr*>(&address), 0);
  if (rc == 0) rc = uv_listen(reinterpret_cast<uv_stream_t*>(&s.listener), 256, on_connection);
  if (rc != 0) {
    error = "serve: cannot listen on " + options.host + ":" + std::to_string(options.port) + ": " + uv_strerror(rc);
    uv_close(reinterpret_cast<uv_handle_t*>(&s.listener), nullptr);
    return false;
  }
  sockaddr_storage bound{};
  int length = sizeof bound;
  uv_tcp_getsockname(&s.listener, reinterpret_cast<sockaddr*>(&bound), &length);
  const int port = bound.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port)
                                               : ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  const bool v6 = options.host.find(':') != std::string::npos;
  std::printf("listening on http://%s%s%s:%d/\n", v6 ? "[" : "", options.host.c_str(), v6 ? "]" : "", port);
  std::fflush(stdout);
  return true;
}

// Stops what start-up began (the render thread, the async) and lets the loop close them.
int abandon(Server& s, uv_loop_t& loop) {
  s.worker.stop();
  uv_close(reinterpret_cast<uv_handle_t*>(&s.results_ready), nullptr);
  uv_run(&loop, UV_RUN_DEFAULT);
  uv_loop_close(&loop);
  return 1;
}

}  // namespace

int run_server(const ServerOptions& options, std::string& error) {
  auto server = std::make_unique<Server>();
  Server& s = *server;
  s.options = options;
  s.limits = {{options.max_header_bytes, options.max_body_bytes}, options.request_timeout_ms,
              options.idle_timeout_ms, options.write_timeout_ms, options.max_unsent_bytes};
  s.routes.token = options.token;
  s.routes.client_key = random_client_key();
  if (!is_loopback(options.host) && options.token.empty()) {
    error = "serve: listening on " + options.host + " (not loopback) requires --token";
    return 1;
  }
  s.store = Store::open(options.store_directory, Store::Mode::read_only, error);
  ModelDescription description;
  if (!s.store || !describe_model(*s.store, description, error)) return 1;
  use_description(s, std::move(description));
  if (s.store->without_lock_file())
    std::fprintf(stderr, "plantview serve: %s is read-only: reading it without LMDB's lock file "
                 "(no import may write to it while this server runs)\n", options.store_directory.c_str());
  if (!load_web_files(options.web_directory, s.routes.files))
    std::fprintf(stderr, "plantview serve: no viewer page in %s (the API still works)\n",
                 options.web_directory.c_str());

  // Encoding and object look-ups run on libuv's pool: one thread per core (at least 4), unless
  // the operator chose otherwise. Must be set before the pool first starts.
  if (!std::getenv("UV_THREADPOOL_SIZE"))
    setenv("UV_THREADPOOL_SIZE", std::to_string(std::max(4u, std::thread::hardware_concurrency())).c_str(), 1);
  uv_loop_t loop;
  uv_loop_init(&loop);
  s.loop = &loop;
  uv_async_init(&loop, &s.results_ready, [](uv_async_t* h) {
    auto& self = *static_cast<Server*>(h->data);
    for (auto& r : self.worker.take_results()) self.on_render_done(std::move(r));
  });
  s.results_ready.data = &s;
  if (!s.worker.start(*s.store, {options.vertex_budget_bytes, options.device, options.renderers, options.max_queue},
                      [&s] { uv_async_send(&s.results_ready); }, error))
    return abandon(s, loop);
  std::fprintf(stderr, "plantview serve: rendering on %s\n", s.worker.device_description().c_str());
  s.queue_warm_up();
  // Frames are encoded through the image module: it loads while the server listens. Not earlier:
  // the render thread's EGL initialisation loads its drivers under the same loader lock.
  preload_image_io();
  if (!listen_on(s, error)) return abandon(s, loop);

  uv_signal_init(&loop, &s.sigint);
  uv_signal_init(&loop, &s.sigterm);
  s.sigint.data = s.sigterm.data = &s;
  const auto on_signal = [](uv_signal_t* h, int) { static_cast<Server*>(h->data)->begin_shutdown(); };
  uv_signal_start(&s.sigint, on_signal, SIGINT);
  uv_signal_start(&s.sigterm, on_signal, SIGTERM);
  uv_timer_init(&loop, &s.shutdown_timer);
  s.shutdown_timer.data = &s;
  uv_timer_init(&loop, &s.follow_timer);
  s.follow_timer.data = &s;
  uv_timer_start(
      &s.follow_timer, [](uv_timer_t* t) { static_cast<Server*>(t->data)->follow_commits(); },
      kFollowIntervalMs, kFollowIntervalMs);
  uv_timer_init(&loop, &s.stream_timer);
  s.stream_timer.data = &s;
  std::signal(SIGPIPE, SIG_IGN);

  uv_run(&loop, UV_RUN_DEFAULT);
  uv_loop_close(&loop);
  s.store.reset();
  std::fprintf(stderr, "plantview serve: stopped\n");
  return 0;
}

}  // namespace plantview::service
