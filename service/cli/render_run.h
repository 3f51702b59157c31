// The parts of `plantview render` that its files share: the typed command line
// (render_plan.cpp), writing images and the renderer's session (render_output.cpp), and the two
// ways a run goes: cameras and paths (render_commands.cpp), review views (render_views.cpp).
// Errors: usage errors print their message and give exit status 2 (usage_error); runtime
// failures print "plantview: ..." to stderr and give 1 (fail).
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli/ordered_tasks.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview::cli::rendering {

namespace fs = std::filesystem;

struct RenderArgs {
  std::string store, camera, path, views, out, size = "1280x720", lod_policy = "screen-space",
                                               shard = "0/1", format = "png", occlusion = "on",
                                               occlusion_test = "automatic";
  double pixel_error = kStillPixelError;  // render.h: stills are read closely
  uint64_t vertex_budget_mb = 512;
  int device = -1, quality = 90;
  uint32_t samples = 0;
  std::string antialias = "automatic", highlight;
  std::string bcf;  // with --views: the BCF file written once the job is complete
  bool no_centrelines = false, no_hlod = false, no_subpixel = false, force = false;
  bool no_ground = false, no_ambient_occlusion = false;
  std::string colour_by, hide, only;  // view_filters.h: ObjectStyle
  std::string changes;  // R1 or R1..R2: a change image (render.h: RenderOptions::changes)
  // Sections (view_filters.h): --clip (repeatable, at most kMaxClipPlanes), --section-box,
  // --no-caps.
  std::vector<std::string> clip;
  std::string section_box;
  bool no_caps = false;
};

// What the command line asks for, typed and checked. Every usage error is found while making it,
// before any file is read or written.
struct RenderPlan {
  enum class Mode { single, path, views } mode = Mode::single;
  uint32_t width = 0, height = 0, shard_index = 0, shard_count = 1;
  RenderOptions options;
  ImageFormat format = ImageFormat::png;
  std::optional<Camera> camera;  // single: the camera given, else the plant's default
  // --highlight's words, each an object id or tag (resolve_highlight turns them into
  // options.highlight_ids once the store is open).
  std::vector<std::string> highlight;
};

// Fills `plan` from `a`: 0, or the exit status of the usage error it printed. Reads no file.
int plan_render(const RenderArgs& a, RenderPlan& plan);
// The options of `plantview render` onto `render`, into `args`.
void add_render_options(CLI::App* render, RenderArgs* args);
// --highlight's words as store ids: a decimal word is an id if an object has it, else each
// word is a tag (an object's name, as stored or with a leading '/'; a tag naming several
// objects highlights them all). False with a message naming the first word that matches
// nothing ("--highlight: no object has the id or the tag '12345'"), or the store's error.
bool resolve_highlight(const ReadView& view, const std::vector<std::string>& words,
                       std::vector<uint64_t>& ids, std::string& error, bool& usage);

bool read_text(const std::string& path, std::string& out, std::string& error);
int fail(const std::string& message);
double ms_since(std::chrono::steady_clock::time_point start);

// The directory a single image goes into must exist and take files, checked before rendering.
bool check_image_destination(const std::string& out, std::string& error);
// Encodes `image` and writes it atomically (farm/output_dir.h); stats.ms.encode gets the time.
bool write_image_file(const fs::path& path, const Image& image, ImageFormat format, int quality,
                      FrameStats& stats, std::string& error);

// One image on its way to a file (OrderedTasks' work writes it; its done reads the outcome).
struct ImageToWrite {
  fs::path path;
  Image image;
  FrameStats stats;
  bool ok = false;
  std::string error;
};

// Writes the images of a run of views on other threads while the next view renders: at most
// threads + 1 images wait, and their buffers are rendered into again once written.
class ImageWriter {
 public:
  ImageWriter(ImageFormat format, int quality)
      : format_(format),
        quality_(quality),
        tasks_(OrderedTasks::default_threads(), OrderedTasks::default_threads() + 1) {}

  // An image buffer to render into: one already written, or a new one.
  Image take_buffer() {
    if (spare_.empty()) return {};
    Image image = std::move(spare_.back());
    spare_.pop_back();
    return image;
  }
  // Writes `image` (with the stats of its frame) to `path`; then, on this thread and in the
  // order written, calls done(written) and takes the buffer back.
  void write(fs::path path, Image&& image, const FrameStats& stats,
             std::function<void(ImageToWrite&)> done) {
    auto job = std::make_shared<ImageToWrite>();
    job->path = std::move(path);
    job->image = std::move(image);
    job->stats = stats;
    tasks_.submit(
        [job, format = format_, quality = quality_] {
          job->ok = write_image_file(job->path, job->image, format, quality, job->stats, job->error);
        },
        [this, job, done = std::move(done)] {
          done(*job);
          spare_.push_back(std::move(job->image));
        });
  }
  // Waits until every image is written and its done called.
  void finish() { tasks_.finish(); }

 private:
  ImageFormat format_;
  int quality_;
  std::vector<Image> spare_;  // written images' buffers (declared before tasks_: outlives it)
  OrderedTasks tasks_;
};

// The GPU context, the image module and a renderer of `store`, in the order they must come.
struct RenderSession {
  std::unique_ptr<GpuContext> context;
  std::unique_ptr<Renderer> renderer;
};
bool start_rendering(int device, const Store& store, const RenderOptions& options,
                     RenderSession& session, std::string& error);
// The legend of a frame coloured by an attribute (FrameStats::legend; nothing when its key is
// empty) appended to caption lines, with their colour keys (swatches aligned to lines):
// "Colour by KEY", then a line per category with its object count, other values, and the
// objects without the key; or the ramp's bar with its range and unit. heading false: without
// the first line (the caller's title says it).
void add_legend_lines(const FrameLegend& legend, std::vector<std::string>& lines,
                      std::vector<CaptionSwatch>& swatches, bool heading = true);
// A caption in columns side by side (legends beside a view's lines, long legends): each
// column's lines after their keys (image.h: add_caption with swatches), every column as high
// as the tallest, the title over the first. One column: add_caption itself.
struct CaptionColumn {
  std::vector<std::string> lines;
  std::vector<CaptionSwatch> swatches;
};
bool add_caption_columns(Image& image, std::string_view title,
                         const std::vector<CaptionColumn>& columns, std::string& error);
// The legend's lines (add_legend_lines) as columns of `rows` lines each, appended to `columns`.
void add_legend_columns(const FrameLegend& legend, size_t rows, std::vector<CaptionColumn>& columns,
                        bool heading = true);
// Says on stderr how long after the process started the first image was written.
void report_first_image(std::chrono::steady_clock::time_point t_start);

// `render --views`: the farm's shard (farm/scheduler.h states the contract).
int render_views(const RenderArgs& a, const RenderPlan& plan);

}  // namespace plantview::cli::rendering
