// GL backend: shaders, buffers, framebuffer, draw and read back (rules in gl_backend.h).
#include "gl_backend.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <malloc.h>
#include <sys/mman.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <mutex>
#include <type_traits>
#include <utility>

#include <glm/gtc/type_ptr.hpp>

#include "frame_plan.h"
#include "gl/program_sources.h"
#include "lod.h"

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

std::string_view occlusion_test_name(OcclusionTest test) {
  switch (test) {
    case OcclusionTest::automatic: return "automatic";
    case OcclusionTest::coarse: return "coarse";
    case OcclusionTest::exact: return "exact";
  }
  return "?";
}

}  // namespace plantview

namespace plantview::detail {

static_assert(std::is_same_v<GlName, GLuint>);

namespace {

constexpr uint64_t kInitialArenaVertices = 1u << 16;  // the GPU buffers grow from here
constexpr GLfloat kBackground[4] = {0.80f, 0.84f, 0.88f, 1.0f};
constexpr float kSeeThroughAlpha = 0.22f;  // occluders of a highlighted subject
constexpr double kOcclusionRadiusM = 0.6;  // ambient occlusion's reach

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

// Links the shaders of `source` into a program; 0 with the log in `error`.
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

GLint at(GLuint program, const char* name) { return glGetUniformLocation(program, name); }

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

// A ghosted colour: most of its saturation gone, lifted towards white.
uint32_t ghost(uint32_t rgba) {
  const float r = float(rgba & 0xff), g = float((rgba >> 8) & 0xff), b = float((rgba >> 16) & 0xff);
  const float luma = 0.299f * r + 0.587f * g + 0.114f * b;
  const auto channel = [&](float c) {
    const float grey = luma + 0.2f * (c - luma);
    return uint32_t(std::lround(grey + 0.6f * (255.0f - grey)));
  };
  return channel(r) | channel(g) << 8 | channel(b) << 16 | (rgba & 0xff000000u);
}

}  // namespace

Look look_of(const RenderOptions& options, const DAabb& model_bounds) {
  Look look;
  look.antialias = options.antialias;
  look.method = options.antialias_method;
  look.samples = options.samples;
  look.ground = options.ground;
  look.ambient_occlusion = options.ambient_occlusion;
  look.highlight_ids = options.highlight_ids;
  look.model_bounds = model_bounds;
  return look;
}

GlBackend::Mapping::~Mapping() { reset(); }

void GlBackend::Mapping::reset() {
  if (data_) munmap(data_, bytes_);
  data_ = nullptr;
  bytes_ = 0;
  committed_ = 0;
}

void GlBackend::Mapping::commit_to(size_t end_bytes) {
  if (end_bytes <= committed_ || !can_commit_) return;
  const size_t target = std::min(bytes_, (end_bytes + kCommitStep - 1) / kCommitStep * kCommitStep);
  if (madvise(static_cast<char*>(data_) + committed_, target - committed_, MADV_POPULATE_WRITE) != 0) {
    can_commit_ = false;  // (before Linux 5.14, or refused: the writes fault the pages in)
    return;
  }
  committed_ = target;
}

bool GlBackend::Mapping::map(size_t bytes) {
  assert(!data_ && bytes > 0);
  // Anonymous pages read as zero and take memory only once written; no swap is reserved for
  // the untouched rest.
  void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) return false;
  data_ = p;
  bytes_ = bytes;
  return true;
}

GlBackend::~GlBackend() {
  // The driver draws from the mapped arena until its buffers are gone (the mappings are
  // unmapped after this body).
  if (arena_mapped()) glFinish();
  for (const GLuint program : {surface_program_, proxy_program_, centreline_program_, ground_program_,
                               occlusion_program_, finish_program_, reduce_program_,
                               reduce_multisampled_program_, box_test_program_})
    if (program) glDeleteProgram(program);
  for (const auto& [key, program] : reduce_fixed_) glDeleteProgram(program);
  release_grid(occlusion_grid_);
  release_grid(reduce_grid_);
  GLuint buffers[] = {arena_,        arena_objects_, index_buffers_[0], index_buffers_[1],
                      table_buffer_, proxy_buffer_,  box_buffer_,       seen_buffer_};
  glDeleteBuffers(8, buffers);
  GLuint vaos[] = {vao_, empty_vao_};
  glDeleteVertexArrays(2, vaos);
  GLuint samplers[] = {linear_sampler_, nearest_sampler_};
  glDeleteSamplers(2, samplers);
  release_target(scene_);
  release_target(resolved_);
  release_target(output_);
}

namespace {

// A software renderer allocates and frees its buffers for binned triangles and shaded
// vertices draw by draw, tens of MB a frame (bounded drawing draws many pieces a frame). glibc
// gives the free top of a heap above 128 KB (the default trim threshold) back to the system,
// and every page of it faults in again at the next draw. Kept up to kKeptFreeHeapBytes a heap
// instead, with blocks up to kHeapBlockBytes from the heap rather than mapped on their own:
// x100's walk (render --path, 12 views, 256 MB) 196,000 -> 115,000 page faults, drawing
// 400 -> 320 ms a frame, the same peak memory. Process-wide, set once, by the first renderer
// made on a software device.
constexpr size_t kKeptFreeHeapBytes = size_t(64) << 20;
constexpr size_t kHeapBlockBytes = size_t(32) << 20;

void keep_freed_heap_memory() {
#if defined(__GLIBC__)
  static std::once_flag once;
  std::call_once(once, [] {
    mallopt(M_MMAP_THRESHOLD, int(kHeapBlockBytes));
    mallopt(M_TRIM_THRESHOLD, int(kKeptFreeHeapBytes));
  });
#endif
}

}  // namespace

