// Progress of the program's long commands (gen, path): a line redrawn on a terminal, nothing in a
// pipe, and the same result either way (and whatever gen's --threads).
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

struct Outcome {
  int status = -1;
  std::string err;  // stderr (on a terminal: everything the terminal showed)
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class IngestCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("plantview-ingest-cli-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // stderr into a file: not a terminal.
  Outcome in_pipe(const std::vector<std::string>& args) {
    const fs::path err = dir_ / "stderr";
    std::string cmd = PLANTVIEW_BIN;
    for (const std::string& a : args) cmd += " '" + a + "'";
    cmd += " </dev/null >/dev/null 2>" + err.string();
    const int raw = std::system(cmd.c_str());
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, slurp(err)};
  }

  // Standard input, output and error on a pseudo-terminal.
  Outcome on_terminal(const std::vector<std::string>& args) {
    int master = -1;
    const pid_t pid = ::forkpty(&master, nullptr, nullptr, nullptr);
    if (pid < 0) return {};
    if (pid == 0) {
      std::vector<char*> argv{const_cast<char*>(PLANTVIEW_BIN)};
      for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      ::execv(PLANTVIEW_BIN, argv.data());
      ::_exit(127);
    }
    Outcome r;
    char buffer[4096];
    for (;;) {
      const ssize_t n = ::read(master, buffer, sizeof buffer);
      if (n > 0) {
        r.err.append(buffer, size_t(n));
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else {
        break;  // EIO once the child has closed its side
      }
    }
    ::close(master);
    int status = 0;
    ::waitpid(pid, &status, 0);
    r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
  }
  fs::path dir_;
};

TEST_F(IngestCli, GenAndPathShowProgressOnATerminalAndNothingInAPipeWithTheSameResults) {
  const std::string piped = (dir_ / "piped").string(), shown = (dir_ / "shown").string();
  // The revisions' commit times (store.h) are the same in both: the stores can be compared.
  setenv("SOURCE_DATE_EPOCH", "1765000000", 1);
  struct Unset {
    ~Unset() { unsetenv("SOURCE_DATE_EPOCH"); }
  } unset;
  const Outcome gen_piped = in_pipe({"gen", "--preset", "a", "--store", piped});
  ASSERT_EQ(gen_piped.status, 0) << gen_piped.err;
  EXPECT_EQ(gen_piped.err.find('\r'), std::string::npos) << gen_piped.err;
  EXPECT_EQ(gen_piped.err.find('%'), std::string::npos) << gen_piped.err;
  EXPECT_NE(gen_piped.err.find("committed"), std::string::npos) << "the closing line stays";

  // One thread this time: the same store all the same.
  const Outcome gen_shown = on_terminal({"gen", "--preset", "a", "--threads", "1", "--store", shown});
  ASSERT_EQ(gen_shown.status, 0) << gen_shown.err;
  EXPECT_NE(gen_shown.err.find("\rgenerating preset a"), std::string::npos) << gen_shown.err;
  EXPECT_NE(gen_shown.err.find("100.0%"), std::string::npos) << gen_shown.err;
  EXPECT_NE(gen_shown.err.find("committing"), std::string::npos) << gen_shown.err;
  EXPECT_TRUE(slurp(fs::path(piped) / "data.mdb") == slurp(fs::path(shown) / "data.mdb"));

  const std::string piped_path = (dir_ / "piped.json").string();
  const std::string shown_path = (dir_ / "shown.json").string();
  const Outcome path_piped =
      in_pipe({"path", "--store", piped, "--frames", "5", "--out", piped_path});
  ASSERT_EQ(path_piped.status, 0) << path_piped.err;
  EXPECT_TRUE(path_piped.err.empty()) << path_piped.err;
  const Outcome path_shown =
      on_terminal({"path", "--store", shown, "--frames", "5", "--out", shown_path});
  ASSERT_EQ(path_shown.status, 0) << path_shown.err;
  EXPECT_NE(path_shown.err.find("\rpath: reading the equipment"), std::string::npos)
      << path_shown.err;
  EXPECT_NE(path_shown.err.find("100.0%"), std::string::npos) << path_shown.err;
  // The same plant, the same walk.
  EXPECT_EQ(slurp(piped_path), slurp(shown_path));
  EXPECT_FALSE(slurp(piped_path).empty());
}

}  // namespace
