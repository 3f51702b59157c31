// Routes: a parsed request in, a decision out. Pure (no sockets, no GL, no store): the token,
// the method, every parameter and its limits are checked here, and the answer is either a
// complete reply or the work to do (a render job, an object look-up, a measurement, the metrics
// page).
//
// Rules
//   - Checks in this order: shutting down (503, and the connection closes), the bearer token
//     (401 with WWW-Authenticate), the method (405 with Allow: GET), the query string (400),
//     then the endpoint's own parameters (400 naming the parameter), unknown paths (404).
//   - Every error reply is {"error": "..."} (application/json) naming what was wrong.
//   - Camera parameters are parsed once into a Camera (eye, target and up as 3 numbers each,
//     fov as 1, degrees) and checked with validate_camera; neither eye nor target: the default
//     view (camera.h: default_camera of the config's overview_boxes, else of its bounds), and
//     then `up` or `fov` is refused (it would be ignored).
//   - Missing parameters are named as missing (/api/pick without x: "missing 'x'").
//   - View filters, on frame, stats and pick alike (view_filters.h): clip=PX,PY,PZ,NX,NY,NZ
//     (repeatable, at most kMaxClipPlanes; the normal points into the removed side),
//     box=MINX,MINY,MINZ,MAXX,MAXY,MAXZ (kept inside), caps=0|1, colour_by=KEY, hide=W[,W],
//     only=W[,W], highlight=ID|TAG[,...], changes=R1[..R2] (a change image). Their syntax is
//     checked here (400 naming the parameter); whether a colour_by key or a highlight word
//     names anything, or the store can draw a change range, is the render worker's to say
//     (render_worker.h: 400, 404 and 422).
//   - Latest-wins slots: a render job's slot (RenderJob::client) is its connection's, or the one
//     named by `client=ID` where ID is a client id this server issued (issue_client_id: the
//     connection number and a keyed hash of it, so that ids cannot be guessed or forged without
//     the server's key). Any other `client` value (another server's id, a made-up name, the old
//     "connection:N" form) is ignored: the connection's own slot is used. So a client can only
//     name its own slot, or one whose id it was given. Every render answer carries the id of
//     the slot it used (X-Plantview-Client), for the client to send on other connections.
//   - /api/objects/{tag-or-id}: the rest of the path, percent-decoded; all digits: an id (or a
//     name, if no object has that id); anything else a name (tag), as stored, else with the
//     leading '/' plant names carry ("P-101A" finds "/P-101A").
//   - /api/stream: a WebSocket upgrade (docs/stream.md), checked after the shutdown and before
//     the bearer token: GET (405), an upgrade to "websocket" (426 with Upgrade: websocket),
//     Sec-WebSocket-Version 13 (426 with Sec-WebSocket-Version: 13), a valid Sec-WebSocket-Key
//     (400), no query string (400: the token never goes in the URL). The token: a subprotocol
//     plantview.token.<token> (a wrong one: 401) or a matching Authorization header; without
//     either the upgrade is accepted unauthenticated and the stream's first message must carry
//     the token (stream.h). The answer names the subprotocol plantview.v1 when the client
//     offered it, never the token's.
//   - /api/measure?a=&b=: exactly those two, each non-empty and at most 1024 bytes (400 naming
//     the parameter otherwise); each names an object as /api/objects does (measure.h).
// Threads: any; route() reads its inputs and nothing else.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <variant>

#include "plantview/model.h"
#include "server/http.h"
#include "server/render_job.h"
#include "server/request_parser.h"

namespace plantview::service {

struct StaticFile {
  std::string content_type;
  std::string bytes;
};

// The server's secret for client ids: 128 random bits, made once per process.
using ClientKey = std::array<uint64_t, 2>;
// From the operating system's random source (getrandom).
ClientKey random_client_key();
// The client id of a connection's latest-wins slot: 32 hex digits (the connection number, then
// SipHash-2-4 of it under `key`).
std::string issue_client_id(const ClientKey& key, uint64_t connection_id);
// The connection number an id issued under `key` names; false if `id` is not such an id.
bool client_slot_of(const ClientKey& key, std::string_view id, uint64_t& connection_id);

// What the routes know of the server: fixed once it listens.
struct RouteConfig {
  std::string token;                        // "": no token required
  ClientKey client_key{};                   // the server's: random_client_key()
  std::map<std::string, StaticFile> files;  // by path ("/", "/viewer.js", ...)
  std::string model_json;                   // the /api/model answer
  DAabb bounds;                             // the model's
  std::vector<DAabb> overview_boxes;        // what the default view is fitted to (camera.h);
                                            // empty: the bounds
};

// A complete answer (the connection adds Content-Length, Connection and Cache-Control).
struct Reply {
  int status = 200;
  std::string content_type;
  std::string body;
  Fields headers;
  bool close = false;  // the connection closes after it, whatever the request asked
};
// /api/objects/{tag-or-id}: by id when `id` is not zero (then by `name` if no object has the id),
// else by name (`name`, then "/" + name if no object has it and it does not start with '/').
struct ObjectLookup {
  uint64_t id = 0;
  std::string name;  // never empty
};
// /api/measure?a=&b=: the two objects' words (tag or id, as /api/objects reads them).
struct MeasureLookup {
  std::string a, b;  // never empty
};
struct MetricsPage {};
// /api/stream: an upgrade to accept.
struct StreamUpgrade {
  std::string response;        // the complete 101 response
  bool authenticated = false;  // the token came with the upgrade, or none is required
};

struct Routed {
  std::string endpoint;  // for the metrics: "frame", "objects", "page", "other", ...
  std::variant<Reply, RenderJob, ObjectLookup, MetricsPage, MeasureLookup, StreamUpgrade> decision;
};

// `connection_id`: the connection the request came on (its latest-wins slot, unless `client`
// names an issued id).
Routed route(const Request& request, const RouteConfig& config, bool shutting_down,
             uint64_t connection_id);

// The endpoint name of a path, as the metrics count it.
std::string endpoint_of(std::string_view path);
Reply error_reply(int status, std::string_view message, Fields headers = {}, bool close = false);

}  // namespace plantview::service
