// The HTTP service over real loopback sockets: every endpoint, malformed and abusive requests,
// pipelining, many clients at once, the token rule and shutdown. Runs the built plantview binary.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/box_row.h"
#include "support/http_client.h"
#include "support/serve_process.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A small plant: a few boxes, a pipe and a tee, so that frames are quick on a CPU.
const std::string& small_store() {
  // Removed when the test program exits (the servers it started have stopped by then).
  static const test::TempDir store_dir;
  static const std::string dir = [] {
    const fs::path d = store_dir.path();
    std::string error;
    auto store = Store::open(d.string(), Store::Mode::read_write, error);
    if (!store) {
      ADD_FAILURE() << "cannot create the test store: " << error;
      return d.string();
    }
    const std::vector<Object> objects = test::box_row_objects();
    const IngestResult result = ingest_objects(*store, objects);
    EXPECT_TRUE(result) << result.error().message;
    return d.string();
  }();
  return dir;
}

using Launch = test::Launch;

// A server on `store` (small_store() by default), with `extra` options.
class Server : public test::ServeProcess {
 public:
  explicit Server(std::vector<std::string> extra = {}, const std::string& store = small_store(),
                  const Launch& launch = {})
      : ServeProcess(PLANTVIEW_BIN, store, std::move(extra), launch) {}
};

using Response = test_support::HttpResponse;
using Client = test_support::HttpClient;

// Decodes an image answer and checks its size.
bool is_image(const Response& r, uint32_t w, uint32_t h, const std::string& ext) {
  if (r.status != 200) return false;
  static std::atomic<int> counter{0};
  const fs::path file = fs::temp_directory_path() /
                        ("plantview-service-image-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + ext);
  std::ofstream(file, std::ios::binary) << r.body;
  Image image;
  std::string error;
  const bool ok = read_image(file.string(), image, error);
  fs::remove(file);
  return ok && image.width == w && image.height == h;
}

nlohmann::json json_of(const Response& r) { return nlohmann::json::parse(r.body, nullptr, false); }

// Polls /readyz on one connection until it answers 200; the statuses seen, in order.
std::vector<int> wait_until_ready(int port, std::chrono::seconds limit = 20s) {
  std::vector<int> seen;
  Client c(port);
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    const int status = c.request("/readyz").status;
    if (seen.empty() || seen.back() != status) seen.push_back(status);
    if (status == 200 || status == 0) break;
    std::this_thread::sleep_for(10ms);
  }
  return seen;
}

const std::string kView = "eye=-6,-12,8&target=7.5,0,0&up=0,0,1&fov=50";

TEST(Service, ModelFrameStatsPickObjectsMetricsAndPage) {
  Server server;
  Client c(server.port());
  ASSERT_TRUE(c.connected());
  Response model = c.request("/api/model");
  ASSERT_EQ(model.status, 200);
  const auto m = json_of(model);
  EXPECT_EQ(m["objects"], 6);
  EXPECT_EQ(m["camera"]["eye"].size(), 3u);
  EXPECT_EQ(m["bounds"]["max"][0], 16.0);

  Response jpeg = c.request("/api/frame?" + kView + "&w=160&h=90&format=jpeg&quality=70");
  EXPECT_TRUE(is_image(jpeg, 160, 90, ".jpg")) << jpeg.status << " " << jpeg.body.substr(0, 200);
  EXPECT_EQ(jpeg.headers["content-type"], "image/jpeg");
  EXPECT_EQ(jpeg.headers["x-objects-visible"], "6");
  EXPECT_EQ(jpeg.headers["x-triangles"], "72");
  Response png = c.request("/api/frame?" + kView + "&w=120&h=80&format=png&lod=none");
  EXPECT_TRUE(is_image(png, 120, 80, ".png"));
  Response default_view = c.request("/api/frame?w=64&h=64");
  EXPECT_TRUE(is_image(default_view, 64, 64, ".jpg"));

  Response stats = c.request("/api/stats?" + kView + "&w=160&h=90&px=2");
  ASSERT_EQ(stats.status, 200);
  EXPECT_EQ(json_of(stats)["objects_visible"], 6);

  // The middle box (index 2 of 0..5 at x = 6 m) is at the centre of a view down its axis.
  Response pick = c.request("/api/pick?eye=6,-10,0&target=6,0,0&w=100&h=100&x=50&y=50");
  ASSERT_EQ(pick.status, 200);
  const auto picked = json_of(pick)["object"];
  ASSERT_TRUE(picked.is_object()) << pick.body;
  EXPECT_EQ(picked["name"], "/BOX-2");
  EXPECT_EQ(picked["class"], "equipment");
  EXPECT_EQ(picked["attributes"][1]["value"], "2");
  Response nothing = c.request("/api/pick?eye=6,-10,0&target=6,0,0&w=100&h=100&x=0&y=0");
  EXPECT_TRUE(json_of(nothing)["object"].is_null());

  Response object = c.request("/api/objects/" + picked["id"].get<std::string>());
  ASSERT_EQ(object.status, 200);
  EXPECT_EQ(json_of(object)["name"], "/BOX-2");
  EXPECT_EQ(c.request("/api/objects/12345").status, 404);
  EXPECT_EQ(c.request("/api/objects/abc").status, 404);  // a tag no object has
  Response by_tag = c.request("/api/objects/BOX-2");  // as stored, "/BOX-2"
  ASSERT_EQ(by_tag.status, 200) << by_tag.body;
  EXPECT_EQ(json_of(by_tag)["id"], picked["id"]);
  EXPECT_EQ(c.request("/api/objects/").status, 400);

  Response metrics = c.request("/metrics");
  ASSERT_EQ(metrics.status, 200);
  EXPECT_NE(metrics.body.find("plantview_requests_total{endpoint=\"frame\",status=\"200\"} 3"), std::string::npos)
      << metrics.body;
  EXPECT_NE(metrics.body.find("plantview_render_milliseconds_count{kind=\"frame\"} 3"), std::string::npos)
      << metrics.body;
  EXPECT_NE(metrics.body.find("plantview_render_milliseconds_count{kind=\"stats\"} 1"), std::string::npos);
  EXPECT_NE(metrics.body.find("plantview_render_milliseconds_count{kind=\"pick\"} 2"), std::string::npos);
  EXPECT_NE(metrics.body.find("plantview_queue_depth"), std::string::npos);

  Response page = c.request("/");
  if (fs::exists(fs::path(PLANTVIEW_WEB_DIR) / "index.html")) {
    EXPECT_EQ(page.status, 200);
    EXPECT_NE(page.headers["content-type"].find("text/html"), std::string::npos);
  }
  EXPECT_EQ(c.request("/nope").status, 404);
  EXPECT_EQ(server.stop(), 0);
}

