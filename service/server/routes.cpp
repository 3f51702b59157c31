// Rules: routes.h.
#include "server/routes.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <cstdio>
#include <optional>
#include <utility>
#include <vector>

#include <sys/random.h>

#include "server/websocket.h"

namespace plantview::service {

namespace {

constexpr uint32_t kMaxSide = 4096;  // pixels, either side of an image the service renders

bool parse_u32(std::string_view text, uint32_t& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return !text.empty() && ec == std::errc() && end == text.data() + text.size();
}

bool parse_double(std::string_view text, double& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return !text.empty() && ec == std::errc() && end == text.data() + text.size() && std::isfinite(out);
}

// --- the camera ---------------------------------------------------------------------------------

// The numbers of one camera field, comma-separated ("+1.5" allowed); false with the message the
// --camera form gives for a bad number.
bool parse_numbers(std::string_view key, std::string_view value, std::vector<double>& out,
                   std::string& error) {
  out.clear();
  for (;;) {
    const size_t comma = std::min(value.find(','), value.size());
    std::string_view token = value.substr(0, comma);
    const std::string_view original = token;
    if (!token.empty() && token.front() == '+') token.remove_prefix(1);
    double v = 0;
    if (!parse_double(token, v)) {
      error = "camera: '" + std::string(key) + "' has a bad number '" + std::string(original) + "'";
      return false;
    }
    out.push_back(v);
    if (comma == value.size()) return true;
    value.remove_prefix(comma + 1);
  }
}

bool to_vector(std::string_view key, const std::vector<double>& values, glm::dvec3& out, std::string& error) {
  if (values.size() != 3) {
    error = "camera: '" + std::string(key) + "' needs 3 numbers, got " + std::to_string(values.size());
    return false;
  }
  out = {values[0], values[1], values[2]};
  return true;
}

struct CameraText {
  std::string_view eye, target;               // empty: not given
  std::optional<std::string_view> up, fov;    // given empty: a bad number
};

// Parses eye, target, up and fov into a Camera and validates it. Bad numbers are reported
// before wrong counts, each in the order eye, target, up, fov.
bool parse_camera_fields(const CameraText& text, Camera& camera, std::string& error) {
  std::vector<double> eye, target, up, fov = {camera.fov_deg};
  if (!parse_numbers("eye", text.eye, eye, error) || !parse_numbers("target", text.target, target, error) ||
      (text.up && !parse_numbers("up", *text.up, up, error)) ||
      (text.fov && !parse_numbers("fov", *text.fov, fov, error)))
    return false;
  if (!to_vector("eye", eye, camera.eye_m, error) || !to_vector("target", target, camera.target_m, error))
    return false;
  if (!text.up) camera.up = default_up(camera.target_m - camera.eye_m);
  else if (!to_vector("up", up, camera.up, error)) return false;
  if (fov.size() != 1) {
    error = "camera: 'fov' needs 1 number";
    return false;
  }
  camera.fov_deg = fov[0];
  return validate_camera(camera, error);
}

// --- client ids ---------------------------------------------------------------------------------

uint64_t rotl(uint64_t x, int b) { return (x << b) | (x >> (64 - b)); }

// SipHash-2-4 (Aumasson and Bernstein) of one 64-bit word under a 128-bit key: a keyed hash
// made for short inputs, so that an id cannot be made without the key.
uint64_t siphash_word(const ClientKey& key, uint64_t word) {
  uint64_t v0 = 0x736f6d6570736575ull ^ key[0], v1 = 0x646f72616e646f6dull ^ key[1];
  uint64_t v2 = 0x6c7967656e657261ull ^ key[0], v3 = 0x7465646279746573ull ^ key[1];
  const auto round = [&] {
    v0 += v1; v1 = rotl(v1, 13); v1 ^= v0; v0 = rotl(v0, 32);
    v2 += v3; v3 = rotl(v3, 16); v3 ^= v2;
    v0 += v3; v3 = rotl(v3, 21); v3 ^= v0;
    v2 += v1; v1 = rotl(v1, 17); v1 ^= v2; v2 = rotl(v2, 32);
  };
  const auto compress = [&](uint64_t m) {
    v3 ^= m;
    round();
    round();
    v0 ^= m;
  };
  compress(word);
  compress(uint64_t(8) << 56);  // the length byte (8) and no tail
  v2 ^= 0xff;
  for (int i = 0; i < 4; ++i) round();
  return v0 ^ v1 ^ v2 ^ v3;
}

bool parse_hex64(std::string_view text, uint64_t& out) {
  if (text.size() != 16) return false;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out, 16);
  return ec == std::errc() && end == text.data() + text.size();
}

// --- percent-decoding of a path segment ----------------------------------------------------------

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// False with a message naming the offset of a bad escape ('+' is a plus sign in a path).
bool percent_decode(std::string_view text, std::string& out, std::string& error) {
  out.clear();
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '%') {
      out += text[i];
      continue;
    }
    const int hi = i + 2 < text.size() ? hex_value(text[i + 1]) : -1;
    const int lo = hi >= 0 ? hex_value(text[i + 2]) : -1;
    if (hi < 0 || lo < 0) {
      error = "bad percent escape at byte " + std::to_string(i) + " of the object's tag";
      return false;
    }
    out += char(hi * 16 + lo);
    i += 2;
  }
  return true;
}

