// GL backend: the objects' pass: surfaces, proxy boxes, centrelines and see-through triangles
// from the frame's index lists, and a highlight's three draws (rules in gl/backend.h).
#include "gl/backend.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

#include "frame_plan.h"
#include "gl/programs.h"
#include "lod.h"

namespace plantview::detail {

namespace {

constexpr float kSeeThroughAlpha = 0.22f;  // occluders of a highlighted subject

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

std::span<const TableEntry> GlBackend::highlighted(std::span<const TableEntry> table,
                                                   std::span<const uint64_t> pick_ids,
                                                   std::span<const uint64_t> highlight_ids,
    std::span<const std::pair<uint64_t, uint32_t>> subject_colours) {
  highlight_sorted_.assign(highlight_ids.begin(), highlight_ids.end());
  std::sort(highlight_sorted_.begin(), highlight_sorted_.end());
  highlight_table_.assign(table.begin(), table.end());
  see_through_subjects_ = false;
  for (TableEntry& e : highlight_table_) {
    // The pick word's low bits index the pick table; its high bits are the tie-break, kept for
    // the context too (it only orders coinciding depths).
    const uint32_t pick = e.pick & (kPickLimit - 1);
    const uint64_t id = pick && pick <= pick_ids.size() ? pick_ids[pick - 1] : 0;
    if (id && std::binary_search(highlight_sorted_.begin(), highlight_sorted_.end(), id)) {
      // A change image's or a clash view's subject: its colour, its own alpha; a see-through
      // one's alpha is the subject colour's.
      const auto c = std::lower_bound(subject_colours.begin(), subject_colours.end(),
                                      std::pair<uint64_t, uint32_t>(id, 0));
      if (c != subject_colours.end() && c->first == id) {
        const bool see_through = (c->second >> 24) < 255;
        e.colour = see_through ? c->second : (c->second & 0x00ffffffu) | (e.colour & 0xff000000u);
        see_through_subjects_ = see_through_subjects_ || see_through;
      }
      continue;
    }
    e.pick &= ~(kPickLimit - 1);
    e.colour = ghost(e.colour);
  }
  return highlight_table_;
}

void GlBackend::draw_phase(const FrameView& view, const IndexCounts& counts,
                           std::span<const TableEntry> table,
                           std::span<const uint32_t> proxy_tables,
                           std::span<const uint64_t> pick_ids, const Look& look, bool with_ids,
                           bool wait) {
  const bool highlight = !look.highlight_ids.empty();
  if (highlight) table = highlighted(table, pick_ids, look.highlight_ids, look.subject_colours);
  upload_stream(table_buffer_, table_capacity_, table.size_bytes(), {{table.data(), table.size_bytes()}});
  upload_stream(proxy_buffer_, proxy_capacity_, proxy_tables.size_bytes(),
                {{proxy_tables.data(), proxy_tables.size_bytes()}});
  begin_pass(view, frame_plan_, with_ids);
  if (!highlight) {
    draw_lists(counts, proxy_tables.size(), 0, 1.0f, with_ids);
  } else {
    // The subject, marking its pixels; the context where it is not; the context in front of
    // it, see-through (gl/backend.h). See-through subjects mark theirs without drawing, and
    // are drawn last.
    glEnable(GL_STENCIL_TEST);
    glStencilFunc(GL_ALWAYS, 1, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
    draw_lists(counts, proxy_tables.size(), see_through_subjects_ ? 3 : 1, 1.0f, with_ids);
    if (see_through_subjects_) {
      glColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      draw_lists(counts, proxy_tables.size(), 4, 1.0f, with_ids);
      glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    }
    glStencilFunc(GL_EQUAL, 0, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    draw_lists(counts, proxy_tables.size(), 2, 1.0f, with_ids);
    glStencilFunc(GL_EQUAL, 1, 0xff);
    draw_lists(counts, proxy_tables.size(), 2, kSeeThroughAlpha, with_ids);
    glDisable(GL_STENCIL_TEST);
    if (see_through_subjects_) draw_lists(counts, proxy_tables.size(), 4, 1.0f, with_ids);
  }
  set_clipping(false);
  if (wait) glFinish();
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
  const GLuint centreline = drawing_program(ProgramId::centreline);
  glProgramUniformMatrix4fv(gl_program(ProgramId::cap_plane),
                            at(gl_program(ProgramId::cap_plane), "u_view_projection"), 1, GL_FALSE,
                            glm::value_ptr(view.view_projection));
  for (const GLuint program :
       {drawing_program(ProgramId::surface), drawing_program(ProgramId::proxy), centreline,
        gl_program(ProgramId::ground), gl_program(ProgramId::surface)}) {
    glProgramUniform1i(program, at(program, "u_clip_count"), clip_count_);
    if (clip_count_)
      glProgramUniform4fv(program, at(program, "u_clip"), clip_count_, glm::value_ptr(clip_[0]));
    glProgramUniformMatrix4fv(program, at(program, "u_view_projection"), 1, GL_FALSE,
                              glm::value_ptr(view.view_projection));
    glProgramUniform3fv(program, at(program, "u_key"), 1, glm::value_ptr(key));
    glProgramUniformMatrix3fv(program, at(program, "u_ray"), 1, GL_FALSE, glm::value_ptr(ray));
    glProgramUniform2f(program, at(program, "u_window_scale"), 2.0f / float(w), 2.0f / float(h));
  }
  glProgramUniform2f(centreline, at(centreline, "u_viewport"), float(w), float(h));
  glProgramUniform1f(centreline, at(centreline, "u_focal_px"), focal_px);
  glProgramUniform1f(centreline, at(centreline, "u_near"), float(kNearPlaneM));
  set_clipping(true);
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

void GlBackend::draw_cut_capped(size_t first, size_t count, int mode) {
  // Highlight modes (gl/shaders/object_table.glsl): the context (2) is drawn only where the
  // subject (stencil bit 0) is not; the subject (1) marks its pixels in bit 0.
  const bool marks = mode == 1 || mode == 3;  // the (opaque) subject
  const GLuint not_subject = mode == 2 ? 1u : 0u, subject = marks ? 1u : 0u;
  const GLenum test = mode == 2 ? GL_EQUAL : GL_ALWAYS;
  const GLuint surface = drawing_program(ProgramId::surface);
  glEnable(GL_STENCIL_TEST);
  // 1. Both sides, back faces shaded as caps: a front face drawn clears the mark, a back face
  //    sets it.
  glStencilFuncSeparate(GL_FRONT, test, GLint(subject), not_subject);
  glStencilFuncSeparate(GL_BACK, test, GLint(kCapStencilBit | subject), not_subject);
  glStencilMask(kCapStencilBit | subject);
  glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
  glProgramUniform1i(surface, at(surface, "u_cap"), 1);
  draw_triangles(first, count);
  glProgramUniform1i(surface, at(surface, "u_cap"), 0);
  // 2. Where marked, the depth moved onto the cut: a square on each plane the eye is on the
  //    removed side of, the first drawn over whatever is there, the others only where farther
  //    (the ray enters the kept region at the farthest of them); the last clears the marks.
  std::vector<int> entries;
  for (int i = 0; i < clip_count_; ++i)
    if (clip_[size_t(i)].w > 0) entries.push_back(i);
  glStencilMask(kCapStencilBit);
  if (entries.empty()) {
    // The eye is in the kept region: a back face seen is the inside of a solid it is in.
    const GLint zero = 0;
    glClearNamedFramebufferiv(scene_.framebuffer, GL_STENCIL, 0, &zero);
  } else {
    const GLuint cap_plane = gl_program(ProgramId::cap_plane);
    glUseProgram(cap_plane);
    glBindVertexArray(empty_vao_);
    set_clipping(false);
    glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glStencilFunc(GL_EQUAL, GLint(kCapStencilBit), kCapStencilBit);
    for (size_t e = 0; e < entries.size(); ++e) {
      const glm::vec3 n(clip_[size_t(entries[e])]);
      const float w = clip_[size_t(entries[e])].w;
      const glm::vec3 foot = -w * n;  // the plane's nearest point to the eye
      const glm::vec3 u = glm::normalize(
          glm::cross(n, std::abs(n.z) < 0.9f ? glm::vec3(0, 0, 1) : glm::vec3(1, 0, 0)));
      const glm::vec3 v = glm::cross(n, u);
      const float reach = 1e4f + w;  // metres: beyond any ray crossing that matters
      const glm::vec3 corners[4] = {foot - reach * (u + v), foot + reach * (u - v),
                                    foot - reach * (u - v), foot + reach * (u + v)};
      glProgramUniform3fv(cap_plane, at(cap_plane, "u_corners"), 4, glm::value_ptr(corners[0]));
      glDepthFunc(e == 0 ? GL_ALWAYS : GL_LESS);
      const bool last = e + 1 == entries.size();
      glStencilOp(GL_KEEP, last ? GL_ZERO : GL_KEEP, last ? GL_ZERO : GL_KEEP);
      glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    }
    glDepthFunc(GL_GREATER);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    set_clipping(true);
    glBindVertexArray(vao_);
    glUseProgram(surface);
  }
  glStencilMask(0xff);
  // The highlight's stencil state back (draw_phase).
  if (mode == 0) {
    glDisable(GL_STENCIL_TEST);
  } else if (marks) {
    glStencilFunc(GL_ALWAYS, 1, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
  } else {
    glStencilFunc(GL_EQUAL, 0, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
  }
}

void GlBackend::draw_lists(const IndexCounts& counts, size_t proxies, int mode, float alpha,
                           bool with_ids) {
  const size_t n_closed = counts[kClosed], n_cut = counts[kClosedCut], n_open = counts[kOpen];
  const size_t n_opaque = n_closed + n_cut + n_open, n_transparent = counts[kTransparent],
               n_lines = counts[kLines];
  // Mode 4 draws see-through subjects: blended at their own alpha, their outline stronger.
  const bool see_through = alpha < 1.0f || mode == 4;
  const GLuint surface = drawing_program(ProgramId::surface),
               proxy = drawing_program(ProgramId::proxy),
               centreline = drawing_program(ProgramId::centreline);
  // The closed solids the section does not cut need no clipping: the plain program (cheaper).
  const GLuint plain = gl_program(ProgramId::surface);
  for (const GLuint program : {surface, proxy, centreline, plain}) {
    glProgramUniform1i(program, at(program, "u_mode"), mode);
    glProgramUniform1f(program, at(program, "u_alpha"), alpha);
  }
  for (const GLuint program : {surface, proxy, plain})
    glProgramUniform1f(program, at(program, "u_rim"), mode == 4 ? float(kSeeThroughSubjectRim) : 0.0f);
  if (see_through) {
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDepthMask(GL_FALSE);
    const GLenum colour_only[] = {GL_COLOR_ATTACHMENT0, GL_NONE};
    glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, colour_only);
  } else {
    glDisablei(GL_BLEND, 0);
  }
  glBindVertexArray(vao_);
  // The cut solids first: their caps must be drawn before whatever lies inside them (a pipe
  // through a vessel), which would otherwise hide the back faces that mark where a cap goes.
  glUseProgram(surface);
  if (n_cut && caps_ && !see_through) {
    draw_cut_capped(n_closed, n_cut, mode);
  } else if (n_cut) {
    glEnable(GL_CULL_FACE);
    draw_triangles(n_closed, n_cut);
    glDisable(GL_CULL_FACE);
  }
  if (n_closed) {
    // Closed solids have outward, counter-clockwise faces: their back faces are never seen.
    glUseProgram(plain);
    if (plain != surface) set_clipping(false);  // (it writes no clip distance)
    glEnable(GL_CULL_FACE);
    draw_triangles(0, n_closed);
    glDisable(GL_CULL_FACE);
    if (plain != surface) set_clipping(true);
    glUseProgram(surface);
  }
  if (n_open) draw_triangles(n_closed + n_cut, n_open);
  if (proxies) {
    // Only the faces the eye sees are drawn (kProxyVertex).
    glUseProgram(proxy);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, proxy_buffer_);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, GLsizei(18 * proxies));
    glBindVertexArray(vao_);
    glUseProgram(surface);
  }
  if (n_lines) {
    // Centrelines blend their coverage; they write depth like the pipes they stand for.
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(centreline);
    glDrawElements(GL_LINES, GLsizei(n_lines), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>((n_opaque + n_transparent) * sizeof(uint32_t)));
    glUseProgram(surface);
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

}  // namespace plantview::detail
