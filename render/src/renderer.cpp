// Renderer: cull, choose, stream, draw and read back one frame (see render.h for the rules).
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <unordered_map>
#include <unordered_set>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "lod.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "hlod.h"
#include "residency.h"

namespace plantview {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

constexpr uint32_t kProxyVertices = 24;   // the unit cube of budget proxies, at arena offset 0
constexpr uint32_t kProxyKey = UINT32_MAX;
constexpr uint32_t kRunKeyBit = 0x80000000u;  // residency keys of merged runs: bit | run index
constexpr uint64_t kBytesPerVertex = sizeof(PackedVertex) + sizeof(uint32_t);
constexpr uint64_t kInitialArenaVertices = 1u << 16;  // the GPU buffers grow from here
constexpr size_t kKnownObjectsKept = 10000;  // decoded objects kept beyond the resident ones
constexpr size_t kMaxVisibleObjects = 60000;  // objects drawn one by one in a frame, at most
constexpr double kMaxNodeProxyPixels = 256;   // ... unless nodes this size would have to be boxes

// One entry of the per-frame object table (std430: two vec4), read by the vertex shader.
struct TableEntry {
  float offset_m[3];  // the object's origin relative to the eye
  uint32_t colour;    // RGBA8
  float scale[3];     // 1 for objects; the box size for proxies
  uint32_t pick;      // index into the frame's pick table + 1
};
static_assert(sizeof(TableEntry) == 32);

// A decoded object (or a merged pipeline run): what it takes to tessellate it and to write its
// indices at any level. Objects are kept while resident and a while after.
struct Known {
  uint64_t id = 0;
  ObjectClass object_class = ObjectClass::other;
  Colour colour;
  glm::dvec3 origin_m{0.0};
  uint64_t pipeline_id = 0;
  // The primitives, while needed: until the object is first resident, and always for facet
  // groups (whose plans point into them) and merged runs (which the store does not hold); other
  // objects are decoded again from the store when they must be tessellated again.
  std::vector<Primitive> primitives;
  std::vector<MeshPlan> own_plans;  // facet groups' plans (others share the renderer's)
  bool keeps_primitives = false;
  struct Part {
    const MeshPlan* plan;   // shared per template (errors zeroed: see error_m), or own_plans
    uint32_t first_vertex;  // within the object's vertices
    uint32_t primitive;     // index into primitives
    // While resident: the part's first vertex within what the arena holds of the object, and
    // the plan whose indices address those vertices (the template's own at base 0, else its
    // compaction, shared by every object of that template; null: `plan` itself).
    uint32_t resident_first = 0;
    const MeshPlan* resident_plan = nullptr;
  };
  std::vector<Part> parts;
  std::vector<CentrelineSegment> centreline;  // pipes: drawn as lines when thin on screen
  uint32_t vertex_count = 0;
  uint32_t centreline_first = 0;
  uint8_t level_count = 1;
  bool has_lines = false, has_triangles = false;
  std::array<float, kMaxLevels> error_m{};  // largest over the triangle parts
  float pipe_diameter_m = 0;
  int32_t run = -1;                 // the pipeline run it belongs to, if any
  uint32_t table = UINT32_MAX;      // object-table entry while resident
  // While resident: the finest level whose vertices are in the arena. At base 0 every vertex
  // is there and the templates' indices serve every level; above 0 only the vertices of levels
  // >= base are, compacted part by part (see Part::resident_plan).
  uint8_t base = 0;
  uint32_t resident_centreline_first = 0;
  uint64_t last_seen = 0;           // frame
};

// Template plans are shared by every primitive of the template and winding; their errors are
// zeroed (they differ with the placement's scale: Known::error_m holds the object's).
struct PlanKey {
  const uint32_t* finest;  // the template's level-0 indices: unique per template
  bool flip;
  bool operator==(const PlanKey&) const = default;
};
struct PlanKeyHash {
  size_t operator()(const PlanKey& k) const { return std::hash<const void*>()(k.finest) ^ size_t(k.flip); }
};

// A template's levels from `base` on, over only the vertices they use: what an object resident
// from a coarser base draws with. Depends on the template alone (its index spans, the base and
// the winding), so it is built once per renderer and shared by every object of that template.
struct Compaction {
  std::vector<uint32_t> kept;  // template vertex numbers, in the compacted order
  std::array<std::vector<uint32_t>, kMaxLevels> indices;  // levels >= base, into `kept`
  MeshPlan plan;  // the template's plan with these indices; vertex_count = kept.size()
};
struct CompactionKey {
  const uint32_t* finest;  // the template's level-0 indices: unique per template
  uint8_t base;
  bool flip;
  bool operator==(const CompactionKey&) const = default;
};
struct CompactionKeyHash {
  size_t operator()(const CompactionKey& k) const {
    return std::hash<const void*>()(k.finest) ^ (size_t(k.base) << 1) ^ (size_t(k.flip) << 5);
  }
};

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_normal;
layout(location = 2) in uint a_object;
layout(std430, binding = 0) readonly buffer Objects { vec4 objects[]; };
uniform mat4 u_view_projection;
// Per-object values are flat, and the view direction is rebuilt per fragment from its window
// position: fewer interpolated values make each triangle cheaper to set up and to bin.
out vec3 v_normal;
flat out vec4 v_colour;
flat out uint v_pick;
void main() {
  vec4 a = objects[2u * a_object];
  vec4 b = objects[2u * a_object + 1u];
  vec3 p = a_position * b.xyz + a.xyz;
  v_normal = a_normal.xyz;
  v_colour = unpackUnorm4x8(floatBitsToUint(a.w));
  v_pick = floatBitsToUint(b.w);
  gl_Position = u_view_projection * vec4(p, 1.0);
}
)";

const char* kFragmentShader = R"(#version 450 core
in vec3 v_normal;
flat in vec4 v_colour;
flat in uint v_pick;
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uint o_pick;
uniform vec3 u_sun;  // unit, towards the light, in the camera-relative frame
// The ray through a window position: u_ray * vec3(position * u_window_scale - 1, -1), in the
// camera-relative frame (not normalised).
uniform mat3 u_ray;
uniform vec2 u_window_scale;
void main() {
  vec3 base = v_colour.rgb;
  float n_length = length(v_normal);
  vec3 lit;
  if (n_length < 0.5) {
    lit = base * 0.8;  // lines have no normal
  } else {
    vec3 n = v_normal / n_length;
    vec3 to_eye = -normalize(u_ray * vec3(gl_FragCoord.xy * u_window_scale - 1.0, -1.0));
    if (dot(n, to_eye) < 0.0) n = -n;  // two-sided: open meshes and facet groups
    float head = max(dot(n, to_eye), 0.0);
    float sun = max(dot(n, u_sun), 0.0);
    lit = base * (0.22 + 0.48 * head + 0.38 * sun);
  }
  o_colour = vec4(min(lit, vec3(1.0)), v_colour.a);
  o_pick = v_pick;
}
)";

GLuint compile(GLenum type, const char* source, std::string& error) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    error = std::string("renderer: shader does not compile: ") + log;
    glDeleteShader(shader);
    return 0;
  }
  return shader;
}

}  // namespace

std::string_view lod_policy_name(LodPolicy policy) {
  switch (policy) {
    case LodPolicy::screen_space: return "screen-space";
    case LodPolicy::distance: return "distance";
    case LodPolicy::none: return "none";
  }
  return "?";
}

bool parse_lod_policy(std::string_view name, LodPolicy& policy) {
  if (name == "screen-space" || name == "screen_space" || name == "sse") policy = LodPolicy::screen_space;
  else if (name == "distance") policy = LodPolicy::distance;
  else if (name == "none") policy = LodPolicy::none;
  else return false;
  return true;
}

