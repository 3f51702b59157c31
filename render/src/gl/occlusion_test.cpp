// GL backend: occlusion culling's reads of the depth drawn so far: the depth reduction (coarse
// grid) and the exact box test (rules in gl/backend.h; callers: occlusion.h).
#include "gl/backend.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include <glm/gtc/type_ptr.hpp>

#include "frame_plan.h"
#include "gl/programs.h"

namespace plantview::detail {

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
  const GLuint box_test = gl_program(ProgramId::box_test);
  glProgramUniformMatrix4fv(box_test, at(box_test, "u_view_projection"), 1,
                            GL_FALSE, glm::value_ptr(view.view_projection));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, box_buffer_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, seen_buffer_);
  glUseProgram(box_test);
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
  GLuint p = gl_program(multisampled ? ProgramId::depth_reduction_multisampled
                                     : ProgramId::depth_reduction);
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

}  // namespace plantview::detail
