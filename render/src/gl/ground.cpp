// GL backend: the ground pass (rules in gl/backend.h; the shaders: gl/shaders/ground.*.glsl).
#include "gl/backend.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>

#include "frame_plan.h"
#include "gl/programs.h"

namespace plantview::detail {

// The ground: where nothing else was drawn (it lies below the whole model, so an eye above it
// sees it only there), and only from above. A section never clips it: it is a cue of where the
// plant stands, not part of the model, and a plan slab reads best over its floor grid.
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
  const GLuint p = gl_program(ProgramId::ground);  // it writes no clip distance (none enabled)
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

}  // namespace plantview::detail