TEST(Service, BadParametersAreRefusedWithAReason) {
  Server server;
  Client c(server.port());
  const std::pair<std::string, std::string> cases[] = {
      {"/api/frame?w=5000&h=10", "'w'"},
      {"/api/frame?w=0&h=10", "'w'"},
      {"/api/frame?w=-3&h=10", "'w'"},
      {"/api/frame?w=10&h=1e9", "'h'"},
      {"/api/frame?w=10&h=10&zoom=2", "unknown parameter 'zoom'"},
      {"/api/frame?eye=nan,0,0&target=1,1,1", "bad number"},
      {"/api/frame?eye=inf,0,0&target=1,1,1", "bad number"},
      {"/api/frame?eye=1,2&target=1,1,1", "3 numbers"},
      {"/api/frame?eye=1,1,1&target=1,1,1", "eye is on the target"},
      {"/api/frame?eye=1,1,1", "both"},
      {"/api/frame?format=gif", "'format'"},
      {"/api/frame?quality=0", "'quality'"},
      {"/api/frame?lod=fast", "'lod'"},
      {"/api/frame?px=-1", "'px'"},
      {"/api/frame?px=nan", "'px'"},
      {"/api/frame?w=1&w=2", "twice"},
      {"/api/frame?w=%zz", "percent"},
      {"/api/pick?w=10&h=10&x=10&y=0", "inside"},
      {"/api/pick?w=10&h=10", "missing 'x'"},
      {"/api/pick?w=10&h=10&x=1", "missing 'y'"},
      {"/api/frame?fov=30", "'fov' needs 'eye' and 'target'"},
      {"/api/stats?format=png", "unknown parameter 'format'"},
      {"/api/model?x=1", "no parameters"},
  };
  for (const auto& [target, reason] : cases) {
    Response r = c.request(target);
    EXPECT_EQ(r.status, 400) << target;
    EXPECT_EQ(r.headers["content-type"], "application/json") << target;
    const auto j = json_of(r);
    ASSERT_TRUE(j.contains("error")) << target << ": " << r.body;
    EXPECT_NE(j["error"].get<std::string>().find(reason), std::string::npos) << target << ": " << r.body;
  }
  // The connection still serves after all that.
  EXPECT_TRUE(is_image(c.request("/api/frame?w=32&h=32"), 32, 32, ".jpg"));
  Response post = [&] {
    c.send("POST /api/frame HTTP/1.1\r\nHost: t\r\nContent-Length: 2\r\n\r\nhi");
    return c.read();
  }();
  EXPECT_EQ(post.status, 405);
  EXPECT_EQ(post.headers["allow"], "GET");
}