// --- the view's filters: sections, styling and highlight (view_filters.h) ----------------------

bool is_view_filter(std::string_view key) {
  return key == "clip" || key == "box" || key == "caps" || key == "colour_by" || key == "highlight" ||
         key == "hide" || key == "only" || key == "changes";
}

// One of is_view_filter's parameters into the job; false with a message naming the parameter.
bool parse_view_filter(std::string_view key, const std::string& value, RenderJob& job, std::string& error) {
  const std::string what = "'" + std::string(key) + "'";
  if (key == "clip") {
    if (job.section.planes.size() == kMaxClipPlanes) {
      error = what + ": at most " + std::to_string(kMaxClipPlanes) + " clip planes";
      return false;
    }
    ClipPlane plane;
    if (!parse_clip_plane(value, what, plane, error)) return false;
    job.section.planes.push_back(plane);
  } else if (key == "box") {
    if (!parse_section_box(value, what, job.section.box, error)) return false;
    job.section.has_box = true;
  } else if (key == "caps") {
    if (value != "0" && value != "1") {
      error = what + " must be 0 (cut solids open) or 1 (capped), got '" + value.substr(0, 32) + "'";
      return false;
    }
    job.section.capped = value == "1";
  } else if (key == "colour_by") {
    job.style.colour_by = value;  // "" the model's colours; an unknown key is the renderer's 400
  } else if (key == "hide") {
    return parse_word_list(value, what, job.style.hide, error);
  } else if (key == "only") {
    return parse_word_list(value, what, job.style.only, error);
  } else if (key == "highlight") {
    return parse_word_list(value, what, job.highlight, error);
  } else if (key == "changes") {
    ChangeRange range;
    if (!parse_change_range(value.substr(0, 64), range, error)) {
      error = what + ": " + error;
      return false;
    }
    job.changes = range;
  }
  return true;
}

// --- the view: camera, size and LOD shared by frame, stats and pick -----------------------------

