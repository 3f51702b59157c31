// GL backend: every OpenGL call of the renderer. Shaders, the vertex arena's GPU buffers (grown
// on demand up to the budget), the index, object-table and proxy buffers, the framebuffer,
// drawing the frame's index lists and reading the image back.
//
// Rules
//   - The arena is two GPU buffers indexed alike: vertices (PackedVertex) and the object-table
//     index of each vertex (uint32). They hold at least what streaming asks for and never more
//     than the budget; growing at least doubles them (each growth allocates new buffers, which
//     the driver zeroes, and copies the old: about 1 ms a MB on llvmpipe).
//   - The index buffer holds the frame's lists one after the other in IndexList order; it is
//     written through an unsynchronised mapping, which is safe because every frame is finished
//     (read back) before the next begins.
//   - Draw order: closed opaque solids (back faces culled), open opaque meshes, lines, proxy
//     boxes (instanced unit cubes at arena offset 0, one object-table entry each), then the
//     see-through triangles blended without writing depth. Depth is reversed (greater wins).
//   - Object ids are written only when read back (with_ids).
// Units: arena offsets and sizes in vertices; buffer capacities in bytes; pixels.
// Threads: the thread whose GL context was current at init(), which must stay current for
//   every call and for the destructor.
// Errors: false with "renderer: ..." naming what failed (shader log, sizes, the GL error code).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "plantview/image.h"
#include "plantview/primitives.h"

namespace plantview::detail {

struct FrameView;

// One entry of the per-frame object table (std430: two vec4), read by the vertex shader.
struct TableEntry {
  float offset_m[3];  // the object's origin relative to the eye
  uint32_t colour;    // RGBA8
  float scale[3];     // 1 for objects; the box size for proxies
  uint32_t pick;      // index into the frame's pick table + 1; 0: no object
};
static_assert(sizeof(TableEntry) == 32);

inline constexpr uint64_t kBytesPerVertex = sizeof(PackedVertex) + sizeof(uint32_t);
inline constexpr uint32_t kProxyVertices = 24;  // the unit cube of proxy boxes, at arena offset 0

using GlName = uint32_t;  // a GLuint: the name of a GL object (0: none)

// The frame's index lists, in this order in the index buffer.
enum IndexList : uint8_t { kClosed, kOpen, kTransparent, kLines, kIndexListCount };
using IndexCounts = std::array<size_t, kIndexListCount>;

class GlBackend {
 public:
  GlBackend() = default;
  ~GlBackend();
  GlBackend(const GlBackend&) = delete;
  GlBackend& operator=(const GlBackend&) = delete;

  // Compiles the shaders and makes the buffers and vertex arrays, the arena at its initial size
  // (at most budget_vertices, which bounds every later growth). Needs a current OpenGL 4.5
  // context.
  bool init(uint64_t budget_vertices, std::string& error);

  // The arena buffers hold at least `vertices` (capped at the budget), keeping their contents.
  bool grow_arena(uint64_t vertices, std::string& error);
  // Writes vertices at arena offset `first` (and, unless `objects` is empty, their object-table
  // indices alike). The range must lie within the arena's current size.
  void upload(uint64_t first, std::span<const PackedVertex> vertices,
              std::span<const uint32_t> objects);

  // The index buffer, mapped for writing `count` indices; unmap_indices() before drawing. Null
  // with an error if it cannot be mapped.
  uint32_t* map_indices(size_t count, std::string& error);
  void unmap_indices();

  // Draws the lists (counts per list, as written) and the proxy boxes, one per entry of
  // `proxy_tables`, with the object table `table`, into a framebuffer of the view's size with
  // `samples` per pixel (0: 4 on a GPU, 1 on a software renderer; at most what GL allows);
  // waits for the GPU to finish.
  bool draw(const FrameView& view, const IndexCounts& counts, std::span<const TableEntry> table,
            std::span<const uint32_t> proxy_tables, uint32_t samples, bool with_ids,
            std::string& error);
  // Reads the frame drawn back into `out` (top row first). with_ids: also the object ids, each
  // pixel's pick value p mapped to pick_ids[p - 1] (0 where nothing was drawn).
  bool read_back(uint32_t width, uint32_t height, bool with_ids,
                 std::span<const uint64_t> pick_ids, Image& out, std::string& error);

 private:
  bool ensure_framebuffer(uint32_t width, uint32_t height, uint32_t samples, std::string& error);
  void release_framebuffer();
  void bind_arena();
  // Binds and clears the framebuffer and sets the program's uniforms for the view.
  void begin_pass(const FrameView& view, bool with_ids);
  // One draw call per non-empty list, and the proxy boxes (instanced), in the order of the rules.
  void draw_lists(const IndexCounts& counts, size_t proxies);

  uint64_t budget_vertices_ = 0;
  GlName program_ = 0, vao_ = 0, proxy_vao_ = 0, arena_ = 0, arena_objects_ = 0,
           index_buffer_ = 0, table_buffer_ = 0, proxy_buffer_ = 0, cube_indices_ = 0;
  uint64_t arena_vertices_ = 0;  // size of the GPU buffers, in vertices (<= the budget)
  int32_t u_view_projection_ = -1, u_sun_ = -1, u_ray_ = -1, u_window_scale_ = -1;
  // Drawing goes to `framebuffer_` (multisampled when samples > 1), then is resolved into
  // `resolved_` (single-sampled) for reading back.
  GlName framebuffer_ = 0, colour_rb_ = 0, pick_rb_ = 0, depth_rb_ = 0;
  GlName resolved_ = 0, resolved_colour_ = 0, resolved_pick_ = 0;
  uint32_t fb_width_ = 0, fb_height_ = 0, fb_samples_ = 0;
  size_t index_capacity_ = 0, table_capacity_ = 0, proxy_capacity_ = 0;  // bytes
  std::vector<uint32_t> pick_pixels_;  // read-back scratch
};

}  // namespace plantview::detail