// clip=, box=, caps=, colour_by=, hide=, only= and highlight= on frame, stats and pick: accepted,
// refused with a 400 naming the parameter when malformed, and highlight words looked up in the
// store (a tag or an id; one naming nothing is a 404 that names it). Whether the image obeys
// them is the renderer's (test_render.cpp); here the HTTP layer.
TEST(Service, ViewFilterParametersAreAcceptedAndBadOnesRefusedNamingThem) {
  Server server;
  Client c(server.port());
  ASSERT_TRUE(c.connected());
  const std::string id = json_of(c.request("/api/objects/BOX-2"))["id"].get<std::string>();
  const std::string filters = "&clip=0,0,0.5,0,0,1&clip=14,0,0,1,0,0&box=-1,-1,-1,16,1,1&caps=1"
                              "&colour_by=Type&hide=pipe&only=equipment,BOX-*";
  for (const std::string& highlight : std::vector<std::string>{"BOX-2", "/BOX-2", id, "BOX-1," + id}) {
    const std::string view = kView + filters + "&highlight=" + highlight;
    Response frame = c.request("/api/frame?" + view + "&w=64&h=48&format=png");
    EXPECT_TRUE(is_image(frame, 64, 48, ".png")) << highlight << ": " << frame.status << " " << frame.body;
    EXPECT_EQ(c.request("/api/stats?" + view + "&w=64&h=48").status, 200) << highlight;
    EXPECT_EQ(c.request("/api/pick?" + view + "&w=64&h=48&x=32&y=24").status, 200) << highlight;
  }
  for (const std::string path : {"/api/frame?", "/api/stats?", "/api/pick?x=1&y=1&"}) {
    Response unknown = c.request(path + kView + "&highlight=BOX-2,NO-SUCH-TAG");
    EXPECT_EQ(unknown.status, 404) << path << ": " << unknown.body;
    EXPECT_NE(unknown.body.find("'highlight': no object has the id or the tag 'NO-SUCH-TAG'"), std::string::npos)
        << unknown.body;
  }
  const std::pair<std::string, std::string> bad[] = {
      {"clip=0,0,0,0,0,0", "'clip'"},
      {"clip=0,0,0,0,0,1&clip=0,0,0,0,0,1&clip=0,0,0,0,0,1&clip=0,0,0,0,0,1&clip=0,0,0,0,0,1"
       "&clip=0,0,0,0,0,1&clip=0,0,0,0,0,1",
       "'clip': at most 6"},
      {"box=2,0,0,1,1,1", "'box'"},
      {"caps=2", "'caps'"},
      {"hide=", "'hide'"},
      {"only=", "'only'"},
      {"highlight=", "'highlight'"},
  };
  for (const std::string path : {"/api/frame?", "/api/stats?", "/api/pick?x=1&y=1&"}) {
    for (const auto& [query, reason] : bad) {
      Response r = c.request(path + query);
      EXPECT_EQ(r.status, 400) << path << query;
      EXPECT_NE(r.body.find(reason), std::string::npos) << path << query << ": " << r.body;
    }
  }
  // The view of one request does not stay with the renderer: the next plain frame sees all six.
  Response plain = c.request("/api/frame?" + kView + "&w=160&h=90");
  EXPECT_EQ(plain.headers["x-objects-visible"], "6");
  EXPECT_EQ(server.stop(), 0);
}

// A colour_by key no object has is the caller's mistake: 400 with the renderer's message (which
// lists the keys), not a 500. Skipped where the renderer does not yet colour by attributes (it
// then draws the frame).
TEST(Service, AnUnknownColourByKeyIsA400) {
  Server server;
  Client c(server.port());
  Response r = c.request("/api/frame?" + kView + "&w=32&h=32&colour_by=NoSuchKey");
  if (r.status == 200) GTEST_SKIP() << "this renderer ignores colour_by";
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_NE(r.body.find("Type"), std::string::npos) << r.body;
  EXPECT_EQ(server.stop(), 0);
}

TEST(Service, BrokenHttpHugeHeadersAndBodiesCloseOnlyThatConnection) {
  Server server;
  Client broken(server.port());
  broken.send("THIS IS NOT HTTP\r\n\r\n");
  Response r = broken.read();
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("malformed"), std::string::npos);
  EXPECT_TRUE(broken.closed_by_server());

  Client huge(server.port());
  huge.send("GET /api/model HTTP/1.1\r\nHost: t\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n");
  EXPECT_EQ(huge.read().status, 431);

  Client body(server.port());
  body.send("GET /api/model HTTP/1.1\r\nHost: t\r\nContent-Length: 10000000\r\n\r\n");
  EXPECT_EQ(body.read().status, 413);

  Client fine(server.port());
  EXPECT_EQ(fine.request("/api/model").status, 200);
}

