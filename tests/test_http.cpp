// The service's parts without a server: the request parser (every truncation and every split of
// valid input, limits, malformed input), routes (token, method, parameters, the typed camera,
// the decisions), the metrics text, and the render worker on whatever EGL offers.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <variant>

#include <nlohmann/json.hpp>

#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/box_row.h"
#include "server/metrics.h"
#include "server/objects_json.h"
#include "server/render_worker.h"
#include "server/request_parser.h"
#include "server/routes.h"
#include "support/temp_dir.h"

namespace plantview::service {
namespace {

namespace fs = std::filesystem;

// --- the request parser -------------------------------------------------------------------------

// Feeds `bytes` in pieces cut at `cuts` (ascending offsets); collects the requests, and the
// error if one ends the input.
struct Parsed {
  std::vector<Request> requests;
  std::optional<RequestError> error;
  bool in_request = false;  // at the end
};

Parsed parse_in_pieces(std::string_view bytes, const std::vector<size_t>& cuts, RequestLimits limits = {}) {
  RequestParser parser(limits);
  Parsed out;
  size_t from = 0;
  std::vector<size_t> ends = cuts;
  ends.push_back(bytes.size());
  for (const size_t end : ends) {
    std::string_view piece = bytes.substr(from, end - from);
    from = end;
    while (!piece.empty()) {
      size_t used = 0;
      const auto result = parser.feed(piece, used);
      EXPECT_LE(used, piece.size());
      if (result == RequestParser::Result::error) {
        out.error = parser.error();
        return out;
      }
      piece.remove_prefix(used);
      if (result == RequestParser::Result::request) {
        out.requests.push_back(std::move(parser.request()));
        if (!out.requests.back().keep_alive) return out;  // a connection reads no further
      } else {
        EXPECT_TRUE(piece.empty());
      }
    }
  }
  out.in_request = parser.in_request();
  return out;
}

Parsed parse_whole(std::string_view bytes, RequestLimits limits = {}) { return parse_in_pieces(bytes, {}, limits); }

const std::string kGet =
    "GET /api/frame?w=64&h=32&eye=1%2C2%2C3&target=0,0,0&client=a+b HTTP/1.1\r\n"
    "Host: t\r\nauthorization: Bearer s3cret\r\nX-Other: 1\r\n\r\n";
const std::string kPostWithBody = "POST /api/model HTTP/1.1\r\nHost: t\r\nContent-Length: 5\r\n\r\nhello";
const std::string kChunked =
    "GET /metrics HTTP/1.1\r\nHost: t\r\nTransfer-Encoding: chunked\r\n\r\n3\r\nabc\r\n0\r\n\r\n";
const std::string kClose = "GET /api/model HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n";

TEST(RequestParser, AValidRequestGivesMethodPathDecodedQueryAndTheAuthorizationHeader) {
  const Parsed p = parse_whole(kGet);
  ASSERT_FALSE(p.error);
  ASSERT_EQ(p.requests.size(), 1u);
  const Request& r = p.requests[0];
  EXPECT_EQ(r.method, "GET");
  EXPECT_EQ(r.path, "/api/frame");
  const Fields expected = {{"w", "64"}, {"h", "32"}, {"eye", "1,2,3"}, {"target", "0,0,0"}, {"client", "a b"}};
  EXPECT_EQ(r.query, expected);
  EXPECT_TRUE(r.query_error.empty());
  EXPECT_EQ(r.authorization, "Bearer s3cret");
  EXPECT_TRUE(r.keep_alive);
  EXPECT_FALSE(p.in_request);
}

TEST(RequestParser, ConnectionCloseAndHttp10WithoutKeepAliveEndTheConnection) {
  EXPECT_FALSE(parse_whole(kClose).requests.at(0).keep_alive);
  EXPECT_FALSE(parse_whole("GET / HTTP/1.0\r\n\r\n").requests.at(0).keep_alive);
  EXPECT_TRUE(parse_whole("GET / HTTP/1.0\r\nConnection: keep-alive\r\n\r\n").requests.at(0).keep_alive);
}

TEST(RequestParser, EveryTruncationOfAValidRequestWaitsForMore) {
  for (const std::string& valid : {kGet, kPostWithBody, kChunked, kClose}) {
    for (size_t n = 1; n < valid.size(); ++n) {
      const Parsed p = parse_whole(std::string_view(valid).substr(0, n));
      ASSERT_FALSE(p.error) << n << " bytes of " << valid << ": " << p.error->message;
      ASSERT_TRUE(p.requests.empty()) << n << " bytes of " << valid;
      EXPECT_TRUE(p.in_request) << n << " bytes of " << valid;
    }
    EXPECT_EQ(parse_whole(valid).requests.size(), 1u) << valid;
  }
}

TEST(RequestParser, PipelinedRequestsSplitAtEveryByteParseAsTheWhole) {
  const std::string stream = kGet + kPostWithBody + kChunked + kGet + kClose + kGet;
  const Parsed whole = parse_whole(stream);
  ASSERT_FALSE(whole.error);
  ASSERT_EQ(whole.requests.size(), 5u);  // nothing after Connection: close
  EXPECT_EQ(whole.requests[1].method, "POST");
  EXPECT_EQ(whole.requests[2].path, "/metrics");
  EXPECT_FALSE(whole.requests[4].keep_alive);
  for (size_t cut = 1; cut < stream.size(); ++cut) {
    const Parsed split = parse_in_pieces(stream, {cut});
    ASSERT_FALSE(split.error) << "cut at " << cut;
    ASSERT_EQ(split.requests.size(), whole.requests.size()) << "cut at " << cut;
    for (size_t i = 0; i < whole.requests.size(); ++i) {
      EXPECT_EQ(split.requests[i].path, whole.requests[i].path) << "cut at " << cut;
      EXPECT_EQ(split.requests[i].query, whole.requests[i].query) << "cut at " << cut;
      EXPECT_EQ(split.requests[i].authorization, whole.requests[i].authorization) << "cut at " << cut;
    }
  }
  // And one byte at a time.
  std::vector<size_t> every;
  for (size_t i = 1; i < stream.size(); ++i) every.push_back(i);
  EXPECT_EQ(parse_in_pieces(stream, every).requests.size(), whole.requests.size());
}

TEST(RequestParser, HeadersOverTheLimitAre431) {
  const RequestLimits limits{1000, 100};
  const Parsed big_header = parse_whole("GET / HTTP/1.1\r\nX-Big: " + std::string(2000, 'a') + "\r\n\r\n", limits);
  ASSERT_TRUE(big_header.error);
  EXPECT_EQ(big_header.error->status, 431);
  EXPECT_EQ(big_header.error->message, "request headers larger than 1000 bytes");
  const Parsed big_url = parse_whole("GET /" + std::string(2000, 'u') + " HTTP/1.1\r\n\r\n", limits);
  ASSERT_TRUE(big_url.error);
  EXPECT_EQ(big_url.error->status, 431);
  // The limit counts the head as sent: 1000 bytes are fine, 1001 are not, whole or in pieces.
  const std::string at_limit = "GET / HTTP/1.1\r\nX: " + std::string(977, 'a') + "\r\n\r\n";
  ASSERT_EQ(at_limit.size(), 1000u);
  EXPECT_FALSE(parse_whole(at_limit, limits).error);
  EXPECT_FALSE(parse_in_pieces(at_limit, {1000 - 3}, limits).error);
  const std::string over_limit = "GET / HTTP/1.1\r\nX: " + std::string(978, 'a') + "\r\n\r\n";
  ASSERT_TRUE(parse_whole(over_limit, limits).error);
  EXPECT_EQ(parse_whole(over_limit, limits).error->status, 431);
  // A malformed byte past the limit is still 431, however the bytes arrive (the first problem in
  // byte order decides); one within the limit is 400.
  const std::string bad_late = "GET / HTTP/1.1\r\nX: " + std::string(1200, 'a') + "\x01\r\n\r\n";
  const std::string bad_early = "GET / HTTP/1.1\r\nX: a\x01" + std::string(1200, 'a') + "\r\n\r\n";
  for (size_t cut : {size_t(0), size_t(7), size_t(500), size_t(999), size_t(1001)}) {
    const Parsed late = cut == 0 ? parse_whole(bad_late, limits) : parse_in_pieces(bad_late, {cut}, limits);
    ASSERT_TRUE(late.error) << "cut at " << cut;
    EXPECT_EQ(late.error->status, 431) << "cut at " << cut;
    const Parsed early = cut == 0 ? parse_whole(bad_early, limits) : parse_in_pieces(bad_early, {cut}, limits);
    ASSERT_TRUE(early.error) << "cut at " << cut;
    EXPECT_EQ(early.error->status, 400) << "cut at " << cut;
  }
  // Many small headers add up.
  std::string many = "GET / HTTP/1.1\r\n";
  for (int i = 0; i < 200; ++i) many += "X-H" + std::to_string(i) + ": v\r\n";
  const Parsed many_headers = parse_whole(many + "\r\n", limits);
  ASSERT_TRUE(many_headers.error);
  EXPECT_EQ(many_headers.error->status, 431);
}

TEST(RequestParser, BodiesOverTheLimitAre413DeclaredOrChunked) {
  const RequestLimits limits{1000, 100};
  const Parsed declared = parse_whole("GET / HTTP/1.1\r\nContent-Length: 101\r\n\r\n", limits);
  ASSERT_TRUE(declared.error);
  EXPECT_EQ(declared.error->status, 413);
  EXPECT_EQ(declared.error->message, "request body larger than 100 bytes");
  const std::string chunk = std::string(60, 'b');
  const Parsed chunked = parse_whole("GET / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n3c\r\n" + chunk +
                                         "\r\n3c\r\n" + chunk + "\r\n0\r\n\r\n",
                                     limits);
  ASSERT_TRUE(chunked.error);
  EXPECT_EQ(chunked.error->status, 413);
  EXPECT_FALSE(parse_whole("GET / HTTP/1.1\r\nContent-Length: 100\r\n\r\n" + std::string(100, 'x'), limits).error);
}

TEST(RequestParser, ABadPercentEscapeCompletesTheRequestWithAQueryError) {
  for (const std::string target : {"/api/frame?w=%zz", "/api/frame?w=%4", "/api/frame?%=1"}) {
    const Parsed p = parse_whole("GET " + target + " HTTP/1.1\r\n\r\n");
    ASSERT_EQ(p.requests.size(), 1u) << target;
    EXPECT_NE(p.requests[0].query_error.find("bad percent escape"), std::string::npos) << target;
    EXPECT_TRUE(p.requests[0].query.empty()) << target;
  }
  EXPECT_NE(parse_whole("GET /a?w=1&w=2 HTTP/1.1\r\n\r\n").requests.at(0).query_error.find("twice"), std::string::npos);
  EXPECT_NE(parse_whole("GET /a?=2 HTTP/1.1\r\n\r\n").requests.at(0).query_error.find("no name"), std::string::npos);
}

TEST(RequestParser, MalformedRequestsAre400NamingHttpParsersReason) {
  for (const std::string bad : {"THIS IS NOT HTTP\r\n\r\n", "FETCH / HTTP/1.1\r\n\r\n", "GET / HTTP/9.x\r\n\r\n",
                                "GET / HTTP/1.1\r\nBad Header\r\n\r\n",
                                "GET / HTTP/1.1\r\nContent-Length: x\r\n\r\n"}) {
    const Parsed p = parse_whole(bad);
    ASSERT_TRUE(p.error) << bad;
    EXPECT_EQ(p.error->status, 400) << bad;
    EXPECT_EQ(p.error->message.rfind("malformed HTTP: ", 0), 0u) << p.error->message;
    EXPECT_GT(p.error->message.size(), 16u);
  }
}

// --- routes -------------------------------------------------------------------------------------

Request get(const std::string& target, std::string authorization = "") {
  Parsed p = parse_whole("GET " + target + " HTTP/1.1\r\nHost: t\r\n" +
                         (authorization.empty() ? "" : "Authorization: " + authorization + "\r\n") + "\r\n");
  EXPECT_EQ(p.requests.size(), 1u) << target;
  return p.requests.empty() ? Request{} : p.requests[0];
}

RouteConfig config() {
  RouteConfig c;
  c.client_key = {0x0123456789abcdefull, 0xfedcba9876543210ull};
  c.model_json = "{\"objects\":6}\n";
  c.bounds = {{-1, -1, -1}, {16, 1, 1}};
  c.files["/"] = {"text/html; charset=utf-8", "<html></html>"};
  return c;
}

Reply reply_of(const Routed& r) {
  const Reply* reply = std::get_if<Reply>(&r.decision);
  EXPECT_TRUE(reply) << "not a reply (endpoint " << r.endpoint << ")";
  return reply ? *reply : Reply{};
}

// The error message of a 400 (or other error) reply.
std::string error_of(const Routed& r, int status) {
  const Reply reply = reply_of(r);
  EXPECT_EQ(reply.status, status) << reply.body;
  EXPECT_EQ(reply.content_type, "application/json");
  return reply.body;
}

RenderJob job_of(const Routed& r) {
  const RenderJob* job = std::get_if<RenderJob>(&r.decision);
  EXPECT_TRUE(job) << (std::holds_alternative<Reply>(r.decision) ? std::get<Reply>(r.decision).body : "");
  return job ? *job : RenderJob{};
}

TEST(Routes, TheTokenIsCheckedBeforeAnythingButShutdownAndTheViewerPage) {
  RouteConfig c = config();
  c.token = "s3cret";
  const Reply none = reply_of(route(get("/api/model"), c, false, 1));
  EXPECT_EQ(none.status, 401);
  EXPECT_EQ(none.headers, (Fields{{"WWW-Authenticate", "Bearer"}}));
  EXPECT_EQ(reply_of(route(get("/api/model", "Bearer wrong"), c, false, 1)).status, 401);
  EXPECT_EQ(reply_of(route(get("/api/model", "Bearer s3cret2"), c, false, 1)).status, 401);
  EXPECT_EQ(reply_of(route(get("/api/model", "Bearer s3cre"), c, false, 1)).status, 401);
  EXPECT_EQ(reply_of(route(get("/nope?%zz"), c, false, 1)).status, 401);  // before the query
  // The viewer page's files need none (a browser cannot send it on navigation); the API does.
  for (const auto& [file, content] : c.files) {
    const Reply page = reply_of(route(get(file), c, false, 1));
    EXPECT_EQ(page.status, 200) << file;
    EXPECT_EQ(page.body, content.bytes) << file;
  }
  EXPECT_FALSE(c.files.empty());
  const Reply good = reply_of(route(get("/api/model", "Bearer s3cret"), c, false, 1));
  EXPECT_EQ(good.status, 200);
  EXPECT_EQ(good.body, c.model_json);
  const Reply closing = reply_of(route(get("/api/model", "Bearer s3cret"), c, true, 1));
  EXPECT_EQ(closing.status, 503);
  EXPECT_TRUE(closing.close);
}

TEST(Routes, OnlyGetIsServed) {
  Parsed p = parse_whole(kPostWithBody);
  const Reply r = reply_of(route(p.requests.at(0), config(), false, 1));
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.headers, (Fields{{"Allow", "GET"}}));
}

ObjectLookup lookup_of(const Routed& r) {
  const ObjectLookup* lookup = std::get_if<ObjectLookup>(&r.decision);
  EXPECT_TRUE(lookup) << (std::holds_alternative<Reply>(r.decision) ? std::get<Reply>(r.decision).body : "");
  return lookup ? *lookup : ObjectLookup{};
}

TEST(Routes, UnknownPathsAndBadObjectPathsAreRefused) {
  EXPECT_NE(error_of(route(get("/nope"), config(), false, 1), 404).find("no such resource: /nope"), std::string::npos);
  EXPECT_NE(error_of(route(get("/api/objects/"), config(), false, 1), 400).find("missing the object's tag or id"),
            std::string::npos);
  EXPECT_NE(error_of(route(get("/api/objects/P%2"), config(), false, 1), 400).find("bad percent escape at byte 1"),
            std::string::npos);
  EXPECT_NE(error_of(route(get("/api/objects/" + std::string(1025, 'x')), config(), false, 1), 400).find("at most 1024"),
            std::string::npos);
  EXPECT_NE(error_of(route(get("/api/objects/12?x=1"), config(), false, 1), 400).find("no parameters"), std::string::npos);
}

TEST(Routes, AnObjectIsNamedByItsIdOrItsTag) {
  const Routed by_id = route(get("/api/objects/12345"), config(), false, 1);
  EXPECT_EQ(by_id.endpoint, "objects");
  EXPECT_EQ(lookup_of(by_id).id, 12345u);
  EXPECT_EQ(lookup_of(by_id).name, "12345");  // a tag of digits, if no object has that id
  const ObjectLookup tag = lookup_of(route(get("/api/objects/F-01-004"), config(), false, 1));
  EXPECT_EQ(tag.id, 0u);
  EXPECT_EQ(tag.name, "F-01-004");
  // Percent-decoded, '/' kept: what the viewer sends for "/P-101 A" and for "/AREA/P-1".
  EXPECT_EQ(lookup_of(route(get("/api/objects/%2FP-101%20A"), config(), false, 1)).name, "/P-101 A");
  EXPECT_EQ(lookup_of(route(get("/api/objects//AREA/P-1"), config(), false, 1)).name, "/AREA/P-1");
  EXPECT_EQ(lookup_of(route(get("/api/objects/0"), config(), false, 1)).name, "0");
  EXPECT_EQ(lookup_of(route(get("/api/objects/99999999999999999999999"), config(), false, 1)).id, 0u);
}

TEST(Routes, PagesModelAndMetricsTakeNoParameters) {
  const Reply page = reply_of(route(get("/"), config(), false, 1));
  EXPECT_EQ(page.status, 200);
  EXPECT_EQ(page.content_type, "text/html; charset=utf-8");
  EXPECT_NE(error_of(route(get("/?a=1"), config(), false, 1), 400).find("no parameters"), std::string::npos);
  EXPECT_NE(error_of(route(get("/api/model?x=1"), config(), false, 1), 400).find("no parameters"), std::string::npos);
  EXPECT_TRUE(std::holds_alternative<MetricsPage>(route(get("/metrics"), config(), false, 1).decision));
}

TEST(Routes, AFrameRequestBecomesARenderJobWithItsTypedCamera) {
  const RenderJob job = job_of(route(get("/api/frame?eye=-6,-12,8.5&target=7.5,0,0&up=0,1,0&fov=40&w=160&h=90"
                                         "&format=png&quality=70&lod=none&px=2.5"),
                                     config(), false, 7));
  EXPECT_EQ(job.kind, RenderJob::Kind::frame);
  EXPECT_EQ(job.camera.eye_m, glm::dvec3(-6, -12, 8.5));
  EXPECT_EQ(job.camera.target_m, glm::dvec3(7.5, 0, 0));
  EXPECT_EQ(job.camera.up, glm::dvec3(0, 1, 0));
  EXPECT_EQ(job.camera.fov_deg, 40.0);
  EXPECT_EQ(job.width, 160u);
  EXPECT_EQ(job.height, 90u);
  EXPECT_EQ(job.format, ImageFormat::png);
  EXPECT_EQ(job.quality, 70);
  EXPECT_EQ(job.policy, LodPolicy::none);
  EXPECT_EQ(job.pixel_error, 2.5);
  EXPECT_EQ(job.mode, FrameMode::still);  // unless asked: never degraded
  EXPECT_EQ(job.client, "connection:7");
  EXPECT_EQ(job.client_id, issue_client_id(config().client_key, 7));
  EXPECT_EQ(job_of(route(get("/api/frame?mode=interactive"), config(), false, 7)).mode, FrameMode::interactive);
  EXPECT_EQ(job_of(route(get("/api/frame?mode=still"), config(), false, 7)).mode, FrameMode::still);
}

TEST(Routes, DefaultsAreTheModelsViewFiftyAndUpZOrNorthInAPlanView) {
  const RenderJob plain = job_of(route(get("/api/frame"), config(), false, 1));
  EXPECT_EQ(plain.width, 1280u);
  EXPECT_EQ(plain.height, 720u);
  EXPECT_EQ(plain.format, ImageFormat::jpeg);
  EXPECT_EQ(plain.quality, 85);
  EXPECT_EQ(plain.camera, default_camera(config().bounds, 1280.0 / 720.0));
  const RenderJob partial = job_of(route(get("/api/stats?eye=%2B1,2,3&target=4,5,6"), config(), false, 1));
  EXPECT_EQ(partial.kind, RenderJob::Kind::stats);
  EXPECT_EQ(partial.camera.eye_m, glm::dvec3(1, 2, 3));
  EXPECT_EQ(partial.camera.up, glm::dvec3(0, 0, 1));
  EXPECT_EQ(partial.camera.fov_deg, 50.0);
  // A plan view without up: north (+y) at the top, as every camera form has it.
  const RenderJob plan = job_of(route(get("/api/frame?eye=3,4,90&target=3,4,0"), config(), false, 1));
  EXPECT_EQ(plan.camera.up, glm::dvec3(0, 1, 0));
}

TEST(Routes, UpOrFovWithoutACameraIsRefusedNotIgnored) {
  for (const std::string q : {"fov=30", "up=0,1,0", "up=0,1,0&fov=30", "fov=30&eye=&target="}) {
    const std::string body = error_of(route(get("/api/frame?" + q), config(), false, 1), 400);
    EXPECT_NE(body.find("needs 'eye' and 'target'"), std::string::npos) << q << ": " << body;
    EXPECT_NE(body.find(q[0] == 'f' ? "'fov'" : "'up'"), std::string::npos) << q << ": " << body;
  }
  EXPECT_NE(error_of(route(get("/api/stats?fov=30"), config(), false, 1), 400).find("'fov' needs"), std::string::npos);
  EXPECT_NE(error_of(route(get("/api/pick?up=0,1,0&x=1&y=1"), config(), false, 1), 400).find("'up' needs"),
            std::string::npos);
}

// --- latest-wins slots: a client names only its own ----------------------------------------------

TEST(ClientSlots, WithoutAnIdARequestUsesItsConnectionsSlotAndIsToldItsId) {
  const RenderJob job = job_of(route(get("/api/frame"), config(), false, 5));
  EXPECT_EQ(job.client, "connection:5");
  EXPECT_EQ(job.client_id.size(), 32u);
  uint64_t named = 0;
  ASSERT_TRUE(client_slot_of(config().client_key, job.client_id, named));
  EXPECT_EQ(named, 5u);
}

TEST(ClientSlots, AnIssuedIdNamesItsSlotFromAnyConnection) {
  const std::string id = issue_client_id(config().client_key, 5);
  for (const std::string path : {"/api/frame", "/api/stats", "/api/pick?x=0&y=0&"}) {
    const std::string target = path + (path.back() == '&' ? "" : "?") + "client=" + id;
    const RenderJob job = job_of(route(get(target), config(), false, 9));
    EXPECT_EQ(job.client, "connection:5") << target;
    EXPECT_EQ(job.client_id, id) << target;
  }
}

TEST(ClientSlots, AnotherConnectionsSlotCannotBeNamed) {
  const RouteConfig c = config();
  const std::string id5 = issue_client_id(c.client_key, 5);
  RouteConfig other = c;
  other.client_key[1] ^= 1;
  std::string forged = id5;
  forged[31] = forged[31] == '0' ? '1' : '0';  // the right slot number, a wrong tag
  const std::string made_up[] = {
      "connection:5", "connection:5/frame", "5", forged, id5.substr(0, 31), id5 + "0",
      issue_client_id(other.client_key, 5),  // another server's (or this one's before a restart)
      std::string(16, '0') + id5.substr(16),
  };
  for (const std::string& value : made_up) {
    const RenderJob job = job_of(route(get("/api/frame?client=" + value), c, false, 9));
    EXPECT_EQ(job.client, "connection:9") << value;  // its own, not 5's
    EXPECT_EQ(job.client_id, issue_client_id(c.client_key, 9)) << value;
  }
  uint64_t named = 0;
  EXPECT_FALSE(client_slot_of(c.client_key, forged, named));
  // Ids of different connections differ in their tags, not only in their numbers.
  EXPECT_NE(issue_client_id(c.client_key, 5).substr(16), issue_client_id(c.client_key, 6).substr(16));
}

TEST(ClientSlots, KeysFromTheSystemDiffer) {
  const ClientKey a = random_client_key(), b = random_client_key();
  EXPECT_NE(a, b);
  EXPECT_NE(issue_client_id(a, 1), issue_client_id(b, 1));
}

TEST(Routes, BadParametersAreRefusedNamingTheParameter) {
  const std::pair<std::string, std::string> cases[] = {
      {"/api/frame?w=5000&h=10", "'w' must be a whole number of pixels in 1..4096, got '5000'"},
      {"/api/frame?w=0", "'w'"},
      {"/api/frame?h=-3", "'h'"},
      {"/api/frame?zoom=2", "unknown parameter 'zoom'"},
      {"/api/stats?format=png", "unknown parameter 'format'"},
      {"/api/pick?quality=5&x=1&y=1", "unknown parameter 'quality'"},
      {"/api/frame?format=gif", "'format' must be jpeg or png"},
      {"/api/frame?mode=fast", "'mode' must be interactive or still"},
      {"/api/stats?mode=still", "unknown parameter 'mode'"},
      {"/api/frame?quality=101", "'quality' must be 1..100"},
      {"/api/frame?lod=fast", "'lod'"},
      {"/api/frame?px=0", "'px'"},
      {"/api/frame?px=inf", "'px'"},
      {"/api/frame?w=%zz", "bad percent escape"},
      {"/api/frame?w=1&w=2", "given twice"},
  };
  for (const auto& [target, reason] : cases)
    EXPECT_NE(error_of(route(get(target), config(), false, 1), 400).find(reason), std::string::npos) << target;
}

TEST(Routes, CameraErrorsAreTheCameraFormsMessages) {
  const std::pair<std::string, std::string> cases[] = {
      {"eye=nan,0,0&target=1,1,1", "camera: 'eye' has a bad number 'nan'"},
      {"eye=inf,0,0&target=1,1,1", "camera: 'eye' has a bad number 'inf'"},
      {"eye=1,,0&target=1,1,1", "camera: 'eye' has a bad number ''"},
      {"eye=1,2,3&target=1,x,1", "camera: 'target' has a bad number 'x'"},
      {"eye=1,2&target=1,1,1", "camera: 'eye' needs 3 numbers, got 2"},
      {"eye=1,2,3&target=1,1,1,1", "camera: 'target' needs 3 numbers, got 4"},
      // Bad numbers are found before wrong counts.
      {"eye=1,2&target=1,1,q", "camera: 'target' has a bad number 'q'"},
      {"eye=1,1,1&target=1,1,1", "camera: the eye is on the target"},
      {"eye=0,0,5&target=0,0,0&up=0,0,-1", "camera: 'up' is zero or along the view direction"},
      {"eye=0,-5,0&target=0,0,0&up=0,0,0", "camera: 'up' is zero or along the view direction"},
      {"eye=0,-5,0&target=0,0,0&up=", "camera: 'up' has a bad number ''"},
      {"eye=0,-5,0&target=0,0,0&fov=180", "camera: fov must be in (0, 179) degrees"},
      {"eye=0,-5,0&target=0,0,0&fov=0", "camera: fov must be in (0, 179) degrees"},
      {"eye=0,-5,0&target=0,0,0&fov=40,50", "camera: 'fov' needs 1 number"},
      {"eye=1,1,1", "give both 'eye' and 'target', or neither"},
      {"target=1,1,1", "give both 'eye' and 'target', or neither"},
  };
  for (const auto& [query, reason] : cases) {
    const std::string body = error_of(route(get("/api/frame?" + query), config(), false, 1), 400);
    EXPECT_NE(body.find(reason), std::string::npos) << query << ": " << body;
  }
}

TEST(Routes, APickNeedsAPixelInsideTheImage) {
  const RenderJob pick = job_of(route(get("/api/pick?w=100&h=50&x=99&y=49"), config(), false, 3));
  EXPECT_EQ(pick.kind, RenderJob::Kind::pick);
  EXPECT_EQ(pick.x, 99u);
  EXPECT_EQ(pick.y, 49u);
  EXPECT_EQ(pick.client, "connection:3");
  for (const std::string q : {"w=100&h=50&x=100&y=0", "w=100&h=50&x=0&y=50"})
    EXPECT_NE(error_of(route(get("/api/pick?" + q), config(), false, 1), 400).find("inside the w x h image (100x50)"),
              std::string::npos)
        << q;
  // Missing is named as missing, not as out of the image.
  EXPECT_NE(error_of(route(get("/api/pick?w=100&h=50"), config(), false, 1), 400).find("missing 'x'"), std::string::npos);
  EXPECT_NE(error_of(route(get("/api/pick?w=100&h=50&y=1"), config(), false, 1), 400).find("missing 'x'"),
            std::string::npos);
  EXPECT_NE(error_of(route(get("/api/pick?w=100&h=50&x=1"), config(), false, 1), 400).find("missing 'y'"),
            std::string::npos);
  EXPECT_NE(error_of(route(get("/api/pick?x=-1&y=0"), config(), false, 1), 400).find("'x' must be a pixel position"),
            std::string::npos);
}

TEST(Routes, ViewFiltersOnFrameStatsAndPickBecomeTheJobsSectionStyleAndHighlight) {
  const std::string filters =
      "clip=0,0,12,0,0,2&clip=1,2,3,-1,0,0&box=-1,-2,-3,4,5,6&caps=0&colour_by=Material&hide=pipe,F-*"
      "&only=equipment&highlight=P-101A,12345";
  for (const std::string path : {"/api/frame?", "/api/stats?", "/api/pick?x=1&y=1&"}) {
    const RenderJob job = job_of(route(get(path + filters), config(), false, 1));
    ASSERT_EQ(job.section.planes.size(), 2u) << path;
    EXPECT_EQ(job.section.planes[0].point_m, glm::dvec3(0, 0, 12));
    EXPECT_EQ(job.section.planes[0].normal, glm::dvec3(0, 0, 1));  // normalised
    EXPECT_EQ(job.section.planes[1].normal, glm::dvec3(-1, 0, 0));
    EXPECT_TRUE(job.section.has_box);
    EXPECT_EQ(job.section.box.min, glm::dvec3(-1, -2, -3));
    EXPECT_EQ(job.section.box.max, glm::dvec3(4, 5, 6));
    EXPECT_FALSE(job.section.capped);
    EXPECT_EQ(job.style.colour_by, "Material");
    EXPECT_EQ(job.style.hide, (std::vector<std::string>{"pipe", "F-*"}));
    EXPECT_EQ(job.style.only, (std::vector<std::string>{"equipment"}));
    EXPECT_EQ(job.highlight, (std::vector<std::string>{"P-101A", "12345"}));
  }
  const RenderJob plain = job_of(route(get("/api/frame?w=8&h=8"), config(), false, 1));
  EXPECT_TRUE(plain.section.empty());
  EXPECT_TRUE(plain.section.capped);
  EXPECT_TRUE(plain.style.empty());
  EXPECT_TRUE(plain.highlight.empty());

  const std::string seven = "clip=0,0,1,0,0,1&clip=0,0,1,0,0,1&clip=0,0,1,0,0,1&clip=0,0,1,0,0,1"
                            "&clip=0,0,1,0,0,1&clip=0,0,1,0,0,1&clip=0,0,1,0,0,1";
  const std::pair<std::string, std::string> bad[] = {
      {"clip=0,0,0,0,0,0", "'clip': the plane's normal"},
      {"clip=1,2,3", "'clip': expected PX,PY,PZ,NX,NY,NZ"},
      {"clip=0,0,0,0,0,nan", "'clip'"},
      {seven, "'clip': at most 6 clip planes"},
      {"box=1,0,0,0,1,1", "'box': the box's min x"},
      {"box=0,0,0,1,1", "'box': expected MINX"},
      {"caps=yes", "'caps' must be 0"},
      {"hide=", "'hide': expected words"},
      {"only=,,", "'only': expected words"},
      {"highlight=", "'highlight': expected words"},
      {"box=0,0,0,1,1,1&box=0,0,0,2,2,2", "'box' is given twice"},
  };
  for (const std::string path : {"/api/frame?", "/api/stats?", "/api/pick?x=1&y=1&"})
    for (const auto& [query, reason] : bad)
      EXPECT_NE(error_of(route(get(path + query), config(), false, 1), 400).find(reason), std::string::npos)
          << path << query;
}

TEST(RenderWorker, RendererErrorsAboutViewFiltersAreTheCallersNotTheServers) {
  EXPECT_TRUE(is_view_filter_error("colour_by 'Foo': no object has it; keys: Material, Type"));
  EXPECT_TRUE(is_view_filter_error("--colour-by Foo: unknown key"));
  EXPECT_TRUE(is_view_filter_error("section: the box is empty"));
  EXPECT_FALSE(is_view_filter_error("cannot read object 12: MDB_CORRUPTED"));
  EXPECT_FALSE(is_view_filter_error(""));
}

TEST(Routes, EndpointsAreNamedForTheMetrics) {
  EXPECT_EQ(endpoint_of("/api/frame"), "frame");
  EXPECT_EQ(endpoint_of("/api/objects/123"), "objects");
  EXPECT_EQ(endpoint_of("/"), "page");
  EXPECT_EQ(endpoint_of("/viewer.js"), "viewer.js");
  EXPECT_EQ(endpoint_of("/metrics"), "metrics");
  EXPECT_EQ(endpoint_of("/a/"), "other");
  EXPECT_EQ(endpoint_of("/" + std::string(40, 'x')), "other");
  // Unknown paths share one series, and a client's bytes never reach a label.
  EXPECT_EQ(endpoint_of("/a\"b"), "other");
  EXPECT_EQ(endpoint_of("/x\ny"), "other");
  EXPECT_EQ(endpoint_of("/api/frame/extra"), "other");
}

// --- metrics ------------------------------------------------------------------------------------

TEST(Metrics, CountsHistogramAndGaugesAreExposedInPrometheusText) {
  Metrics m;
  m.count_answer("frame", 200);
  m.count_answer("frame", 200);
  m.count_answer("frame", 400);
  FrameStats fast, slow;
  fast.ms.total = 8;
  fast.ms.encode = 1;  // 9 ms: the 10 ms bucket
  fast.arena_bytes_resident = 111;
  fast.objects_evicted = 2;
  fast.arena_bytes_uploaded = 1000;
  slow.ms.total = 300;  // the 500 ms bucket
  slow.arena_bytes_resident = 222;
  slow.objects_evicted = 3;
  slow.arena_bytes_uploaded = 500;
  m.count_rendered(RenderJob::Kind::frame, fast);
  m.count_rendered(RenderJob::Kind::frame, slow);
  m.count_rendered(RenderJob::Kind::pick, fast);  // its own histogram, not the frames'
  m.superseded = 4;
  m.rejected_busy = 5;
  const std::string text = metrics_text(m, {1 << 20, 6, 7});
  for (const std::string line : {
           "plantview_requests_total{endpoint=\"frame\",status=\"200\"} 2\n",
           "plantview_requests_total{endpoint=\"frame\",status=\"400\"} 1\n",
           "plantview_render_milliseconds_bucket{kind=\"frame\",le=\"10\"} 1\n",
           "plantview_render_milliseconds_bucket{kind=\"frame\",le=\"250\"} 1\n",
           "plantview_render_milliseconds_bucket{kind=\"frame\",le=\"500\"} 2\n",
           "plantview_render_milliseconds_bucket{kind=\"frame\",le=\"10000\"} 2\n",
           "plantview_render_milliseconds_bucket{kind=\"frame\",le=\"+Inf\"} 2\n",
           "plantview_render_milliseconds_sum{kind=\"frame\"} 309\n",
           "plantview_render_milliseconds_count{kind=\"frame\"} 2\n",
           "plantview_render_milliseconds_count{kind=\"stats\"} 0\n",
           "plantview_render_milliseconds_bucket{kind=\"pick\",le=\"10\"} 1\n",
           "plantview_render_milliseconds_count{kind=\"pick\"} 1\n",
           "plantview_arena_bytes 111\n",
           "plantview_arena_budget_bytes 1048576\n",
           "plantview_evictions_total 7\n",
           "plantview_uploaded_bytes_total 2500\n",
           "plantview_queue_depth 6\n",
           "plantview_superseded_total 4\n",
           "plantview_busy_total 5\n",
           "plantview_connections 7\n",
           "# TYPE plantview_render_milliseconds histogram\n",
       })
    EXPECT_NE(text.find(line), std::string::npos) << line << "in\n" << text;
  EXPECT_EQ(escape_label_value("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
}

// --- the render worker --------------------------------------------------------------------------

// Six 2 m boxes along x (0, 3, ..., 15 m), as the service tests use.
const std::string& six_boxes() {
  // Removed when the test program exits.
  static const test::TempDir store_dir;
  static const std::string dir = [] {
    std::string error;
    auto store = Store::open(store_dir.str(), Store::Mode::read_write, error);
    if (!store) {
      ADD_FAILURE() << "cannot create the test store: " << error;
      return store_dir.str();
    }
    const std::vector<Object> objects = test::box_row_objects();
    const IngestResult result = ingest_objects(*store, objects);
    EXPECT_TRUE(result) << result.error().message;
    return store_dir.str();
  }();
  return dir;
}

// Results as the worker hands them over; `hold` keeps the render thread inside its notify call
// (after a result, before the next job) until released, so that a test can queue jobs while
// the worker is known to be between jobs.
class Results {
 public:
  std::function<void()> notifier() {
    return [this] {
      std::unique_lock lock(mutex_);
      ++notified_;
      changed_.notify_all();
      changed_.wait(lock, [&] { return !hold_; });
    };
  }
  void hold(bool on) {
    std::lock_guard lock(mutex_);
    hold_ = on;
    changed_.notify_all();
  }
  // Waits until `n` results have been announced.
  bool wait_for(int n) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, std::chrono::seconds(60), [&] { return notified_ >= n; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  int notified_ = 0;
  bool hold_ = false;
};

// One renderer, 16 MB, `max_queue` jobs waiting at most.
RenderWorkerOptions one_renderer(uint32_t max_queue) { return {16 << 20, -1, 1, max_queue}; }

std::string header_of(const RenderResult& r, const std::string& name) {
  for (const auto& [key, value] : r.headers)
    if (key == name) return value;
  return "(no " + name + ")";
}

RenderJob frame_job(uint64_t ticket, const std::string& client, uint32_t side = 64) {
  RenderJob job;
  job.kind = RenderJob::Kind::frame;
  job.camera.eye_m = {-6, -12, 8};
  job.camera.target_m = {7.5, 0, 0};
  job.width = job.height = side;
  job.client = client;
  job.ticket = ticket;
  return job;
}

TEST(RenderWorker, ANewerJobOfTheSameClientReplacesTheWaitingOneAndAFullQueueIsBusy) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, one_renderer(2), results.notifier(), error)) << error;
  results.hold(true);
  uint64_t dropped = 0;
  EXPECT_EQ(worker.submit(frame_job(1, "first"), dropped), RenderWorker::Submitted::queued);
  ASSERT_TRUE(results.wait_for(1));  // job 1 is done; the render thread waits in notify
  EXPECT_EQ(worker.submit(frame_job(2, "c"), dropped), RenderWorker::Submitted::queued);
  EXPECT_EQ(worker.submit(frame_job(3, "c", 32), dropped), RenderWorker::Submitted::replaced);
  EXPECT_EQ(dropped, 2u);
  EXPECT_EQ(worker.submit(frame_job(4, "d"), dropped), RenderWorker::Submitted::queued);
  EXPECT_EQ(worker.submit(frame_job(5, "e"), dropped), RenderWorker::Submitted::busy);
  EXPECT_EQ(worker.queue_depth(), 2u);
  EXPECT_FALSE(worker.idle());
  results.hold(false);
  ASSERT_TRUE(results.wait_for(3));
  worker.stop();
  std::vector<uint64_t> tickets;
  for (const RenderResult& r : worker.take_results()) {
    tickets.push_back(r.ticket);
    EXPECT_EQ(r.status, 200);
    EXPECT_TRUE(r.needs_encoding);
    if (r.ticket == 3) {
      EXPECT_EQ(r.image.width, 32u);  // the newer one's size
    }
  }
  EXPECT_EQ(tickets, (std::vector<uint64_t>{1, 3, 4}));  // in the order they waited
  EXPECT_TRUE(worker.idle());
}

TEST(RenderWorker, JobsSubmittedWhileItRendersAreAllAnsweredAndStopFinishesTheQueue) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, one_renderer(64), results.notifier(), error)) << error;
  std::set<uint64_t> answered;
  const auto take = [&] {
    for (RenderResult& r : worker.take_results()) {
      EXPECT_EQ(r.status, 200) << r.body;
      EXPECT_TRUE(answered.insert(r.ticket).second) << "answered twice: " << r.ticket;
    }
  };
  constexpr uint64_t kJobs = 24;
  for (uint64_t t = 1; t <= kJobs; ++t) {
    uint64_t dropped = 0;
    RenderJob job = frame_job(t, "client-" + std::to_string(t), 24 + uint32_t(t));
    if (t % 3 == 1) job.kind = RenderJob::Kind::stats;
    ASSERT_EQ(worker.submit(std::move(job), dropped), RenderWorker::Submitted::queued);
    take();  // while it renders
  }
  worker.stop();  // lets the queued jobs finish
  take();
  EXPECT_EQ(answered.size(), kJobs);
  EXPECT_TRUE(worker.idle());
}

