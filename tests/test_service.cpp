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
#include "support/http_client.h"
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
    std::vector<Object> objects;
    for (int i = 0; i < 6; ++i) {
      Object o;
      o.name = "/BOX-" + std::to_string(i);
      o.source = "test";
      o.id = object_id(o.source, o.name);
      o.object_class = ObjectClass::equipment;
      o.origin_m = {i * 3.0, 0, 0};
      o.colour = {uint8_t(40 * i), 120, 200, 255};
      o.primitives.push_back(Primitive{Placement{}, Box{2, 2, 2}});
      o.attributes = {{"Type", "EQUI"}, {"Index", std::to_string(i)}};
      objects.push_back(std::move(o));
    }
    const IngestResult result = ingest_objects(*store, objects);
    EXPECT_TRUE(result) << result.error().message;
    return d.string();
  }();
  return dir;
}

class Server {
 public:
  explicit Server(std::vector<std::string> extra = {}, const std::string& store = small_store()) {
    int out[2];
    EXPECT_EQ(pipe(out), 0);
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], 1);
      close(out[0]);
      std::vector<std::string> args = {PLANTVIEW_BIN, "serve", "--store", store, "--listen", "127.0.0.1:0",
                                       "--vertex-budget", "64"};
      args.insert(args.end(), extra.begin(), extra.end());
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(PLANTVIEW_BIN, argv.data());
      _exit(127);
    }
    close(out[1]);
    // "listening on http://127.0.0.1:PORT/"
    std::string line;
    char c;
    pollfd pfd{out[0], POLLIN, 0};
    while (line.find('\n') == std::string::npos && poll(&pfd, 1, 30000) > 0 && read(out[0], &c, 1) == 1) line += c;
    close(out[0]);
    const size_t colon = line.rfind(':');
    if (colon != std::string::npos) port_ = std::atoi(line.c_str() + colon + 1);
    EXPECT_GT(port_, 0) << "server did not start: '" << line << "'";
  }
  ~Server() { stop(); }
  int port() const { return port_; }
  // SIGTERM; returns the exit status.
  int stop() {
    if (pid_ > 0) kill(pid_, SIGTERM);
    return wait();
  }
  // Waits for the server to exit (after a signal sent by the test itself).
  int wait() {
    if (pid_ <= 0) return status_;
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = 0;
    status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return status_;
  }
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = 0;
  int port_ = 0;
  int status_ = -1;
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
  EXPECT_NE(metrics.body.find("plantview_frame_milliseconds_count"), std::string::npos);
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
  // second.
  Client busy(server.port()), busy2(server.port()), a(server.port()), b(server.port());
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

}  // namespace
}  // namespace plantview