TEST(Service, ASlowClientTimesOutAndADepartingOneDisturbsNobody) {
  Server server({"--request-timeout", "0.5"});
  Client slow(server.port());
  slow.send("GET /api/mod");  // and nothing more
  Response r = slow.read();
  EXPECT_EQ(r.status, 408);

  for (int i = 0; i < 5; ++i) {
    Client gone(server.port());
    gone.get("/api/frame?w=800&h=600&format=png");
  }  // closed before the answer
  Client fine(server.port());
  EXPECT_TRUE(is_image(fine.request("/api/frame?w=48&h=32&format=png"), 48, 32, ".png"));
}

TEST(Service, PipelinedRequestsAreAnsweredInOrder) {
  Server server;
  Client c(server.port());
  // The second frame in another latest-wins slot (another connection's, by the id the server
  // issued it), so that it does not supersede the first.
  const std::string other = Client(server.port()).request("/api/stats?w=8&h=8").headers["x-plantview-client"];
  c.send("GET /api/frame?w=40&h=30&format=png HTTP/1.1\r\nHost: t\r\n\r\n"
         "GET /api/model HTTP/1.1\r\nHost: t\r\n\r\n"
         "GET /api/frame?w=20&h=10&format=png&client=" + other + " HTTP/1.1\r\nHost: t\r\n\r\n"
         "GET /api/stats?w=20&h=10 HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n"
         "GET /api/model HTTP/1.1\r\nHost: t\r\n\r\n");
  EXPECT_TRUE(is_image(c.read(), 40, 30, ".png"));
  Response model = c.read();
  EXPECT_EQ(model.status, 200);
  EXPECT_TRUE(json_of(model).contains("objects"));
  EXPECT_TRUE(is_image(c.read(), 20, 10, ".png"));
  Response stats = c.read();
  EXPECT_EQ(stats.status, 200);
  EXPECT_EQ(stats.headers["connection"], "close");
  EXPECT_TRUE(c.closed_by_server());  // nothing after Connection: close
}