TEST(RenderWorker, APickReadsTheObjectFromTheRenderersSnapshot) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, one_renderer(8), results.notifier(), error)) << error;
  RenderJob pick;
  pick.kind = RenderJob::Kind::pick;
  pick.camera.eye_m = {6, -10, 0};
  pick.camera.target_m = {6, 0, 0};
  pick.width = pick.height = 100;
  pick.x = pick.y = 50;
  pick.client = "p";
  pick.ticket = 1;
  RenderJob miss = pick;
  miss.x = miss.y = 0;
  miss.client = "q";
  miss.ticket = 2;
  uint64_t dropped = 0;
  worker.submit(pick, dropped);
  worker.submit(miss, dropped);
  ASSERT_TRUE(results.wait_for(2));
  worker.stop();
  const auto done = worker.take_results();
  ASSERT_EQ(done.size(), 2u);
  EXPECT_EQ(done[0].status, 200);
  EXPECT_NE(done[0].body.find("\"name\":\"/BOX-2\""), std::string::npos) << done[0].body;
  EXPECT_EQ(done[1].body, "{\"object\":null}\n");
}

TEST(RenderWorker, ClientsAreServedRoundRobinNotInArrivalOrder) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, one_renderer(16), results.notifier(), error)) << error;
  results.hold(true);
  uint64_t dropped = 0;
  worker.submit(frame_job(1, "first"), dropped);
  ASSERT_TRUE(results.wait_for(1));  // the renderer waits between jobs
  // Client a asks for a frame, statistics and a pick before b and c ask for anything.
  RenderJob a_stats = frame_job(3, "a"), a_pick = frame_job(4, "a");
  a_stats.kind = RenderJob::Kind::stats;
  a_pick.kind = RenderJob::Kind::pick;
  for (RenderJob job : {frame_job(2, "a"), a_stats, a_pick, frame_job(5, "b"), frame_job(6, "c")})
    ASSERT_EQ(worker.submit(std::move(job), dropped), RenderWorker::Submitted::queued);  // kinds don't replace
  EXPECT_EQ(worker.queue_depth(), 5u);
  results.hold(false);
  ASSERT_TRUE(results.wait_for(6));
  worker.stop();
  std::vector<uint64_t> order;
  for (const RenderResult& r : worker.take_results()) order.push_back(r.ticket);
  // b and c wait for one job of a, not three.
  EXPECT_EQ(order, (std::vector<uint64_t>{1, 2, 5, 6, 3, 4}));
}