std::string FrameStats::to_json() const {
  std::string levels;
  for (size_t l = 0; l < triangles_by_level.size(); ++l)
    levels += (l ? "," : "") + std::to_string(triangles_by_level[l]);
  char times[400];
  std::snprintf(times, sizeof times,
                "{\"cull\":%.3f,\"choose\":%.3f,\"stream\":%.3f,\"draw\":%.3f,"
                "\"read_back\":%.3f,\"encode\":%.3f,\"total\":%.3f}",
                ms.cull, ms.choose, ms.stream, ms.draw, ms.read_back, ms.encode, ms.total);
  return "{\"objects_visible\":" + std::to_string(objects_visible) +
         ",\"objects_culled\":" + std::to_string(objects_culled) +
         ",\"triangles\":" + std::to_string(triangles) + ",\"lines\":" + std::to_string(lines) +
         ",\"triangles_by_level\":[" + levels + "]" +
         ",\"centreline_pipes\":" + std::to_string(centreline_pipes) +
         ",\"hlod_merges\":" + std::to_string(hlod_merges) +
         ",\"hlod_members\":" + std::to_string(hlod_members) +
         ",\"budget_proxies\":" + std::to_string(budget_proxies) +
         ",\"budget_coarsened\":" + std::to_string(budget_coarsened) +
         ",\"objects_refined\":" + std::to_string(objects_refined) +
         ",\"objects_subpixel\":" + std::to_string(objects_subpixel) +
         ",\"node_proxies\":" + std::to_string(node_proxies) +
         ",\"node_proxy_pixels\":" + std::to_string(node_proxy_pixels) +
         ",\"objects_in_node_proxies\":" + std::to_string(objects_in_node_proxies) +
         ",\"draw_commands\":" + std::to_string(draw_commands) +
         ",\"arena_bytes_budget\":" + std::to_string(arena_bytes_budget) +
         ",\"arena_bytes_resident\":" + std::to_string(arena_bytes_resident) +
         ",\"arena_bytes_uploaded\":" + std::to_string(arena_bytes_uploaded) +
         ",\"arena_bytes_evicted\":" + std::to_string(arena_bytes_evicted) +
         ",\"objects_resident\":" + std::to_string(objects_resident) +
         ",\"objects_tessellated\":" + std::to_string(objects_tessellated) +
         ",\"objects_evicted\":" + std::to_string(objects_evicted) + ",\"ms\":" + times + "}";
}

struct Renderer::State {
  const Store* store = nullptr;
  RenderOptions options;
  std::unique_ptr<ReadView> view;
  glm::dvec3 spatial_origin{0.0};
  DAabb bounds;
  uint64_t frame_number = 0;
  bool drop_primitives = false;  // see open_view

  // Residency (in vertices) and what is known of decoded objects and runs, by residency key.
  detail::Residency residency{0};
  std::unordered_map<uint32_t, Known> known;
  std::unordered_map<PlanKey, MeshPlan, PlanKeyHash> plans;  // few: per template and winding
  std::unordered_map<CompactionKey, Compaction, CompactionKeyHash> compactions;  // few: per template
  // Pipeline HLOD: runs found so far, the run of each member slot, pipelines analysed.
  std::deque<detail::PipelineRun> runs;  // (a deque: growing it copies nothing)
  std::vector<detail::PipelineRun> branch_runs;
  std::vector<uint64_t> run_decided_frame;
  std::vector<uint8_t> run_merged, run_drawn;
  // Pipelines analysed, with their runs: [first, first + count) of `runs` (a member finds its
  // run there: a pipeline has few runs, and a map by member would cost 40 bytes a member).
  std::unordered_map<uint64_t, std::pair<uint32_t, uint32_t>> pipeline_runs;

  // The object table: entries handed to resident objects, and to proxies for one frame.
  std::vector<TableEntry> table;
  std::vector<uint32_t> table_free;
  uint32_t table_used = 0;  // high-water mark

  // GL objects. The arena is two buffers indexed alike: vertices and their object-table index.
  GLuint program = 0, vao = 0, proxy_vao = 0, arena = 0, arena_objects = 0, index_buffer = 0,
         table_buffer = 0, proxy_buffer = 0, cube_indices = 0;
  uint64_t arena_vertices_gl = 0;  // size of the GPU buffers, in vertices (<= the budget)
  GLint u_view_projection = -1, u_sun = -1, u_ray = -1, u_window_scale = -1;
  // Drawing goes to `framebuffer` (multisampled when samples > 1), then is resolved into
  // `resolved` (single-sampled) for reading back.
  GLuint framebuffer = 0, colour_rb = 0, pick_rb = 0, depth_rb = 0;
  GLuint resolved = 0, resolved_colour = 0, resolved_pick = 0;
  uint32_t fb_width = 0, fb_height = 0, fb_samples = 0;
  size_t index_capacity = 0, table_capacity = 0, proxy_capacity = 0;

  // Per-frame scratch, reused so that frames allocate little once warm.
  struct Visible {
    uint32_t slot;
    float min[3], max[3];  // relative to the spatial origin
    double distance_m;
    double px_per_m;
  };
  struct Draw {
    uint32_t key;
    Known* known;  // node of `known`: stable while the frame runs
    uint8_t level;
    bool centreline;
    const Visible* visible;
    double distance_m = 0;    // from the eye to the nearest point of its bounds
    bool drawn = false;       // resident this frame (else a proxy box or nothing)
    uint32_t arena_first = 0;  // the object's first vertex in the arena, once drawn
  };
  // The frame's index lists, in this order in the index buffer: closed opaque solids (back
  // faces culled), open opaque meshes, see-through triangles, lines.
  enum List : uint8_t { kClosed, kOpen, kTransparent, kLines, kListCount };
  static List list_of(const Known& k, const Known::Part& part) {
    if (part.plan->topology == Topology::lines) return kLines;
    if (k.colour.a < 255) return kTransparent;
    return part.plan->closed ? kClosed : kOpen;
  }
  std::array<size_t, kListCount> list_counts{};
  std::vector<uint32_t> draw_order;
  std::vector<Visible> visible;
  std::vector<Draw> draws;
  std::vector<uint32_t> stack, count_stack;
  std::vector<std::array<float, 6>> node_proxies;  // min, max relative to the spatial origin
  std::vector<PackedVertex> vertices, compacted;
  std::vector<uint32_t> vertex_objects, remap;
  std::vector<uint32_t> proxy_tables;
  std::vector<uint64_t> pick_ids;
  std::vector<std::pair<uint32_t, uint64_t>> evicted;
  std::vector<uint32_t> pick_pixels;
  Object object;  // decode target

  ~State() {
    if (program) glDeleteProgram(program);
    GLuint buffers[] = {arena, arena_objects, index_buffer, table_buffer, proxy_buffer, cube_indices};
    glDeleteBuffers(6, buffers);
    GLuint vaos[] = {vao, proxy_vao};
    glDeleteVertexArrays(2, vaos);
    release_framebuffer();
  }

  void release_framebuffer() {
    GLuint fbs[] = {framebuffer, resolved};
    glDeleteFramebuffers(2, fbs);
    GLuint rbs[] = {colour_rb, pick_rb, depth_rb, resolved_colour, resolved_pick};
    glDeleteRenderbuffers(5, rbs);
    framebuffer = colour_rb = pick_rb = depth_rb = resolved = resolved_colour = resolved_pick = 0;
    fb_width = fb_height = fb_samples = 0;
  }

  uint32_t table_acquire() {
    if (!table_free.empty()) {
      const uint32_t t = table_free.back();
      table_free.pop_back();
      return t;
    }
    if (table_used == table.size()) table.resize(std::max<size_t>(1024, table.size() * 2));
    return table_used++;
  }

  bool init_gl(std::string& error);
  bool grow_arena(uint64_t vertices_needed, std::string& error);
  void bind_arena();
  bool ensure_framebuffer(uint32_t w, uint32_t h, std::string& error);
  bool open_view(std::string& error);
  void fill_known(Known& k, Object& o, bool keeps_primitives);
  Known* know(uint32_t slot, std::string& error);
  void analyse_pipeline(uint64_t pipeline_id, std::string& error);
  Known* know_run(uint32_t run);
  const Compaction& compaction(const MeshPlan& plan, uint8_t base);
  // Vertices an object takes in the arena when resident from level `base` on.
  uint64_t resident_vertices(const Known& k, uint8_t base) {
    base = uint8_t(std::min<uint32_t>(base, k.level_count - 1u));
    if (base == 0) return k.vertex_count;
    uint64_t n = 2 * k.centreline.size();
    for (const Known::Part& part : k.parts) {
      const uint8_t part_base = uint8_t(part.plan->clamp_level(base));
      n += part_base == 0 ? part.plan->vertex_count : compaction(*part.plan, part_base).kept.size();
    }
    return n;
  }
  bool make_resident(uint32_t key, Known& k, uint8_t base, FrameStats& stats, std::string& error,
                     bool& fits);
  void release(uint32_t key, Known& k) {
    residency.drop(key);
    if (k.table != UINT32_MAX) table_free.push_back(k.table);
    k.table = UINT32_MAX;
  }
  void forget_old(FrameStats& stats);
  bool frame(const Camera& camera, uint32_t w, uint32_t h, bool draw, bool with_ids, Image* out,
             FrameStats& stats, std::string& error);
};

