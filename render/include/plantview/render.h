// plantview/render.h: the headless renderer. Turns a store and a camera into an image, an
// object-id buffer and the frame's LOD statistics, for models far larger than memory.
//
// Per frame (Zhou et al. 2012 section 4, Su et al. section 5.3):
//   1. cull     walk the store's spatial tree against the view frustum. Screen-space policy:
//               objects whose extent projects under the pixel error are left out, and a tree
//               node spanning under 3 x the pixel error is drawn as one box (that size doubles
//               until at most 60,000 objects remain in view), so a far view of a huge plant
//               costs what the image holds, not what the plant holds;
//   2. choose   a level per visible object by LodPolicy (screen-space error by default); pipes
//               whose diameter projects under about a pixel are drawn as their centreline.
//               Pipeline HLOD: a straight run of pipes and inline components is drawn as one
//               cylinder where the components' relief projects under the pixel error;
//   3. stream   vertices of newly visible objects are tessellated from their parameters into one
//               GPU vertex arena of fixed size (20 bytes a vertex: position, packed normal and
//               the object-table index). The GPU buffer grows to what each frame needs,
//               doubling, up to the budget; a model larger than the budget at full resolution
//               gets the whole budget at once (growing copies the buffer, and old plus new would
//               exceed it), and its resident objects keep only what drawing needs (their
//               primitives are decoded again from the store if they must be tessellated again). An
//               object is made resident from one level below its chosen one (from the chosen
//               one once the arena is half full): the vertices of a level serve every coarser
//               level, so coarsening, and refining within that slack, only changes the index
//               range drawn; refining beyond it tessellates the object again. Every resident
//               object has a visibility counter, reset when it is visible and incremented each
//               frame it is not; when the arena is full, the largest counters are evicted first.
//               The arena never exceeds its budget: a visible object that does not fit is made
//               resident at its coarsest level (`budget_coarsened`), else drawn as its box
//               (`budget_proxies`);
//   4. draw     one draw call per kind of geometry (closed solids with back faces culled, open
//               meshes, see-through, lines, boxes): every vertex carries the index of its object
//               in a per-frame object table that holds the object's origin relative to the eye
//               (computed in double precision), its colour and its pick id; so plants
//               kilometres from the origin do not jitter, and the draw-call count does not grow
//               with the object count;
//               Nearest objects are drawn first, so that hidden fragments fail the depth test
//               before they are shaded; object ids are drawn only when asked for;
//   5. read back colour (RGBA8, sRGB values) and object ids (after resolving multisampling).
//
// Units: lengths in metres, angles in degrees where the name says _deg, times in milliseconds.
// Threads: a GpuContext and every Renderer made with it belong to the thread that made them.
// Errors: fallible calls return false (or null) and fill `error` with what and where.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/model.h"

