// Replicas behind a real load balancer (haproxy): two `plantview serve` processes on loopback
// ports, health checks on /readyz, retries with redispatch for GETs. Sixteen clients fetch
// frames through haproxy while one replica is drained (SIGTERM) and restarted, and then the
// other is killed (SIGKILL) and restarted: no client may see an error, every client keeps
// getting frames, and each restarted replica rejoins. Prints the figures (requests, errors,
// haproxy's retries and redispatches). Label `replicas`: runs once in CI, about 20 s.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "plantview/ingest.h"
#include "plantview/store.h"
#include "support/box_row.h"
#include "support/http_client.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Client = test_support::HttpClient;
using Clock = std::chrono::steady_clock;

// Six boxes: quick frames on a CPU.
void build_store(const std::string& dir) {
  std::string error;
  auto store = Store::open(dir, Store::Mode::read_write, error);
  ASSERT_TRUE(store) << error;
  const std::vector<Object> objects = test::box_row_objects();
  const IngestResult result = ingest_objects(*store, objects);
  ASSERT_TRUE(result) << result.error().message;
}

// A loopback port nobody listens on now (the kernel's choice; free again once closed).
int free_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof a;
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &length);
  close(fd);
  return ntohs(a.sin_port);
}

// Starts a program with stdout and stderr into `log`; its process id.
pid_t spawn(std::vector<std::string> args, const fs::path& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execvp(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// Exit status of a child, waiting at most `limit`; -1 if it is still running then.
int wait_exit(pid_t pid, std::chrono::milliseconds limit) {
  const auto until = Clock::now() + limit;
  do {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(20ms);
  } while (Clock::now() < until);
  return -1;
}

bool wait_ready(int port, std::chrono::milliseconds limit) {
  const auto until = Clock::now() + limit;
  while (Clock::now() < until) {
    Client c(port, 2);
    if (c.connected() && c.request("/readyz").status == 200) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

// haproxy's statistics as CSV rows by "proxy/server": column name -> value.
std::map<std::string, std::map<std::string, std::string>> haproxy_stats(int port) {
  std::map<std::string, std::map<std::string, std::string>> rows;
  // HTTP/1.0, so that haproxy ends the page by closing (its HTTP/1.1 answer is chunked).
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval tv{5, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string page;
  const std::string request = "GET /stats;csv HTTP/1.0\r\n\r\n";
  if (connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      send(fd, request.data(), request.size(), MSG_NOSIGNAL) == ssize_t(request.size())) {
    char chunk[16384];
    for (ssize_t n; (n = recv(fd, chunk, sizeof chunk, 0)) > 0;) page.append(chunk, size_t(n));
  }
  close(fd);
  // The body, chunked: "<hex size>\r\n<bytes>\r\n" until a size of 0.
  std::string csv;
  const size_t head_end = page.find("\r\n\r\n");
  for (size_t at = head_end == std::string::npos ? page.size() : head_end + 4; at < page.size();) {
    const size_t line_end = page.find("\r\n", at);
    const size_t size = std::strtoul(page.c_str() + at, nullptr, 16);
    if (line_end == std::string::npos || size == 0 || line_end + 2 + size > page.size()) break;
    csv += page.substr(line_end + 2, size);
    at = line_end + 2 + size + 2;
  }
  std::istringstream lines(csv);
  std::string header, line;
  std::getline(lines, header);
  if (header.rfind("# ", 0) != 0) return rows;
  std::vector<std::string> names;
  std::istringstream h(header.substr(2));
  for (std::string name; std::getline(h, name, ',');) names.push_back(name);
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    std::map<std::string, std::string> row;
    size_t i = 0;
    for (std::string v; std::getline(fields, v, ',') && i < names.size(); ++i) row[names[i]] = v;
    rows[row["pxname"] + "/" + row["svname"]] = row;
  }
  return rows;
}

bool wait_status(int stats_port, const std::string& server, const std::string& status, std::chrono::milliseconds limit) {
  const auto until = Clock::now() + limit;
  while (Clock::now() < until) {
    if (haproxy_stats(stats_port)["replicas/" + server]["status"].rfind(status, 0) == 0) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

uint64_t stat(int stats_port, const std::string& row, const std::string& column) {
  const std::string v = haproxy_stats(stats_port)[row][column];
  return v.empty() ? 0 : std::stoull(v);
}

TEST(Replicas, ClientsThroughHaproxySeeNoErrorWhileReplicasDrainDieAndRejoin) {
  if (std::system("command -v haproxy >/dev/null") != 0) GTEST_SKIP() << "haproxy is not installed";
  const test::TempDir dir;
  fs::create_directories(dir.path());
  const std::string store = (dir.path() / "store").string();
  build_store(store);
  const int front = free_port(), stats_port = free_port();
  const int ports[2] = {free_port(), free_port()};
  const char* names[2] = {"a", "b"};
  // The replicas read one store; a balancer is one client address, so room for its connections.
  const auto start_replica = [&](int i) {
    return spawn({PLANTVIEW_BIN, "serve", "--store", store, "--listen", "127.0.0.1:" + std::to_string(ports[i]),
                  "--vertex-budget", "64", "--shutdown-timeout", "10"},
                 dir.path() / (std::string("replica-") + names[i] + ".log"));
  };
  pid_t replica[2] = {start_replica(0), start_replica(1)};

  const fs::path config = dir.path() / "haproxy.cfg";
  std::ofstream(config) << "global\n"
                           "  maxconn 512\n"
                           "defaults\n"
                           "  mode http\n"
                           "  timeout connect 1s\n"
                           "  timeout client 30s\n"
                           "  timeout server 10s\n"
                           "  retries 3\n"
                           "  option redispatch 1\n"
                           "  retry-on conn-failure empty-response response-timeout\n"
                           "frontend plantview\n"
                           "  bind 127.0.0.1:" << front << "\n"
                           "  default_backend replicas\n"
                           "backend replicas\n"
                           "  balance roundrobin\n"
                           "  http-reuse never\n"
                           "  option httpchk GET /readyz\n"
                           "  http-check expect status 200\n"
                           "  default-server inter 200ms fall 2 rise 2 maxconn 24\n"
                           "  server a 127.0.0.1:" << ports[0] << " check\n"
                           "  server b 127.0.0.1:" << ports[1] << " check\n"
                           "listen stats\n"
                           "  bind 127.0.0.1:" << stats_port << "\n"
                           "  stats enable\n"
                           "  stats uri /stats\n";
  const pid_t haproxy = spawn({"haproxy", "-f", config.string(), "-db"}, dir.path() / "haproxy.log");
  // Stops what the test started, by process id, however the test ends.
  struct StopAll {
    pid_t* replicas;
    pid_t balancer;
    ~StopAll() {
      for (int i = 0; i < 2; ++i)
        if (replicas[i] > 0) {
          kill(replicas[i], SIGKILL);
          waitpid(replicas[i], nullptr, 0);
          replicas[i] = 0;
        }
      kill(balancer, SIGTERM);
      waitpid(balancer, nullptr, 0);
    }
  } stop_all{replica, haproxy};
  ASSERT_TRUE(wait_ready(ports[0], 30s) && wait_ready(ports[1], 30s)) << "replicas did not become ready";
  ASSERT_TRUE(wait_status(stats_port, "a", "UP", 10s) && wait_status(stats_port, "b", "UP", 10s))
      << "haproxy does not see both replicas";

  constexpr int kClients = 16;
  std::atomic<bool> stop{false};
  std::atomic<int> phase{0};  // 0: both up, 1: a restarted, 2: b killed, 3: b restarted
  std::atomic<uint64_t> requests{0}, errors{0};
  std::vector<std::array<std::atomic<uint64_t>, 4>> frames(kClients);
  std::vector<std::string> first_errors;
  std::mutex errors_mutex;
  std::vector<std::thread> clients;
  for (int t = 0; t < kClients; ++t) {
    clients.emplace_back([&, t] {
      auto c = std::make_unique<Client>(front, 20);
      for (int f = 0; !stop; ++f) {
        const int p = phase;
        test_support::HttpResponse r = c->request(
            "/api/frame?w=320&h=180&eye=" + std::to_string(-5 - (f % 9)) + ",-12," + std::to_string(4 + t % 5) +
            "&target=7.5,0,0");
        requests += 1;
        const bool image = r.status == 200 && r.headers["content-type"] == "image/jpeg" && !r.body.empty();
        if (image) {
          frames[size_t(t)][size_t(p)] += 1;
        } else {
          errors += 1;
          std::lock_guard lock(errors_mutex);
          if (first_errors.size() < 10)
            first_errors.push_back(std::to_string(r.status) + " " + r.body.substr(0, 120));
        }
        if (r.status == 0 || r.headers["connection"] == "close") c = std::make_unique<Client>(front, 20);
      }
    });
  }

  // Phase 0 -> 1: replica a drains (SIGTERM) and exits 0; a new a starts and rejoins.
  std::this_thread::sleep_for(2s);
  const auto term_at = Clock::now();
  kill(replica[0], SIGTERM);
  const int drained = wait_exit(replica[0], 15s);
  const double drain_s = std::chrono::duration<double>(Clock::now() - term_at).count();
  replica[0] = drained >= 0 ? start_replica(0) : replica[0];
  EXPECT_EQ(drained, 0) << "replica a did not drain and exit 0";
  EXPECT_TRUE(wait_ready(ports[0], 30s));
  EXPECT_TRUE(wait_status(stats_port, "a", "UP", 10s)) << "replica a did not rejoin";
  phase = 1;
  std::this_thread::sleep_for(2s);
  // Phase 2: replica b dies with requests in flight (SIGKILL); haproxy retries elsewhere.
  kill(replica[1], SIGKILL);
  waitpid(replica[1], nullptr, 0);
  phase = 2;
  std::this_thread::sleep_for(2s);
  // Phase 3: b restarts and rejoins.
  replica[1] = start_replica(1);
  EXPECT_TRUE(wait_ready(ports[1], 30s));
  EXPECT_TRUE(wait_status(stats_port, "b", "UP", 10s)) << "replica b did not rejoin";
  phase = 3;
  std::this_thread::sleep_for(2s);
  stop = true;
  for (auto& t : clients) t.join();

  // The restarted replicas served frames of their own (counted since they started).
  uint64_t rejoined_frames[2] = {};
  for (int i = 0; i < 2; ++i) {
    Client c(ports[i], 5);
    const std::string metrics = c.request("/metrics").body;
    const std::string key = "plantview_requests_total{endpoint=\"frame\",status=\"200\"} ";
    const size_t at = metrics.find(key);
    if (at != std::string::npos) rejoined_frames[i] = std::stoull(metrics.substr(at + key.size()));
  }
  const uint64_t retries = stat(stats_port, "replicas/BACKEND", "wretr");
  const uint64_t redispatches = stat(stats_port, "replicas/BACKEND", "wredis");
  std::printf("replicas: %llu requests, %llu errors, haproxy retries %llu, redispatches %llu; "
              "drain of a took %.2f s; frames since restart: a %llu, b %llu\n",
              (unsigned long long)requests.load(), (unsigned long long)errors.load(), (unsigned long long)retries,
              (unsigned long long)redispatches, drain_s, (unsigned long long)rejoined_frames[0],
              (unsigned long long)rejoined_frames[1]);
  for (int t = 0; t < kClients; ++t)
    std::printf("  client %2d frames by phase: %llu %llu %llu %llu\n", t,
                (unsigned long long)frames[size_t(t)][0].load(), (unsigned long long)frames[size_t(t)][1].load(),
                (unsigned long long)frames[size_t(t)][2].load(), (unsigned long long)frames[size_t(t)][3].load());

  EXPECT_EQ(errors.load(), 0u) << (first_errors.empty() ? "" : first_errors.front());
  for (int t = 0; t < kClients; ++t)
    for (int p = 0; p < 4; ++p) EXPECT_GT(frames[size_t(t)][size_t(p)].load(), 0u) << "client " << t << " phase " << p;
  EXPECT_GT(rejoined_frames[0], 0u) << "the restarted replica a got no frames";
  EXPECT_GT(rejoined_frames[1], 0u) << "the restarted replica b got no frames";
}

}  // namespace
}  // namespace plantview
