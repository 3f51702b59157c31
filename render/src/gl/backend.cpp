// GL backend: init, the frame's order of passes (begin_frame, draw_phase, finish_frame) and the
// look's names (rules in gl/backend.h).
#include "gl/backend.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <malloc.h>

#include <algorithm>
#include <mutex>
#include <string>
#include <type_traits>

#include "frame_plan.h"
#include "gl/programs.h"

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

namespace {

constexpr uint64_t kInitialArenaVertices = 1u << 16;  // the GPU buffers grow from here
constexpr GLfloat kBackground[4] = {0.80f, 0.84f, 0.88f, 1.0f};

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

static_assert(std::is_same_v<GlName, GLuint>);

int section_half_spaces(const Section& section, const glm::dvec3& eye_m, const DAabb& model_bounds,
                        std::array<glm::vec4, 8>& out) {
  int count = 0;
  const auto add = [&](const glm::dvec3& normal, const glm::dvec3& point_m) {
    if (count == kMaxClipHalfSpaces) return;
    out[size_t(count++)] = glm::vec4(glm::vec3(normal), float(glm::dot(normal, eye_m - point_m)));
  };
  for (const ClipPlane& plane : section.planes) add(plane.normal, plane.point_m);
  if (section.has_box) {
    for (int axis = 0; axis < 3; ++axis) {
      glm::dvec3 normal(0.0);
      normal[axis] = -1.0;
      // A face with the whole model on its kept side removes nothing.
      if (model_bounds.empty() || model_bounds.min[axis] < section.box.min[axis])
        add(normal, section.box.min);
      normal[axis] = 1.0;
      if (model_bounds.empty() || model_bounds.max[axis] > section.box.max[axis])
        add(normal, section.box.max);
    }
  }
  return count;
}

Look look_of(const RenderOptions& options, const DAabb& model_bounds) {
  Look look;
  look.antialias = options.antialias;
  look.method = options.antialias_method;
  look.samples = options.samples;
  look.ground = options.ground;
  look.ambient_occlusion = options.ambient_occlusion;
  look.highlight_ids = options.highlight_ids;
  look.section = &options.section;
  look.model_bounds = model_bounds;
  return look;
}

GlBackend::~GlBackend() {
  // The driver draws from the mapped arena until its buffers are gone (the mappings are
  // unmapped after this body).
  if (arena_mapped()) glFinish();
  for (const GLuint program : programs_)
    if (program) glDeleteProgram(program);
  for (const auto& [key, program] : reduce_fixed_) glDeleteProgram(program);
  release_grid(occlusion_grid_);
  release_grid(reduce_grid_);
  GLuint buffers[] = {arena_,        arena_objects_, index_buffers_[0], index_buffers_[1],
                      table_buffer_, proxy_buffer_,  box_buffer_,       seen_buffer_};
  glDeleteBuffers(8, buffers);
  release_ghost_buffers();
  GLuint vaos[] = {vao_, empty_vao_};
  glDeleteVertexArrays(2, vaos);
  GLuint samplers[] = {linear_sampler_, nearest_sampler_};
  glDeleteSamplers(2, samplers);
  release_target(scene_);
  release_target(resolved_);
  release_target(output_);
}

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

  for (size_t i = 0; i < kProgramCount; ++i)
    if (i < kProgramsAtInit && !(programs_[i] = link(program_source(ProgramId(i)), error)))
      return false;

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

bool GlBackend::begin_frame(const FrameView& view, const Look& look, bool with_ids,
                            std::string& error) {
  frame_plan_ = plan_for(look);
  const Plan& plan = frame_plan_;
  const uint32_t w = view.width, h = view.height;
  clip_count_ = look.section && !look.section->empty()
                    ? section_half_spaces(*look.section, view.eye_m, look.model_bounds, clip_)
                    : 0;
  caps_ = clip_count_ > 0 && look.section->capped;
  for (size_t i = kProgramsAtInit; clip_count_ > 0 && i < kProgramCount; ++i)
    if (!programs_[i] && !(programs_[i] = link(program_source(ProgramId(i)), error))) return false;
  // Stencil once a frame highlights (the subject's pixels are marked in it), kept for the frames
  // after; the resolved depth has the scene's format (a blit copies it).
  const bool stencil = scene_.has_stencil || !look.highlight_ids.empty() || caps_;
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
  // The ground first: what stands on it is drawn over it, and what is blended (see-through
  // triangles, centrelines' feathered edges) blends over it rather than being painted over.
  // No clip distance is enabled for it (a previous frame's section may have left them on): its
  // program writes none.
  set_clipping(false);
  if (look.ground) draw_ground(view, look.model_bounds, with_ids);
  final_ = nullptr;
  return true;
}

void GlBackend::finish_frame(const FrameView& view, bool with_ids, bool wait) {
  finish(view, frame_plan_, with_ids);
  if (wait)
    glFinish();
  else
    glFlush();  // so that the GPU (llvmpipe's threads) draws while the caller works
}

void GlBackend::wait() { glFinish(); }

void GlBackend::set_clipping(bool on) const {
  for (int i = 0; i < kMaxClipHalfSpaces; ++i) {
    if (on && i < clip_count_) glEnable(GLenum(GL_CLIP_DISTANCE0 + i));
    else glDisable(GLenum(GL_CLIP_DISTANCE0 + i));
  }
}

}  // namespace plantview::detail
