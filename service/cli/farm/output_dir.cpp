#include "cli/farm/output_dir.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

namespace plantview::cli::farm {

namespace fs = std::filesystem;

namespace {

std::string temp_name_for(const fs::path& path) {
  return (path.parent_path() / (".tmp-" + std::to_string(::getpid()) + "-" + path.filename().string()))
      .string();
}

bool write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    bytes.remove_prefix(size_t(n));
  }
  return true;
}

}  // namespace

bool prepare_output_dir(const fs::path& dir, std::string& error) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    error = "cannot create the output directory " + dir.string() + ": " + ec.message();
    return false;
  }
  if (!fs::is_directory(dir, ec)) {
    error = "the output " + dir.string() + " is not a directory";
    return false;
  }
  const std::string probe = (dir / (".tmp-" + std::to_string(::getpid()) + "-probe")).string();
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = "the output directory " + dir.string() + " is not writable: " + std::strerror(errno);
    return false;
  }
  ::close(fd);
  ::unlink(probe.c_str());
  return true;
}

bool write_file_atomically(const fs::path& path, std::string_view bytes, std::string& error) {
  const std::string temp = temp_name_for(path);
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = "cannot write " + temp + ": " + std::strerror(errno);
    return false;
  }
  // The data reaches the disk before the rename makes it visible under its final name.
  const bool written = write_all(fd, bytes) && ::fsync(fd) == 0;
  const int saved = errno;
  ::close(fd);
  if (!written || ::rename(temp.c_str(), path.c_str()) != 0) {
    error = "cannot write " + path.string() + ": " + std::strerror(written ? errno : saved);
    ::unlink(temp.c_str());
    return false;
  }
  return true;
}

bool copy_file_atomically(const fs::path& from, const fs::path& path, std::string& error) {
  std::ifstream in(from, std::ios::binary);
  if (!in) {
    error = "cannot read " + from.string() + ": " + std::strerror(errno);
    return false;
  }
  const std::string temp = temp_name_for(path);
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = "cannot write " + temp + ": " + std::strerror(errno);
    return false;
  }
  std::vector<char> buffer(1 << 20);
  bool written = true;
  while (written && in) {
    in.read(buffer.data(), std::streamsize(buffer.size()));
    written = write_all(fd, std::string_view(buffer.data(), size_t(in.gcount())));
  }
  const bool read_whole = in.eof() && !in.bad();
  written = written && read_whole && ::fsync(fd) == 0;
  const int saved = errno;
  ::close(fd);
  if (!written || ::rename(temp.c_str(), path.c_str()) != 0) {
    error = read_whole ? "cannot write " + path.string() + ": " + std::strerror(written ? errno : saved)
                       : "cannot read " + from.string();
    ::unlink(temp.c_str());
    return false;
  }
  return true;
}

bool read_file(const fs::path& path, std::string& out, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot read " + path.string() + ": " + std::strerror(errno);
    return false;
  }
  std::ostringstream s;
  s << in.rdbuf();
  out = s.str();
  return true;
}

DirLock::DirLock(const fs::path& dir, std::string& error) {
  const std::string path = (dir / ".farm.lock").string();
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    error = "cannot open " + path + ": " + std::strerror(errno);
    return;
  }
  while (::flock(fd_, LOCK_EX) != 0) {
    if (errno == EINTR) continue;
    error = "cannot lock " + path + ": " + std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    return;
  }
}

DirLock::~DirLock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the lock
}

}  // namespace plantview::cli::farm
