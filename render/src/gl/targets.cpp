// GL backend: the framebuffers a frame is drawn, resolved and finished into, and how a look
// chooses them (rules in gl/backend.h).
#include "gl/backend.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <string>

namespace plantview::detail {

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

}  // namespace plantview::detail
