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
//   - Shutdown: stop accepting and reading; answer what was read; close connections as they
//     finish, or all of them at the shutdown deadline; once no connection, pool work or render
//     job is left, stop the render thread and close the handles, so that uv_run returns and the
//     store closes.
#include "plantview/server.h"

#include <arpa/inet.h>
#include <uv.h>

#include <algorithm>
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

namespace plantview::service {

namespace {

constexpr size_t kMaxServedAddresses = 16384;

struct Ticket {
  Connection* connection = nullptr;  // null once the connection has closed
  std::shared_ptr<Pending> pending;
  RenderJob::Kind kind = RenderJob::Kind::frame;  // render tickets: for the metrics
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
  }
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
    gauges.ready = ready && !stopping;
    c.answer(p, text_reply("text/plain; version=0.0.4", metrics_text(metrics, gauges)), false);
  } else if (auto* lookup = std::get_if<ObjectLookup>(&routed.decision)) {
    look_up_object(c, p, std::move(*lookup));
  } else if (auto* pair = std::get_if<MeasureLookup>(&routed.decision)) {
    measure(c, p, std::move(*pair));
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

// --- shutdown -----------------------------------------------------------------------------------

void Server::begin_shutdown() {
  if (stopping) return;
  stopping = true;
  uv_timer_stop(&follow_timer);
  shutdown_started_ms = uv_now(loop);
  std::fprintf(stderr, "plantview serve: shutting down (finishing %zu requests)\n", tickets.size());
  uv_close(reinterpret_cast<uv_handle_t*>(&listener), nullptr);
  for (Connection* c : connections) c->stop_reading();
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
  std::signal(SIGPIPE, SIG_IGN);

  uv_run(&loop, UV_RUN_DEFAULT);
  uv_loop_close(&loop);
  s.store.reset();
  std::fprintf(stderr, "plantview serve: stopped\n");
  return 0;
}

}  // namespace plantview::service