TEST(Service, ThirtyTwoClientsOfFiftyFramesEachAllGetTheirImages) {
  Server server;
  constexpr int kClients = 32, kFrames = 50;
  std::atomic<int> good{0}, bad{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kClients; ++t) {
    threads.emplace_back([&, t] {
      Client c(server.port());
      for (int f = 0; f < kFrames; ++f) {
        const uint32_t w = 24 + uint32_t(t), h = 16 + uint32_t(f % 7);
        Response r = c.request("/api/frame?w=" + std::to_string(w) + "&h=" + std::to_string(h) +
                               "&format=png&eye=" + std::to_string(-5 - f) + ",-10,5&target=7,0,0");
        (is_image(r, w, h, ".png") ? good : bad) += 1;
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(good.load(), kClients * kFrames);
  EXPECT_EQ(bad.load(), 0);
}

TEST(Service, ANewerRequestOfTheSameClientSupersedesAWaitingOne) {
  Server server;
  // Keep the render threads busy, then queue two requests of one client on two connections (the
  // id the server issued to the first, sent by both): the first waits and is superseded by the
  // second. Two full-size frames without LOD on both render threads take minutes under the
  // ThreadSanitizer on a loaded 2-core machine: the reads wait that long (what is tested is
  // which request is answered, not how fast).
  constexpr int kPatientS = 300;
  Client busy(server.port(), kPatientS), busy2(server.port(), kPatientS), a(server.port(), kPatientS),
      b(server.port(), kPatientS);
  const std::string id = a.request("/api/stats?w=8&h=8").headers["x-plantview-client"];
  ASSERT_EQ(id.size(), 32u);
  busy.get("/api/frame?w=2000&h=2000&format=png&lod=none");
  busy2.get("/api/frame?w=2000&h=2000&format=png&lod=none");
  std::this_thread::sleep_for(50ms);
  a.get("/api/frame?w=30&h=30&client=" + id);
  std::this_thread::sleep_for(50ms);
  b.get("/api/frame?w=31&h=31&client=" + id);
  Response first = a.read(), second = b.read();
  EXPECT_EQ(busy.read().status, 200);
  EXPECT_EQ(busy2.read().status, 200);
  // The first may have started before the second arrived on a fast machine; then both are
  // images. Otherwise it is answered 409.
  EXPECT_TRUE(first.status == 409 || is_image(first, 30, 30, ".jpg")) << first.status;
  EXPECT_TRUE(is_image(second, 31, 31, ".jpg"));
}

TEST(Service, AFullQueueAnswers503WithRetryAfter) {
  Server server({"--max-queue", "1"});
  // Not before the server's own first frame has left the queue.
  ASSERT_EQ(wait_until_ready(server.port()).back(), 200);
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < 6; ++i) {
    clients.push_back(std::make_unique<Client>(server.port()));
    clients.back()->get("/api/frame?w=1500&h=1500&format=png&lod=none");
  }
  int busy = 0, ok = 0;
  for (auto& c : clients) {
    Response r = c->read();
    if (r.status == 503) {
      ++busy;
      EXPECT_EQ(r.headers["retry-after"], "1");
    } else if (r.status == 200) {
      ++ok;
    }
  }
  EXPECT_GT(busy, 0);
  EXPECT_GT(ok, 0);
  EXPECT_EQ(busy + ok, 6);
}

TEST(Service, ConnectionsBeyondTheLimitAreRefused) {
  Server server({"--max-clients", "2"});
  Client a(server.port()), b(server.port());
  EXPECT_EQ(a.request("/api/model").status, 200);
  EXPECT_EQ(b.request("/api/model").status, 200);
  Client c(server.port());
  Response r = c.read();
  EXPECT_EQ(r.status, 503);
  EXPECT_EQ(a.request("/api/model").status, 200);
}

TEST(Service, TheTokenIsRequiredWhenGivenAndOffLoopback) {
  {
    Server server({"--token", "s3cret"});
    Client c(server.port());
    Response none = c.request("/api/model");
    EXPECT_EQ(none.status, 401);
    EXPECT_EQ(none.headers["www-authenticate"], "Bearer");
    EXPECT_EQ(c.request("/api/model", "Authorization: Bearer wrong\r\n").status, 401);
    EXPECT_EQ(c.request("/api/model", "Authorization: Bearer s3cret\r\n").status, 200);
    // The viewer page opens without it (it sends the token with its API requests).
    Response page = c.request("/");
    EXPECT_EQ(page.status, 200);
    EXPECT_NE(page.body.find("<html"), std::string::npos);
    EXPECT_EQ(c.request("/viewer.js").status, 200);
  }
  // Binding beyond loopback without a token does not start.
  const std::string command = std::string(PLANTVIEW_BIN) + " serve --store " + small_store() +
                              " --listen 0.0.0.0:0 2>&1";
  FILE* p = popen(command.c_str(), "r");
  std::string out;
  char buf[256];
  while (fgets(buf, sizeof buf, p)) out += buf;
  const int status = pclose(p);
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_NE(out.find("--token"), std::string::npos) << out;
}

TEST(Service, ShutdownFinishesTheFrameInFlight) {
  Server server;
  Client c(server.port());
  c.get("/api/frame?w=1200&h=1200&format=png&lod=none");
  std::this_thread::sleep_for(100ms);
  kill(server.pid(), SIGTERM);
  EXPECT_TRUE(is_image(c.read(), 1200, 1200, ".png"));
  EXPECT_EQ(server.wait(), 0);
}


// --- operations: health, drain, read-only stores, metrics ---------------------------------------

TEST(Service, ReadyzSays503UntilTheFirstFrameThen200AndHealthzNeedsNoToken) {
  Server server({"--token", "s3cret"});
  const std::vector<int> seen = wait_until_ready(server.port());
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 200);
  for (size_t i = 0; i + 1 < seen.size(); ++i) EXPECT_EQ(seen[i], 503) << "before ready";
  Client c(server.port());
  Response live = c.request("/healthz");
  EXPECT_EQ(live.status, 200);
  EXPECT_EQ(c.request("/readyz?x=1").status, 400);
  EXPECT_EQ(c.request("/api/model").status, 401);  // the token still guards everything else
  Response metrics = c.request("/metrics", "Authorization: Bearer s3cret\r\n");
  EXPECT_NE(metrics.body.find("plantview_ready 1\n"), std::string::npos) << metrics.body;
  // The warm-up frame is the server's own: it is not counted as a client's.
  EXPECT_NE(metrics.body.find("plantview_render_milliseconds_count{kind=\"frame\"} 0\n"), std::string::npos);
  EXPECT_EQ(server.stop(), 0);
}

TEST(Service, SigtermDrainLosesNoRequestAlreadyRead) {
  Server server;
  ASSERT_EQ(wait_until_ready(server.port()).back(), 200);
  // A slow frame first, so that the others wait in the queue when the signal comes.
  Client busy(server.port());
  busy.get("/api/frame?w=1400&h=1400&format=png&lod=none");
  // One frame per connection: each its own latest-wins slot, so none supersedes another.
  constexpr int kClients = 16;
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < kClients; ++i) {
    clients.push_back(std::make_unique<Client>(server.port()));
    clients.back()->get("/api/frame?w=" + std::to_string(40 + i) + "&h=30&format=png");
  }
  // Every request has been read once the server answers one sent after them on a connection
  // of its own (connections are read in the order their bytes arrive).
  Client probe(server.port());
  EXPECT_EQ(probe.request("/healthz").status, 200);
  kill(server.pid(), SIGTERM);
  std::this_thread::sleep_for(100ms);
  Client late(server.port());
  EXPECT_FALSE(late.connected() && late.request("/healthz").status == 200) << "accepted after SIGTERM";
  EXPECT_TRUE(is_image(busy.read(), 1400, 1400, ".png"));
  int images = 0;
  for (int i = 0; i < kClients; ++i) {
    Response r = clients[size_t(i)]->read();
    images += is_image(r, 40 + uint32_t(i), 30, ".png");
    EXPECT_EQ(r.headers["connection"], "close");  // the last answer it owes, while draining
    EXPECT_TRUE(clients[size_t(i)]->closed_by_server());
  }
  EXPECT_EQ(images, kClients);
  EXPECT_EQ(server.wait(), 0);
}

// A viewer page of `bytes` bytes, so that a client that does not read leaves megabytes unsent
// without any rendering.
fs::path big_web_directory(const test::TempDir& dir, size_t bytes) {
  fs::create_directories(dir.path());
  std::ofstream(dir.path() / "index.html", std::ios::binary) << std::string(bytes, 'x');
  return dir.path();
}

// Sends pipelined requests for the big page and reads nothing; the socket's receive buffer is
// small, so the server's bytes stay queued.
std::unique_ptr<Client> non_reading_client(int port, int pages) {
  auto c = std::make_unique<Client>(port, test_support::ConnectOptions{"", 4096, 10});
  std::string batch;
  for (int i = 0; i < pages; ++i) batch += "GET / HTTP/1.1\r\nHost: t\r\n\r\n";
  c->send(batch);
  return c;
}

// Polls /metrics on `c` until it shows `line`; false if it does not within `limit`.
bool wait_for_metric(Client& c, const std::string& line, std::chrono::seconds limit = 10s) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    if (c.request("/metrics").body.find(line) != std::string::npos) return true;
    std::this_thread::sleep_for(20ms);
  }
  return false;
}