TEST(Degradation, InteractiveFramesGetCheaperAsPressureGrowsStillsStatsAndPicksNever) {
  RenderJob interactive = frame_job(1, "i");
  interactive.mode = FrameMode::interactive;
  const auto degraded = [&](size_t demand, size_t renderers) {
    const Degradation d = choose_degradation(interactive, demand, renderers);
    return std::pair<double, uint32_t>(d.pixel_error_factor, d.size_divisor);
  };
  using P = std::pair<double, uint32_t>;
  EXPECT_EQ(degraded(1, 1), P(1, 1));
  EXPECT_EQ(degraded(2, 1), P(4, 1));  // a coarser pixel error first
  EXPECT_EQ(degraded(3, 1), P(4, 1));
  EXPECT_EQ(degraded(4, 1), P(4, 2));  // then a lower resolution
  EXPECT_EQ(degraded(6, 1), P(4, 2));
  EXPECT_EQ(degraded(7, 1), P(4, 4));
  EXPECT_EQ(degraded(64, 1), P(4, 4));
  // Pressure is per renderer.
  EXPECT_EQ(degraded(2, 2), P(1, 1));
  EXPECT_EQ(degraded(3, 2), P(4, 1));
  EXPECT_EQ(degraded(7, 2), P(4, 2));
  EXPECT_EQ(degraded(13, 2), P(4, 4));
  for (const auto kind : {RenderJob::Kind::stats, RenderJob::Kind::pick}) {
    RenderJob other = interactive;
    other.kind = kind;
    EXPECT_FALSE(choose_degradation(other, 64, 1).any());
  }
  RenderJob still = interactive;
  still.mode = FrameMode::still;
  EXPECT_FALSE(choose_degradation(still, 64, 1).any());
}

