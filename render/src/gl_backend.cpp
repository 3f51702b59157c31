// GL backend: shaders, buffers, framebuffer, draw and read back (rules in gl_backend.h).
#include "gl_backend.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <cstdio>
#include <initializer_list>
#include <type_traits>
#include <utility>

#include <glm/gtc/type_ptr.hpp>

#include "frame_plan.h"

namespace plantview {

std::string_view antialias_method_name(AntialiasMethod method) {
  switch (method) {
    case AntialiasMethod::automatic: return "automatic";
    case AntialiasMethod::multisampling: return "multisampling";
    case AntialiasMethod::supersampling: return "supersampling";
    case AntialiasMethod::edge_filter: return "edge-filter";
  }
  return "?";
}

}  // namespace plantview

namespace plantview::detail {

static_assert(std::is_same_v<GlName, GLuint>);

namespace {

constexpr uint64_t kInitialArenaVertices = 1u << 16;  // the GPU buffers grow from here

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_normal;
layout(location = 2) in uint a_object;
layout(std430, binding = 0) readonly buffer Objects { vec4 objects[]; };
uniform mat4 u_view_projection;
// Per-object values are flat, and the view direction is rebuilt per fragment from its window
// position: fewer interpolated values make each triangle cheaper to set up and to bin.
out vec3 v_normal;
flat out vec4 v_colour;
flat out uint v_pick;
void main() {
  vec4 a = objects[2u * a_object];
  vec4 b = objects[2u * a_object + 1u];
  vec3 p = a_position * b.xyz + a.xyz;
  v_normal = a_normal.xyz;
  v_colour = unpackUnorm4x8(floatBitsToUint(a.w));
  v_pick = floatBitsToUint(b.w);
  gl_Position = u_view_projection * vec4(p, 1.0);
}
)";

const char* kFragmentShader = R"(#version 450 core
in vec3 v_normal;
flat in vec4 v_colour;
flat in uint v_pick;
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uint o_pick;
uniform vec3 u_sun;  // unit, towards the light, in the camera-relative frame
// The ray through a window position: u_ray * vec3(position * u_window_scale - 1, -1), in the
// camera-relative frame (not normalised).
uniform mat3 u_ray;
uniform vec2 u_window_scale;
void main() {
  vec3 base = v_colour.rgb;
  float n_length = length(v_normal);
  vec3 lit;
  if (n_length < 0.5) {
    lit = base * 0.8;  // lines have no normal
  } else {
    vec3 n = v_normal / n_length;
    vec3 to_eye = -normalize(u_ray * vec3(gl_FragCoord.xy * u_window_scale - 1.0, -1.0));
    if (dot(n, to_eye) < 0.0) n = -n;  // two-sided: open meshes and facet groups
    float head = max(dot(n, to_eye), 0.0);
    float sun = max(dot(n, u_sun), 0.0);
    lit = base * (0.22 + 0.48 * head + 0.38 * sun);
  }
  o_colour = vec4(min(lit, vec3(1.0)), v_colour.a);
  o_pick = v_pick;
}
)";

GLuint compile(GLenum type, const char* source, std::string& error) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
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

// Fills a stream buffer from `parts`, one after the other, growing it by half again when it is
// too small. No invalidation: the buffer is idle (the last frame was read back), and new storage
// would be zeroed every frame.
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

}  // namespace

GlBackend::~GlBackend() {
  if (program_) glDeleteProgram(program_);
  GLuint buffers[] = {arena_, arena_objects_, index_buffer_, table_buffer_, proxy_buffer_, cube_indices_};
  glDeleteBuffers(6, buffers);
  GLuint vaos[] = {vao_, proxy_vao_};
  glDeleteVertexArrays(2, vaos);
  release_framebuffer();
}

