// GL backend: finishing a frame: multisampling resolved, ambient occlusion, then the finishing
// pass into the output's size (rules in gl/backend.h).
#include "gl/backend.h"

#include <epoxy/gl.h>

#include "frame_plan.h"
#include "gl/programs.h"
#include "lod.h"

namespace plantview::detail {

namespace {

constexpr double kOcclusionRadiusM = 0.6;  // ambient occlusion's reach

}  // namespace

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
    const GLuint o = gl_program(ProgramId::ambient_occlusion);
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

  const GLuint p = gl_program(ProgramId::finish);
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

}  // namespace plantview::detail