bool GlBackend::init(uint64_t budget_vertices, std::string& error, ArenaMemory memory) {
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
  const auto* renderer_name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const std::string name = renderer_name ? renderer_name : "";
  software_ = name.find("llvmpipe") != std::string::npos ||
              name.find("softpipe") != std::string::npos ||
              name.find("SwiftShader") != std::string::npos;
  if (software_) keep_freed_heap_memory();

  GLuint* const programs[kProgramCount] = {
      &surface_program_,        &proxy_program_,  &centreline_program_,
      &ground_program_,         &occlusion_program_, &finish_program_,
      &reduce_program_,         &reduce_multisampled_program_, &box_test_program_};
  for (size_t i = 0; i < kProgramCount; ++i)
    if (!(*programs[i] = link(program_source(ProgramId(i)), error))) return false;

  glCreateBuffers(1, &index_buffers_[0]);
  glCreateBuffers(1, &index_buffers_[1]);
  glCreateBuffers(1, &table_buffer_);
  glCreateBuffers(1, &proxy_buffer_);
  glCreateBuffers(1, &box_buffer_);
  glCreateBuffers(1, &seen_buffer_);

  // The objects' vertex array reads position and normal from the arena (binding 0) and the
  // object-table index from binding 1 (the arena's second buffer). Attribute 3 is the normal
  // word as an integer: a centreline's diameter. Proxy boxes and the box test read no vertices
  // (empty_vao_).
  glCreateVertexArrays(1, &vao_);
  glEnableVertexArrayAttrib(vao_, 0);
  glVertexArrayAttribFormat(vao_, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao_, 0, 0);
  glEnableVertexArrayAttrib(vao_, 1);
  glVertexArrayAttribFormat(vao_, 1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 12);
  glVertexArrayAttribBinding(vao_, 1, 0);
  glEnableVertexArrayAttrib(vao_, 2);
  glVertexArrayAttribIFormat(vao_, 2, 1, GL_UNSIGNED_INT, 0);
  glVertexArrayAttribBinding(vao_, 2, 1);
  glEnableVertexArrayAttrib(vao_, 3);
  glVertexArrayAttribIFormat(vao_, 3, 1, GL_UNSIGNED_INT, 12);
  glVertexArrayAttribBinding(vao_, 3, 0);
  glVertexArrayElementBuffer(vao_, index_buffers_[drawn_indices_]);
  glCreateVertexArrays(1, &empty_vao_);

  glCreateSamplers(1, &linear_sampler_);
  glCreateSamplers(1, &nearest_sampler_);
  for (const GLuint sampler : {linear_sampler_, nearest_sampler_}) {
    const GLint filter = sampler == linear_sampler_ ? GL_LINEAR : GL_NEAREST;
    glSamplerParameteri(sampler, GL_TEXTURE_MIN_FILTER, filter);
    glSamplerParameteri(sampler, GL_TEXTURE_MAG_FILTER, filter);
    glSamplerParameteri(sampler, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glSamplerParameteri(sampler, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  }
  if (memory == ArenaMemory::automatic && software_ && map_arena()) return true;
  return grow_arena(std::min<uint64_t>(kInitialArenaVertices, budget_vertices_), error);
}

bool GlBackend::map_arena() {
  if (!epoxy_has_gl_extension("GL_AMD_pinned_memory")) return false;
  const auto give_up = [&] {
    mapped_vertices_.reset();
    mapped_objects_.reset();
    return false;
  };
  if (!mapped_vertices_.map(budget_vertices_ * sizeof(PackedVertex)) ||
      !mapped_objects_.map(budget_vertices_ * sizeof(uint32_t)))
    return give_up();
  GLuint buffers[2];
  glCreateBuffers(2, buffers);
  const Mapping* memory[2] = {&mapped_vertices_, &mapped_objects_};
  const size_t sizes[2] = {sizeof(PackedVertex), sizeof(uint32_t)};
  for (int b = 0; b < 2; ++b) {
    glBindBuffer(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, buffers[b]);
    glBufferData(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, GLsizeiptr(budget_vertices_ * sizes[b]),
                 memory[b]->data(), GL_STREAM_DRAW);
  }
  glBindBuffer(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, 0);
  if (glGetError() != GL_NO_ERROR) {  // (llvmpipe: a buffer over 4 GB)
    glDeleteBuffers(2, buffers);
    return give_up();
  }
  arena_ = buffers[0];
  arena_objects_ = buffers[1];
  arena_vertices_ = budget_vertices_;
  bind_arena();
  return true;
}

void GlBackend::bind_arena() {
  glVertexArrayVertexBuffer(vao_, 0, arena_, 0, sizeof(PackedVertex));
  glVertexArrayVertexBuffer(vao_, 1, arena_objects_, 0, sizeof(uint32_t));
}

bool GlBackend::grow_arena(uint64_t vertices, std::string& error) {
  vertices = std::min(vertices, budget_vertices_);  // (a full arena evicts instead)
  if (vertices <= arena_vertices_) return true;
  const uint64_t size = std::min(budget_vertices_, std::max(vertices + vertices / 2, arena_vertices_ * 2));
  const auto start = std::chrono::steady_clock::now();
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
  growth_ms_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return true;
}

void GlBackend::upload(uint64_t first, std::span<const PackedVertex> vertices,
                       std::span<const uint32_t> objects) {
  if (arena_mapped()) {
    mapped_vertices_.commit_to((first + vertices.size()) * sizeof(PackedVertex));
    if (!objects.empty()) mapped_objects_.commit_to((first + objects.size()) * sizeof(uint32_t));
    std::memcpy(static_cast<PackedVertex*>(mapped_vertices_.data()) + first, vertices.data(), vertices.size_bytes());
    if (!objects.empty())
      std::memcpy(static_cast<uint32_t*>(mapped_objects_.data()) + first, objects.data(), objects.size_bytes());
    return;
  }
  glNamedBufferSubData(arena_, GLintptr(first * sizeof(PackedVertex)),
                       GLsizeiptr(vertices.size_bytes()), vertices.data());
  if (!objects.empty())
    glNamedBufferSubData(arena_objects_, GLintptr(first * sizeof(uint32_t)),
                         GLsizeiptr(objects.size_bytes()), objects.data());
}

uint32_t* GlBackend::map_indices(size_t count, std::string& error, bool next) {
  const unsigned which = next ? 1 - drawn_indices_ : drawn_indices_;
  const GLuint buffer = index_buffers_[which];
  size_t& capacity = index_capacities_[which];
  const size_t bytes = std::max<size_t>(count, 1) * sizeof(uint32_t);
  if (bytes > capacity) {
    capacity = std::max(bytes, capacity * 3 / 2);
    glNamedBufferData(buffer, GLsizeiptr(capacity), nullptr, GL_STREAM_DRAW);
  }
  // Unsynchronised: nothing the GPU may still draw reads it (the drawn one: the previous frame
  // was finished, read back, before this one began, and a frame's phases wait for each other;
  // the next one: drawn only from the next frame on), and invalidating would make the driver
  // allocate (and zero) new storage every frame.
  auto* indices = static_cast<uint32_t*>(glMapNamedBufferRange(
      buffer, 0, GLsizeiptr(bytes), GL_MAP_WRITE_BIT | GL_MAP_UNSYNCHRONIZED_BIT));
  if (!indices) error = "renderer: cannot map " + std::to_string(bytes >> 20) + " MB of index buffer";
  return indices;
}

void GlBackend::unmap_indices(bool next) {
  glUnmapNamedBuffer(index_buffers_[next ? 1 - drawn_indices_ : drawn_indices_]);
}

void GlBackend::use_next_indices() {
  drawn_indices_ = 1 - drawn_indices_;
  glVertexArrayElementBuffer(vao_, index_buffers_[drawn_indices_]);
}

// --- framebuffers -------------------------------------------------------------------------------

void GlBackend::ensure_grid(Grid& g, uint32_t gl_format, uint32_t w, uint32_t h) {
  if (g.framebuffer && g.width == w && g.height == h) return;
  release_grid(g);
  glCreateTextures(GL_TEXTURE_2D, 1, &g.texture);
  glTextureStorage2D(g.texture, 1, GLenum(gl_format), GLsizei(w), GLsizei(h));
  glCreateFramebuffers(1, &g.framebuffer);
  glNamedFramebufferTexture(g.framebuffer, GL_COLOR_ATTACHMENT0, g.texture, 0);
  g.width = w;
  g.height = h;
}

void GlBackend::release_grid(Grid& g) {
  if (g.framebuffer) glDeleteFramebuffers(1, &g.framebuffer);
  if (g.texture) glDeleteTextures(1, &g.texture);
  g = Grid{};
}

void GlBackend::release_target(Target& t) {
  if (t.framebuffer) glDeleteFramebuffers(1, &t.framebuffer);
  GLuint names[] = {t.colour, t.pick};
  if (t.samples > 1) glDeleteRenderbuffers(2, names);
  else glDeleteTextures(2, names);
  if (t.depth) glDeleteTextures(1, &t.depth);
  t = Target{};
}

// The id attachment costs as much memory as the colour one (and clearing it, a pass over it), so
// a target has one only once a frame has asked for ids; it keeps it for the frames after. Depth
// is 32-bit float, with 8 bits of stencil (llvmpipe: 8 bytes a sample, twice the memory and the
// clearing) only where `stencil` asks: once a frame has highlighted (begin_frame()).
bool GlBackend::ensure_target(Target& t, uint32_t w, uint32_t h, uint32_t samples, bool depth,
                              bool pick, bool stencil, std::string& error) {
  if (t.framebuffer && t.width == w && t.height == h && t.samples == samples && t.has_depth == depth &&
      (t.has_pick || !pick) && (!depth || t.has_stencil == stencil))
    return true;
  release_target(t);
  glCreateFramebuffers(1, &t.framebuffer);
  t.width = w;
  t.height = h;
  t.samples = samples;
  t.has_depth = depth;
  t.has_pick = pick;
  t.has_stencil = depth && stencil;
  const auto attach = [&](GLuint& name, GLenum format, GLenum attachment) {
    if (samples > 1) {
      glCreateRenderbuffers(1, &name);
      glNamedRenderbufferStorageMultisample(name, GLsizei(samples), format, GLsizei(w), GLsizei(h));
      glNamedFramebufferRenderbuffer(t.framebuffer, attachment, GL_RENDERBUFFER, name);
    } else {
      glCreateTextures(GL_TEXTURE_2D, 1, &name);
      glTextureStorage2D(name, 1, format, GLsizei(w), GLsizei(h));
      glNamedFramebufferTexture(t.framebuffer, attachment, name, 0);
    }
  };
  const GLenum depth_format = t.has_stencil ? GL_DEPTH32F_STENCIL8 : GL_DEPTH_COMPONENT32F;
  const GLenum depth_attachment = t.has_stencil ? GL_DEPTH_STENCIL_ATTACHMENT : GL_DEPTH_ATTACHMENT;
  attach(t.colour, GL_RGBA8, GL_COLOR_ATTACHMENT0);
  if (pick) attach(t.pick, GL_R32UI, GL_COLOR_ATTACHMENT1);
  if (depth && samples > 1) {
    // A texture, not a renderbuffer: the depth reduction reads every sample.
    glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &t.depth);
    glTextureStorage2DMultisample(t.depth, GLsizei(samples), depth_format, GLsizei(w),
                                  GLsizei(h), GL_TRUE);
    glNamedFramebufferTexture(t.framebuffer, depth_attachment, t.depth, 0);
  } else if (depth) {
    attach(t.depth, depth_format, depth_attachment);
  }
  const GLenum buffers[] = {GL_COLOR_ATTACHMENT0, GLenum(pick ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(t.framebuffer, 2, buffers);
  if (glCheckNamedFramebufferStatus(t.framebuffer, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
    error = "renderer: cannot make a " + std::to_string(w) + "x" + std::to_string(h) +
            " framebuffer with " + std::to_string(samples) + " samples";
    release_target(t);
    return false;
  }
  return true;
}

// Automatic: multisampling on a GPU (cheap there); supersampling on a software renderer, where
// it costs (fragments x 4) less than multisampling does on llvmpipe and smooths thin pipes too
// (measured: render.h); `samples` given, multisampling with that many.
GlBackend::Plan GlBackend::plan_for(const Look& look) const {
  Plan plan;
  plan.occlusion = look.ambient_occlusion;
  if (!look.antialias) return plan;
  AntialiasMethod method = look.method;
  if (method == AntialiasMethod::automatic)  // (samples given: that multisampling, 1 none)
    method = software_ && look.samples == 0 ? AntialiasMethod::supersampling
                                            : AntialiasMethod::multisampling;
  switch (method) {
    case AntialiasMethod::multisampling: {
      GLint max_samples = 1, max_integer_samples = 1;
      glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
      glGetIntegerv(GL_MAX_INTEGER_SAMPLES, &max_integer_samples);
      plan.samples = std::clamp<uint32_t>(look.samples ? look.samples : 4, 1,
                                          uint32_t(std::min(max_samples, max_integer_samples)));
      break;
    }
    case AntialiasMethod::supersampling: plan.scale = 2; break;
    case AntialiasMethod::edge_filter: plan.edge_filter = true; break;
    case AntialiasMethod::automatic: break;
  }
  return plan;
}

// --- drawing ------------------------------------------------------------------------------------

std::span<const TableEntry> GlBackend::highlighted(std::span<const TableEntry> table,
                                                   std::span<const uint64_t> pick_ids,
                                                   std::span<const uint64_t> highlight_ids) {
  highlight_sorted_.assign(highlight_ids.begin(), highlight_ids.end());
  std::sort(highlight_sorted_.begin(), highlight_sorted_.end());
  highlight_table_.assign(table.begin(), table.end());
  for (TableEntry& e : highlight_table_) {
    // The pick word's low bits index the pick table; its high bits are the tie-break, kept for
    // the context too (it only orders coinciding depths).
    const uint32_t pick = e.pick & (kPickLimit - 1);
    const uint64_t id = pick && pick <= pick_ids.size() ? pick_ids[pick - 1] : 0;
    if (id && std::binary_search(highlight_sorted_.begin(), highlight_sorted_.end(), id)) continue;
    e.pick &= ~(kPickLimit - 1);
    e.colour = ghost(e.colour);
  }
  return highlight_table_;
}

bool GlBackend::begin_frame(const FrameView& view, const Look& look, bool with_ids,
                            std::string& error) {
  frame_plan_ = plan_for(look);
  const Plan& plan = frame_plan_;
  const uint32_t w = view.width, h = view.height;
  // Stencil once a frame highlights (the subject's pixels are marked in it), kept for the frames
  // after; the resolved depth has the scene's format (a blit copies it).
  const bool stencil = scene_.has_stencil || !look.highlight_ids.empty();
  if (!ensure_target(scene_, w * plan.scale, h * plan.scale, plan.samples, true, with_ids, stencil,
                     error))
    return false;
  if (plan.samples > 1 &&
      !ensure_target(resolved_, w, h, 1, plan.occlusion, with_ids, stencil, error))
    return false;
  if (plan.finish() && !ensure_target(output_, w, h, 1, false, with_ids, false, error)) return false;
  begin_pass(view, plan, with_ids);
  const GLuint no_pick[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(scene_.framebuffer, GL_COLOR, 0, kBackground);
  if (with_ids) glClearNamedFramebufferuiv(scene_.framebuffer, GL_COLOR, 1, no_pick);
  if (scene_.has_stencil) {
    glClearNamedFramebufferfi(scene_.framebuffer, GL_DEPTH_STENCIL, 0, 0.0f, 0);
  } else {
    const float far_depth = 0.0f;  // reversed depth
    glClearNamedFramebufferfv(scene_.framebuffer, GL_DEPTH, 0, &far_depth);
  }
  final_ = nullptr;
  return true;
}

void GlBackend::draw_phase(const FrameView& view, const IndexCounts& counts,
                           std::span<const TableEntry> table,
                           std::span<const uint32_t> proxy_tables,
                           std::span<const uint64_t> pick_ids, const Look& look, bool with_ids,
                           bool wait) {
  const bool highlight = !look.highlight_ids.empty();
  if (highlight) table = highlighted(table, pick_ids, look.highlight_ids);
  upload_stream(table_buffer_, table_capacity_, table.size_bytes(), {{table.data(), table.size_bytes()}});
  upload_stream(proxy_buffer_, proxy_capacity_, proxy_tables.size_bytes(),
                {{proxy_tables.data(), proxy_tables.size_bytes()}});
  begin_pass(view, frame_plan_, with_ids);
  if (!highlight) {
    draw_lists(counts, proxy_tables.size(), 0, 1.0f, with_ids);
  } else {
    // The subject, marking its pixels; the context where it is not; the context in front of
    // it, see-through (gl_backend.h).
    glEnable(GL_STENCIL_TEST);
    glStencilFunc(GL_ALWAYS, 1, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
    draw_lists(counts, proxy_tables.size(), 1, 1.0f, with_ids);
    glStencilFunc(GL_EQUAL, 0, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    draw_lists(counts, proxy_tables.size(), 2, 1.0f, with_ids);
    glStencilFunc(GL_EQUAL, 1, 0xff);
    draw_lists(counts, proxy_tables.size(), 2, kSeeThroughAlpha, with_ids);
    glDisable(GL_STENCIL_TEST);
  }
  if (wait) glFinish();
}

void GlBackend::finish_frame(const FrameView& view, const Look& look, bool with_ids, bool wait) {
  if (look.ground) draw_ground(view, look.model_bounds, with_ids);
  finish(view, frame_plan_, with_ids);
  if (wait)
    glFinish();
  else
    glFlush();  // so that the GPU (llvmpipe's threads) draws while the caller works
}

void GlBackend::wait() { glFinish(); }

bool GlBackend::test_boxes(const FrameView& view, std::span<const glm::vec4> boxes,
                           std::vector<uint32_t>& seen, std::string& error) {
  const size_t count = boxes.size() / 2;
  seen.assign(count, 0);
  if (count == 0) return true;
  upload_stream(box_buffer_, box_capacity_, boxes.size_bytes(), {{boxes.data(), boxes.size_bytes()}});
  const size_t seen_bytes = count * sizeof(uint32_t);
  if (seen_bytes > seen_capacity_) {
    seen_capacity_ = std::max(seen_bytes, seen_capacity_ * 3 / 2);
    glNamedBufferData(seen_buffer_, GLsizeiptr(seen_capacity_), nullptr, GL_STREAM_READ);
  }
  const uint32_t zero = 0;
  glClearNamedBufferSubData(seen_buffer_, GL_R32UI, 0, GLsizeiptr(seen_bytes), GL_RED_INTEGER,
                            GL_UNSIGNED_INT, &zero);
  glBindFramebuffer(GL_FRAMEBUFFER, scene_.framebuffer);
  glViewport(0, 0, GLsizei(scene_.width), GLsizei(scene_.height));
  glColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glColorMaski(1, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GEQUAL);
  glDepthMask(GL_FALSE);
  glDisable(GL_CULL_FACE);  // only the faces the eye sees are drawn
  glDisablei(GL_BLEND, 0);
  glEnable(GL_DEPTH_CLAMP);
  glProgramUniformMatrix4fv(box_test_program_, at(box_test_program_, "u_view_projection"), 1,
                            GL_FALSE, glm::value_ptr(view.view_projection));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, box_buffer_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, seen_buffer_);
  glUseProgram(box_test_program_);
  glBindVertexArray(empty_vao_);
  glDrawArrays(GL_TRIANGLES, 0, GLsizei(18 * count));
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glGetNamedBufferSubData(seen_buffer_, 0, GLsizeiptr(seen_bytes), seen.data());
  glDisable(GL_DEPTH_CLAMP);
  glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
  glDisable(GL_CULL_FACE);
  if (const GLenum e = glGetError(); e != GL_NO_ERROR) {
    error = "renderer: the occlusion box test failed (GL error " + std::to_string(e) + ")";
    return false;
  }
  return true;
}

bool GlBackend::reduce_depth(uint32_t cells_width, uint32_t cells_height,
                             std::vector<float>& depth, std::string& error) {
  ensure_grid(reduce_grid_, GL_R32F, cells_width, cells_height);
  const bool multisampled = scene_.samples > 1;
  GLuint p = multisampled ? reduce_multisampled_program_ : reduce_program_;
  if (scene_.width % cells_width == 0 && scene_.height % cells_height == 0) {
    // Whole pixels per cell (1280x720 into 320x180, say): a program with those numbers
    // compiled in, which runs several times faster on llvmpipe.
    const std::array<uint32_t, 3> key{scene_.width / cells_width, scene_.height / cells_height,
                                      std::max(scene_.samples, 1u)};
    auto it = std::find_if(reduce_fixed_.begin(), reduce_fixed_.end(),
                           [&](const auto& e) { return e.first == key; });
    if (it == reduce_fixed_.end()) {
      const GLuint fixed = link(depth_reduction_source(multisampled, key), error);
      if (!fixed) return false;
      it = reduce_fixed_.insert(reduce_fixed_.end(), {key, fixed});
    }
    p = it->second;
  }
  glProgramUniform1i(p, at(p, "u_depth"), 1);
  glProgramUniform2i(p, at(p, "u_source"), GLint(scene_.width), GLint(scene_.height));
  glProgramUniform2i(p, at(p, "u_cells"), GLint(cells_width), GLint(cells_height));
  glProgramUniform1i(p, at(p, "u_samples"), GLint(std::max(scene_.samples, 1u)));
  glDisable(GL_DEPTH_TEST);
  glDisablei(GL_BLEND, 0);
  glBindTextureUnit(1, scene_.depth);
  glBindSampler(1, nearest_sampler_);
  glBindFramebuffer(GL_FRAMEBUFFER, reduce_grid_.framebuffer);
  glViewport(0, 0, GLsizei(cells_width), GLsizei(cells_height));
  glUseProgram(p);
  glBindVertexArray(empty_vao_);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  glBindTextureUnit(1, 0);
  glBindSampler(1, 0);
  depth.resize(size_t(cells_width) * cells_height);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glNamedFramebufferReadBuffer(reduce_grid_.framebuffer, GL_COLOR_ATTACHMENT0);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, reduce_grid_.framebuffer);
  glReadPixels(0, 0, GLsizei(cells_width), GLsizei(cells_height), GL_RED, GL_FLOAT, depth.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glEnable(GL_DEPTH_TEST);
  if (const GLenum gl_error = glGetError(); gl_error != GL_NO_ERROR) {
    char buf[80];
    std::snprintf(buf, sizeof buf, "renderer: OpenGL error 0x%x in the depth reduction", gl_error);
    error = buf;
    return false;
  }
  return true;
}

void GlBackend::begin_pass(const FrameView& view, const Plan& plan, bool with_ids) {
  const uint32_t w = scene_.width, h = scene_.height;
  glBindFramebuffer(GL_FRAMEBUFFER, scene_.framebuffer);
  // The object ids are written only when they are read back.
  const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0, GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, draw_buffers);
  glViewport(0, 0, GLsizei(w), GLsizei(h));
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);  // two-sided: facet groups and open meshes are seen from both sides
  glCullFace(GL_BACK);      // (closed solids and boxes: back faces culled where enabled)
  glFrontFace(GL_CCW);

  // The key light: 50 degrees up, from behind the eye's left shoulder (turned with the view
  // about the vertical, so every view is lit alike).
  const glm::vec3 forward = glm::vec3(glm::transpose(view.rotation) * glm::vec4(0, 0, -1, 0));
  const glm::vec3 right = glm::vec3(glm::transpose(view.rotation) * glm::vec4(1, 0, 0, 0));
  glm::vec2 back(-forward.x, -forward.y), left(-right.x, -right.y);
  glm::vec2 horizontal = back + 0.8f * left;
  if (glm::length(horizontal) < 1e-3f) horizontal = glm::vec2(-0.6f, -0.8f);
  horizontal = glm::normalize(horizontal) * std::cos(glm::radians(50.0f));
  const glm::vec3 key = glm::normalize(glm::vec3(horizontal, std::sin(glm::radians(50.0f))));
  // View space to the camera-relative frame, with the half-angle tangents of the view.
  const glm::mat3 ray = glm::transpose(glm::mat3(view.rotation)) *
                        glm::mat3(glm::vec3(view.aspect / view.focal, 0, 0),
                                  glm::vec3(0, 1.0f / view.focal, 0), glm::vec3(0, 0, 1));
  const float focal_px = float(view.focal_px * plan.scale);
  for (const GLuint program : {surface_program_, proxy_program_, centreline_program_, ground_program_}) {
    glProgramUniformMatrix4fv(program, at(program, "u_view_projection"), 1, GL_FALSE,
                              glm::value_ptr(view.view_projection));
    glProgramUniform3fv(program, at(program, "u_key"), 1, glm::value_ptr(key));
    glProgramUniformMatrix3fv(program, at(program, "u_ray"), 1, GL_FALSE, glm::value_ptr(ray));
    glProgramUniform2f(program, at(program, "u_window_scale"), 2.0f / float(w), 2.0f / float(h));
  }
  glProgramUniform2f(centreline_program_, at(centreline_program_, "u_viewport"), float(w), float(h));
  glProgramUniform1f(centreline_program_, at(centreline_program_, "u_focal_px"), focal_px);
  glProgramUniform1f(centreline_program_, at(centreline_program_, "u_near"), float(kNearPlaneM));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, table_buffer_);
}

void GlBackend::draw_triangles(size_t first, size_t count) const {
  const size_t piece = software_ && bounded_drawing_ ? 3 * kSoftwarePieceTriangles : count;
  GLsync previous = nullptr;
  for (size_t done = 0; done < count; done += piece) {
    glDrawElements(GL_TRIANGLES, GLsizei(std::min(piece, count - done)), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>((first + done) * sizeof(uint32_t)));
    if (done + piece >= count) break;
    // This piece is binned: the one before must be rasterised before the next is binned.
    const GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    if (previous) {
      glClientWaitSync(previous, GL_SYNC_FLUSH_COMMANDS_BIT, GL_TIMEOUT_IGNORED);
      glDeleteSync(previous);
    }
    previous = fence;
  }
  if (previous) glDeleteSync(previous);
}

void GlBackend::draw_lists(const IndexCounts& counts, size_t proxies, int mode, float alpha,
                           bool with_ids) {
  const size_t n_closed = counts[kClosed], n_open = counts[kOpen];
  const size_t n_opaque = n_closed + n_open, n_transparent = counts[kTransparent],
               n_lines = counts[kLines];
  const bool see_through = alpha < 1.0f;
  for (const GLuint program : {surface_program_, proxy_program_, centreline_program_}) {
    glProgramUniform1i(program, at(program, "u_mode"), mode);
    glProgramUniform1f(program, at(program, "u_alpha"), alpha);
  }
  if (see_through) {
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDepthMask(GL_FALSE);
    const GLenum colour_only[] = {GL_COLOR_ATTACHMENT0, GL_NONE};
    glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, colour_only);
  } else {
    glDisablei(GL_BLEND, 0);
  }
  glUseProgram(surface_program_);
  glBindVertexArray(vao_);
  if (n_closed) {
    // Closed solids have outward, counter-clockwise faces: their back faces are never seen.
    glEnable(GL_CULL_FACE);
    draw_triangles(0, n_closed);
    glDisable(GL_CULL_FACE);
  }
  if (n_open) draw_triangles(n_closed, n_open);
  if (proxies) {
    // Only the faces the eye sees are drawn (kProxyVertex).
    glUseProgram(proxy_program_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, proxy_buffer_);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, GLsizei(18 * proxies));
    glBindVertexArray(vao_);
    glUseProgram(surface_program_);
  }
  if (n_lines) {
    // Centrelines blend their coverage; they write depth like the pipes they stand for.
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(centreline_program_);
    glDrawElements(GL_LINES, GLsizei(n_lines), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>((n_opaque + n_transparent) * sizeof(uint32_t)));
    glUseProgram(surface_program_);
    if (!see_through) glDisablei(GL_BLEND, 0);
  }
  if (n_transparent) {
    // See-through objects after the rest, blended, not hiding what lies behind them.
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDepthMask(GL_FALSE);
    draw_triangles(n_opaque, n_transparent);
  }
  glDepthMask(GL_TRUE);
  glDisablei(GL_BLEND, 0);
  if (see_through) {
    const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0, GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
    glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, draw_buffers);
  }
  glBindVertexArray(0);
}