bool parse_view(const RouteConfig& config, const Fields& query, std::initializer_list<std::string_view> allowed,
                uint64_t connection_id, RenderJob& job, std::string& error) {
  static constexpr std::string_view common[] = {"eye", "target", "up", "fov", "w", "h", "lod", "px", "client",
                                                "clip", "box", "caps", "colour_by", "highlight", "hide", "only",
                                                "changes"};
  CameraText camera;
  uint64_t slot = connection_id;
  job.width = 1280;
  job.height = 720;
  for (const auto& [key, value] : query) {
    if (std::find(std::begin(common), std::end(common), key) == std::end(common) &&
        std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      error = "unknown parameter '" + key + "'";
      return false;
    }
    if (key == "eye") camera.eye = value;
    else if (key == "target") camera.target = value;
    else if (key == "up") camera.up = value;
    else if (key == "fov") camera.fov = value;
    else if (key == "client") client_slot_of(config.client_key, value, slot);  // else: its own
    else if (is_view_filter(key)) {
      if (!parse_view_filter(key, value, job, error)) return false;
    }
    else if (key == "w" || key == "h") {
      uint32_t v = 0;
      if (!parse_u32(value, v) || v == 0 || v > kMaxSide) {
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
  job.client = "connection:" + std::to_string(slot);
  job.client_id = issue_client_id(config.client_key, slot);
  // A query field given empty counts as absent (as the --camera text it once became did).
  if (camera.eye.empty() != camera.target.empty()) {
    error = "give both 'eye' and 'target', or neither (the default view)";
    return false;
  }
  if (camera.eye.empty() && (camera.up || camera.fov)) {
    error = std::string(camera.up ? "'up'" : "'fov'") +
            " needs 'eye' and 'target': without them the view is the default one, which has its own";
    return false;
  }
  if (camera.eye.empty()) {
    const double aspect = double(job.width) / job.height;
    job.camera = config.overview_boxes.empty() ? default_camera(config.bounds, aspect)
                                               : default_camera(config.overview_boxes, aspect);
    return true;
  }
  job.camera = Camera{};
  return parse_camera_fields(camera, job.camera, error);
}

bool parse_frame(const Fields& query, RenderJob& job, std::string& error) {
  for (const auto& [key, value] : query) {
    if (key == "mode") {
      if (value == "interactive") job.mode = FrameMode::interactive;
      else if (value == "still") job.mode = FrameMode::still;
      else {
        error = "'mode' must be interactive or still";
        return false;
      }
    }
    if (key == "format" && !image_format_from_name(value, job.format)) {
      error = "'format' must be jpeg or png";
      return false;
    }
    if (key == "quality") {
      uint32_t quality = 0;
      if (!parse_u32(value, quality) || quality < 1 || quality > 100) {
        error = "'quality' must be 1..100";
        return false;
      }
      job.quality = int(quality);
    }
  }
  return true;
}

bool parse_pick(const Fields& query, RenderJob& job, std::string& error) {
  bool have_x = false, have_y = false;
  for (const auto& [key, value] : query) {
    if (key != "x" && key != "y") continue;
    uint32_t v = 0;
    if (!parse_u32(value, v)) {
      error = "'" + key + "' must be a pixel position";
      return false;
    }
    (key == "x" ? job.x : job.y) = v;
    (key == "x" ? have_x : have_y) = true;
  }
  if (!have_x || !have_y) {
    error = !have_x ? "missing 'x' (the pixel column to pick, 0 at the left)"
                    : "missing 'y' (the pixel row to pick, 0 at the top)";
    return false;
  }
  if (job.x >= job.width || job.y >= job.height) {
    error = "'x' and 'y' must lie inside the w x h image (" + std::to_string(job.width) + "x" +
            std::to_string(job.height) + "), got " + std::to_string(job.x) + "," + std::to_string(job.y);
    return false;
  }
  return true;
}

// The render endpoints: a job, or the 400 (or 404) that says why not.
std::variant<Reply, RenderJob> route_render(const Request& request, const RouteConfig& config,
                                            uint64_t connection_id) {
  RenderJob job;
  std::string error;
  const std::string& path = request.path;
  if (path == "/api/frame") {
    job.kind = RenderJob::Kind::frame;
    if (!parse_view(config, request.query, {"format", "quality", "mode"}, connection_id, job, error) ||
        !parse_frame(request.query, job, error))
      return error_reply(400, error);
  } else if (path == "/api/stats") {
    job.kind = RenderJob::Kind::stats;
    if (!parse_view(config, request.query, {}, connection_id, job, error)) return error_reply(400, error);
  } else if (path == "/api/pick") {
    job.kind = RenderJob::Kind::pick;
    if (!parse_view(config, request.query, {"x", "y"}, connection_id, job, error) ||
        !parse_pick(request.query, job, error))
      return error_reply(400, error);
  } else {
    return error_reply(404, "no such resource: " + path.substr(0, 128));
  }
  return job;
}

// /api/objects/{tag-or-id}: the rest of the path names the object.
std::variant<Reply, ObjectLookup> route_object(std::string_view rest, bool no_parameters) {
  constexpr size_t kMaxTagBytes = 1024;
  ObjectLookup lookup;
  std::string error;
  if (rest.empty()) return error_reply(400, "missing the object's tag or id: /api/objects/{tag-or-id}");
  if (rest.size() > 3 * kMaxTagBytes) return error_reply(400, "an object's tag is at most 1024 bytes");
  if (!percent_decode(rest, lookup.name, error)) return error_reply(400, error);
  if (lookup.name.size() > kMaxTagBytes) return error_reply(400, "an object's tag is at most 1024 bytes");
  if (!no_parameters) return error_reply(400, "/api/objects takes no parameters");
  uint64_t id = 0;
  const auto [end, ec] = std::from_chars(lookup.name.data(), lookup.name.data() + lookup.name.size(), id);
  if (ec == std::errc() && end == lookup.name.data() + lookup.name.size()) lookup.id = id;
  return lookup;
}

// /api/measure?a=TAG|ID&b=TAG|ID: both named once, nothing else.
std::variant<Reply, MeasureLookup> route_measure(const Fields& query) {
  constexpr size_t kMaxTagBytes = 1024;
  MeasureLookup lookup;
  bool have_a = false, have_b = false;
  for (const auto& [name, value] : query) {
    if (name != "a" && name != "b") return error_reply(400, "/api/measure takes only 'a' and 'b', not '" + name.substr(0, 64) + "'");
    bool& have = name == "a" ? have_a : have_b;
    if (have) return error_reply(400, "'" + name + "' given twice");
    if (value.empty()) return error_reply(400, "'" + name + "' is empty: give an object's tag or id");
    if (value.size() > kMaxTagBytes) return error_reply(400, "an object's tag is at most 1024 bytes");
    have = true;
    (name == "a" ? lookup.a : lookup.b) = value;
  }
  if (!have_a) return error_reply(400, "missing 'a' (an object's tag or id)");
  if (!have_b) return error_reply(400, "missing 'b' (an object's tag or id)");
  return lookup;
}

// Compares in constant time over the expected length.
bool token_matches(std::string_view authorization, const std::string& token) {
  const std::string expected = "Bearer " + token;
  unsigned diff = unsigned(authorization.size() ^ expected.size());
  for (size_t i = 0; i < expected.size(); ++i)
    diff |= unsigned(uint8_t(expected[i]) ^ uint8_t(i < authorization.size() ? authorization[i] : 0));
  return diff == 0;
}

bool contains_word(std::string_view list, std::string_view word) {
  size_t at = 0;
  while (at <= list.size()) {
    size_t end = std::min(list.find(',', at), list.size());
    std::string_view item = list.substr(at, end - at);
    while (!item.empty() && (item.front() == ' ' || item.front() == '\t')) item.remove_prefix(1);
    while (!item.empty() && (item.back() == ' ' || item.back() == '\t')) item.remove_suffix(1);
    if (item.size() == word.size() &&
        std::equal(item.begin(), item.end(), word.begin(), [](char a, char b) { return std::tolower(a) == std::tolower(b); }))
      return true;
    at = end + 1;
  }
  return false;
}

// /api/stream: the WebSocket handshake (routes.h).
std::variant<Reply, StreamUpgrade> route_stream(const Request& request, const RouteConfig& config) {
  if (request.method != "GET") return error_reply(405, "only GET is served", {{"Allow", "GET"}});
  if (!request.upgrade || !contains_word(request.upgrade_to, "websocket"))
    return error_reply(426, "/api/stream is a WebSocket: upgrade to it", {{"Upgrade", "websocket"}}, true);
  if (request.websocket_version != "13")
    return error_reply(426, "Sec-WebSocket-Version must be 13", {{"Sec-WebSocket-Version", "13"}}, true);
  if (!ws::valid_client_key(request.websocket_key))
    return error_reply(400, "Sec-WebSocket-Key must be base64 of 16 bytes", {}, true);
  if (!request.query.empty() || !request.query_error.empty())
    return error_reply(400, "/api/stream takes no parameters (the token goes in a subprotocol or the hello message)", {}, true);
  StreamUpgrade upgrade;
  upgrade.authenticated = config.token.empty() || token_matches(request.authorization, config.token);
  std::string_view protocols = request.websocket_protocols;
  bool v1 = false;
  while (!protocols.empty()) {
    const size_t comma = std::min(protocols.find(','), protocols.size());
    std::string_view item = protocols.substr(0, comma);
    protocols.remove_prefix(std::min(comma + 1, protocols.size()));
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    if (item == "plantview.v1") v1 = true;
    constexpr std::string_view kToken = "plantview.token.";
    if (item.substr(0, kToken.size()) == kToken && !config.token.empty()) {
      if (!token_matches("Bearer " + std::string(item.substr(kToken.size())), config.token))
        return error_reply(401, "the token in the plantview.token subprotocol is wrong", {}, true);
      upgrade.authenticated = true;
    }
  }
  upgrade.response = "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Accept: " + ws::accept_key(request.websocket_key) + "\r\n";
  if (v1) upgrade.response += "Sec-WebSocket-Protocol: plantview.v1\r\n";
  upgrade.response += "\r\n";
  return upgrade;
}

Reply ok(std::string content_type, std::string body) {
  Reply r;
  r.content_type = std::move(content_type);
  r.body = std::move(body);
  return r;
}

}  // namespace

std::string endpoint_of(std::string_view path) {
  // A fixed set: a label value never comes from the client's bytes (a quote or a newline in it
  // would break every scrape) and unknown paths add no series.
  static constexpr std::pair<std::string_view, std::string_view> kEndpoints[] = {
      {"/", "page"},           {"/index.html", "page"},    {"/viewer.js", "viewer.js"},
      {"/viewer.css", "viewer.css"}, {"/api/model", "model"}, {"/api/frame", "frame"},
      {"/api/stats", "stats"}, {"/api/pick", "pick"},      {"/metrics", "metrics"},
      {"/api/measure", "measure"}, {"/api/stream", "stream"}};
  if (path.rfind("/api/objects/", 0) == 0) return "objects";
  for (const auto& [known, name] : kEndpoints)
    if (path == known) return std::string(name);
  return "other";
}

ClientKey random_client_key() {
  ClientKey key{};
  // getrandom blocks only until the system's pool is first seeded (boot), and reads of up to
  // 256 bytes are not interrupted.
  size_t got = 0;
  auto* bytes = reinterpret_cast<char*>(key.data());
  while (got < sizeof key) {
    const ssize_t n = getrandom(bytes + got, sizeof key - got, 0);
    if (n > 0) got += size_t(n);
  }
  return key;
}

std::string issue_client_id(const ClientKey& key, uint64_t connection_id) {
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(connection_id),
                static_cast<unsigned long long>(siphash_word(key, connection_id)));
  return text;
}

bool client_slot_of(const ClientKey& key, std::string_view id, uint64_t& connection_id) {
  uint64_t number = 0, tag = 0;
  if (id.size() != 32 || !parse_hex64(id.substr(0, 16), number) || !parse_hex64(id.substr(16), tag)) return false;
  // One comparison of two words: its time says nothing of how much of a guess was right.
  if (siphash_word(key, number) != tag) return false;
  connection_id = number;
  return true;
}

Reply error_reply(int status, std::string_view message, Fields headers, bool close) {
  Reply r;
  r.status = status;
  r.content_type = "application/json";
  r.body = error_body(message);
  r.headers = std::move(headers);
  r.close = close;
  return r;
}

Routed route(const Request& request, const RouteConfig& config, bool shutting_down,
             uint64_t connection_id) {
  Routed out{endpoint_of(request.path), Reply{}};
  auto& decision = out.decision;
  const std::string& path = request.path;
  const bool no_parameters = request.query.empty();
  // The viewer page's own files hold no plant data: a browser opens them without the token
  // (it cannot send one on navigation) and sends it with every API request (web/viewer.js).
  const auto page_file = config.files.find(path);
  const bool page = page_file != config.files.end() && request.method == "GET";
  if (shutting_down) {
    decision = error_reply(503, "the server is shutting down", {}, true);
  } else if (path == "/api/stream") {
    std::visit([&](auto&& d) { decision = std::move(d); }, route_stream(request, config));
  } else if (!page && !config.token.empty() && !token_matches(request.authorization, config.token)) {
    decision = error_reply(401, "a valid 'Authorization: Bearer' token is required", {{"WWW-Authenticate", "Bearer"}});
  } else if (request.method != "GET") {
    decision = error_reply(405, "only GET is served", {{"Allow", "GET"}});
  } else if (!request.query_error.empty()) {
    decision = error_reply(400, request.query_error);
  } else if (page) {
    decision = no_parameters ? ok(page_file->second.content_type, page_file->second.bytes)
                             : error_reply(400, "the page takes no parameters");
  } else if (path == "/api/model") {
    decision = no_parameters ? ok("application/json", config.model_json)
                             : error_reply(400, "/api/model takes no parameters");
  } else if (path == "/metrics") {
    decision = MetricsPage{};
  } else if (path == "/api/measure") {
    std::visit([&](auto&& d) { decision = std::move(d); }, route_measure(request.query));
  } else if (path.rfind("/api/objects/", 0) == 0) {
    std::visit([&](auto&& d) { decision = std::move(d); }, route_object(std::string_view(path).substr(13), no_parameters));
  } else {
    std::visit([&](auto&& d) { decision = std::move(d); }, route_render(request, config, connection_id));
  }
  return out;
}

}  // namespace plantview::service
