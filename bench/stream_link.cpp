// Rules: stream_link.h.
#include "stream_link.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sched.h>
#include <signal.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <memory>
#include <vector>

namespace plantview::bench {

namespace {

using Clock = std::chrono::steady_clock;

bool sh(const std::string& command, std::string& error) {
  const int rc = std::system((command + " 2>/tmp/pvbench-ip.err").c_str());
  if (rc == 0) return true;
  std::string why;
  if (FILE* f = std::fopen("/tmp/pvbench-ip.err", "r")) {
    char line[256];
    if (std::fgets(line, sizeof line, f)) why = line;
    std::fclose(f);
    while (!why.empty() && why.back() == '\n') why.pop_back();
  }
  error = "'" + command + "' failed" + (why.empty() ? "" : ": " + why);
  return false;
}

// Namespaces and host interfaces of bench processes that no longer run.
void remove_leftovers() {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/run/netns", ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("pvbench", 0) != 0) continue;
    const int pid = std::atoi(name.c_str() + 7);
    if (pid > 0 && kill(pid, 0) == 0) continue;
    std::system(("ip netns del " + name + " 2>/dev/null").c_str());
    std::system(("ip link del " + name + "h 2>/dev/null").c_str());
  }
}

}  // namespace

int connect_tcp(const std::string& host, int port, std::string& error) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    error = std::string("socket: ") + std::strerror(errno);
    return -1;
  }
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  inet_pton(AF_INET, host.c_str(), &a.sin_addr);
  if (connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    error = "connect " + host + ":" + std::to_string(port) + ": " + std::strerror(errno);
    close(fd);
    return -1;
  }
  const int one = 1;
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

bool ShapedLink::make(double rate_mbit, std::string& error) {
  if (geteuid() != 0) {
    error = "needs root (ip netns, tc)";
    return false;
  }
  remove_leftovers();
  const std::string id = std::to_string(getpid());
  ns_ = "pvbench" + id;
  host_if_ = ns_ + "h";
  if (host_if_.size() > 15) host_if_ = "pvb" + id.substr(id.size() > 10 ? id.size() - 10 : 0) + "h";
  const std::string peer_if = host_if_.substr(0, host_if_.size() - 1) + "p";
  // A /30 of 10.213.0.0/16 per process.
  const unsigned n = unsigned(getpid()) % 16384;
  const std::string prefix = "10.213." + std::to_string(n / 64) + ".";
  const unsigned base = (n % 64) * 4;
  host_ip_ = prefix + std::to_string(base + 1);
  const std::string peer_ip = prefix + std::to_string(base + 2);
  made_ = true;  // from here on remove() undoes what was made
  if (!sh("ip netns add " + ns_, error) || !sh("ip -n " + ns_ + " link set lo up", error) ||
      !sh("ip link add " + host_if_ + " type veth peer name " + peer_if + " netns " + ns_, error) ||
      !sh("ip addr add " + host_ip_ + "/30 dev " + host_if_, error) ||
      !sh("ip link set " + host_if_ + " up", error) ||
      !sh("ip -n " + ns_ + " addr add " + peer_ip + "/30 dev " + peer_if, error) ||
      !sh("ip -n " + ns_ + " link set " + peer_if + " up", error))
    return false;
  if (rate_mbit > 0) {
    // A bucket of 32 KB (burst: a few packets at once), and a queue of 100 ms at the rate.
    char rate[64];
    std::snprintf(rate, sizeof rate, "rate %.3fmbit burst 32kb latency 100ms", rate_mbit);
    if (!sh("tc qdisc add dev " + host_if_ + " root tbf " + rate, error) ||
        !sh("ip netns exec " + ns_ + " tc qdisc add dev " + peer_if + " root tbf " + rate, error))
      return false;
  }
  return true;
}