// The ground: where nothing else was drawn (it lies below the whole model, so an eye above it
// sees it only there), and only from above.
void GlBackend::draw_ground(const FrameView& view, const DAabb& bounds, bool with_ids) {
  if (bounds.empty()) return;
  const double ground_z = bounds.min.z - view.eye_m.z;
  if (ground_z >= 0) return;
  const glm::dvec2 size(bounds.max.x - bounds.min.x, bounds.max.y - bounds.min.y);
  const double radius = std::max(0.5 * glm::length(size), 1.0);
  // Squares of 1, 10 or 100 m..., about a hundredth of the plant, heavier lines every ten.
  const double grid = std::pow(10.0, std::floor(std::log10(std::max(radius / 25.0, 0.1))));
  const glm::dvec2 centre = 0.5 * glm::dvec2(bounds.min.x + bounds.max.x, bounds.min.y + bounds.max.y) -
                            glm::dvec2(view.eye_m);
  const glm::dvec2 phase(std::fmod(view.eye_m.x, 10 * grid), std::fmod(view.eye_m.y, 10 * grid));
  const GLuint p = ground_program_;
  glProgramUniform1f(p, at(p, "u_ground_z"), float(ground_z));
  glProgramUniform2f(p, at(p, "u_grid_phase"), float(phase.x), float(phase.y));
  glProgramUniform1f(p, at(p, "u_grid_m"), float(grid));
  glProgramUniform2f(p, at(p, "u_centre"), float(centre.x), float(centre.y));
  glProgramUniform1f(p, at(p, "u_radius_m"), float(radius));
  glProgramUniform1f(p, at(p, "u_reach_m"), float(3 * radius + 20));  // (kGroundFragment's fade)
  const GLenum colour_only[] = {GL_COLOR_ATTACHMENT0, GL_NONE};
  glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, colour_only);
  glEnablei(GL_BLEND, 0);
  glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glUseProgram(p);
  glBindVertexArray(empty_vao_);
  glDrawArrays(GL_TRIANGLES, 0, 6);
  glDisablei(GL_BLEND, 0);
  const GLenum restored[] = {GL_COLOR_ATTACHMENT0, GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, restored);
  glBindVertexArray(0);
}