// Issue 43: degradation lifts a rung a frame, so that no frame streams every finer level at
// once; it falls at once.
TEST(Degradation, LiftsARungAFrameAndFallsAtOnce) {
  using P = std::pair<double, uint32_t>;
  uint8_t rung = 0;
  const auto step = [&](Degradation wanted) {
    const Degradation d = step_degradation(wanted, rung);
    return P(d.pixel_error_factor, d.size_divisor);
  };
  const Degradation none, coarser{4, 1}, half{4, 2}, quarter{4, 4};
  EXPECT_EQ(step(quarter), P(4, 4));
  EXPECT_EQ(rung, 4);
  EXPECT_EQ(step(none), P(4, 2));
  EXPECT_EQ(step(none), P(4, 1));
  EXPECT_EQ(step(none), P(2, 1));  // a rung of its own on the way back
  EXPECT_EQ(step(none), P(1, 1));
  EXPECT_EQ(rung, 0);
  EXPECT_EQ(step(half), P(4, 2));  // load comes: at once
  EXPECT_EQ(step(coarser), P(4, 1));  // one rung lighter: as wanted
  EXPECT_EQ(step(quarter), P(4, 4));
  EXPECT_EQ(step(coarser), P(4, 2));
  for (const Degradation& d : {none, coarser, half, quarter}) {
    uint8_t r = degradation_rung(d);
    const Degradation same = step_degradation(d, r);
    EXPECT_EQ(P(same.pixel_error_factor, same.size_divisor), P(d.pixel_error_factor, d.size_divisor));
  }
}