namespace plantview {

class Store;
class ReadView;

// ---------------------------------------------------------------------------------------------
// Cameras.

// A perspective camera in model space. `fov_deg` is the vertical field of view.
struct Camera {
  glm::dvec3 eye_m{0.0, -10.0, 0.0};
  glm::dvec3 target_m{0.0};
  glm::dvec3 up{0.0, 0.0, 1.0};
  double fov_deg = 50.0;
  bool operator==(const Camera&) const = default;
};

// Parses "eye=X,Y,Z,target=X,Y,Z[,up=X,Y,Z][,fov=DEG]" (the --camera form). Rejects missing or
// non-finite numbers, an eye on the target, an up along the view, and fov outside (0, 179).
bool parse_camera(std::string_view text, Camera& out, std::string& error);
// The rules parse_camera applies to a camera however it was made: false with a message ("camera:
// the eye is on the target", "camera: 'up' is zero or along the view direction", "camera: fov
// must be in (0, 179) degrees").
bool validate_camera(const Camera& camera, std::string& error);
std::string format_camera(const Camera& camera);  // the form parse_camera reads
// A camera that frames the whole of `bounds` from above one corner, for an image of `aspect`
// (width / height).
Camera default_camera(const DAabb& bounds, double aspect);

// A camera path: what `plantview path` writes and `render --path` reads. JSON: a list of
// {"eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov": deg}.
std::string camera_path_json(const std::vector<Camera>& cameras);
bool parse_camera_path(std::string_view json, std::vector<Camera>& out, std::string& error);

enum class PathKind { walkthrough, orbit };
bool parse_path_kind(std::string_view name, PathKind& kind);
// A path of `frames` cameras. orbit: around the plant's bounds, looking at their centre.
// walkthrough: starts outside the plant, approaches it and walks into it at eye height along
// the gaps between its equipment (the objects of class equipment, given by their bounds), like
// Zhou et al.'s Fig. 6 run.
std::vector<Camera> make_camera_path(PathKind kind, int frames, const DAabb& plant_bounds,
                                     const std::vector<DAabb>& equipment_bounds);
// The same for a store's plant: its bounds, and the bounds of its equipment (every object is
// read once). False with a message if the store cannot be read or holds no geometry.
bool make_camera_path(PathKind kind, int frames, const Store& store, std::vector<Camera>& out,
                      std::string& error);

// ---------------------------------------------------------------------------------------------
// Options and statistics.

enum class LodPolicy {
  screen_space,  // the coarsest level whose error projects under pixel_error (default)
  distance,      // the papers' rules: level by distance over object size (Zhou), pipes as
                 // centrelines beyond a distance proportional to their radius (Su's d2)
  none,          // full resolution (level 0) everywhere
};
std::string_view lod_policy_name(LodPolicy policy);
bool parse_lod_policy(std::string_view name, LodPolicy& policy);

struct RenderOptions {
  LodPolicy lod_policy = LodPolicy::screen_space;
  double pixel_error = 1.0;                        // screen_space: allowed error in pixels
  uint64_t vertex_budget_bytes = 512ull << 20;     // the GPU vertex arena's fixed size
  bool centrelines = true;                         // thin pipes as lines (screen_space, distance)
  bool hlod = true;                                // merge straight pipeline runs when allowed
  uint32_t samples = 0;                            // multisampling per pixel (1: off); 0: auto,
                                                   // 4 on a GPU, 1 on a software renderer (where
                                                   // 4 samples triple the draw time)
  bool subpixel_culling = true;                    // screen_space: leave out objects under the
                                                   // pixel error on screen
};

struct FrameStats {
  uint64_t objects_visible = 0, objects_culled = 0;  // culled: outside the frustum
  uint64_t triangles = 0, lines = 0;
  std::array<uint64_t, 8> triangles_by_level{};
  uint64_t centreline_pipes = 0;  // pipes (and merged runs) drawn as their centreline
  uint64_t hlod_merges = 0;       // pipeline runs drawn as one cylinder (or line)
  uint64_t hlod_members = 0;      // visible pipes and inline components those runs replaced
  uint64_t budget_proxies = 0;    // visible objects drawn as boxes because the arena was full
  uint64_t budget_coarsened = 0;  // objects made resident at their coarsest level to fit
  uint64_t objects_refined = 0;   // resident objects tessellated again for a finer level
  uint64_t objects_subpixel = 0;  // in the frustum but under the pixel error on screen
  uint64_t node_proxies = 0;      // tree nodes of a few pixels drawn as one box each
  double node_proxy_pixels = 0;   // the node size (px) under which they were: 3 x the pixel
                                  // error, more when the view holds over 60,000 objects
  uint64_t objects_in_node_proxies = 0;
  uint64_t draw_commands = 0;
  uint64_t arena_bytes_budget = 0, arena_bytes_resident = 0;
  uint64_t arena_bytes_uploaded = 0, arena_bytes_evicted = 0;
  uint64_t objects_resident = 0, objects_tessellated = 0, objects_evicted = 0;
  struct Times {
    double cull = 0, choose = 0, stream = 0, draw = 0, read_back = 0, encode = 0, total = 0;
  } ms;
  // One JSON object (one line): the fields above, times under "ms".
  std::string to_json() const;
};

// ---------------------------------------------------------------------------------------------
// Images.
//
// Image files, encoding and comparison go through OpenImageIO in a loadable module
// (plantview_image_oiio), loaded once per process by the first call below that needs it, or
// earlier by preload_image_io(). Looked for at $PLANTVIEW_IMAGE_MODULE when that is set (and
// only there), else beside the running executable, else where the build wrote it. When it
// cannot be loaded, every call that needs it fails with a message naming each path tried and
// why. All functions here may be called from any thread.

// A rendered frame. Row 0 is the top. `object_ids` holds, per pixel, the id (model.h) of the
// object drawn there, 0 where there is none.
struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;          // width * height * 4
  std::vector<uint64_t> object_ids;   // width * height (empty if not asked for)
};