// The same on a connection of its own.
bool wait_for_metric(int port, const std::string& line, std::chrono::seconds limit = 10s) {
  Client c(port);
  return wait_for_metric(c, line, limit);
}

TEST(Service, AClientThatDoesNotReadIsDisconnectedAtTheWriteDeadline) {
  const test::TempDir web;
  constexpr size_t kPage = 8u << 20;
  Server server({"--web", big_web_directory(web, kPage).string(), "--write-timeout", "0.5"});
  auto stuck = non_reading_client(server.port(), 4);
  // The stuck client reads nothing until the server says it has given up on it: how soon that is
  // depends on the machine (seconds under the sanitizers on a loaded one), what it does does not.
  Client fine(server.port());
  EXPECT_TRUE(wait_for_metric(fine, "plantview_timed_out_connections_total 1\n", 120s));
  bool closed = false;
  const size_t received = stuck->read_until_closed(closed);
  EXPECT_TRUE(closed);
  EXPECT_LT(received, 4 * kPage);
  const Response metrics = fine.request("/metrics");
  EXPECT_NE(metrics.body.find("plantview_connections 1\n"), std::string::npos) << metrics.body;
}

TEST(Service, SigtermExitsWithinTheShutdownDeadlineDespiteAClientThatDoesNotRead) {
  const test::TempDir web;
  Server server({"--web", big_web_directory(web, 8u << 20).string(), "--shutdown-timeout", "1"});
  auto stuck = non_reading_client(server.port(), 4);
  // Its requests have been read and the first answer is on its way.
  ASSERT_TRUE(wait_for_metric(server.port(), "plantview_requests_total{endpoint=\"page\",status=\"200\"}"));
  const auto signalled = std::chrono::steady_clock::now();
  kill(server.pid(), SIGTERM);
  // The deadline (1 s), then the render thread's and the store's close: a second or so, several
  // under the sanitizers. Without the deadline it would wait for the client for ever.
  EXPECT_EQ(server.wait_at_most(20s), 0);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count();
  EXPECT_GE(seconds, 0.9);
  EXPECT_LT(seconds, 15.0);
}

TEST(Service, ARequestFollowedByAHalfCloseIsAnsweredThenClosed) {
  Server server;
  Client c(server.port());
  c.get("/api/frame?w=32&h=24&format=png");
  c.half_close();
  EXPECT_TRUE(is_image(c.read(), 32, 24, ".png"));
  EXPECT_TRUE(c.closed_by_server());
}

// --- hostile clients: silent connections, per-address limits ------------------------------------

