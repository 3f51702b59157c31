// The store's writer lock and the file naming its holder (writer_lock.h).
#include "writer_lock.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "plantview/store.h"

namespace plantview {

namespace {
std::atomic<bool> g_lock_wait{true};
}  // namespace

void set_import_lock_wait(bool wait) { g_lock_wait = wait; }

namespace detail {

namespace {

std::string writer_path(const std::string& directory) { return directory + "/import.writer"; }

// This process's command line, arguments joined by spaces ("plantview import a.rvm --store s").
std::string own_command_line() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  while (!all.empty() && all.back() == '\0') all.pop_back();
  for (char& c : all) {
    if (c == '\0') c = ' ';
  }
  // The program as its file name, not the path it was run by.
  const size_t space = all.find(' ');
  const size_t slash = all.rfind('/', space);
  if (slash != std::string::npos) all.erase(0, slash + 1);
  return all.empty() ? "pid " + std::to_string(::getpid()) : all;
}

}  // namespace

std::string describe_writer(const std::string& directory) {
  std::ifstream in(writer_path(directory));
  long pid = 0;
  long long started = 0;
  std::string command;
  if (!(in >> pid >> started) || pid <= 0) return "another import";
  in.ignore(1);
  std::getline(in, command);
  if (::kill(pid_t(pid), 0) != 0 && errno == ESRCH) return "another import";  // stale file
  const std::time_t t = std::time_t(started);
  std::tm local{};
  char when[16] = "?";
  if (localtime_r(&t, &local)) std::strftime(when, sizeof when, "%H:%M:%S", &local);
  return "the import by pid " + std::to_string(pid) + " (" + command + ", started " + when + ")";
}

bool WriterLock::acquire(const std::string& directory, std::string& error) {
  release();
  const std::string lock_path = directory + "/import.lock";
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = "store " + directory + ": opening " + lock_path + ": " + std::strerror(errno);
    return false;
  }
  int rc;
  while ((rc = ::flock(fd, LOCK_EX | LOCK_NB)) != 0 && errno == EINTR) {
  }
  if (rc != 0 && errno == EWOULDBLOCK) {
    const std::string who = describe_writer(directory);
    if (!g_lock_wait) {
      error = "store " + directory + ": busy: " + who + " is writing it (--no-wait)";
      ::close(fd);
      return false;
    }
    std::fprintf(stderr, "store %s: waiting for %s\n", directory.c_str(), who.c_str());
    std::fflush(stderr);
    while ((rc = ::flock(fd, LOCK_EX)) != 0 && errno == EINTR) {
    }
  }
  if (rc != 0) {
    error = "store " + directory + ": locking " + lock_path + ": " + std::strerror(errno);
    ::close(fd);
    return false;
  }
  fd_ = fd;
  directory_ = directory;
  // Who holds it, for the next writer's message (written whole, then renamed into place).
  const auto now = std::chrono::system_clock::now();
  const long long seconds =
      std::chrono::duration_cast<std::chrono::seconds>(now.time_since_epoch()).count();
  const std::string temp = writer_path(directory) + "." + std::to_string(::getpid());
  {
    std::ofstream out(temp, std::ios::trunc);
    out << ::getpid() << ' ' << seconds << ' ' << own_command_line() << '\n';
  }
  std::error_code ec;
  std::filesystem::rename(temp, writer_path(directory), ec);  // advice only: failures ignored
  if (ec) std::filesystem::remove(temp, ec);
  return true;
}

void WriterLock::release() {
  if (fd_ < 0) return;
  std::error_code ec;
  std::filesystem::remove(writer_path(directory_), ec);
  ::close(fd_);  // drops the flock
  fd_ = -1;
}

}  // namespace detail
}  // namespace plantview