// Largest image the renderer and encoders accept in either direction.
inline constexpr uint32_t kMaxImageSide = 16384;

// Starts loading the image module on a background thread and returns at once (loading it
// takes about half a second on Debian, where OpenImageIO brings some 260 libraries). Image calls
// made meanwhile wait for it; a second call does nothing; a failed load is reported by the first
// image call. The load holds the dynamic loader's lock throughout, so other threads' dlopen and
// dlsym wait for it meanwhile: EGL initialisation, and libepoxy at the first call of each GL
// function. Call it once images are sure to be needed, after GpuContext::create.
void preload_image_io();

enum class ImageFormat { png, jpeg };
// From a file name's extension (.png, .jpg, .jpeg) or a format name ("png", "jpeg", "jpg").
bool image_format_from_name(std::string_view name, ImageFormat& format);
// Encodes RGB (alpha dropped) into memory; jpeg_quality 1..100.
bool encode_image(const Image& image, ImageFormat format, int jpeg_quality,
                  std::vector<uint8_t>& out, std::string& error);
bool write_image(const std::string& path, const Image& image, int jpeg_quality,
                 std::string& error);
// Reads an image file as RGBA8.
bool read_image(const std::string& path, Image& out, std::string& error);

struct ImageComparison {
  double psnr_db = 0;          // over RGB, 8-bit; +infinity for identical images
  double max_difference = 0;   // largest channel difference, 0..1
  double differing_share = 0;  // share of pixels with any channel differing by more than 1/255
};
// Compares two images of the same size (error otherwise). If diff_path is given, writes an
// image of the per-pixel absolute differences, amplified, there.
bool compare_images(const Image& a, const Image& b, ImageComparison& out, std::string& error);
bool write_difference_image(const Image& a, const Image& b, const std::string& path,
                            std::string& error);

// ---------------------------------------------------------------------------------------------
// The GPU context and the renderer.

// An OpenGL 4.5 core context with no display: EGL_EXT_platform_device first (hardware devices
// before software ones), then Mesa's surfaceless platform (llvmpipe on machines without a GPU).
class GpuContext {
 public:
  // device_index < 0: the first hardware device, else the first that works; >= 0: that device
  // of EGL_EXT_platform_device's list (error if there is none such).
  static std::unique_ptr<GpuContext> create(int device_index, std::string& error);
  ~GpuContext();
  GpuContext(const GpuContext&) = delete;
  GpuContext& operator=(const GpuContext&) = delete;

  // "EGL device 0 (EGL_EXT_device_drm /dev/dri/card0): NVIDIA H200 ..., OpenGL 4.5 ..." or
  // "Mesa surfaceless: llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 ...".
  const std::string& description() const;
  // Makes the context current on the calling thread.
  bool make_current(std::string& error);

 private:
  struct State;
  explicit GpuContext(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Renders frames of one store. Holds one read snapshot of the store for its life (call
// refresh() to see later imports) and the GPU resources of its arena. Uses the GpuContext
// current on its thread; the context must outlive it.
class Renderer {
 public:
  static std::unique_ptr<Renderer> create(const Store& store, const RenderOptions& options,
                                          std::string& error);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Renders one frame of width x height (1..kMaxImageSide). with_ids: also read back the
  // object-id buffer. Fills `stats` (ms.encode is left to the caller).
  bool render(const Camera& camera, uint32_t width, uint32_t height, bool with_ids, Image& out,
              FrameStats& stats, std::string& error);
  // Culls and chooses levels without drawing (LOD statistics for a view).
  bool statistics(const Camera& camera, uint32_t width, uint32_t height, FrameStats& stats,
                  std::string& error);

  // Starts a new read snapshot and forgets everything resident.
  bool refresh(std::string& error);
  void set_options(const RenderOptions& options);  // the vertex budget is fixed at creation
  const RenderOptions& options() const;
  const DAabb& model_bounds() const;
  // The read snapshot frames are drawn from: a pick reads its object from the same commit as the
  // frame it picks in. Valid until refresh() or destruction; the renderer's thread only.
  const ReadView& read_view() const;

 private:
  struct State;
  explicit Renderer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace plantview