test_support::ConnectOptions from(const std::string& address) {
  return {.source_address = address, .receive_buffer_bytes = 0, .receive_timeout_s = 10};
}

TEST(Service, SilentConnectionsCannotLockOutAClientAlreadyServed) {
  // A long request deadline: what lets the served client in is the reserved share, not the
  // silent connections timing out.
  Server server({"--max-clients", "16", "--request-timeout", "30"});
  ASSERT_EQ(wait_until_ready(server.port()).back(), 200);  // from 127.0.0.1: served
  {
    Client known(server.port(), from("127.0.0.1"));
    ASSERT_EQ(known.request("/api/model").status, 200);
  }
  std::vector<std::unique_ptr<Client>> silent;
  for (int i = 0; i < 24; ++i)
    silent.push_back(std::make_unique<Client>(server.port(), from("127.0.0." + std::to_string(2 + i % 4))));
  std::this_thread::sleep_for(200ms);  // all accepted (or refused) by now
  const auto start = std::chrono::steady_clock::now();
  Client known(server.port(), from("127.0.0.1"));
  EXPECT_TRUE(is_image(known.request("/api/frame?w=64&h=48"), 64, 48, ".jpg"));
  // Well before the silent connections' deadline (30 s) would have freed a slot; about 0.1 s
  // here, a few seconds under the sanitizers.
  EXPECT_LT(std::chrono::steady_clock::now() - start, 10s);
  // A stranger meanwhile finds the unreserved slots full.
  Client stranger(server.port(), from("127.0.0.20"));
  Response refused = stranger.read();
  EXPECT_EQ(refused.status, 503);
  EXPECT_EQ(refused.headers["retry-after"], "1");
  Response metrics = known.request("/metrics");
  // 12 silent connections fill the unreserved three quarters; the other 12 and the stranger
  // are refused.
  EXPECT_NE(metrics.body.find("plantview_refused_connections_total 13\n"), std::string::npos) << metrics.body;
}

TEST(Service, ConnectionsPerAddressAreLimitedAndSilentOnesCloseAtTheRequestDeadline) {
  Server server({"--max-per-address", "2", "--request-timeout", "0.5"});
  Client a(server.port(), from("127.0.0.5")), b(server.port(), from("127.0.0.5"));
  std::this_thread::sleep_for(100ms);
  Client c(server.port(), from("127.0.0.5"));
  Response r = c.read();
  EXPECT_EQ(r.status, 503);
  EXPECT_NE(r.body.find("127.0.0.5"), std::string::npos) << r.body;
  Client other(server.port(), from("127.0.0.6"));
  EXPECT_EQ(other.request("/api/model").status, 200);
  // a and b never sent a byte: closed when the deadline passes, without an answer.
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(a.closed_by_server());
  EXPECT_TRUE(b.closed_by_server());
  EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);
}

TEST(Service, TheTokenComesFromAFileOrTheEnvironment) {
  const test::TempDir dir;
  fs::create_directories(dir.path());
  const fs::path file = dir.path() / "token";
  std::ofstream(file) << "fr0m-file\n";
  {
    Server server({"--token-file", file.string()});
    Client c(server.port());
    EXPECT_EQ(c.request("/api/model").status, 401);
    EXPECT_EQ(c.request("/api/model", "Authorization: Bearer fr0m-file\r\n").status, 200);
  }
  {
    Server server({}, small_store(), Launch{{{"PLANTVIEW_TOKEN", "fr0m-env"}}, {}});
    Client c(server.port());
    EXPECT_EQ(c.request("/api/model").status, 401);
    EXPECT_EQ(c.request("/api/model", "Authorization: Bearer fr0m-env\r\n").status, 200);
  }
  const std::string both = std::string(PLANTVIEW_BIN) + " serve --store " + small_store() + " --token a --token-file " +
                           file.string() + " >/dev/null 2>&1";
  EXPECT_EQ(WEXITSTATUS(std::system(both.c_str())), 2);
}

// A copy of the test store (data.mdb only) in a directory of its own.
fs::path copy_of_store(const test::TempDir& dir) {
  fs::create_directories(dir.path());
  fs::copy_file(fs::path(small_store()) / "data.mdb", dir.path() / "data.mdb");
  return dir.path();
}

void expect_serves_frames(Server& server) {
  ASSERT_GT(server.port(), 0);
  EXPECT_EQ(wait_until_ready(server.port()).back(), 200);
  Client c(server.port());
  EXPECT_TRUE(is_image(c.request("/api/frame?w=48&h=32&format=png"), 48, 32, ".png"));
  EXPECT_EQ(server.stop(), 0);
}

