// GL backend: compiling and linking the programs, uniform lookup, stream buffers (rules in
// gl/programs.h).
#include "gl/programs.h"

#include <algorithm>
#include <string>
#include <vector>

namespace plantview::detail {

namespace {

GLenum gl_stage(ShaderStage stage) {
  switch (stage) {
    case ShaderStage::vertex: return GL_VERTEX_SHADER;
    case ShaderStage::geometry: return GL_GEOMETRY_SHADER;
    case ShaderStage::fragment: return GL_FRAGMENT_SHADER;
  }
  return GL_NONE;
}

GLuint compile(const ShaderSource& source, std::string& error) {
  const GLuint shader = glCreateShader(gl_stage(source.stage));
  std::vector<const char*> texts;
  for (const ShaderPart& part : source.parts) texts.push_back(part.text.c_str());
  glShaderSource(shader, GLsizei(texts.size()), texts.data(), nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    error = std::string("renderer: shader does not compile: ") + log;
    glDeleteShader(shader);
    return 0;
  }
  return shader;
}

}  // namespace

GLuint link(const ProgramSource& source, std::string& error) {
  const std::string name(source.name);
  std::vector<GLuint> shaders;
  bool ok = true;
  for (const ShaderSource& s : source.shaders) {
    const GLuint shader = compile(s, error);
    if (!shader) {
      ok = false;
      break;
    }
    shaders.push_back(shader);
  }
  GLuint program = 0;
  if (ok) {
    program = glCreateProgram();
    for (const GLuint shader : shaders) glAttachShader(program, shader);
    glLinkProgram(program);
    GLint linked = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &linked);
    if (!linked) {
      char log[2048] = {};
      glGetProgramInfoLog(program, sizeof log, nullptr, log);
      error = "renderer: the " + name + " shaders do not link: " + log;
      glDeleteProgram(program);
      program = 0;
    }
  } else {
    error = "renderer: " + name + ": " + error.substr(std::string("renderer: ").size());
  }
  for (const GLuint shader : shaders) glDeleteShader(shader);
  return program;
}

void upload_stream(GLuint buffer, size_t& capacity, size_t bytes,
                   std::initializer_list<std::pair<const void*, size_t>> parts) {
  if (bytes > capacity) {
    capacity = std::max(bytes, capacity * 3 / 2);
    glNamedBufferData(buffer, GLsizeiptr(capacity), nullptr, GL_STREAM_DRAW);
  }
  size_t at = 0;
  for (const auto& [data, size] : parts) {
    if (size) glNamedBufferSubData(buffer, GLintptr(at), GLsizeiptr(size), data);
    at += size;
  }
}

}  // namespace plantview::detail
