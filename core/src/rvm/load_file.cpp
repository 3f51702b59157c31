// load_file: the one function of plantview/rvm.h that touches the file system.
#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "plantview/rvm.h"

namespace plantview {

ParseResult<std::vector<std::byte>> load_file(const std::filesystem::path& path) {
  const auto failure = [&](const char* what) {
    const char* reason = errno != 0 ? std::strerror(errno) : "the file changed while being read";
    return ParseError{path.string() + ": " + what + ": " + reason, 0, 0};
  };
  errno = 0;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), std::fclose);
  if (!file) return failure("cannot open");
  // A directory opens for reading on Linux, and seeking to its end gives a nonsense size; the
  // size of anything else that is not a regular file (a pipe) is found by seeking, or not at all.
  struct stat status;
  if (fstat(fileno(file.get()), &status) != 0) return failure("cannot stat");
  if (S_ISDIR(status.st_mode)) {
    return ParseError{path.string() + ": is a directory, not a file", 0, 0};
  }
  if (std::fseek(file.get(), 0, SEEK_END) != 0) return failure("cannot seek");
  const long size = std::ftell(file.get());
  if (size < 0 || std::fseek(file.get(), 0, SEEK_SET) != 0) return failure("cannot seek");
  std::vector<std::byte> bytes(static_cast<size_t>(size));
  if (std::fread(bytes.data(), 1, bytes.size(), file.get()) != bytes.size()) {
    return failure("cannot read");
  }
  return bytes;
}

}  // namespace plantview
