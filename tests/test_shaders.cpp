// The GL backend's shaders under Khronos' reference compiler (glslangValidator, OpenGL GLSL 4.50
// semantics: no -V): every shader of every program, put together exactly as the backend puts it
// (gl/program_sources.h, every variant of the depth reduction), compiles, and the shaders of each
// stage of a program link. No GL context. Skipped with a message when glslangValidator is
// missing (scripts/deps.sh installs glslang-tools).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "gl/program_sources.h"

namespace plantview::detail {
namespace {

namespace fs = std::filesystem;

// Runs `command` through the shell: its exit status and what it printed (stdout and stderr).
int run(const std::string& command, std::string& output) {
  output.clear();
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return -1;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, pipe)) output.append(buf, n);
  return pclose(pipe);
}

bool have_glslang() {
  std::string output;
  return run("command -v glslangValidator", output) == 0;
}

// Where a line of a shader's text came from: "render/src/gl/shaders/<file>:<line>" for a .glsl
// file's, "<name> line <n>" for one made by program_sources.cpp.
std::string origin(const ShaderSource& shader, int line) {
  int first = 1;
  for (const ShaderPart& part : shader.parts) {
    const int lines = int(std::count(part.text.begin(), part.text.end(), '\n'));
    if (line < first + lines) {
      const int at = line - first + 1;
      if (part.name.starts_with("("))
        return std::string(part.name) + " line " + std::to_string(at);
      return "render/src/gl/shaders/" + std::string(part.name) + ":" + std::to_string(at);
    }
    first += lines;
  }
  return "line " + std::to_string(line) + " (past the end)";
}

// glslangValidator's messages with each "ERROR: <file>:<line>:" (the file as its index when it
// is the only one) followed by the .glsl file and line of the part it lies in. The compiler names
// each file (`files`: path, shader) before its messages.
std::string with_origins(const std::string& output,
                         const std::vector<std::pair<std::string, const ShaderSource*>>& files) {
  static const std::regex kLocation(R"(^(ERROR|WARNING): (\S+):([0-9]+):)");
  std::istringstream in(output);
  std::string line, out;
  const ShaderSource* shader = nullptr;
  while (std::getline(in, line)) {
    for (const auto& [path, s] : files)
      if (line == path) shader = s;
    std::smatch m;
    if (std::regex_search(line, m, kLocation)) {
      for (const auto& [path, s] : files)
        if (m.str(2) == path) shader = s;
      if (shader)
        line = m.str(1) + ": " + origin(*shader, std::stoi(m.str(3))) + ":" + m.suffix().str();
    }
    out += line + "\n";
  }
  return out;
}

std::string parts_of(const ShaderSource& shader) {
  std::string names;
  for (const ShaderPart& part : shader.parts) names += (names.empty() ? "" : " + ") + std::string(part.name);
  return names;
}

// Every program the backend links: those of init() and the depth reduction's variants with whole
// pixels per cell (reduce_depth()), plain and multisampled: 4x4 pixels a cell of one sample each
// (1280x720 into 320x180), and 8x8 of four.
std::vector<ProgramSource> every_program() {
  std::vector<ProgramSource> programs;
  for (size_t i = 0; i < kProgramCount; ++i) programs.push_back(program_source(ProgramId(i)));
  for (const bool multisampled : {false, true})
    for (const ReductionStep step : {ReductionStep{4, 4, 1}, ReductionStep{8, 8, 4}})
      programs.push_back(depth_reduction_source(multisampled, step));
  return programs;
}

class ShaderCheck : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("plantview_shaders_" + std::to_string(getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(ShaderCheck, EveryProgramCompilesAndLinksUnderTheReferenceCompiler) {
  if (!have_glslang())
    GTEST_SKIP() << "glslangValidator is missing (Debian: glslang-tools, scripts/deps.sh): the "
                    "shaders are not checked";
  // One run a stage of each program: every shader compiled on its own (as glCompileShader sees
  // it), then the stage's shaders linked (-l).
  int file_index = 0;
  for (const ProgramSource& program : every_program()) {
    for (const ShaderStage stage : {ShaderStage::vertex, ShaderStage::geometry, ShaderStage::fragment}) {
      std::vector<std::pair<std::string, const ShaderSource*>> files;
      std::string command = "glslangValidator -l -S " + std::string(stage_name(stage));
      std::string listing;
      for (const ShaderSource& shader : program.shaders) {
        if (shader.stage != stage) continue;
        std::string text;
        for (const ShaderPart& part : shader.parts) {
          ASSERT_TRUE(part.text.ends_with('\n')) << part.name << " does not end with a newline";
          text += part.text;
        }
        const fs::path path = dir_ / ("shader" + std::to_string(file_index++) + "." +
                                      std::string(stage_name(stage)) + ".glsl");
        std::ofstream(path) << text;
        files.emplace_back(path.string(), &shader);
        command += " '" + path.string() + "'";
        listing += "  " + path.string() + ": " + parts_of(shader) + "\n";
      }
      if (files.empty()) continue;
      std::string output;
      EXPECT_EQ(run(command, output), 0)
          << "the " << program.name << " program's " << stage_name(stage)
          << " shaders do not compile or link:\n" << listing << with_origins(output, files);
    }
  }
}

TEST(ShaderSources, EveryShaderFileIsPartOfAProgram) {
  std::set<std::string_view> used;
  for (const ProgramSource& program : every_program())
    for (const ShaderSource& shader : program.shaders)
      for (const ShaderPart& part : shader.parts) used.insert(part.name);
  for (const std::string_view name : shader_file_names())
    EXPECT_TRUE(used.contains(name)) << "render/src/gl/shaders/" << name << " is in no program";
}

}  // namespace
}  // namespace plantview::detail