TEST(Degradation, TwoInteractiveClientsOnOneRendererTheOneTakenWhileTheOtherWaitsIsCoarser) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, one_renderer(16), results.notifier(), error)) << error;
  results.hold(true);
  uint64_t dropped = 0;
  worker.submit(frame_job(1, "first"), dropped);
  ASSERT_TRUE(results.wait_for(1));
  for (uint64_t t : {2, 3}) {
    RenderJob job = frame_job(t, t == 2 ? "a" : "b");
    job.mode = FrameMode::interactive;
    worker.submit(std::move(job), dropped);
  }
  results.hold(false);
  ASSERT_TRUE(results.wait_for(3));
  worker.stop();
  std::map<uint64_t, RenderResult> by_ticket;
  for (RenderResult& r : worker.take_results()) by_ticket[r.ticket] = std::move(r);
  // a was taken while b waited: 2 requests for 1 renderer. b was taken alone.
  EXPECT_EQ(header_of(by_ticket[2], "X-Plantview-Degraded"), "pixel-error");
  EXPECT_EQ(header_of(by_ticket[2], "X-Plantview-Pixel-Error"), "4");
  EXPECT_EQ(header_of(by_ticket[2], "X-Plantview-Jpeg-Quality"), "60");
  EXPECT_EQ(header_of(by_ticket[3], "X-Plantview-Degraded"), "none");
  EXPECT_EQ(header_of(by_ticket[3], "X-Plantview-Pixel-Error"), "1");
  EXPECT_EQ(header_of(by_ticket[3], "X-Plantview-Jpeg-Quality"), "85");
}