bool Renderer::State::init_gl(std::string& error) {
  if (eglGetCurrentContext() == EGL_NO_CONTEXT) {
    error = "renderer: no current OpenGL context (create a GpuContext first)";
    return false;
  }
  if (epoxy_gl_version() < 45) {
    error = "renderer: OpenGL 4.5 is required, the context has " +
            std::to_string(epoxy_gl_version() / 10) + "." + std::to_string(epoxy_gl_version() % 10);
    return false;
  }
  const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader, error);
  if (!vs) return false;
  const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader, error);
  if (!fs) {
    glDeleteShader(vs);
    return false;
  }
  program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(program, sizeof log, nullptr, log);
    error = std::string("renderer: shaders do not link: ") + log;
    return false;
  }
  u_view_projection = glGetUniformLocation(program, "u_view_projection");
  u_sun = glGetUniformLocation(program, "u_sun");
  u_ray = glGetUniformLocation(program, "u_ray");
  u_window_scale = glGetUniformLocation(program, "u_window_scale");

  glCreateBuffers(1, &index_buffer);
  glCreateBuffers(1, &table_buffer);
  glCreateBuffers(1, &proxy_buffer);
  glCreateBuffers(1, &cube_indices);
  static constexpr uint32_t kCube[36] = {0,  2,  1,  0,  3,  2,  4,  5,  6,  4,  6,  7,
                                         8,  10, 9,  8,  11, 10, 12, 13, 14, 12, 14, 15,
                                         16, 18, 17, 16, 19, 18, 20, 21, 22, 20, 22, 23};
  glNamedBufferStorage(cube_indices, sizeof kCube, kCube, 0);

  // Both vertex arrays read position and normal from the arena (binding 0) and the object-table
  // index from binding 1: per vertex for objects (the arena's second buffer), per instance for
  // proxies (the cube's vertices are shared).
  const auto make_vertex_array = [](GLuint& array) {
    glCreateVertexArrays(1, &array);
    glEnableVertexArrayAttrib(array, 0);
    glVertexArrayAttribFormat(array, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(array, 0, 0);
    glEnableVertexArrayAttrib(array, 1);
    glVertexArrayAttribFormat(array, 1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 12);
    glVertexArrayAttribBinding(array, 1, 0);
    glEnableVertexArrayAttrib(array, 2);
    glVertexArrayAttribIFormat(array, 2, 1, GL_UNSIGNED_INT, 0);
    glVertexArrayAttribBinding(array, 2, 1);
  };
  make_vertex_array(vao);
  glVertexArrayElementBuffer(vao, index_buffer);
  make_vertex_array(proxy_vao);
  glVertexArrayBindingDivisor(proxy_vao, 1, 1);
  glVertexArrayVertexBuffer(proxy_vao, 1, proxy_buffer, 0, sizeof(uint32_t));
  glVertexArrayElementBuffer(proxy_vao, cube_indices);
  return grow_arena(std::min<uint64_t>(kInitialArenaVertices, options.vertex_budget_bytes / kBytesPerVertex),
                    error);
}

void Renderer::State::bind_arena() {
  glVertexArrayVertexBuffer(vao, 0, arena, 0, sizeof(PackedVertex));
  glVertexArrayVertexBuffer(vao, 1, arena_objects, 0, sizeof(uint32_t));
  glVertexArrayVertexBuffer(proxy_vao, 0, arena, 0, sizeof(PackedVertex));
}