TEST(Service, AStoreInADirectoryTheServerMayNotWriteIsServed) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to run the server as another user (nobody)";
  if (std::system("command -v setpriv >/dev/null") != 0) GTEST_SKIP() << "setpriv (util-linux) is missing";
  const test::TempDir dir;
  const fs::path store = copy_of_store(dir);
  // What a writer left: a lock file the reader may not write, in a directory it may not write.
  { std::ofstream(store / "lock.mdb") << ""; }
  fs::permissions(store / "data.mdb", fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  fs::permissions(store / "lock.mdb", fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  fs::permissions(store, fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                             fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec);
  Server server({}, store.string(),
                Launch{{{"HOME", "/tmp"}}, {"setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"}});
  expect_serves_frames(server);
  EXPECT_EQ(fs::file_size(store / "lock.mdb"), 0u);
}

TEST(Service, AStoreOnAReadOnlyMountIsServed) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root for a read-only bind mount (unshare -m)";
  if (std::system("unshare -m true 2>/dev/null") != 0) GTEST_SKIP() << "unshare -m is not permitted here";
  const test::TempDir dir;
  const fs::path store = copy_of_store(dir);
  // A private mount namespace: the bind mount is the server's alone and ends with it.
  const std::string script = "mount --bind -o ro \"$1\" \"$1\" && shift && exec \"$@\"";
  Server server({}, store.string(), Launch{{}, {"unshare", "-m", "sh", "-c", script, "sh", store.string()}});
  expect_serves_frames(server);
  EXPECT_FALSE(fs::exists(store / "lock.mdb"));  // nothing was written
}

// The python3 that has prometheus_client (Debian's python3-prometheus-client), or "".
std::string python_with_prometheus_client() {
  for (const char* python : {"/usr/bin/python3", "python3"})
    if (std::system((std::string(python) + " -c 'import prometheus_client.parser' 2>/dev/null").c_str()) == 0)
      return python;
  return {};
}

TEST(Service, MetricsParseAsPrometheusTextAfterHostilePaths) {
  const std::string python = python_with_prometheus_client();
  if (python.empty()) GTEST_SKIP() << "python3 with prometheus_client (python3-prometheus-client) is missing";
  Server server;
  Client c(server.port());
  // Paths a client might use to inject label text; each is answered and counted as 'other'
  // (or as malformed HTTP).
  for (const std::string path : {"/a\"b", "/a\\\\b", "/%0Ainjected{x=\"1\"} 1", "/a%22b"}) {
    Client hostile(server.port());
    hostile.send("GET " + path + " HTTP/1.1\r\nHost: t\r\n\r\n");
    EXPECT_NE(hostile.read().status, 0) << path;
  }
  EXPECT_EQ(c.request("/api/frame?w=32&h=32").status, 200);
  EXPECT_EQ(c.request("/api/stats?w=32&h=32").status, 200);
  const Response metrics = c.request("/metrics");
  ASSERT_EQ(metrics.status, 200);
  const test::TempDir dir;
  fs::create_directories(dir.path());
  std::ofstream(dir.path() / "metrics.txt", std::ios::binary) << metrics.body;
  // Parses the page, and prints every sample as name{labels} value, one a line.
  std::ofstream(dir.path() / "parse.py") << R"(import sys
from prometheus_client.parser import text_string_to_metric_families
for family in text_string_to_metric_families(open(sys.argv[1]).read()):
    for s in family.samples:
        labels = ",".join(k + "=" + v for k, v in sorted(s.labels.items()))
        print(f"{s.name}{{{labels}}} {s.value!r}")
)";
  const std::string command = python + " " + (dir.path() / "parse.py").string() + " " +
                              (dir.path() / "metrics.txt").string() + " 2>&1";
  FILE* p = popen(command.c_str(), "r");
  std::string out;
  char buf[512];
  while (fgets(buf, sizeof buf, p)) out += buf;
  ASSERT_EQ(pclose(p), 0) << out << "\nfrom\n" << metrics.body;
  const auto has = [&](const std::string& line) { return out.find(line + "\n") != std::string::npos; };
  EXPECT_TRUE(has("plantview_render_milliseconds_count{kind=frame} 1.0")) << out;
  EXPECT_TRUE(has("plantview_render_milliseconds_count{kind=stats} 1.0")) << out;
  EXPECT_TRUE(has("plantview_render_milliseconds_count{kind=pick} 0.0")) << out;
  EXPECT_TRUE(has("plantview_requests_total{endpoint=other,status=404} 3.0") ||
              has("plantview_requests_total{endpoint=other,status=404} 4.0"))
      << out;
  EXPECT_EQ(out.find("injected"), std::string::npos) << out;
  // Integers are written as integers (a byte count as 5.19906e+07 loses digits).
  EXPECT_EQ(metrics.body.find("e+"), std::string::npos) << metrics.body;
}

}  // namespace
}  // namespace plantview