bool GlBackend::init(uint64_t budget_vertices, std::string& error) {
  budget_vertices_ = budget_vertices;
  if (eglGetCurrentContext() == EGL_NO_CONTEXT) {
    error = "renderer: no current OpenGL context (create a GpuContext first)";
    return false;
  }
  if (epoxy_gl_version() < 45) {
    error = "renderer: OpenGL 4.5 is required, the context has " +
            std::to_string(epoxy_gl_version() / 10) + "." + std::to_string(epoxy_gl_version() % 10);
    return false;
  }
  const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader, error);
  if (!vs) return false;
  const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader, error);
  if (!fs) {
    glDeleteShader(vs);
    return false;
  }
  program_ = glCreateProgram();
  glAttachShader(program_, vs);
  glAttachShader(program_, fs);
  glLinkProgram(program_);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(program_, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(program_, sizeof log, nullptr, log);
    error = std::string("renderer: shaders do not link: ") + log;
    return false;
  }
  u_view_projection_ = glGetUniformLocation(program_, "u_view_projection");
  u_sun_ = glGetUniformLocation(program_, "u_sun");
  u_ray_ = glGetUniformLocation(program_, "u_ray");
  u_window_scale_ = glGetUniformLocation(program_, "u_window_scale");

  glCreateBuffers(1, &index_buffer_);
  glCreateBuffers(1, &table_buffer_);
  glCreateBuffers(1, &proxy_buffer_);
  glCreateBuffers(1, &cube_indices_);
  static constexpr uint32_t kCube[36] = {0,  2,  1,  0,  3,  2,  4,  5,  6,  4,  6,  7,
                                         8,  10, 9,  8,  11, 10, 12, 13, 14, 12, 14, 15,
                                         16, 18, 17, 16, 19, 18, 20, 21, 22, 20, 22, 23};
  glNamedBufferStorage(cube_indices_, sizeof kCube, kCube, 0);

  // Both vertex arrays read position and normal from the arena (binding 0) and the object-table
  // index from binding 1: per vertex for objects (the arena's second buffer), per instance for
  // proxies (the cube's vertices are shared).
  const auto make_vertex_array = [](GLuint& array) {
    glCreateVertexArrays(1, &array);
    glEnableVertexArrayAttrib(array, 0);
    glVertexArrayAttribFormat(array, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(array, 0, 0);
    glEnableVertexArrayAttrib(array, 1);
    glVertexArrayAttribFormat(array, 1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 12);
    glVertexArrayAttribBinding(array, 1, 0);
    glEnableVertexArrayAttrib(array, 2);
    glVertexArrayAttribIFormat(array, 2, 1, GL_UNSIGNED_INT, 0);
    glVertexArrayAttribBinding(array, 2, 1);
  };
  make_vertex_array(vao_);
  glVertexArrayElementBuffer(vao_, index_buffer_);
  make_vertex_array(proxy_vao_);
  glVertexArrayBindingDivisor(proxy_vao_, 1, 1);
  glVertexArrayVertexBuffer(proxy_vao_, 1, proxy_buffer_, 0, sizeof(uint32_t));
  glVertexArrayElementBuffer(proxy_vao_, cube_indices_);
  return grow_arena(std::min<uint64_t>(kInitialArenaVertices, budget_vertices_), error);
}

void GlBackend::bind_arena() {
  glVertexArrayVertexBuffer(vao_, 0, arena_, 0, sizeof(PackedVertex));
  glVertexArrayVertexBuffer(vao_, 1, arena_objects_, 0, sizeof(uint32_t));
  glVertexArrayVertexBuffer(proxy_vao_, 0, arena_, 0, sizeof(PackedVertex));
}