void GlBackend::finish(const FrameView& view, const Plan& plan, bool with_ids) {
  const Target* source = &scene_;
  if (plan.samples > 1) {
    // Colour averages its samples; ids and depth take one (they do not average).
    for (const GLenum attachment : {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1}) {
      if (attachment == GL_COLOR_ATTACHMENT1 && !with_ids) break;
      glNamedFramebufferReadBuffer(scene_.framebuffer, attachment);
      const GLenum draw_buffers[] = {attachment == GL_COLOR_ATTACHMENT0 ? attachment : GL_NONE,
                                     attachment == GL_COLOR_ATTACHMENT1 ? attachment : GL_NONE};
      glNamedFramebufferDrawBuffers(resolved_.framebuffer, 2, draw_buffers);
      glBlitNamedFramebuffer(scene_.framebuffer, resolved_.framebuffer, 0, 0, GLint(scene_.width),
                             GLint(scene_.height), 0, 0, GLint(scene_.width), GLint(scene_.height),
                             GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    if (plan.occlusion)
      glBlitNamedFramebuffer(scene_.framebuffer, resolved_.framebuffer, 0, 0, GLint(scene_.width),
                             GLint(scene_.height), 0, 0, GLint(scene_.width), GLint(scene_.height),
                             GL_DEPTH_BUFFER_BIT, GL_NEAREST);
    const GLenum both[] = {GL_COLOR_ATTACHMENT0, GLenum(resolved_.has_pick ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
    glNamedFramebufferDrawBuffers(resolved_.framebuffer, 2, both);
    source = &resolved_;
  }
  final_ = source;
  if (!plan.finish()) return;

  glDisable(GL_DEPTH_TEST);
  glDisablei(GL_BLEND, 0);
  glBindVertexArray(empty_vao_);
  glBindTextureUnit(1, source->depth ? source->depth : scene_.depth);
  glBindSampler(1, nearest_sampler_);
  if (plan.occlusion) {
    const uint32_t ao_width = (output_.width + 1) / 2, ao_height = (output_.height + 1) / 2;
    ensure_grid(occlusion_grid_, GL_RG32F, ao_width, ao_height);
    const GLuint o = occlusion_program_;
    glProgramUniform1i(o, at(o, "u_depth"), 1);
    glProgramUniform1i(o, at(o, "u_scale"), GLint(plan.scale));
    glProgramUniform1i(o, at(o, "u_step"), GLint(2 * plan.scale));
    glProgramUniform1f(o, at(o, "u_near"), float(kNearPlaneM));
    glProgramUniform2f(o, at(o, "u_ndc_to_view"), view.aspect / view.focal, 1.0f / view.focal);
    glProgramUniform1f(o, at(o, "u_focal_px"), float(view.focal_px * plan.scale));
    glProgramUniform1f(o, at(o, "u_radius_m"), float(kOcclusionRadiusM));
    glBindFramebuffer(GL_FRAMEBUFFER, occlusion_grid_.framebuffer);
    glViewport(0, 0, GLsizei(ao_width), GLsizei(ao_height));
    glUseProgram(o);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

  const GLuint p = finish_program_;
  glProgramUniform1i(p, at(p, "u_colour"), 0);
  glProgramUniform1i(p, at(p, "u_depth"), 1);
  glProgramUniform1i(p, at(p, "u_pick"), 2);
  glProgramUniform1i(p, at(p, "u_occlusion"), 3);
  glProgramUniform1i(p, at(p, "u_scale"), GLint(plan.scale));
  glProgramUniform1i(p, at(p, "u_edge_filter"), plan.edge_filter);
  glProgramUniform1i(p, at(p, "u_occlusion_on"), plan.occlusion);
  glBindTextureUnit(3, plan.occlusion ? occlusion_grid_.texture : 0);
  glBindSampler(3, nearest_sampler_);
  glBindTextureUnit(0, source->colour);
  glBindSampler(0, linear_sampler_);
  glBindTextureUnit(2, source->pick);
  glBindSampler(2, nearest_sampler_);
  glBindFramebuffer(GL_FRAMEBUFFER, output_.framebuffer);
  const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0, GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(output_.framebuffer, 2, draw_buffers);
  glViewport(0, 0, GLsizei(output_.width), GLsizei(output_.height));
  glUseProgram(p);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  for (GLuint unit = 0; unit < 4; ++unit) {
    glBindTextureUnit(unit, 0);
    glBindSampler(unit, 0);
  }
  glEnable(GL_DEPTH_TEST);
  final_ = &output_;
}

bool GlBackend::read_back(uint32_t w, uint32_t h, bool with_ids,
                          std::span<const uint64_t> pick_ids, Image& out, std::string& error) {
  if (!final_ || final_->width != w || final_->height != h) {
    error = "renderer: nothing drawn at " + std::to_string(w) + "x" + std::to_string(h) + " to read back";
    return false;
  }
  const GLuint source = final_->framebuffer;
  out.width = w;
  out.height = h;
  out.rgba.resize(size_t(w) * h * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, source);
  glNamedFramebufferReadBuffer(source, GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, GLsizei(w), GLsizei(h), GL_RGBA, GL_UNSIGNED_BYTE, out.rgba.data());
  // GL's rows run bottom up; the image's top down: swapped a row at a time (a byte-wise swap
  // took 0.3 ms more of a 1280x720 read-back).
  const size_t row = size_t(w) * 4;
  row_.resize(row);
  for (uint32_t y = 0; y < h / 2; ++y) {
    uint8_t* top = out.rgba.data() + y * row;
    uint8_t* bottom = out.rgba.data() + (h - 1 - y) * row;
    std::memcpy(row_.data(), top, row);
    std::memcpy(top, bottom, row);
    std::memcpy(bottom, row_.data(), row);
  }
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
