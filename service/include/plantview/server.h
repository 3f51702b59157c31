// plantview/server.h: the plantview HTTP service: frames, LOD statistics, picking and object attributes of one
// store over HTTP/1.1, and the browser viewer page from web/.
//
// Threads
//   - The loop thread (libuv) accepts connections, parses requests (http-parser), answers what
//     needs no rendering or storage, and writes responses. It never blocks on rendering,
//     storage or encoding.
//   - N render threads (`renderers`), each with its own EGL context, renderer and vertex
//     arena: frames, statistics and picks run there, one per renderer at a time, taken
//     round-robin across clients, and come back to the loop through a uv_async handle.
//   - Object look-ups run on libuv's thread pool, each with its own read view of the store.
//
// Following imports: an import or generate into the served store is served within a second of
// its commit (typically tens of milliseconds), no request failing meanwhile. Each renderer
// moves to the newest commit between jobs (idle ones within 100 ms), so a frame, its statistics
// and its pick read one commit and no old read transaction keeps the data file growing; look-ups
// read a view begun for the request; /api/model is described again after each commit. Every
// API answer carries X-Plantview-Revision (the revision its data came from). An import that
// fails or is killed never committed: nothing served changes. A store opened without its lock
// file (read-only copies, store.h) must not be written while it is served.
//
// Queueing rules
//   - A client (its connection, or the slot an id the server issued names: `client=` with the
//     X-Plantview-Client header of an earlier answer) has at most one render request of each
//     kind (frame, stats, pick) waiting: a newer one replaces it, and the older is answered 409
//     (superseded). A client cannot name another's slot.
//   - Under load (more requests than renderers) interactive frames (mode=interactive) are
//     rendered cheaper: a coarser pixel error, then a lower resolution, JPEG quality 60 at most;
//     stills (mode=still, the default) never are. X-Plantview-* headers say what was used.
//   - At most `max_queue` render requests wait; past that the answer is 503 with Retry-After.
//   - Responses on a connection go out in request order (pipelining). A connection whose
//     unsent output exceeds a limit stops being read until the client catches up, so a slow
//     reader cannot make the server buffer without bound.
//
// Limits (each answered with a JSON error {"error": "..."} and the status in parentheses):
// header bytes (431), body bytes (413), a request not complete within the request timeout
// (408), connections refused at accept (503, below), malformed HTTP (400), bad, non-finite or
// unknown parameters (400), images over 4096x4096 (400), unknown objects (404), methods other
// than GET (405), a missing or wrong bearer token (401).
//
// Hostile clients: every connection must send its first complete request within the request
// timeout of being accepted (else it is closed), and must take some of the bytes owed to it
// within the write timeout while any wait (else it is closed); what it may leave unsent is
// capped (max_unsent_bytes). At accept a connection is refused (503, Retry-After) beyond
// max_clients open connections, beyond max_clients_per_address from one IP address, and, for
// an address that has not completed a request yet (one refused for its token does not count),
// beyond max_clients - reserved_clients: the reserved share stays for clients already served,
// so that connections that never send a byte cannot lock out those who do. Behind a load
// balancer every connection comes from the balancer's address: give max_clients_per_address
// room for its connections.
//
// Health (answered before the token check and routing, GET only, no parameters):
//   /healthz  200 while the process runs its loop (liveness);
//   /readyz   200 once the store is open and the renderer has drawn a first frame, 503 before
//             that and while draining (readiness: a load balancer sends frames only when 200).
//
// Shutdown (drain): SIGINT or SIGTERM closes the listener (new connections are refused by the
// kernel, so a balancer retries them elsewhere) and stops reading; every request already read
// is answered, the last answer of each connection with "Connection: close"; then the render
// thread stops, the store is closed and run_server returns 0. Connections still open
// shutdown_timeout_ms after the signal (a client that does not read) are closed.
//
// This is the module's only public header. Inside (service/server/, private): the request
// parser (bytes to requests, pure), routes (a request to a response or a job, pure), metrics,
// connections (libuv), the render worker, frame encoding and the loop that joins them.
#pragma once

#include <cstdint>
#include <string>

namespace plantview::service {

struct ServerOptions {
  std::string store_directory;
  std::string web_directory;           // where index.html, viewer.js and viewer.css are
  std::string host = "127.0.0.1";
  uint16_t port = 8080;                // 0: any free port (printed when listening)
  uint64_t vertex_budget_bytes = 512ull << 20;  // per renderer
  uint32_t max_clients = 64;           // open connections
  uint32_t max_queue = 64;             // render requests waiting
  std::string token;                   // required (as a Bearer token) unless on loopback
  int device = -1;                     // EGL device, as GpuContext::create takes it
  uint32_t renderers = 0;              // render threads, each with its own context and vertex
                                       // arena; 0: one per EGL device on hardware, on a software
                                       // renderer as the cores allow (server/render_worker.h)
  uint32_t request_timeout_ms = 10000; // from a request's first byte to its last
  uint32_t idle_timeout_ms = 120000;   // a keep-alive connection with nothing to do
  uint32_t max_header_bytes = 16384;
  uint32_t max_body_bytes = 65536;
  uint64_t max_unsent_bytes = 32ull << 20;  // per connection, before it stops being read
  uint32_t write_timeout_ms = 30000;   // bytes owed and none taken by the client for this long
  uint32_t shutdown_timeout_ms = 30000;  // after SIGTERM, connections still open are closed
  uint32_t max_clients_per_address = 32; // open connections from one IP address
  uint32_t reserved_clients = 16;      // of max_clients, kept for addresses already served
  uint32_t stream_ping_ms = 15000;     // /api/stream: a ping this often; a stream that sends
                                       // nothing (not even a pong) for 3 times it is closed (1001)
};

// Runs the service until SIGINT or SIGTERM. Prints "listening on http://HOST:PORT/" on stdout
// once it accepts connections. Returns 0 after a clean shutdown; 1 with `error` set when it
// could not start (store, GPU, address).
int run_server(const ServerOptions& options, std::string& error);

}  // namespace plantview::service