// Many clients and one renderer: what an interactive frame gave up shows in its headers, and a
// still waiting with them is rendered in full.
TEST(Degradation, UnderLoadInteractiveHeadersShowTheCoarserQualityAndAStillIsNeverDegraded) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, one_renderer(16), results.notifier(), error)) << error;
  results.hold(true);
  uint64_t dropped = 0;
  worker.submit(frame_job(1, "first"), dropped);
  ASSERT_TRUE(results.wait_for(1));
  // Seven viewers move, one rests: 8 requests for one renderer.
  for (uint64_t t = 2; t <= 8; ++t) {
    RenderJob job = frame_job(t, "moving-" + std::to_string(t), 160);
    job.height = 96;
    job.mode = FrameMode::interactive;
    job.client_id = "id-" + std::to_string(t);
    worker.submit(std::move(job), dropped);
  }
  RenderJob still = frame_job(9, "resting", 160);
  still.height = 96;
  worker.submit(std::move(still), dropped);
  results.hold(false);
  ASSERT_TRUE(results.wait_for(9));
  // Then one alone (a client whose frames were never degraded): nothing waits, nothing is
  // given up.
  RenderJob alone = frame_job(10, "alone", 160);
  alone.height = 96;
  alone.mode = FrameMode::interactive;
  worker.submit(std::move(alone), dropped);
  ASSERT_TRUE(results.wait_for(10));
  for (uint64_t t = 11; t <= 14; ++t) {
    RenderJob again = frame_job(t, "moving-2", 160);
    again.height = 96;
    again.mode = FrameMode::interactive;
    worker.submit(std::move(again), dropped);
    ASSERT_TRUE(results.wait_for(int(t)));
  }
  worker.stop();
  std::map<uint64_t, RenderResult> by_ticket;
  for (RenderResult& r : worker.take_results()) by_ticket[r.ticket] = std::move(r);
  ASSERT_EQ(by_ticket.size(), 14u);
  struct Expected {
    uint64_t ticket;
    const char *degraded, *pixel_error, *size, *queue;
    uint32_t width;
  };
  // Taken in order: ticket 2 with 7 others waiting (8 for one renderer), ... ticket 8 with 1.
  const Expected expected[] = {
      {2, "pixel-error,resolution", "4", "40x24", "7", 40}, {3, "pixel-error,resolution", "4", "40x24", "6", 40},
      {4, "pixel-error,resolution", "4", "80x48", "5", 80}, {5, "pixel-error,resolution", "4", "80x48", "4", 80},
      {6, "pixel-error,resolution", "4", "80x48", "3", 80}, {7, "pixel-error", "4", "160x96", "2", 160},
      {8, "pixel-error", "4", "160x96", "1", 160},          {10, "none", "1", "160x96", "0", 160},
  };
  for (const Expected& e : expected) {
    const RenderResult& r = by_ticket[e.ticket];
    EXPECT_EQ(r.status, 200) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Mode"), "interactive") << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Degraded"), e.degraded) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Pixel-Error"), e.pixel_error) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Render-Size"), e.size) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Queue"), e.queue) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Jpeg-Quality"), std::string(e.ticket == 10 ? "85" : "60")) << e.ticket;
    EXPECT_EQ(r.quality, e.ticket == 10 ? 85 : 60) << e.ticket;
    EXPECT_EQ(r.image.width, e.width) << e.ticket;  // the image has the size rendered
    EXPECT_NE(header_of(r, "X-Plantview-Render-Ms").find('.'), std::string::npos) << e.ticket;
  }
  EXPECT_EQ(header_of(by_ticket[2], "X-Plantview-Client"), "id-2");
  // moving-2, alone now, was last at a quarter of the size: its quality steps back a rung a
  // frame (step_degradation), not at once.
  const Expected lifting[] = {{11, "pixel-error,resolution", "4", "80x48", "0", 80},
                              {12, "pixel-error", "4", "160x96", "0", 160},
                              {13, "pixel-error", "2", "160x96", "0", 160},
                              {14, "none", "1", "160x96", "0", 160}};
  for (const Expected& e : lifting) {
    const RenderResult& r = by_ticket[e.ticket];
    EXPECT_EQ(header_of(r, "X-Plantview-Degraded"), e.degraded) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Pixel-Error"), e.pixel_error) << e.ticket;
    EXPECT_EQ(header_of(r, "X-Plantview-Render-Size"), e.size) << e.ticket;
  }
  const RenderResult& s = by_ticket[9];
  EXPECT_EQ(header_of(s, "X-Plantview-Mode"), "still");
  EXPECT_EQ(header_of(s, "X-Plantview-Degraded"), "none");
  EXPECT_EQ(header_of(s, "X-Plantview-Pixel-Error"), "1");
  EXPECT_EQ(header_of(s, "X-Plantview-Render-Size"), "160x96");
  EXPECT_EQ(header_of(s, "X-Plantview-Queue"), "0");
  EXPECT_EQ(s.image.width, 160u);
  EXPECT_EQ(s.quality, 85);
}

