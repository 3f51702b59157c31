// Routes: a parsed request in, a decision out. Pure (no sockets, no GL, no store): the token,
// the method, every parameter and its limits are checked here, and the answer is either a
// complete reply or the work to do (a render job, an object look-up, the metrics page).
//
// Rules
//   - Checks in this order: shutting down (503, and the connection closes), the bearer token
//     (401 with WWW-Authenticate), the method (405 with Allow: GET), the query string (400),
//     then the endpoint's own parameters (400 naming the parameter), unknown paths (404).
//   - Every error reply is {"error": "..."} (application/json) naming what was wrong.
//   - Camera parameters are parsed once into a Camera (eye, target and up as 3 numbers each,
//     fov as 1, degrees) and checked with validate_camera; neither eye nor target: the default
//     view (camera.h: default_camera of the config's overview_boxes, else of its bounds).
// Threads: any; route() reads its inputs and nothing else.
#pragma once

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

// What the routes know of the server: fixed once it listens.
struct RouteConfig {
  std::string token;                        // "": no token required
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
struct ObjectLookup {
  uint64_t id = 0;  // not zero
};
struct MetricsPage {};

struct Routed {
  std::string endpoint;  // for the metrics: "frame", "objects", "page", "other", ...
  std::variant<Reply, RenderJob, ObjectLookup, MetricsPage> decision;
};

// `connection_id` names the connection in a render job's latest-wins key when the request has
// no `client` parameter.
Routed route(const Request& request, const RouteConfig& config, bool shutting_down,
             uint64_t connection_id);

// The endpoint name of a path, as the metrics count it.
std::string endpoint_of(std::string_view path);
Reply error_reply(int status, std::string_view message, Fields headers = {}, bool close = false);

}  // namespace plantview::service