bool GlBackend::grow_arena(uint64_t vertices, std::string& error) {
  vertices = std::min(vertices, budget_vertices_);  // (a full arena evicts instead)
  if (vertices <= arena_vertices_) return true;
  const uint64_t size = std::min(budget_vertices_, std::max(vertices, arena_vertices_ * 2));
  GLuint buffers[2];
  glCreateBuffers(2, buffers);
  glNamedBufferStorage(buffers[0], GLsizeiptr(size * sizeof(PackedVertex)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  glNamedBufferStorage(buffers[1], GLsizeiptr(size * sizeof(uint32_t)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  if (glGetError() != GL_NO_ERROR) {
    glDeleteBuffers(2, buffers);
    error = "renderer: cannot allocate " + std::to_string((size * kBytesPerVertex) >> 20) +
            " MB of the vertex arena";
    return false;
  }
  if (arena_vertices_) {
    glCopyNamedBufferSubData(arena_, buffers[0], 0, 0, GLsizeiptr(arena_vertices_ * sizeof(PackedVertex)));
    glCopyNamedBufferSubData(arena_objects_, buffers[1], 0, 0, GLsizeiptr(arena_vertices_ * sizeof(uint32_t)));
    GLuint old[2] = {arena_, arena_objects_};
    glDeleteBuffers(2, old);
  }
  arena_ = buffers[0];
  arena_objects_ = buffers[1];
  arena_vertices_ = size;
  bind_arena();
  return true;
}

void GlBackend::upload(uint64_t first, std::span<const PackedVertex> vertices,
                       std::span<const uint32_t> objects) {
  glNamedBufferSubData(arena_, GLintptr(first * sizeof(PackedVertex)),
                       GLsizeiptr(vertices.size_bytes()), vertices.data());
  if (!objects.empty())
    glNamedBufferSubData(arena_objects_, GLintptr(first * sizeof(uint32_t)),
                         GLsizeiptr(objects.size_bytes()), objects.data());
}

uint32_t* GlBackend::map_indices(size_t count, std::string& error) {
  const size_t bytes = std::max<size_t>(count, 1) * sizeof(uint32_t);
  if (bytes > index_capacity_) {
    index_capacity_ = std::max(bytes, index_capacity_ * 3 / 2);
    glNamedBufferData(index_buffer_, GLsizeiptr(index_capacity_), nullptr, GL_STREAM_DRAW);
  }
  // Unsynchronised: the previous frame was finished (read back) before this one began, and
  // invalidating would make the driver allocate (and zero) new storage every frame.
  auto* indices = static_cast<uint32_t*>(glMapNamedBufferRange(
      index_buffer_, 0, GLsizeiptr(bytes), GL_MAP_WRITE_BIT | GL_MAP_UNSYNCHRONIZED_BIT));
  if (!indices) error = "renderer: cannot map " + std::to_string(bytes >> 20) + " MB of index buffer";
  return indices;
}

void GlBackend::unmap_indices() { glUnmapNamedBuffer(index_buffer_); }

void GlBackend::release_framebuffer() {
  GLuint fbs[] = {framebuffer_, resolved_};
  glDeleteFramebuffers(2, fbs);
  GLuint rbs[] = {colour_rb_, pick_rb_, depth_rb_, resolved_colour_, resolved_pick_};
  glDeleteRenderbuffers(5, rbs);
  framebuffer_ = colour_rb_ = pick_rb_ = depth_rb_ = resolved_ = resolved_colour_ = resolved_pick_ = 0;
  fb_width_ = fb_height_ = fb_samples_ = 0;
}

bool GlBackend::ensure_framebuffer(uint32_t w, uint32_t h, uint32_t wanted, std::string& error) {
  GLint max_samples = 1;
  glGetIntegerv(GL_MAX_INTEGER_SAMPLES, &max_samples);
  GLint max_colour_samples = 1;
  glGetIntegerv(GL_MAX_SAMPLES, &max_colour_samples);
  if (wanted == 0) {
    const auto* renderer_name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    const std::string name = renderer_name ? renderer_name : "";
    const bool software = name.find("llvmpipe") != std::string::npos ||
                          name.find("softpipe") != std::string::npos ||
                          name.find("SwiftShader") != std::string::npos;
    wanted = software ? 1 : 4;
  }
  const uint32_t samples = std::clamp<uint32_t>(wanted, 1, uint32_t(std::min(max_samples, max_colour_samples)));
  if (framebuffer_ && fb_width_ == w && fb_height_ == h && fb_samples_ == samples) return true;
  release_framebuffer();
  const auto make = [&](GLuint& fb, GLuint& colour, GLuint& pick, GLuint* depth, uint32_t n) {
    glCreateFramebuffers(1, &fb);
    glCreateRenderbuffers(1, &colour);
    glCreateRenderbuffers(1, &pick);
    glNamedRenderbufferStorageMultisample(colour, GLsizei(n > 1 ? n : 0), GL_RGBA8, GLsizei(w), GLsizei(h));
    glNamedRenderbufferStorageMultisample(pick, GLsizei(n > 1 ? n : 0), GL_R32UI, GLsizei(w), GLsizei(h));
    glNamedFramebufferRenderbuffer(fb, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour);
    glNamedFramebufferRenderbuffer(fb, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER, pick);
    if (depth) {
      glCreateRenderbuffers(1, depth);
      glNamedRenderbufferStorageMultisample(*depth, GLsizei(n > 1 ? n : 0), GL_DEPTH_COMPONENT32F, GLsizei(w), GLsizei(h));
      glNamedFramebufferRenderbuffer(fb, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, *depth);
    }
    const GLenum buffers[] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(fb, 2, buffers);
    return glCheckNamedFramebufferStatus(fb, GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
  };
  bool ok = make(framebuffer_, colour_rb_, pick_rb_, &depth_rb_, samples);
  if (ok && samples > 1) ok = make(resolved_, resolved_colour_, resolved_pick_, nullptr, 1);
  if (!ok) {
    error = "renderer: cannot make a " + std::to_string(w) + "x" + std::to_string(h) +
            " framebuffer with " + std::to_string(samples) + " samples";
    release_framebuffer();
    return false;
  }
  fb_width_ = w;
  fb_height_ = h;
  fb_samples_ = samples;
  return true;
}

bool GlBackend::draw(const FrameView& view, const IndexCounts& counts,
                     std::span<const TableEntry> table, std::span<const uint32_t> proxy_tables,
                     uint32_t samples, bool with_ids, std::string& error) {
  if (!ensure_framebuffer(view.width, view.height, samples, error)) return false;
  upload_stream(table_buffer_, table_capacity_, table.size_bytes(), {{table.data(), table.size_bytes()}});
  upload_stream(proxy_buffer_, proxy_capacity_, proxy_tables.size_bytes(),
                {{proxy_tables.data(), proxy_tables.size_bytes()}});
  glVertexArrayVertexBuffer(proxy_vao_, 1, proxy_buffer_, 0, sizeof(uint32_t));
  begin_pass(view, with_ids);
  draw_lists(counts, proxy_tables.size());
  glFinish();
  return true;
}

void GlBackend::begin_pass(const FrameView& view, bool with_ids) {
  const uint32_t w = view.width, h = view.height;
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_);
  // The object ids are written only when they are read back.
  const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0, GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(framebuffer_, 2, draw_buffers);
  glViewport(0, 0, GLsizei(w), GLsizei(h));
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);  // two-sided: facet groups and open meshes are seen from both sides
  const GLfloat background[4] = {0.80f, 0.84f, 0.88f, 1.0f};
  const GLuint no_pick[4] = {0, 0, 0, 0};
  const GLfloat far_depth = 0.0f;
  glClearNamedFramebufferfv(framebuffer_, GL_COLOR, 0, background);
  glClearNamedFramebufferuiv(framebuffer_, GL_COLOR, 1, no_pick);
  glClearNamedFramebufferfv(framebuffer_, GL_DEPTH, 0, &far_depth);
  glUseProgram(program_);
  glUniformMatrix4fv(u_view_projection_, 1, GL_FALSE, glm::value_ptr(view.view_projection));
  const glm::vec3 sun = glm::normalize(glm::mat3(view.rotation) * glm::vec3(0.3f, 0.5f, 0.8f));
  glUniform3fv(u_sun_, 1, glm::value_ptr(sun));
  // View space to the camera-relative frame, with the half-angle tangents of the view.
  const glm::mat3 ray = glm::transpose(glm::mat3(view.rotation)) *
                        glm::mat3(glm::vec3(view.aspect / view.focal, 0, 0),
                                  glm::vec3(0, 1.0f / view.focal, 0), glm::vec3(0, 0, 1));
  glUniformMatrix3fv(u_ray_, 1, GL_FALSE, glm::value_ptr(ray));
  glUniform2f(u_window_scale_, 2.0f / float(w), 2.0f / float(h));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, table_buffer_);
}

void GlBackend::draw_lists(const IndexCounts& counts, size_t proxies) {
  const size_t n_closed = counts[kClosed], n_open = counts[kOpen];
  const size_t n_opaque = n_closed + n_open, n_transparent = counts[kTransparent],
               n_lines = counts[kLines];
  glDisablei(GL_BLEND, 0);
  glBindVertexArray(vao_);
  if (n_closed) {
    // Closed solids have outward, counter-clockwise faces: their back faces are never seen.
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glDrawElements(GL_TRIANGLES, GLsizei(n_closed), GL_UNSIGNED_INT, nullptr);
    glDisable(GL_CULL_FACE);
  }
  if (n_open)
    glDrawElements(GL_TRIANGLES, GLsizei(n_open), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(n_closed * sizeof(uint32_t)));
  if (n_lines)
    glDrawElements(GL_LINES, GLsizei(n_lines), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>((n_opaque + n_transparent) * sizeof(uint32_t)));
  if (proxies) {
    glBindVertexArray(proxy_vao_);
    glDrawElementsInstanced(GL_TRIANGLES, 36, GL_UNSIGNED_INT, nullptr, GLsizei(proxies));
    glBindVertexArray(vao_);
  }
  if (n_transparent) {
    // See-through objects after the rest, blended, not hiding what lies behind them.
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDepthMask(GL_FALSE);
    glDrawElements(GL_TRIANGLES, GLsizei(n_transparent), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(n_opaque * sizeof(uint32_t)));
    glDepthMask(GL_TRUE);
    glDisablei(GL_BLEND, 0);
  }
  glBindVertexArray(0);
}

bool GlBackend::read_back(uint32_t w, uint32_t h, bool with_ids,
                          std::span<const uint64_t> pick_ids, Image& out, std::string& error) {
  GLuint source = framebuffer_;
  if (fb_samples_ > 1) {
    // Colour averages its samples; ids take one sample (integers do not average).
    for (const GLenum attachment : {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1}) {
      if (attachment == GL_COLOR_ATTACHMENT1 && !with_ids) break;
      glNamedFramebufferReadBuffer(framebuffer_, attachment);
      glNamedFramebufferDrawBuffer(resolved_, attachment);
      glBlitNamedFramebuffer(framebuffer_, resolved_, 0, 0, GLint(w), GLint(h), 0, 0, GLint(w), GLint(h),
                             GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    source = resolved_;
  }
  out.width = w;
  out.height = h;
  out.rgba.resize(size_t(w) * h * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, source);
  glNamedFramebufferReadBuffer(source, GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, GLsizei(w), GLsizei(h), GL_RGBA, GL_UNSIGNED_BYTE, out.rgba.data());
  const size_t row = size_t(w) * 4;
  for (uint32_t y = 0; y < h / 2; ++y)
    std::swap_ranges(out.rgba.begin() + y * row, out.rgba.begin() + (y + 1) * row,
                     out.rgba.begin() + (h - 1 - y) * row);
  if (with_ids) {
    pick_pixels_.resize(size_t(w) * h);
    glNamedFramebufferReadBuffer(source, GL_COLOR_ATTACHMENT1);
    glReadPixels(0, 0, GLsizei(w), GLsizei(h), GL_RED_INTEGER, GL_UNSIGNED_INT, pick_pixels_.data());
    out.object_ids.resize(size_t(w) * h);
    for (uint32_t y = 0; y < h; ++y) {
      const uint32_t* src = pick_pixels_.data() + size_t(h - 1 - y) * w;
      uint64_t* dst = out.object_ids.data() + size_t(y) * w;
      for (uint32_t x = 0; x < w; ++x)
        dst[x] = src[x] && src[x] <= pick_ids.size() ? pick_ids[src[x] - 1] : 0;
    }
  } else {
    out.object_ids.clear();
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (const GLenum gl_error = glGetError(); gl_error != GL_NO_ERROR) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "renderer: OpenGL error 0x%x", gl_error);
    error = buf;
    return false;
  }
  return true;
}

}  // namespace plantview::detail