TEST(RenderWorker, SeveralRenderersRenderAtOnceEachWithItsOwnContext) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  Results results;
  RenderWorker worker;
  ASSERT_TRUE(worker.start(*store, {16 << 20, -1, 2, 16}, results.notifier(), error)) << error;
  EXPECT_EQ(worker.renderers(), 2u);
  EXPECT_EQ(worker.device_description().rfind("2 renderers", 0), 0u) << worker.device_description();
  results.hold(true);
  uint64_t dropped = 0;
  worker.submit(frame_job(1, "a"), dropped);
  worker.submit(frame_job(2, "b"), dropped);
  // Both results announced while neither renderer may go on: they rendered side by side.
  ASSERT_TRUE(results.wait_for(2));
  worker.submit(frame_job(3, "c"), dropped);
  results.hold(false);
  ASSERT_TRUE(results.wait_for(3));
  worker.stop();
  std::set<uint64_t> answered;
  for (const RenderResult& r : worker.take_results()) {
    EXPECT_EQ(r.status, 200) << r.body;
    EXPECT_EQ(r.image.width, 64u);
    answered.insert(r.ticket);
  }
  EXPECT_EQ(answered, (std::set<uint64_t>{1, 2, 3}));
  EXPECT_TRUE(worker.idle());
}