void ShapedLink::remove() {
  if (!made_) return;
  made_ = false;
  std::system(("ip link del " + host_if_ + " 2>/dev/null").c_str());  // both ends, their qdiscs
  std::system(("ip netns del " + ns_ + " 2>/dev/null").c_str());
}

int ShapedLink::connect_in(const std::string& host, int port, std::string& error) const {
  // A socket belongs to the namespace it was made in: this thread enters the namespace for
  // socket() alone.
  const int target = open(("/run/netns/" + ns_).c_str(), O_RDONLY | O_CLOEXEC);
  const int self = open("/proc/thread-self/ns/net", O_RDONLY | O_CLOEXEC);
  if (target < 0 || self < 0) {
    error = "open namespace " + ns_ + ": " + std::strerror(errno);
    if (target >= 0) close(target);
    if (self >= 0) close(self);
    return -1;
  }
  int fd = -1;
  if (setns(target, CLONE_NEWNET) != 0) {
    error = std::string("setns: ") + std::strerror(errno);
  } else {
    fd = connect_tcp(host, port, error);
    if (setns(self, CLONE_NEWNET) != 0) std::abort();  // the thread must not stay inside
  }
  close(target);
  close(self);
  return fd;
}

// --- the delay proxy ------------------------------------------------------------------------------

bool DelayProxy::start(const std::string& listen_ip, int target_port, double delay_ms, std::string& error) {
  target_port_ = target_port;
  delay_ms_ = delay_ms;
  listen_fd_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  inet_pton(AF_INET, listen_ip.c_str(), &a.sin_addr);
  socklen_t len = sizeof a;
  if (listen_fd_ < 0 || bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      listen(listen_fd_, 64) != 0 || getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    error = "proxy on " + listen_ip + ": " + std::strerror(errno);
    return false;
  }
  port_ = ntohs(a.sin_port);
  wake_fd_ = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  thread_ = std::thread(&DelayProxy::run, this);
  return true;
}

void DelayProxy::stop() {
  if (!thread_.joinable()) return;
  stopping_ = true;
  const uint64_t one = 1;
  if (write(wake_fd_, &one, sizeof one) < 0) {}
  thread_.join();
  close(listen_fd_);
  close(wake_fd_);
}

namespace {

constexpr size_t kMaxQueuedBytes = size_t(4) << 20;

struct Chunk {
  Clock::time_point due;
  std::string bytes;
  size_t written = 0;
};

// One direction of a proxied connection: read from `from`, held, written to `to`.
struct Direction {
  int from = -1, to = -1;
  std::deque<Chunk> queue;
  size_t queued = 0;
  bool eof = false, shut = false;
};

struct Pair {
  Direction up, down;  // client -> server, server -> client
  bool done() const { return up.shut && down.shut; }
};

}  // namespace

