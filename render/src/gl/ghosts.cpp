// GL backend: a change image's ghosts (change_set.h), drawn see-through after the frame's
// objects from buffers of their own (rules in gl/backend.h: draw_ghosts).
#include <epoxy/gl.h>

#include <cassert>

#include "change_set.h"
#include "frame_plan.h"
#include "gl/backend.h"
#include "gl/programs.h"

namespace plantview::detail {

namespace {

constexpr float kGhostFrontAlpha = 0.5f;    // where a ghost lies in front of what was drawn
constexpr float kGhostBehindAlpha = 0.25f;  // where it lies behind

}  // namespace

void GlBackend::release_ghost_buffers() {
  GLuint buffers[] = {ghost_.vertices, ghost_.objects, ghost_.indices, ghost_.table};
  glDeleteBuffers(4, buffers);
  glDeleteVertexArrays(1, &ghost_.vao);
  ghost_ = GhostBuffers{};
}

void GlBackend::draw_ghosts(const FrameView& view, const GhostMesh& ghosts, uint32_t first_pick,
                            bool with_ids) {
  if (ghosts.empty()) return;
  assert(first_pick + ghosts.ghosts.size() < kPickLimit);
  if (!ghost_.vao) {
    // As the objects' vertex array (backend.cpp: init), over the ghosts' buffers.
    GLuint buffers[4];
    glCreateBuffers(4, buffers);
    ghost_.vertices = buffers[0];
    ghost_.objects = buffers[1];
    ghost_.indices = buffers[2];
    ghost_.table = buffers[3];
    glCreateVertexArrays(1, &ghost_.vao);
    const GLuint vao = ghost_.vao;
    glEnableVertexArrayAttrib(vao, 0);
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao, 0, 0);
    glEnableVertexArrayAttrib(vao, 1);
    glVertexArrayAttribFormat(vao, 1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 12);
    glVertexArrayAttribBinding(vao, 1, 0);
    glEnableVertexArrayAttrib(vao, 2);
    glVertexArrayAttribIFormat(vao, 2, 1, GL_UNSIGNED_INT, 0);
    glVertexArrayAttribBinding(vao, 2, 1);
  }
  // The ghosts' table: origins relative to the eye (in double precision until here).
  ghost_.entries.resize(ghosts.ghosts.size());
  for (size_t i = 0; i < ghosts.ghosts.size(); ++i) {
    const GhostMesh::Ghost& g = ghosts.ghosts[i];
    const glm::dvec3 offset = g.origin_m - view.eye_m;
    TableEntry& e = ghost_.entries[i];
    e.offset_m[0] = float(offset.x);
    e.offset_m[1] = float(offset.y);
    e.offset_m[2] = float(offset.z);
    e.colour = packed_colour(g.colour);
    e.scale[0] = e.scale[1] = e.scale[2] = 1.0f;
    e.pick = first_pick + uint32_t(i) + 1;  // tie-break 0
  }
  const auto bytes = [](const auto& v) { return v.size() * sizeof(v[0]); };
  upload_stream(ghost_.table, ghost_.table_capacity, bytes(ghost_.entries),
                {{ghost_.entries.data(), bytes(ghost_.entries)}});
  upload_stream(ghost_.vertices, ghost_.vertex_capacity, bytes(ghosts.vertices),
                {{ghosts.vertices.data(), bytes(ghosts.vertices)}});
  upload_stream(ghost_.objects, ghost_.object_capacity, bytes(ghosts.vertex_ghosts),
                {{ghosts.vertex_ghosts.data(), bytes(ghosts.vertex_ghosts)}});
  upload_stream(ghost_.indices, ghost_.index_capacity, bytes(ghosts.indices),
                {{ghosts.indices.data(), bytes(ghosts.indices)}});
  glVertexArrayVertexBuffer(ghost_.vao, 0, ghost_.vertices, 0, sizeof(PackedVertex));
  glVertexArrayVertexBuffer(ghost_.vao, 1, ghost_.objects, 0, sizeof(uint32_t));
  glVertexArrayElementBuffer(ghost_.vao, ghost_.indices);

  begin_pass(view, frame_plan_, with_ids);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, ghost_.table);
  const GLuint surface = drawing_program(ProgramId::surface);
  glUseProgram(surface);
  glProgramUniform1i(surface, at(surface, "u_mode"), 0);
  glProgramUniform1f(surface, at(surface, "u_rim"), 0.0f);
  glBindVertexArray(ghost_.vao);
  glEnablei(GL_BLEND, 0);
  glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glDepthMask(GL_FALSE);
  const GLsizei count = GLsizei(ghosts.indices.size());
  // In front of what was drawn: the ghost's own pick where ids are read back.
  glProgramUniform1f(surface, at(surface, "u_alpha"), kGhostFrontAlpha);
  glDrawElements(GL_TRIANGLES, count, GL_UNSIGNED_INT, nullptr);
  // Behind it: fainter, the colour alone (the pick stays what is in front).
  const GLenum colour_only[] = {GL_COLOR_ATTACHMENT0, GL_NONE};
  glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, colour_only);
  glDepthFunc(GL_LEQUAL);
  glProgramUniform1f(surface, at(surface, "u_alpha"), kGhostBehindAlpha);
  glDrawElements(GL_TRIANGLES, count, GL_UNSIGNED_INT, nullptr);
  // The state the frame's other passes expect (begin_pass and draw_lists set the rest).
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_TRUE);
  glDisablei(GL_BLEND, 0);
  glProgramUniform1f(surface, at(surface, "u_alpha"), 1.0f);
  const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0,
                                 GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(scene_.framebuffer, 2, draw_buffers);
  glBindVertexArray(0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, table_buffer_);
  set_clipping(false);
}

}  // namespace plantview::detail