TEST(RenderWorker, OnASoftwareRendererTwoRenderersAndOnePer16CoresOnLargeMachines) {
  EXPECT_EQ(default_software_renderers(1), 1u);
  EXPECT_EQ(default_software_renderers(2), 2u);
  EXPECT_EQ(default_software_renderers(16), 2u);
  EXPECT_EQ(default_software_renderers(64), 4u);
}

// --- objects by tag or id -----------------------------------------------------------------------

// `objects` ingested into a new store in `dir`, then opened read-only (the store in `store`);
// null, with a test failure, if any step fails.
std::unique_ptr<ReadView> ingested_view(const test::TempDir& dir, const std::vector<Object>& objects,
                                        std::unique_ptr<Store>& store) {
  std::string error;
  {
    auto writable = Store::open(dir.str(), Store::Mode::read_write, error);
    if (!writable) {
      ADD_FAILURE() << error;
      return nullptr;
    }
    const IngestResult result = ingest_objects(*writable, objects);
    if (!result) {
      ADD_FAILURE() << result.error().message;
      return nullptr;
    }
  }
  store = Store::open(dir.str(), Store::Mode::read_only, error);
  std::unique_ptr<ReadView> view = store ? store->read(error) : nullptr;
  if (!view) ADD_FAILURE() << error;
  return view;
}

TEST(Objects, AnObjectIsFoundByIdByTagAsStoredOrWithoutItsLeadingSlash) {
  std::string error;
  auto store = Store::open(six_boxes(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  const uint64_t id = object_id("test", "/BOX-3");
  for (const auto& [by_id, name] : std::vector<std::pair<uint64_t, std::string>>{
           {id, std::to_string(id)}, {0, "/BOX-3"}, {0, "BOX-3"}}) {
    const ObjectAnswer a = object_answer(*view, by_id, name);
    EXPECT_EQ(a.status, 200) << name << ": " << a.body;
    EXPECT_NE(a.body.find("\"id\":\"" + std::to_string(id) + "\""), std::string::npos) << a.body;
    EXPECT_NE(a.body.find("\"name\":\"/BOX-3\""), std::string::npos) << a.body;
  }
  const ObjectAnswer none = object_answer(*view, 0, "BOX-9");
  EXPECT_EQ(none.status, 404);
  EXPECT_NE(none.body.find("no object has the tag 'BOX-9'"), std::string::npos) << none.body;
  const ObjectAnswer digits = object_answer(*view, 12345, "12345");
  EXPECT_EQ(digits.status, 404);
  EXPECT_NE(digits.body.find("no object has the id or the tag '12345'"), std::string::npos) << digits.body;
}

TEST(Objects, ATagOfSeveralObjectsIsAConflictListingTheirIds) {
  const test::TempDir dir;
  std::vector<Object> objects;
  for (const char* source : {"a.rvm", "b.rvm"}) {
    Object o;
    o.name = "/TWIN";
    o.source = source;
    o.id = object_id(o.source, o.name);
    o.object_class = ObjectClass::equipment;
    o.primitives.push_back(Primitive{Placement{}, Box{1, 1, 1}});
    objects.push_back(std::move(o));
  }
  std::unique_ptr<Store> store;
  auto view = ingested_view(dir, objects, store);
  ASSERT_TRUE(view);
  const ObjectAnswer a = object_answer(*view, 0, "TWIN");
  EXPECT_EQ(a.status, 409) << a.body;
  EXPECT_NE(a.body.find("names 2 objects"), std::string::npos) << a.body;
  for (const char* source : {"a.rvm", "b.rvm"})
    EXPECT_NE(a.body.find("\"" + std::to_string(object_id(source, "/TWIN")) + "\""), std::string::npos) << a.body;
}

TEST(Objects, APipelineHasTheBoundsOfItsMembers) {
  const test::TempDir dir;
  std::vector<Object> objects;
  Object pipeline;
  pipeline.name = "/LINE-1";
  pipeline.source = "a.rvm";
  pipeline.id = object_id(pipeline.source, pipeline.name);
  pipeline.object_class = ObjectClass::pipeline;
  pipeline.branches.push_back({"/LINE-1/B1", {}});
  for (int i = 0; i < 2; ++i) {
    Object pipe;
    pipe.name = "/LINE-1/PIPE-" + std::to_string(i);
    pipe.source = "a.rvm";
    pipe.id = object_id(pipe.source, pipe.name);
    pipe.object_class = ObjectClass::pipe;
    pipe.pipeline_id = pipeline.id;
    pipe.origin_m = {100.0 + 10.0 * i, 200.0, 5.0};
    pipe.primitives.push_back(Primitive{Placement{}, Box{2, 2, 2}});
    pipeline.branches[0].members.push_back(pipe.id);
    objects.push_back(std::move(pipe));
  }
  objects.push_back(std::move(pipeline));
  std::unique_ptr<Store> store;
  auto view = ingested_view(dir, objects, store);
  ASSERT_TRUE(view);
  const ObjectAnswer a = object_answer(*view, 0, "LINE-1");
  ASSERT_EQ(a.status, 200) << a.body;
  const auto j = nlohmann::json::parse(a.body);
  EXPECT_EQ(j["class"], "pipeline");
  ASSERT_TRUE(j.contains("bounds")) << a.body;
  EXPECT_NEAR(j["bounds"]["min"][0].get<double>(), 99.0, 1e-3);
  EXPECT_NEAR(j["bounds"]["max"][0].get<double>(), 111.0, 1e-3);
  EXPECT_NEAR(j["bounds"]["min"][2].get<double>(), 4.0, 1e-3);
}

TEST(RenderWorker, AStoppedWorkerThatNeverStartedStopsCleanly) {
  RenderWorker worker;
  worker.stop();
  EXPECT_TRUE(worker.idle());
}

}  // namespace
}  // namespace plantview::service