// The GPU buffers hold at least `vertices_needed` (never more than the budget), keeping what
// they held. They at least double, so that a slowly filling arena is not copied often (a new
// buffer is zeroed by the driver and page-faulted in, and the old one copied: about 1 ms a MB
// on llvmpipe).
bool Renderer::State::grow_arena(uint64_t vertices_needed, std::string& error) {
  const uint64_t budget = options.vertex_budget_bytes / kBytesPerVertex;
  vertices_needed = std::min(vertices_needed, budget);  // (a full arena evicts instead)
  if (vertices_needed <= arena_vertices_gl) return true;
  const uint64_t size = std::min(budget, std::max(vertices_needed, arena_vertices_gl * 2));
  GLuint buffers[2];
  glCreateBuffers(2, buffers);
  glNamedBufferStorage(buffers[0], GLsizeiptr(size * sizeof(PackedVertex)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  glNamedBufferStorage(buffers[1], GLsizeiptr(size * sizeof(uint32_t)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  if (glGetError() != GL_NO_ERROR) {
    glDeleteBuffers(2, buffers);
    error = "renderer: cannot allocate " + std::to_string((size * kBytesPerVertex) >> 20) +
            " MB of the vertex arena";
    return false;
  }
  if (arena_vertices_gl) {
    glCopyNamedBufferSubData(arena, buffers[0], 0, 0, GLsizeiptr(arena_vertices_gl * sizeof(PackedVertex)));
    glCopyNamedBufferSubData(arena_objects, buffers[1], 0, 0, GLsizeiptr(arena_vertices_gl * sizeof(uint32_t)));
    GLuint old[2] = {arena, arena_objects};
    glDeleteBuffers(2, old);
  }
  arena = buffers[0];
  arena_objects = buffers[1];
  arena_vertices_gl = size;
  bind_arena();
  return true;
}

bool Renderer::State::ensure_framebuffer(uint32_t w, uint32_t h, std::string& error) {
  GLint max_samples = 1;
  glGetIntegerv(GL_MAX_INTEGER_SAMPLES, &max_samples);
  GLint max_colour_samples = 1;
  glGetIntegerv(GL_MAX_SAMPLES, &max_colour_samples);
  uint32_t wanted = options.samples;
  if (wanted == 0) {
    const auto* renderer_name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    const std::string name = renderer_name ? renderer_name : "";
    const bool software = name.find("llvmpipe") != std::string::npos ||
                          name.find("softpipe") != std::string::npos ||
                          name.find("SwiftShader") != std::string::npos;
    wanted = software ? 1 : 4;
  }
  const uint32_t samples = std::clamp<uint32_t>(wanted, 1, uint32_t(std::min(max_samples, max_colour_samples)));
  if (framebuffer && fb_width == w && fb_height == h && fb_samples == samples) return true;
  release_framebuffer();
  const auto make = [&](GLuint& fb, GLuint& colour, GLuint& pick, GLuint* depth, uint32_t n) {
    glCreateFramebuffers(1, &fb);
    glCreateRenderbuffers(1, &colour);
    glCreateRenderbuffers(1, &pick);
    glNamedRenderbufferStorageMultisample(colour, GLsizei(n > 1 ? n : 0), GL_RGBA8, GLsizei(w), GLsizei(h));
    glNamedRenderbufferStorageMultisample(pick, GLsizei(n > 1 ? n : 0), GL_R32UI, GLsizei(w), GLsizei(h));
    glNamedFramebufferRenderbuffer(fb, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour);
    glNamedFramebufferRenderbuffer(fb, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER, pick);
    if (depth) {
      glCreateRenderbuffers(1, depth);
      glNamedRenderbufferStorageMultisample(*depth, GLsizei(n > 1 ? n : 0), GL_DEPTH_COMPONENT32F, GLsizei(w), GLsizei(h));
      glNamedFramebufferRenderbuffer(fb, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, *depth);
    }
    const GLenum buffers[] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(fb, 2, buffers);
    return glCheckNamedFramebufferStatus(fb, GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
  };
  bool ok = make(framebuffer, colour_rb, pick_rb, &depth_rb, samples);
  if (ok && samples > 1) ok = make(resolved, resolved_colour, resolved_pick, nullptr, 1);
  if (!ok) {
    error = "renderer: cannot make a " + std::to_string(w) + "x" + std::to_string(h) +
            " framebuffer with " + std::to_string(samples) + " samples";
    release_framebuffer();
    return false;
  }
  fb_width = w;
  fb_height = h;
  fb_samples = samples;
  return true;
}

bool Renderer::State::open_view(std::string& error) {
  view = store->read(error);
  if (!view) return false;
  spatial_origin = view->spatial_origin();
  const ModelStatistics statistics = view->info().statistics;
  bounds = statistics.bounds;
  // A model larger than the budget at full resolution (one that will fill it) gets the whole
  // arena now: growing it later copies it, and the old and new buffers together would exceed
  // the budget for a moment. Smaller ones grow as they need (a new buffer costs zeroing it).
  const uint64_t budget_vertices = options.vertex_budget_bytes / kBytesPerVertex;
  if (statistics.triangles > budget_vertices && !grow_arena(budget_vertices, error)) return false;
  // Such a model also drops the primitives of what is resident (decoding them again when they
  // must be tessellated again); a smaller one keeps them, for speed.
  drop_primitives = statistics.triangles > budget_vertices;
  // Forget everything: the snapshot may differ. The proxy cube stays at offset 0.
  known.clear();
  runs.clear();
  run_decided_frame.clear();
  run_merged.clear();
  run_drawn.clear();
  pipeline_runs.clear();
  table_free.clear();
  table_used = 0;
  residency = detail::Residency(options.vertex_budget_bytes / kBytesPerVertex);
  std::vector<std::pair<uint32_t, uint64_t>> none;
  residency.begin_frame();
  if (residency.admit(kProxyKey, kProxyVertices, none) != 0u) {
    error = "renderer: the vertex budget is too small";
    return false;
  }
  PackedVertex cube[kProxyVertices];
  const glm::vec3 normals[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
  for (int f = 0; f < 6; ++f) {
    const int axis = f / 2;
    const float side = float(f % 2);
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const float corners[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int c = 0; c < 4; ++c) {
      glm::vec3 p;
      p[axis] = side;
      p[u] = corners[c][0];
      p[v] = corners[c][1];
      cube[f * 4 + c] = {p, pack_normal(normals[f])};
    }
  }
  glNamedBufferSubData(arena, 0, sizeof cube, cube);
  return true;
}

// Fills a Known from an object (primitives moved out of it).
void Renderer::State::fill_known(Known& k, Object& o, bool keeps_primitives) {
  k.id = o.id;
  k.object_class = o.object_class;
  k.colour = o.colour;
  k.origin_m = o.origin_m;
  k.pipeline_id = o.pipeline_id;
  k.primitives = std::move(o.primitives);
  o.primitives.clear();
  k.keeps_primitives = keeps_primitives;
  k.parts.clear();
  k.parts.reserve(k.primitives.size());
  k.own_plans.clear();
  size_t facet_groups = 0;
  for (const Primitive& p : k.primitives) facet_groups += std::holds_alternative<FacetGroup>(p.shape);
  k.own_plans.reserve(facet_groups);  // never reallocated: parts point into it
  k.keeps_primitives |= facet_groups > 0;
  uint32_t vertex_count = 0;
  for (uint32_t i = 0; i < k.primitives.size(); ++i) {
    MeshPlan plan = plan_mesh(k.primitives[i]);
    if (plan.vertex_count == 0) continue;
    vertex_count += plan.vertex_count;
    if (plan.topology == Topology::lines) {
      k.has_lines = true;
    } else {
      k.has_triangles = true;
      k.level_count = std::max(k.level_count, plan.level_count);
      for (uint32_t l = 0; l < kMaxLevels; ++l)
        k.error_m[l] = std::max(k.error_m[l], plan.error_m[plan.clamp_level(l)]);
    }
    const MeshPlan* shared;
    if (std::holds_alternative<FacetGroup>(k.primitives[i].shape)) {
      shared = &k.own_plans.emplace_back(plan);
    } else {
      plan.error_m = {};
      const auto [it, added] = plans.try_emplace(PlanKey{plan.indices[0].data(), plan.flip_winding}, plan);
      assert(it->second.vertex_count == plan.vertex_count && it->second.closed == plan.closed &&
             it->second.topology == plan.topology && it->second.level_count == plan.level_count);
      shared = &it->second;
    }
    k.parts.push_back({shared, vertex_count - plan.vertex_count, i});
  }
  if (o.object_class == ObjectClass::pipe && !o.centreline.empty()) {
    k.centreline = o.centreline;
    k.centreline_first = vertex_count;
    vertex_count += uint32_t(2 * o.centreline.size());
    for (const auto& s : o.centreline) k.pipe_diameter_m = std::max(k.pipe_diameter_m, s.diameter_m);
  }
  k.vertex_count = vertex_count;
}

Known* Renderer::State::know(uint32_t slot, std::string& error) {
  if (const auto it = known.find(slot); it != known.end()) return &it->second;
  if (!view->object(slot, object, false, error)) return nullptr;
  Known& k = known[slot];
  fill_known(k, object, false);
  if (options.hlod && k.pipeline_id != 0 &&
      (k.object_class == ObjectClass::pipe || k.object_class == ObjectClass::component)) {
    auto it = pipeline_runs.find(k.pipeline_id);
    if (it == pipeline_runs.end()) {
      std::string ignored;  // a pipeline that cannot be read is simply not merged
      analyse_pipeline(k.pipeline_id, ignored);
      it = pipeline_runs.find(k.pipeline_id);
    }
    const auto [first, count] = it->second;
    for (uint32_t r = first; r < first + count && k.run < 0; ++r) {
      const auto& members = runs[r].members;
      if (std::find(members.begin(), members.end(), slot) != members.end()) k.run = int32_t(r);
    }
  }
  return &k;
}

void Renderer::State::analyse_pipeline(uint64_t pipeline_id, std::string& error) {
  // Analysed from now on, with no runs unless some are found below (a pipeline that cannot be
  // read keeps none).
  auto& [pipeline_first, pipeline_count] = pipeline_runs[pipeline_id];
  pipeline_first = uint32_t(runs.size());
  pipeline_count = 0;
  const auto slot = view->slot_of(pipeline_id);
  Object pipeline;
  if (!slot || !view->object(*slot, pipeline, false, error)) return;
  std::vector<Object> members;
  std::vector<std::pair<uint32_t, const Object*>> branch;
  for (const Branch& b : pipeline.branches) {
    members.clear();
    members.reserve(b.members.size());
    std::vector<uint32_t> slots;
    for (const uint64_t id : b.members) {
      const auto s = view->slot_of(id);
      if (!s) continue;
      members.emplace_back();
      if (!view->object(*s, members.back(), false, error)) {
        members.pop_back();
        continue;
      }
      slots.push_back(*s);
    }
    branch.clear();
    for (size_t i = 0; i < members.size(); ++i) branch.emplace_back(slots[i], &members[i]);
    const size_t first = runs.size();
    branch_runs.clear();
    detail::find_runs(branch, branch_runs);
    for (auto& run : branch_runs) runs.push_back(std::move(run));
    for (size_t r = first; r < runs.size(); ++r) {
      for (const uint32_t m : runs[r].members) {
        if (const auto it = known.find(m); it != known.end()) it->second.run = int32_t(r);
      }
    }
  }
  pipeline_count = uint32_t(runs.size()) - pipeline_first;
  run_decided_frame.resize(runs.size(), 0);
  run_merged.resize(runs.size(), 0);
  run_drawn.resize(runs.size(), 0);
}

Known* Renderer::State::know_run(uint32_t run) {
  const uint32_t key = kRunKeyBit | run;
  if (const auto it = known.find(key); it != known.end()) return &it->second;
  const detail::PipelineRun& r = runs[run];
  Object o;
  o.id = 0;
  if (!r.members.empty()) {
    if (const auto it = known.find(r.members.front()); it != known.end()) o.id = it->second.pipeline_id;
  }
  o.object_class = ObjectClass::pipe;
  o.colour = r.colour;
  o.origin_m = r.start_m;
  o.primitives.push_back(detail::merged_cylinder(r, r.start_m));
  o.centreline.push_back({glm::vec3(0.0f), glm::vec3(r.end_m - r.start_m), r.diameter_m});
  Known& k = known[key];
  fill_known(k, o, true);
  return &k;
}

const Compaction& Renderer::State::compaction(const MeshPlan& plan, uint8_t base) {
  const CompactionKey key{plan.indices[0].data(), base, plan.flip_winding};
  if (const auto it = compactions.find(key); it != compactions.end()) return it->second;
  Compaction& c = compactions[key];
  c.plan = plan;
  remap.assign(plan.vertex_count, UINT32_MAX);
  for (uint32_t l = base; l < plan.level_count; ++l) {
    for (const uint32_t v : plan.indices[l]) {
      if (remap[v] == UINT32_MAX) {
        remap[v] = uint32_t(c.kept.size());
        c.kept.push_back(v);
      }
      c.indices[l].push_back(remap[v]);
    }
  }
  for (uint32_t l = 0; l < kMaxLevels; ++l)
    c.plan.indices[l] = c.indices[std::max<uint32_t>(l, base)];  // finer levels are never asked
  c.plan.vertex_count = uint32_t(c.kept.size());
  return c;
}

// Tessellates a known object into the arena from level `base` on (see Known), evicting if
// needed. fits = false when it cannot be placed without evicting what this frame shows.
bool Renderer::State::make_resident(uint32_t key, Known& k, uint8_t base, FrameStats& stats,
                                    std::string& error, bool& fits) {
  base = uint8_t(std::min<uint32_t>(base, k.level_count - 1u));
  const std::vector<Primitive>* primitives = &k.primitives;
  if (k.primitives.empty() && !k.parts.empty()) {  // dropped after an earlier upload
    if (!view->object(key, object, false, error)) return false;
    primitives = &object.primitives;
  }
  vertices.resize(k.vertex_count);
  for (const auto& part : k.parts) {
    write_vertices((*primitives)[part.primitive], *part.plan, glm::dvec3(0.0),
                   std::span<PackedVertex>(vertices.data() + part.first_vertex, part.plan->vertex_count));
  }
  for (size_t s = 0; s < k.centreline.size(); ++s) {
    vertices[k.centreline_first + 2 * s] = {k.centreline[s].start_m, 0u};
    vertices[k.centreline_first + 2 * s + 1] = {k.centreline[s].end_m, 0u};
  }
  const std::vector<PackedVertex>* upload = &vertices;
  k.resident_centreline_first = k.centreline_first;
  for (Known::Part& part : k.parts) {
    part.resident_first = part.first_vertex;
    part.resident_plan = nullptr;
  }
  if (base > 0) {
    // Keep only the vertices that levels >= base use (coarser levels use a subset of them).
    compacted.clear();
    for (Known::Part& part : k.parts) {
      const uint8_t part_base = uint8_t(part.plan->clamp_level(base));
      part.resident_first = uint32_t(compacted.size());
      if (part_base == 0) {  // a one-level part (facet groups among them): all of it
        compacted.insert(compacted.end(), vertices.begin() + part.first_vertex,
                         vertices.begin() + part.first_vertex + part.plan->vertex_count);
        continue;
      }
      const Compaction& c = compaction(*part.plan, part_base);
      part.resident_plan = &c.plan;
      for (const uint32_t v : c.kept) compacted.push_back(vertices[part.first_vertex + v]);
    }
    k.resident_centreline_first = uint32_t(compacted.size());
    compacted.insert(compacted.end(), vertices.begin() + k.centreline_first,
                     vertices.begin() + k.centreline_first + 2 * k.centreline.size());
    upload = &compacted;
  }
  const uint32_t count = uint32_t(upload->size());

  evicted.clear();
  const auto offset = residency.admit(key, count, evicted);
  for (const auto& [victim, units] : evicted) {
    if (const auto it = known.find(victim); it != known.end() && it->second.table != UINT32_MAX) {
      table_free.push_back(it->second.table);
      it->second.table = UINT32_MAX;
    }
    stats.objects_evicted += 1;
    stats.arena_bytes_evicted += units * kBytesPerVertex;
  }
  fits = offset.has_value();
  if (!fits) return true;
  if (!grow_arena(*offset + count, error)) return false;
  k.base = base;
  k.table = table_acquire();
  vertex_objects.assign(count, k.table);
  glNamedBufferSubData(arena, GLintptr(*offset * sizeof(PackedVertex)),
                       GLsizeiptr(count * sizeof(PackedVertex)), upload->data());
  glNamedBufferSubData(arena_objects, GLintptr(*offset * sizeof(uint32_t)),
                       GLsizeiptr(count * sizeof(uint32_t)), vertex_objects.data());
  stats.objects_tessellated += 1;
  stats.arena_bytes_uploaded += uint64_t(count) * kBytesPerVertex;
  if (!k.keeps_primitives && drop_primitives) {
    k.primitives.clear();
    k.primitives.shrink_to_fit();
  }
  return true;
}

// Keeps the decoded-object cache bounded: objects neither resident nor seen lately go.
void Renderer::State::forget_old(FrameStats&) {
  if (known.size() <= kKnownObjectsKept + residency.resident_count()) return;
  // Objects not resident go, the longest unseen first; those seen this frame (drawn as boxes
  // because the arena was full) only if that is not enough.
  for (int pass = 0; pass < 2 && known.size() > kKnownObjectsKept + residency.resident_count(); ++pass) {
    for (auto it = known.begin(); it != known.end();) {
      const bool old = pass == 1 || it->second.last_seen < frame_number;
      if (old && !residency.resident(it->first)) it = known.erase(it);
      else ++it;
    }
  }
}

bool Renderer::State::frame(const Camera& camera, uint32_t w, uint32_t h, bool draw,
                            bool with_ids, Image* out, FrameStats& stats, std::string& error) {
  const auto t_start = Clock::now();
  stats = FrameStats{};
  stats.arena_bytes_budget = options.vertex_budget_bytes;
  if (w == 0 || h == 0 || w > kMaxImageSide || h > kMaxImageSide) {
    error = "renderer: image size " + std::to_string(w) + "x" + std::to_string(h) +
            " is outside 1.." + std::to_string(kMaxImageSide);
    return false;
  }
  if (!view && !open_view(error)) return false;
  ++frame_number;

  // Camera-relative matrices: the eye is the origin of everything drawn.
  const glm::dvec3 forward = glm::normalize(camera.target_m - camera.eye_m);
  // An up along the view (looking straight down, say) falls back to +y, then +x.
  glm::dvec3 up = camera.up;
  if (glm::length(glm::cross(forward, up)) < 1e-9 * glm::length(up)) up = glm::dvec3(0, 1, 0);
  if (glm::length(glm::cross(forward, up)) < 1e-9) up = glm::dvec3(1, 0, 0);
  const glm::mat4 view_rotation = glm::mat4(glm::lookAt(glm::dvec3(0.0), forward, up));
  const float focal = float(1.0 / std::tan(glm::radians(camera.fov_deg) / 2.0));
  const float aspect = float(w) / float(h);
  glm::mat4 projection(0.0f);  // infinite far plane, reversed depth: near -> 1, infinity -> 0
  projection[0][0] = focal / aspect;
  projection[1][1] = focal;
  projection[2][3] = -1.0f;
  projection[3][2] = float(detail::kNearPlaneM);
  const glm::mat4 view_projection = projection * view_rotation;

  // 1. Cull: planes (x, y, z, w) with inside where dot(p, xyz) + w >= 0; no far plane.
  const auto t_cull = Clock::now();
  const glm::mat4 m = glm::transpose(view_projection);  // rows as columns
  const glm::vec4 planes[5] = {m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] - m[2]};
  const glm::vec3 shift = glm::vec3(spatial_origin - camera.eye_m);  // spatial -> eye frame
  const auto nodes = view->spatial_nodes();
  const auto entries = view->spatial_entries();
  const auto outside = [&](const float* mn, const float* mx) {
    for (const glm::vec4& pl : planes) {
      const glm::vec3 p(pl.x > 0 ? mx[0] : mn[0], pl.y > 0 ? mx[1] : mn[1],
                        pl.z > 0 ? mx[2] : mn[2]);
      if (pl.x * (p.x + shift.x) + pl.y * (p.y + shift.y) + pl.z * (p.z + shift.z) + pl.w < 0)
        return true;
    }
    return false;
  };
  const double focal_px = h * 0.5 * focal;
  const auto nearest_distance = [&](const float* mn, const float* mx) {
    glm::dvec3 nearest;
    for (int a = 0; a < 3; ++a)
      nearest[a] = std::clamp(0.0, double(mn[a]) + shift[a], double(mx[a]) + shift[a]);
    return glm::length(nearest);
  };
  const bool subpixel_culling = options.subpixel_culling && options.lod_policy == LodPolicy::screen_space;
  // Returns false, unfinished, once more than kMaxVisibleObjects are found and boxing whole nodes
  // can still make them fewer.
  const auto cull = [&](double node_proxy_px) {
  const bool bounded = subpixel_culling && node_proxy_px < kMaxNodeProxyPixels;
  stats.objects_subpixel = stats.objects_in_node_proxies = 0;
  visible.clear();
  node_proxies.clear();
  stack.clear();
  if (!nodes.empty()) stack.push_back(0);
  while (!stack.empty()) {
    const SpatialNode& node = nodes[stack.back()];
    stack.pop_back();
    if (outside(node.min, node.max)) continue;
    // Tree-level HLOD: a whole node that spans only a few pixels is drawn as one box instead of
    // its objects (which are then not even decoded), so that the cost of a far view of a huge
    // plant is bounded by the image, not by the plant.
    if (subpixel_culling && (node.count == 0 || node.count > 1)) {
      const double extent_m = std::max({node.max[0] - node.min[0], node.max[1] - node.min[1], node.max[2] - node.min[2]});
      const double px = extent_m * focal_px / std::max(nearest_distance(node.min, node.max), detail::kNearPlaneM);
      if (px < node_proxy_px) {
        node_proxies.push_back({node.min[0], node.min[1], node.min[2], node.max[0], node.max[1], node.max[2]});
        // Count the objects it stands for.
        count_stack.assign(1, uint32_t(&node - nodes.data()));
        while (!count_stack.empty()) {
          const SpatialNode& n = nodes[count_stack.back()];
          count_stack.pop_back();
          if (n.count) stats.objects_in_node_proxies += n.count;
          else count_stack.insert(count_stack.end(), {n.first, n.first + 1});
        }
        continue;
      }
    }
    if (node.count == 0) {
      stack.push_back(node.first);
      stack.push_back(node.first + 1);
      continue;
    }
    for (uint32_t e = node.first; e < node.first + node.count; ++e) {
      Visible v{entries[e].slot, {}, {}, 0.0, 0.0};
      entry_bounds(node, entries[e], v.min, v.max);
      if (outside(v.min, v.max)) continue;
      v.distance_m = nearest_distance(v.min, v.max);
      v.px_per_m = focal_px / std::max(v.distance_m, detail::kNearPlaneM);
      // Screen-space policy: an object whose whole extent is under the pixel error is left out
      // (it is not even decoded); that is what keeps far views of huge plants cheap.
      if (subpixel_culling && v.px_per_m * std::max({v.max[0] - v.min[0], v.max[1] - v.min[1],
                                                   v.max[2] - v.min[2]}) < options.pixel_error) {
        stats.objects_subpixel += 1;
        continue;
      }
      visible.push_back(v);
    }
    if (bounded && visible.size() > kMaxVisibleObjects) return false;
  }
  return true;
  };
  // The frame's work is bounded: when more objects than kMaxVisibleObjects are in view, nodes
  // are boxed at ever larger sizes until they fit (huge plants seen whole).
  double node_proxy_px = detail::kNodeProxyPixels * options.pixel_error;
  while (!cull(node_proxy_px)) node_proxy_px *= 2;
  stats.node_proxy_pixels = subpixel_culling ? node_proxy_px : 0;
  stats.objects_visible = visible.size();
  stats.objects_culled = entries.size() - visible.size() - stats.objects_subpixel - stats.objects_in_node_proxies;
  stats.node_proxies = node_proxies.size();
  // Largest on screen first, so that the budget goes where it shows most.
  const auto extent = [](const Visible& v) {
    return std::max({v.max[0] - v.min[0], v.max[1] - v.min[1], v.max[2] - v.min[2]});
  };
  std::sort(visible.begin(), visible.end(), [&](const Visible& a, const Visible& b) {
    return a.px_per_m * extent(a) > b.px_per_m * extent(b);
  });
  stats.ms.cull = ms_since(t_cull);

  // 2. Choose a level (decoding objects seen for the first time), and merge pipeline runs.
  const auto t_choose = Clock::now();
  double decode_ms = 0;
  residency.begin_frame();
  residency.mark_visible(kProxyKey);
  draws.clear();
  const auto choose = [&](const Known& k, double distance_m, double px_per_m, double size_m,
                          uint8_t& level, bool& centreline) {
    level = 0;
    centreline = false;
    const bool thin_pipe = options.centrelines && !k.centreline.empty();
    switch (options.lod_policy) {
      case LodPolicy::none: break;
      case LodPolicy::screen_space:
        level = uint8_t(detail::choose_level_screen_space(k.error_m.data(), k.level_count, px_per_m,
                                                          options.pixel_error));
        centreline = thin_pipe && k.pipe_diameter_m * px_per_m < 1.0;
        break;
      case LodPolicy::distance:
        level = uint8_t(detail::choose_level_distance(k.level_count, distance_m, size_m));
        centreline = thin_pipe && distance_m > detail::kCentrelineRadii * 0.5 * k.pipe_diameter_m;
        break;
    }
  };
  // Objects seen for the first time are decoded in slot order: the store compresses
  // neighbouring slots together, so this decompresses each chunk once.
  const auto t_decode = Clock::now();
  stack.clear();
  for (const Visible& v : visible)
    if (!known.count(v.slot)) stack.push_back(v.slot);
  std::sort(stack.begin(), stack.end());
  for (const uint32_t slot : stack)
    if (!know(slot, error)) return false;
  decode_ms = ms_since(t_decode);
  for (const Visible& v : visible) {
    Known* k = &known.at(v.slot);
    k->last_seen = frame_number;
    residency.mark_visible(v.slot);
    if (k->vertex_count == 0) continue;
    if (k->run >= 0 && options.hlod && options.lod_policy != LodPolicy::none) {
      const uint32_t r = uint32_t(k->run);
      const detail::PipelineRun& run = runs[r];
      if (run_decided_frame[r] != frame_number) {
        run_decided_frame[r] = frame_number;
        run_drawn[r] = 0;
        float mn[3], mx[3];
        for (int a = 0; a < 3; ++a) {
          mn[a] = float(run.bounds.min[a] - spatial_origin[a]);
          mx[a] = float(run.bounds.max[a] - spatial_origin[a]);
        }
        const double d = nearest_distance(mn, mx);
        const double px = focal_px / std::max(d, detail::kNearPlaneM);
        run_merged[r] = options.lod_policy == LodPolicy::screen_space
                            ? run.merge_error_m * px <= options.pixel_error
                            : d > detail::kMergeRadii * 0.5 * run.diameter_m;
        if (run_merged[r]) {
          Known* rk = know_run(r);
          rk->last_seen = frame_number;
          residency.mark_visible(kRunKeyBit | r);
          uint8_t level;
          bool centreline;
          choose(*rk, d, px, glm::length(run.end_m - run.start_m), level, centreline);
          draws.push_back({kRunKeyBit | r, rk, level, centreline, nullptr, d});
          stats.hlod_merges += 1;
        }
      }
      if (run_merged[r]) {
        stats.hlod_members += 1;
        continue;
      }
    }
    uint8_t level;
    bool centreline;
    choose(*k, v.distance_m, v.px_per_m, extent(v), level, centreline);
    draws.push_back({v.slot, k, level, centreline, &v, v.distance_m});
  }
  stats.ms.choose = ms_since(t_choose) - decode_ms;

  // 3. Stream what is not resident, and count every draw's indices at its level.
  const auto t_stream = Clock::now();
  double index_ms = 0;
  list_counts.fill(0);
  proxy_tables.clear();
  pick_ids.clear();
  const auto set_entry = [&](uint32_t t, const glm::dvec3& offset, const glm::vec3& scale,
                             Colour c, uint64_t id) {
    TableEntry& e = table[t];
    e.offset_m[0] = float(offset.x);
    e.offset_m[1] = float(offset.y);
    e.offset_m[2] = float(offset.z);
    e.colour = uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | uint32_t(c.a) << 24;
    e.scale[0] = scale.x;
    e.scale[1] = scale.y;
    e.scale[2] = scale.z;
    pick_ids.push_back(id);
    e.pick = uint32_t(pick_ids.size());
  };
  // Grow the GPU buffers once for what this frame will stream (at most: with the level slack),
  // rather than object by object: every new buffer is zeroed and the old one copied into it.
  {
    const bool roomy = residency.used_units() * 2 < residency.capacity_units();
    uint64_t needed = 0;
    for (const Draw& d : draws) {
      const Known& k = *d.known;
      if (residency.resident(d.key) && d.level >= k.base) continue;
      const uint8_t base = options.lod_policy == LodPolicy::none ? 0
                           : uint8_t(d.level > 0 && roomy ? d.level - 1 : d.level);
      needed += resident_vertices(k, base);
    }
    if (needed && !grow_arena(residency.used_units() + needed, error)) return false;
  }
  for (Draw& d : draws) {
    Known& k = *d.known;
    uint32_t level = d.level;
    if (residency.resident(d.key) && level < k.base) {
      release(d.key, k);  // nearer than its resident vertices serve: tessellate it again
      stats.objects_refined += 1;
    }
    if (!residency.resident(d.key)) {
      // One level of slack below the chosen one, so that coming nearer only swaps indices.
      // (No slack once the arena is half full: then every vertex counts.)
      const bool roomy = residency.used_units() * 2 < residency.capacity_units();
      const uint8_t base = options.lod_policy == LodPolicy::none ? 0
                           : uint8_t(level > 0 && roomy ? level - 1 : level);
      bool fits = false;
      if (!make_resident(d.key, k, base, stats, error, fits)) return false;
      if (!fits && base + 1u < k.level_count) {
        // Over budget: the coarsest level's vertices may still fit.
        if (!make_resident(d.key, k, uint8_t(k.level_count - 1), stats, error, fits)) return false;
        if (fits) stats.budget_coarsened += 1;
      }
      if (!fits) {
        // Still over budget: the object's box, which costs no arena space (merged runs are
        // skipped: their members' boxes would be drawn one by one, and runs are small).
        if (!d.visible) continue;
        stats.budget_proxies += 1;
        const Visible& v = *d.visible;
        const uint32_t t = table_acquire();
        proxy_tables.push_back(t);
        set_entry(t, spatial_origin + glm::dvec3(v.min[0], v.min[1], v.min[2]) - camera.eye_m,
                  glm::vec3(v.max[0] - v.min[0], v.max[1] - v.min[1], v.max[2] - v.min[2]),
                  k.colour, k.id);
        stats.triangles += 12;
        continue;
      }
    }
    level = std::max<uint32_t>(level, k.base);
    d.level = uint8_t(level);
    d.drawn = true;
    d.arena_first = uint32_t(*residency.offset(d.key));
    set_entry(k.table, k.origin_m - camera.eye_m, glm::vec3(1.0f), k.colour, k.id);
    if (d.centreline) {
      stats.centreline_pipes += 1;
      stats.lines += k.centreline.size();
      list_counts[kLines] += 2 * k.centreline.size();
      continue;
    }
    for (const Known::Part& part : k.parts) {
      const uint32_t l = part.plan->clamp_level(level);
      const uint32_t n = part.plan->index_count(l);
      list_counts[list_of(k, part)] += n;
      if (part.plan->topology == Topology::lines) {
        stats.lines += n / 2;
      } else {
        stats.triangles += n / 3;
        stats.triangles_by_level[l] += n / 3;
      }
    }
  }
  for (const auto& b : node_proxies) {
    const uint32_t t = table_acquire();
    proxy_tables.push_back(t);
    set_entry(t, spatial_origin + glm::dvec3(b[0], b[1], b[2]) - camera.eye_m,
              glm::vec3(b[3] - b[0], b[4] - b[1], b[5] - b[2]), Colour{150, 150, 150, 255}, 0);
    stats.triangles += 12;
  }
  residency.end_frame();
  stats.objects_resident = residency.resident_count() - 1;  // not the proxy cube
  stats.arena_bytes_resident = residency.used_units() * kBytesPerVertex;
  stats.draw_commands = proxy_tables.empty() ? 0 : 1;
  for (const size_t n : list_counts) stats.draw_commands += n ? 1 : 0;
  if (!draw) {
    forget_old(stats);
    for (const uint32_t t : proxy_tables) table_free.push_back(t);
    stats.ms.stream = ms_since(t_stream) + decode_ms;
    stats.ms.total = ms_since(t_start);
    return true;
  }

  // Write the index lists straight into the (mapped) index buffer, each draw's indices at its
  // level: no copy of them is kept.
  const auto t_index = Clock::now();
  size_t index_total = 0;
  std::array<size_t, kListCount> list_first{};
  for (int list = 0; list < kListCount; ++list) {
    list_first[list] = index_total;
    index_total += list_counts[list];
  }
  const size_t index_bytes = std::max<size_t>(index_total, 1) * sizeof(uint32_t);
  if (index_bytes > index_capacity) {
    index_capacity = std::max(index_bytes, index_capacity * 3 / 2);
    glNamedBufferData(index_buffer, GLsizeiptr(index_capacity), nullptr, GL_STREAM_DRAW);
  }
  // Unsynchronised: the previous frame was finished (read back) before this one began, and
  // invalidating would make the driver allocate (and zero) new storage every frame.
  auto* indices = static_cast<uint32_t*>(glMapNamedBufferRange(
      index_buffer, 0, GLsizeiptr(index_bytes), GL_MAP_WRITE_BIT | GL_MAP_UNSYNCHRONIZED_BIT));
  if (!indices) {
    error = "renderer: cannot map " + std::to_string(index_bytes >> 20) + " MB of index buffer";
    return false;
  }
  std::array<uint32_t*, kListCount> cursor;
  for (int list = 0; list < kListCount; ++list) cursor[list] = indices + list_first[list];
  // Nearest first: hidden fragments then fail the depth test before they are shaded.
  draw_order.clear();
  for (uint32_t i = 0; i < draws.size(); ++i)
    if (draws[i].drawn) draw_order.push_back(i);
  std::sort(draw_order.begin(), draw_order.end(), [&](uint32_t a, uint32_t b) {
    return draws[a].distance_m < draws[b].distance_m;
  });
  for (const uint32_t i : draw_order) {
    const Draw& d = draws[i];
    const Known& k = *d.known;
    if (d.centreline) {
      const uint32_t first = d.arena_first + k.resident_centreline_first;
      for (uint32_t c = 0; c < 2 * k.centreline.size(); ++c) *cursor[kLines]++ = first + c;
      continue;
    }
    for (const Known::Part& part : k.parts) {
      const MeshPlan& plan = part.resident_plan ? *part.resident_plan : *part.plan;
      uint32_t*& at = cursor[list_of(k, part)];
      at += write_indices(plan, d.level, d.arena_first + part.resident_first,
                          std::span<uint32_t>(at, plan.index_count(d.level)));
    }
  }
  glUnmapNamedBuffer(index_buffer);
  index_ms = ms_since(t_index);
  forget_old(stats);
  stats.ms.stream = ms_since(t_stream) - index_ms + decode_ms;
  stats.ms.choose += index_ms;

  // 4. Draw: one call per list.
  const auto t_draw = Clock::now();
  if (!ensure_framebuffer(w, h, error)) return false;
  const auto upload = [](GLuint buffer, size_t& capacity, size_t bytes,
                         std::initializer_list<std::pair<const void*, size_t>> parts) {
    if (bytes > capacity) {
      capacity = std::max(bytes, capacity * 3 / 2);
      glNamedBufferData(buffer, GLsizeiptr(capacity), nullptr, GL_STREAM_DRAW);
    }  // (no invalidation: the buffer is idle, and new storage would be zeroed every frame)
    size_t at = 0;
    for (const auto& [data, size] : parts) {
      if (size) glNamedBufferSubData(buffer, GLintptr(at), GLsizeiptr(size), data);
      at += size;
    }
  };
  const size_t n_closed = list_counts[kClosed], n_open = list_counts[kOpen];
  const size_t n_opaque = n_closed + n_open, n_transparent = list_counts[kTransparent],
               n_lines = list_counts[kLines];
  upload(table_buffer, table_capacity, table_used * sizeof(TableEntry),
         {{table.data(), table_used * sizeof(TableEntry)}});
  upload(proxy_buffer, proxy_capacity, proxy_tables.size() * sizeof(uint32_t),
         {{proxy_tables.data(), proxy_tables.size() * sizeof(uint32_t)}});
  glVertexArrayVertexBuffer(proxy_vao, 1, proxy_buffer, 0, sizeof(uint32_t));
  for (const uint32_t t : proxy_tables) table_free.push_back(t);

  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  // The object ids are written only when they are read back.
  const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0, GLenum(with_ids ? GL_COLOR_ATTACHMENT1 : GL_NONE)};
  glNamedFramebufferDrawBuffers(framebuffer, 2, draw_buffers);
  glViewport(0, 0, GLsizei(w), GLsizei(h));
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);  // two-sided: facet groups and open meshes are seen from both sides
  const GLfloat background[4] = {0.80f, 0.84f, 0.88f, 1.0f};
  const GLuint no_pick[4] = {0, 0, 0, 0};
  const GLfloat far_depth = 0.0f;
  glClearNamedFramebufferfv(framebuffer, GL_COLOR, 0, background);
  glClearNamedFramebufferuiv(framebuffer, GL_COLOR, 1, no_pick);
  glClearNamedFramebufferfv(framebuffer, GL_DEPTH, 0, &far_depth);
  glUseProgram(program);
  glUniformMatrix4fv(u_view_projection, 1, GL_FALSE, glm::value_ptr(view_projection));
  const glm::vec3 sun = glm::normalize(glm::mat3(view_rotation) * glm::vec3(0.3f, 0.5f, 0.8f));
  glUniform3fv(u_sun, 1, glm::value_ptr(sun));
  // View space to the camera-relative frame, with the half-angle tangents of the view.
  const glm::mat3 ray = glm::transpose(glm::mat3(view_rotation)) *
                        glm::mat3(glm::vec3(aspect / focal, 0, 0), glm::vec3(0, 1.0f / focal, 0), glm::vec3(0, 0, 1));
  glUniformMatrix3fv(u_ray, 1, GL_FALSE, glm::value_ptr(ray));
  glUniform2f(u_window_scale, 2.0f / float(w), 2.0f / float(h));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, table_buffer);
  glDisablei(GL_BLEND, 0);
  glBindVertexArray(vao);
  if (n_closed) {
    // Closed solids have outward, counter-clockwise faces: their back faces are never seen.
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glDrawElements(GL_TRIANGLES, GLsizei(n_closed), GL_UNSIGNED_INT, nullptr);
    glDisable(GL_CULL_FACE);
  }
  if (n_open)
    glDrawElements(GL_TRIANGLES, GLsizei(n_open), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(n_closed * sizeof(uint32_t)));
  if (n_lines)
    glDrawElements(GL_LINES, GLsizei(n_lines), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>((n_opaque + n_transparent) * sizeof(uint32_t)));
  if (!proxy_tables.empty()) {
    glBindVertexArray(proxy_vao);
    glDrawElementsInstanced(GL_TRIANGLES, 36, GL_UNSIGNED_INT, nullptr, GLsizei(proxy_tables.size()));
    glBindVertexArray(vao);
  }
  if (n_transparent) {
    // See-through objects after the rest, blended, not hiding what lies behind them.
    glEnablei(GL_BLEND, 0);
    glBlendFunci(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDepthMask(GL_FALSE);
    glDrawElements(GL_TRIANGLES, GLsizei(n_transparent), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(n_opaque * sizeof(uint32_t)));
    glDepthMask(GL_TRUE);
    glDisablei(GL_BLEND, 0);
  }
  glBindVertexArray(0);
  glFinish();
  stats.ms.draw = ms_since(t_draw);

  // 5. Resolve the samples and read back, top row first.
  const auto t_read = Clock::now();
  GLuint source = framebuffer;
  if (fb_samples > 1) {
    // Colour averages its samples; ids take one sample (integers do not average).
    for (const GLenum attachment : {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1}) {
      if (attachment == GL_COLOR_ATTACHMENT1 && !with_ids) break;
      glNamedFramebufferReadBuffer(framebuffer, attachment);
      glNamedFramebufferDrawBuffer(resolved, attachment);
      glBlitNamedFramebuffer(framebuffer, resolved, 0, 0, GLint(w), GLint(h), 0, 0, GLint(w), GLint(h),
                             GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    source = resolved;
  }
  out->width = w;
  out->height = h;
  out->rgba.resize(size_t(w) * h * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, source);
  glNamedFramebufferReadBuffer(source, GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, GLsizei(w), GLsizei(h), GL_RGBA, GL_UNSIGNED_BYTE, out->rgba.data());
  const size_t row = size_t(w) * 4;
  for (uint32_t y = 0; y < h / 2; ++y)
    std::swap_ranges(out->rgba.begin() + y * row, out->rgba.begin() + (y + 1) * row,
                     out->rgba.begin() + (h - 1 - y) * row);
  if (with_ids) {
    pick_pixels.resize(size_t(w) * h);
    glNamedFramebufferReadBuffer(source, GL_COLOR_ATTACHMENT1);
    glReadPixels(0, 0, GLsizei(w), GLsizei(h), GL_RED_INTEGER, GL_UNSIGNED_INT, pick_pixels.data());
    out->object_ids.resize(size_t(w) * h);
    for (uint32_t y = 0; y < h; ++y) {
      const uint32_t* src = pick_pixels.data() + size_t(h - 1 - y) * w;
      uint64_t* dst = out->object_ids.data() + size_t(y) * w;
      for (uint32_t x = 0; x < w; ++x)
        dst[x] = src[x] && src[x] <= pick_ids.size() ? pick_ids[src[x] - 1] : 0;
    }
  } else {
    out->object_ids.clear();
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (const GLenum gl_error = glGetError(); gl_error != GL_NO_ERROR) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "renderer: OpenGL error 0x%x", gl_error);
    error = buf;
    return false;
  }
  stats.ms.read_back = ms_since(t_read);
  stats.ms.total = ms_since(t_start);
  return true;
}

Renderer::Renderer(std::unique_ptr<State> state) : state_(std::move(state)) {}
Renderer::~Renderer() = default;

std::unique_ptr<Renderer> Renderer::create(const Store& store, const RenderOptions& options,
                                           std::string& error) {
  if (options.vertex_budget_bytes < (1u << 20) || options.vertex_budget_bytes > (64ull << 30)) {
    error = "renderer: the vertex budget must be 1 MB .. 64 GB";
    return nullptr;
  }
  if (!(options.pixel_error > 0.0) || !std::isfinite(options.pixel_error)) {
    error = "renderer: the pixel error must be a positive number";
    return nullptr;
  }
  auto state = std::make_unique<State>();
  state->store = &store;
  state->options = options;
  if (!state->init_gl(error) || !state->open_view(error)) return nullptr;
  return std::unique_ptr<Renderer>(new Renderer(std::move(state)));
}

bool Renderer::render(const Camera& camera, uint32_t width, uint32_t height, bool with_ids,
                      Image& out, FrameStats& stats, std::string& error) {
  return state_->frame(camera, width, height, true, with_ids, &out, stats, error);
}

bool Renderer::statistics(const Camera& camera, uint32_t width, uint32_t height,
                          FrameStats& stats, std::string& error) {
  return state_->frame(camera, width, height, false, false, nullptr, stats, error);
}

bool Renderer::refresh(std::string& error) {
  state_->view.reset();
  return state_->open_view(error);
}

void Renderer::set_options(const RenderOptions& options) {
  const uint64_t budget = state_->options.vertex_budget_bytes;
  state_->options = options;
  state_->options.vertex_budget_bytes = budget;
}

const RenderOptions& Renderer::options() const { return state_->options; }
const DAabb& Renderer::model_bounds() const { return state_->bounds; }
const ReadView& Renderer::read_view() const { return *state_->view; }

}  // namespace plantview
