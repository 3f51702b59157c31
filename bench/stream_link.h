// What bench_stream runs its viewers through: a slow link made on this machine, and the
// clients of the two ways a browser viewer gets frames (HTTP polling, the WebSocket stream).
//
// The link (ShapedLink): a network namespace with a veth pair into it; a token-bucket filter
// (tc tbf) on both ends shapes each direction to the rate; viewers connect from inside the
// namespace to a DelayProxy in the root namespace, which holds every byte for the delay each
// way before passing it on to the server (this kernel has no netem). So a viewer sees the rate
// and a round trip of twice the delay, plus what the bytes queue behind.
// Rules
//   - Needs root (ip netns, tc); make() says so in its error otherwise.
//   - Everything make() adds is named after the process (pvbench<pid>): remove() deletes it,
//     and so does make() for leftovers of processes that no longer run. The destructor
//     removes. A signal handler cannot run ip(8); the bench stops its runs on SIGINT/SIGTERM and
//     then removes.
//   - DelayProxy: one thread (epoll); each accepted connection gets its own connection to the
//     target; each direction is a queue of (due time, bytes), read while it holds under 4 MiB
//     (so the sender still feels a slow reader), written once due.
// Threads: a ShapedLink and a DelayProxy belong to the thread that made them (the proxy runs
// its own thread inside); connect_in() may be called on any thread.
// Errors: false and a message naming the command or call that failed.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

namespace plantview::bench {

class ShapedLink {
 public:
  ShapedLink() = default;
  ~ShapedLink() { remove(); }
  ShapedLink(const ShapedLink&) = delete;
  ShapedLink& operator=(const ShapedLink&) = delete;

  // rate_mbit <= 0: no shaping (the namespace and veth only).
  bool make(double rate_mbit, std::string& error);
  void remove();
  const std::string& host_address() const { return host_ip_; }  // root namespace's end
  // A TCP connection from inside the namespace to host:port (blocking), or -1 with a message.
  int connect_in(const std::string& host, int port, std::string& error) const;

 private:
  std::string ns_, host_if_, host_ip_;
  bool made_ = false;
};

// A TCP connection to host:port from the calling thread's namespace, or -1 with a message.
int connect_tcp(const std::string& host, int port, std::string& error);

class DelayProxy {
 public:
  DelayProxy() = default;
  ~DelayProxy() { stop(); }
  DelayProxy(const DelayProxy&) = delete;
  DelayProxy& operator=(const DelayProxy&) = delete;

  // Listens on listen_ip (port chosen by the system) and forwards to 127.0.0.1:target_port.
  bool start(const std::string& listen_ip, int target_port, double delay_ms, std::string& error);
  void stop();
  int port() const { return port_; }

 private:
  void run();
  int listen_fd_ = -1, wake_fd_ = -1, target_port_ = 0, port_ = 0;
  double delay_ms_ = 0;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

}  // namespace plantview::bench
