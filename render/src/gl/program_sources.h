// The GL backend's programs as sources: which shaders each program links and the text of each,
// put together from the .glsl files of render/src/gl/shaders (built into the program: editing
// one rebuilds) and a few generated lines. The one list that both the backend (programs.h:
// link) and the check by Khronos' reference compiler (tests/test_shaders.cpp) read, so that
// what is checked is what is drawn with. No GL here.
//
// Programs
//   - surface: every triangle of the objects, lit per fragment;
//   - cap plane: a square on a cutting plane, moving the depth of caps onto the cut
//     (gl/backend.h: sections);
//   - proxy: the faces the eye sees of each proxy box, lit as surfaces;
//   - centreline: pipes drawn as their centreline, expanded by a geometry shader into a
//     screen-aligned quad as wide as the pipe's projected diameter;
//   - ground: a square on the ground plane, its grid found per fragment;
//   - ambient occlusion: a full-screen triangle computing ambient occlusion per 2x2 output pixels;
//   - finishing: a full-screen triangle from the drawn frame to the output image;
//   - depth reduction (plain, multisampled, or with whole pixels per cell compiled in): a
//     full-screen triangle over a coarse grid of cells, for occlusion culling (occlusion.h);
//   - box test: occlusion's exact test of boxes against the depth drawn.
// Rules shared by every shader:
//   - Every shader starts with "#version 450 core" (OpenGL 4.5 core; the files hold no #version),
//     then its parts in order; several shaders of one stage in a program link together (a
//     function one declares, another defines: lighting.glsl, box_face.glsl).
//   - Frames: positions are relative to the eye in model axes ("camera-relative": z up), so that
//     plants kilometres from the origin keep float precision. Depth is reversed and infinite:
//     depth = near / distance along the view axis (0 at infinity).
//   - A part's text ends with a newline.
// Threads: any; the sources are made anew on each call.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace plantview::detail {

enum class ShaderStage : uint8_t { vertex, geometry, fragment };
// glslangValidator's name of a stage (-S): "vert", "geom", "frag".
std::string_view stage_name(ShaderStage stage);

// A piece of a shader's text: a .glsl file (name: the file's, under render/src/gl/shaders) or
// lines made here (name in parentheses, say "(version)").
struct ShaderPart {
  std::string_view name;
  std::string text;
};
// One shader object: its parts one after the other, compiled as one source.
struct ShaderSource {
  ShaderStage stage;
  std::vector<ShaderPart> parts;
};
struct ProgramSource {
  std::string_view name;  // in error messages: "the <name> shaders do not link"
  std::vector<ShaderSource> shaders;
};

// The programs the backend links at init, in that order.
enum class ProgramId : uint8_t {
  surface,
  cap_plane,
  proxy,
  centreline,
  ground,
  ambient_occlusion,
  finish,
  depth_reduction,
  depth_reduction_multisampled,
  box_test,
  // The section variants of surface, proxy and centreline (SECTIONS defined: clipped,
  // and surfaces capped), linked when a frame first has a section.
  surface_sections,
  proxy_sections,
  centreline_sections,
};
inline constexpr size_t kProgramCount = size_t(ProgramId::centreline_sections) + 1;
// The programs init() links: those before the section variants.
inline constexpr size_t kProgramsAtInit = size_t(ProgramId::surface_sections);
// The section variant of surface, proxy or centreline (the ground is never clipped).
ProgramId sections_variant(ProgramId id);

ProgramSource program_source(ProgramId id);

// Framebuffer pixels across and up per depth-reduction cell, and samples per pixel: all >= 1.
using ReductionStep = std::array<uint32_t, 3>;
// The depth reduction: of a multisampled depth or not; with `step` whole pixels per cell
// compiled in (loops of constant length: several times faster on llvmpipe) or read from
// uniforms (none).
ProgramSource depth_reduction_source(bool multisampled, std::optional<ReductionStep> step);

// Every .glsl file built into the program, by name: to check that each is used.
std::vector<std::string_view> shader_file_names();

}  // namespace plantview::detail