void DelayProxy::run() {
  const int ep = epoll_create1(EPOLL_CLOEXEC);
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.fd = listen_fd_;
  epoll_ctl(ep, EPOLL_CTL_ADD, listen_fd_, &ev);
  ev.data.fd = wake_fd_;
  epoll_ctl(ep, EPOLL_CTL_ADD, wake_fd_, &ev);
  std::vector<std::unique_ptr<Pair>> pairs;
  const auto delay = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(delay_ms_));
  std::vector<char> buffer(1 << 16);
  while (!stopping_) {
    // What each socket waits for: reading while its direction's queue has room, writing while
    // the direction into it has bytes due.
    const Clock::time_point now = Clock::now();
    Clock::time_point next_due = Clock::time_point::max();
    for (auto& p : pairs) {
      for (int fd : {p->up.from, p->down.from}) {
        Direction& in = fd == p->up.from ? p->up : p->down;     // read from fd
        Direction& out = fd == p->up.from ? p->down : p->up;    // written to fd
        uint32_t events = 0;
        if (!in.eof && in.queued < kMaxQueuedBytes) events |= EPOLLIN;
        if (!out.queue.empty()) {
          if (out.queue.front().due <= now) events |= EPOLLOUT;
          else next_due = std::min(next_due, out.queue.front().due);
        }
        epoll_event e{};
        e.events = events;
        e.data.fd = fd;
        epoll_ctl(ep, EPOLL_CTL_MOD, fd, &e);
      }
    }
    int timeout_ms = -1;
    if (next_due != Clock::time_point::max())
      timeout_ms = int(std::chrono::ceil<std::chrono::milliseconds>(next_due - now).count());
    epoll_event events[64];
    const int n = epoll_wait(ep, events, 64, timeout_ms);
    for (int i = 0; i < n; ++i) {
      const int fd = events[i].data.fd;
      if (fd == wake_fd_) continue;
      if (fd == listen_fd_) {
        const int client = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (client < 0) continue;
        std::string error;
        const int server = connect_tcp("127.0.0.1", target_port_, error);
        if (server < 0) {
          close(client);
          continue;
        }
        fcntl(server, F_SETFL, fcntl(server, F_GETFL) | O_NONBLOCK);
        const int one = 1;
        setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        auto p = std::make_unique<Pair>();
        p->up.from = p->down.to = client;
        p->up.to = p->down.from = server;
        for (int s : {client, server}) {
          epoll_event e{};
          e.events = 0;
          e.data.fd = s;
          epoll_ctl(ep, EPOLL_CTL_ADD, s, &e);
        }
        pairs.push_back(std::move(p));
        continue;
      }
      for (auto& p : pairs) {
        if (fd != p->up.from && fd != p->down.from) continue;
        Direction& in = fd == p->up.from ? p->up : p->down;
        Direction& out = fd == p->up.from ? p->down : p->up;
        if ((events[i].events & (EPOLLIN | EPOLLHUP | EPOLLERR)) && !in.eof && in.queued < kMaxQueuedBytes) {
          const ssize_t got = read(fd, buffer.data(), buffer.size());
          if (got > 0) {
            in.queue.push_back({Clock::now() + delay, std::string(buffer.data(), size_t(got)), 0});
            in.queued += size_t(got);
          } else if (got == 0 || (errno != EAGAIN && errno != EINTR)) {
            in.eof = true;
          }
        }
        if ((events[i].events & EPOLLERR) || ((events[i].events & EPOLLHUP) && in.eof)) {
          // Gone both ways: what it sent goes on; what it would get is dropped.
          in.eof = out.eof = true;
          out.queue.clear();
          out.queued = 0;
          continue;
        }
        if (events[i].events & EPOLLOUT) {
          const Clock::time_point t = Clock::now();
          while (!out.queue.empty() && out.queue.front().due <= t) {
            Chunk& c = out.queue.front();
            const ssize_t put = send(fd, c.bytes.data() + c.written, c.bytes.size() - c.written, MSG_NOSIGNAL);
            if (put <= 0) {
              if (put < 0 && errno != EAGAIN && errno != EINTR) {
                out.queue.clear();  // the reader is gone
                out.queued = 0;
                out.eof = true;
              }
              break;
            }
            c.written += size_t(put);
            out.queued -= size_t(put);
            if (c.written == c.bytes.size()) out.queue.pop_front();
          }
        }
        break;
      }
    }
    // A direction whose sender closed and whose bytes are all passed on is closed onward.
    for (auto& p : pairs) {
      for (Direction* d : {&p->up, &p->down}) {
        if (d->eof && d->queue.empty() && !d->shut) {
          shutdown(d->to, SHUT_WR);
          d->shut = true;
        }
      }
    }
    std::erase_if(pairs, [&](const std::unique_ptr<Pair>& p) {
      if (!p->done()) return false;
      close(p->up.from);
      close(p->up.to);
      return true;
    });
  }
  for (auto& p : pairs) {
    close(p->up.from);
    close(p->up.to);
  }
  close(ep);
}

}  // namespace plantview::bench
