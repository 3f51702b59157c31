// A scratch directory for one test.
//
// TempDir names <system temp>/plantview-<program>-<pid>-<n>: unique on the machine while the
// process lives (tests run in parallel as separate processes), and telling whose it is when a
// killed test leaves it behind. Nothing is at that path when the TempDir is made, so that the code
// under test can create it (as a store does); whatever is there when the TempDir goes is removed,
// errors ignored. Not thread-safe: make TempDirs on one thread.
#pragma once

#include <errno.h>  // program_invocation_short_name (glibc)
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace plantview::test {

class TempDir {
 public:
  TempDir() {
    path_ = std::filesystem::temp_directory_path() /
            ("plantview-" + std::string(program_invocation_short_name) + "-" +
             std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string str() const { return path_.string(); }

 private:
  std::filesystem::path path_;
  static inline int counter_ = 0;
};

}  // namespace plantview::test
