// A `plantview serve` process for tests: started on a free port of 127.0.0.1 (the port read from
// its "listening on http://127.0.0.1:PORT/" line), stopped with SIGTERM when destroyed.
// The caller names the binary (a test's PLANTVIEW_BIN). A server that prints no port fails the
// test through GoogleTest.
#pragma once

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace plantview::test {

// How a test starts its server besides the options: the environment and a program that runs
// the server (e.g. setpriv), as argv before the plantview binary.
struct Launch {
  std::vector<std::pair<std::string, std::string>> environment;
  std::vector<std::string> wrapper;
};

class ServeProcess {
 public:
  // `binary` serve --store `store` --listen 127.0.0.1:0 --vertex-budget 64, then `extra`.
  ServeProcess(const std::string& binary, const std::string& store, std::vector<std::string> extra = {},
               const Launch& launch = {}) {
    int out[2];
    EXPECT_EQ(pipe(out), 0);
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], 1);
      close(out[0]);
      for (const auto& [name, value] : launch.environment) setenv(name.c_str(), value.c_str(), 1);
      std::vector<std::string> args = launch.wrapper;
      for (const std::string& a : {binary, std::string("serve"), std::string("--store"), store,
                                   std::string("--listen"), std::string("127.0.0.1:0"),
                                   std::string("--vertex-budget"), std::string("64")})
        args.push_back(a);
      args.insert(args.end(), extra.begin(), extra.end());
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execvp(argv[0], argv.data());
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
  ~ServeProcess() { stop(); }
  ServeProcess(const ServeProcess&) = delete;
  ServeProcess& operator=(const ServeProcess&) = delete;
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
  // Waits at most `limit` for the server to exit; its status, or -1 (then it is killed).
  int wait_at_most(std::chrono::milliseconds limit) {
    const auto until = std::chrono::steady_clock::now() + limit;
    while (pid_ > 0 && std::chrono::steady_clock::now() < until) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = 0;
        status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        return status_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (pid_ > 0) kill(pid_, SIGKILL);
    wait();
    return -1;
  }
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = 0;
  int port_ = 0;
  int status_ = -1;
};

}  // namespace plantview::test
