// Replays a fuzz harness over files, for builds without libFuzzer (GCC, or clang without
// PLANTVIEW_FUZZ): linked with one harness, it passes each file named on the command line, and
// each regular file directly inside each directory named (sorted by name, not recursively), once
// to LLVMFuzzerTestOneInput.
//
// Exit status: 0 when every input ran and the harness returned 0 for each; 1 on a usage or I/O
// error, on a non-zero return, or when there was no input at all (an empty corpus is a broken
// setup, not a pass). A harness reports a broken property by trapping or aborting: the program
// then dies of that signal after naming the input on stderr.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

// The input being run, for the signal handler (which may only write it out).
const char* g_current = nullptr;

void name_input_and_die(int signal) {
  if (g_current != nullptr) {
    const char prefix[] = "replay: crashed on ";
    (void)!::write(STDERR_FILENO, prefix, sizeof prefix - 1);
    (void)!::write(STDERR_FILENO, g_current, std::strlen(g_current));
    (void)!::write(STDERR_FILENO, "\n", 1);
  }
  ::raise(signal);  // SA_RESETHAND restored the default action: the status shows the signal
}

void install_crash_handlers() {
  struct sigaction action {};
  action.sa_handler = name_input_and_die;
  action.sa_flags = SA_RESETHAND;
  sigemptyset(&action.sa_mask);
  for (int signal : {SIGILL, SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGTRAP}) {
    sigaction(signal, &action, nullptr);
  }
}

// Appends `path` (a file) or the regular files inside it (a directory). False with a message.
bool collect(const std::filesystem::path& path, std::vector<std::filesystem::path>& inputs) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    std::vector<std::filesystem::path> files;
    for (const auto& entry : std::filesystem::directory_iterator(path, ec)) {
      if (entry.is_regular_file(ec)) files.push_back(entry.path());
    }
    if (ec) {
      std::fprintf(stderr, "replay: %s: %s\n", path.c_str(), ec.message().c_str());
      return false;
    }
    std::sort(files.begin(), files.end());
    inputs.insert(inputs.end(), files.begin(), files.end());
    return true;
  }
  if (!std::filesystem::is_regular_file(path, ec)) {
    std::fprintf(stderr, "replay: %s: no such file or directory\n", path.c_str());
    return false;
  }
  inputs.push_back(path);
  return true;
}

bool read_file(const std::filesystem::path& path, std::vector<uint8_t>& bytes) {
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  bytes.resize(ec ? 0 : size_t(size));
  if (ec || !in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size()))) {
    std::fprintf(stderr, "replay: %s: cannot read\n", path.c_str());
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE|DIRECTORY...\n", argv[0]);
    return 1;
  }
  std::vector<std::filesystem::path> inputs;
  for (int i = 1; i < argc; ++i) {
    if (!collect(argv[i], inputs)) return 1;
  }
  if (inputs.empty()) {
    std::fprintf(stderr, "replay: no inputs in the paths given\n");
    return 1;
  }
  install_crash_handlers();
  std::vector<uint8_t> bytes;
  size_t failed = 0;
  for (const auto& path : inputs) {
    if (!read_file(path, bytes)) return 1;
    g_current = path.c_str();
    // A heap block of exactly the input's size, so that ASan catches a read past its end.
    const std::unique_ptr<uint8_t[]> input(new uint8_t[bytes.size()]);
    if (!bytes.empty()) std::memcpy(input.get(), bytes.data(), bytes.size());
    if (LLVMFuzzerTestOneInput(input.get(), bytes.size()) != 0) {
      std::fprintf(stderr, "replay: %s: the harness returned non-zero\n", path.c_str());
      ++failed;
    }
  }
  g_current = nullptr;
  std::printf("replay: %zu inputs, %zu failed\n", inputs.size(), failed);
  return failed == 0 ? 0 : 1;
}
