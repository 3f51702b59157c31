// The GL backend's programs as sources (rules in program_sources.h).
#include "gl/program_sources.h"

#include <cassert>
#include <initializer_list>

#include "gl/shader_files.h"  // generated from gl/shaders/*.glsl (embed_shaders.cmake)
#include "gl/backend.h"

namespace plantview::detail {

namespace {

using namespace shader_files;

// The value of the GLSL constant written `key` then digits in `text` (base 10 or 16); 0 when
// absent. For the checks below, at compile time.
constexpr uint64_t glsl_constant(std::string_view text, std::string_view key, unsigned base) {
  const size_t at = text.find(key);
  if (at == std::string_view::npos) return 0;
  uint64_t value = 0;
  for (size_t i = at + key.size(); i < text.size(); ++i) {
    const char c = text[i];
    const int digit = c >= '0' && c <= '9'                ? c - '0'
                      : base == 16 && c >= 'a' && c <= 'f' ? c - 'a' + 10
                                                           : -1;
    if (digit < 0) break;
    value = value * base + uint64_t(digit);
  }
  return value;
}

// tie_constants.glsl and TableEntry::pick (gl/backend.h) agree.
constexpr std::string_view kTieText = kTieConstants.text;
static_assert(glsl_constant(kTieText, "const uint kPickMask = 0x", 16) == kPickLimit - 1,
              "tie_constants.glsl: kPickMask disagrees with kTieBits (gl/backend.h)");
static_assert(glsl_constant(kTieText, "const uint kTieShift = ", 10) == 32 - kTieBits,
              "tie_constants.glsl: kTieShift disagrees with kTieBits (gl/backend.h)");
static_assert(glsl_constant(kTieText, "const float kTieStep = 1.0 / ", 10) == kTieStepInverse,
              "tie_constants.glsl: kTieStep disagrees with kTieStepInverse (gl/backend.h)");

const ShaderPart kVersion{"(version)", "#version 450 core\n"};

ShaderPart part(const ShaderFile& file) { return {file.name, std::string(file.text)}; }

// A shader of `stage`: the version line, then `files` in order.
ShaderSource shader(ShaderStage stage, std::initializer_list<const ShaderFile*> files) {
  ShaderSource s{stage, {kVersion}};
  for (const ShaderFile* f : files) s.parts.push_back(part(*f));
  return s;
}

// `program` with SECTIONS defined in each shader that takes sections (after the version line).
ProgramSource with_sections(ProgramSource program) {
  program.name = program.name == std::string_view("surface")      ? "surface (sections)"
                 : program.name == std::string_view("proxy")      ? "proxy (sections)"
                                                                  : "centreline (sections)";
  for (ShaderSource& s : program.shaders)
    for (const ShaderPart& p : s.parts)
      if (p.name == kSectionClip.name || p.name == kSurfaceFrag.name) {
        s.parts.insert(s.parts.begin() + 1, ShaderPart{"(sections)", "#define SECTIONS 1\n"});
        break;
      }
  return program;
}

}  // namespace

std::string_view stage_name(ShaderStage stage) {
  switch (stage) {
    case ShaderStage::vertex: return "vert";
    case ShaderStage::geometry: return "geom";
    case ShaderStage::fragment: return "frag";
  }
  return "?";
}

ProgramSource program_source(ProgramId id) {
  using enum ShaderStage;
  switch (id) {
    case ProgramId::surface:
      return {"surface",
              {shader(vertex, {&kTieConstants, &kObjectTable, &kSectionClip, &kSurfaceVert}),
               shader(fragment, {&kSurfaceFrag}), shader(fragment, {&kLighting})}};
    case ProgramId::cap_plane:
      return {"cap plane", {shader(vertex, {&kCapPlaneVert}), shader(fragment, {&kCapPlaneFrag})}};
    case ProgramId::proxy:
      return {"proxy",
              {shader(vertex, {&kTieConstants, &kObjectTable, &kSectionClip, &kProxyVert}),
               shader(vertex, {&kBoxFace}), shader(fragment, {&kSurfaceFrag}),
               shader(fragment, {&kLighting})}};
    case ProgramId::centreline:
      return {"centreline",
              {shader(vertex, {&kTieConstants, &kObjectTable, &kCentrelineVert}),
               shader(geometry, {&kSectionClip, &kCentrelineGeom}),
               shader(fragment, {&kCentrelineFrag}),
               shader(fragment, {&kLighting})}};
    case ProgramId::ground:
      return {"ground", {shader(vertex, {&kTieConstants, &kGroundVert}),
                         shader(fragment, {&kGroundFrag})}};
    case ProgramId::ambient_occlusion:
      return {"ambient occlusion", {shader(vertex, {&kFullScreenVert}),
                                    shader(fragment, {&kAmbientOcclusionFrag})}};
    case ProgramId::finish:
      return {"finishing", {shader(vertex, {&kFullScreenVert}), shader(fragment, {&kFinishFrag})}};
    case ProgramId::depth_reduction: return depth_reduction_source(false, std::nullopt);
    case ProgramId::depth_reduction_multisampled:
      return depth_reduction_source(true, std::nullopt);
    case ProgramId::surface_sections: return with_sections(program_source(ProgramId::surface));
    case ProgramId::proxy_sections: return with_sections(program_source(ProgramId::proxy));
    case ProgramId::centreline_sections:
      return with_sections(program_source(ProgramId::centreline));
    case ProgramId::box_test:
      return {"box test", {shader(vertex, {&kBoxTestVert}), shader(vertex, {&kBoxFace}),
                           shader(fragment, {&kBoxTestFrag})}};
  }
  assert(false && "program_source: not a ProgramId");
  return {};
}

ProgramId sections_variant(ProgramId id) {
  switch (id) {
    case ProgramId::surface: return ProgramId::surface_sections;
    case ProgramId::proxy: return ProgramId::proxy_sections;
    case ProgramId::centreline: return ProgramId::centreline_sections;
    default: break;
  }
  assert(false && "sections_variant: not surface, proxy or centreline");
  return id;
}

ProgramSource depth_reduction_source(bool multisampled, std::optional<ReductionStep> step) {
  ShaderSource fragment{ShaderStage::fragment, {kVersion}};
  if (multisampled) fragment.parts.push_back({"(multisampled)", "#define MULTISAMPLED 1\n"});
  if (step) {
    assert((*step)[0] >= 1 && (*step)[1] >= 1 && (*step)[2] >= 1);
    fragment.parts.push_back({"(step)", "#define STEP_X " + std::to_string((*step)[0]) +
                                            "\n#define STEP_Y " + std::to_string((*step)[1]) +
                                            "\n#define SAMPLES " + std::to_string((*step)[2]) +
                                            "\n"});
  }
  fragment.parts.push_back(part(kDepthReduceFrag));
  return {multisampled && !step ? "multisampled depth reduction" : "depth reduction",
          {shader(ShaderStage::vertex, {&kFullScreenVert}), std::move(fragment)}};
}

std::vector<std::string_view> shader_file_names() {
  std::vector<std::string_view> names;
  for (const ShaderFile& f : kAll) names.push_back(f.name);
  return names;
}

}  // namespace plantview::detail
