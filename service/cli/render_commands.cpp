// `plantview render` and `path`: review images and camera paths.
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "cli/commands.h"
#include "cli/farm/job_inputs.h"
#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"
#include "cli/ordered_tasks.h"
#include "cli/progress.h"
#include "plantview/render.h"
#include "plantview/review.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

namespace fs = std::filesystem;

bool parse_size(const std::string& text, uint32_t& w, uint32_t& h, std::string& error) {
  const size_t x = text.find('x');
  const auto number = [](std::string_view s, uint32_t& v) {
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && end == s.data() + s.size();
  };
  if (x == std::string::npos || !number(std::string_view(text).substr(0, x), w) ||
      !number(std::string_view(text).substr(x + 1), h)) {
    error = "--size: expected WxH, got '" + text + "'";
    return false;
  }
  if (w == 0 || h == 0 || w > kMaxImageSide || h > kMaxImageSide) {
    error = "--size: " + text + " is outside 1.." + std::to_string(kMaxImageSide) + " per side";
    return false;
  }
  return true;
}

bool parse_shard(const std::string& text, uint32_t& index, uint32_t& count, std::string& error) {
  const size_t slash = text.find('/');
  const auto number = [](std::string_view s, uint32_t& v) {
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && end == s.data() + s.size();
  };
  if (slash == std::string::npos || !number(std::string_view(text).substr(0, slash), index) ||
      !number(std::string_view(text).substr(slash + 1), count) || count == 0 || index >= count) {
    error = "--shard: expected I/N with 0 <= I < N, got '" + text + "'";
    return false;
  }
  return true;
}

bool read_text(const std::string& path, std::string& out, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot read " + path;
    return false;
  }
  std::ostringstream s;
  s << in.rdbuf();
  out = s.str();
  return true;
}

// Seconds since this process was created, or a negative number when /proc cannot be read. The
// kernel's start time (/proc/self/stat, field 22) is taken at fork, in clock ticks (10 ms) of
// CLOCK_BOOTTIME, rounded down; so this includes exec, loading the program's libraries and
// their constructors (the user's wait before main), and reads up to one tick too much.
double seconds_since_process_start() {
  std::ifstream in("/proc/self/stat");
  std::string stat;
  std::getline(in, stat);
  // Field 2, the command name, is in parentheses and may hold spaces: count from its end.
  const size_t name_end = stat.rfind(')');
  if (name_end == std::string::npos) return -1;
  std::istringstream fields(stat.substr(name_end + 1));
  std::string field;
  for (int i = 3; i <= 22 && fields >> field; ++i) {}  // fields 3 (state) .. 22 (starttime)
  unsigned long long start_ticks = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), start_ticks);
  const long ticks_per_s = ::sysconf(_SC_CLK_TCK);
  timespec now{};
  if (ec != std::errc() || end != field.data() + field.size() || ticks_per_s <= 0 ||
      ::clock_gettime(CLOCK_BOOTTIME, &now) != 0)
    return -1;
  return double(now.tv_sec) + double(now.tv_nsec) * 1e-9 -
         double(start_ticks) / double(ticks_per_s);
}

int fail(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 1;
}

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

struct RenderArgs {
  std::string store, camera, path, views, out, size = "1280x720", lod_policy = "screen-space",
                                               shard = "0/1", format = "png", occlusion = "on",
                                               occlusion_test = "automatic";
  double pixel_error = kStillPixelError;  // render.h: stills are read closely
  uint64_t vertex_budget_mb = 512;
  int device = -1, quality = 90;
  uint32_t samples = 0;
  std::string antialias = "automatic", highlight;
  bool no_centrelines = false, no_hlod = false, no_subpixel = false, force = false;
  bool no_ground = false, no_ambient_occlusion = false;
};

// "off" or an AntialiasMethod's name.
bool parse_antialias(const std::string& name, RenderOptions& options) {
  if (name == "off") {
    options.antialias = false;
    return true;
  }
  for (AntialiasMethod m : {AntialiasMethod::automatic, AntialiasMethod::multisampling,
                            AntialiasMethod::supersampling, AntialiasMethod::edge_filter}) {
    if (name == antialias_method_name(m)) {
      options.antialias = true;
      options.antialias_method = m;
      return true;
    }
  }
  return false;
}

// An OcclusionTest's name.
bool parse_occlusion_test(const std::string& name, OcclusionTest& test) {
  for (OcclusionTest t : {OcclusionTest::automatic, OcclusionTest::coarse, OcclusionTest::exact}) {
    if (name == occlusion_test_name(t)) {
      test = t;
      return true;
    }
  }
  return false;
}

// "ID,ID,...": decimal store ids.
bool parse_ids(const std::string& text, std::vector<uint64_t>& ids, std::string& error) {
  size_t begin = 0;
  while (begin <= text.size()) {
    const size_t end = std::min(text.find(',', begin), text.size());
    uint64_t id = 0;
    const auto [last, ec] = std::from_chars(text.data() + begin, text.data() + end, id);
    if (ec != std::errc() || last != text.data() + end || end == begin) {
      error = "--highlight: expected decimal object ids separated by commas, got '" + text + "'";
      return false;
    }
    ids.push_back(id);
    begin = end + 1;
  }
  return true;
}

// What the command line asks for, typed and checked. Every usage error is found while making it,
// before any file is read or written.
struct RenderPlan {
  enum class Mode { single, path, views } mode = Mode::single;
  uint32_t width = 0, height = 0, shard_index = 0, shard_count = 1;
  RenderOptions options;
  ImageFormat format = ImageFormat::png;
  std::optional<Camera> camera;  // single: the camera given, else the plant's default
};

// 0, or the exit status of the usage error it printed.
int plan_render(const RenderArgs& a, RenderPlan& plan) {
  std::string error;
  if (!parse_size(a.size, plan.width, plan.height, error) ||
      !parse_shard(a.shard, plan.shard_index, plan.shard_count, error))
    return usage_error(error);
  if (!parse_lod_policy(a.lod_policy, plan.options.lod_policy))
    return usage_error("--lod-policy: '" + a.lod_policy + "' is not one of screen-space, distance, none");
  if (a.quality < 1 || a.quality > 100)
    return usage_error("--quality: " + std::to_string(a.quality) + " is outside 1..100");
  plan.options.pixel_error = a.pixel_error;
  plan.options.vertex_budget_bytes = a.vertex_budget_mb << 20;
  plan.options.centrelines = !a.no_centrelines;
  plan.options.hlod = !a.no_hlod;
  plan.options.subpixel_culling = !a.no_subpixel;
  plan.options.occlusion = a.occlusion == "on";
  if (!parse_occlusion_test(a.occlusion_test, plan.options.occlusion_test))
    return usage_error("--occlusion-test: '" + a.occlusion_test + "' is not one of automatic, coarse, exact");
  plan.options.samples = a.samples;
  if (!parse_antialias(a.antialias, plan.options))
    return usage_error("--antialias: '" + a.antialias +
                       "' is not one of automatic, multisampling, supersampling, edge-filter, off");
  plan.options.ground = !a.no_ground;
  plan.options.ambient_occlusion = !a.no_ambient_occlusion;
  if (!a.highlight.empty() && !parse_ids(a.highlight, plan.options.highlight_ids, error))
    return usage_error(error);
  if (int(!a.camera.empty()) + int(!a.path.empty()) + int(!a.views.empty()) > 1)
    return usage_error("give one of --camera, --path and --views");
  if (!a.camera.empty()) {
    Camera camera;
    if (!parse_camera(a.camera, camera, error)) return usage_error("--camera: " + error);
    plan.camera = camera;
  }
  plan.mode = !a.path.empty()    ? RenderPlan::Mode::path
              : !a.views.empty() ? RenderPlan::Mode::views
                                 : RenderPlan::Mode::single;
  if (plan.mode == RenderPlan::Mode::single) {
    if (!image_format_from_name(a.out, plan.format))
      return usage_error("--out: " + a.out +
                         ": use a .png, .jpg or .jpeg name (or a directory with --path or --views)");
    return 0;
  }
  // Many images: --out is a directory, never an image file's name.
  const char* with = plan.mode == RenderPlan::Mode::path ? "--path" : "--views";
  if (!image_format_from_name(a.format, plan.format))
    return usage_error("--format: '" + a.format + "' is not png or jpeg");
  ImageFormat named;
  const std::string extension = fs::path(a.out).extension().string();
  if (!extension.empty() && image_format_from_name(extension, named))
    return usage_error("--out: " + a.out + " names an image file; with " + std::string(with) +
                       " give the directory the images go into");
  std::error_code ec;
  if (fs::exists(a.out, ec) && !fs::is_directory(a.out, ec))
    return usage_error("--out: " + a.out + " is a file; with " + std::string(with) +
                       " give the directory the images go into");
  return 0;
}

// The directory a single image goes into must exist and take files, checked before rendering.
bool check_image_destination(const std::string& out, std::string& error) {
  const fs::path parent = fs::path(out).parent_path().empty() ? fs::path(".") : fs::path(out).parent_path();
  std::error_code ec;
  if (!fs::is_directory(parent, ec)) {
    error = "--out: the directory " + parent.string() + " (of " + out + ") does not exist";
    return false;
  }
  return farm::prepare_output_dir(parent, error);
}

// Encodes `image` and writes it atomically (farm/output_dir.h); stats.ms.encode gets the time.
bool write_image_file(const fs::path& path, const Image& image, ImageFormat format, int quality,
                      FrameStats& stats, std::string& error) {
  const auto t_encode = std::chrono::steady_clock::now();
  std::vector<uint8_t> bytes;
  if (!encode_image(image, format, quality, bytes, error)) return false;
  if (!farm::write_file_atomically(
          path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), error))
    return false;
  stats.ms.encode = ms_since(t_encode);
  return true;
}

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
                     RenderSession& session, std::string& error) {
  session.context = GpuContext::create(device, error);
  if (!session.context) return false;
  // Images are needed from here on. Not before the context: EGL loads its drivers (libLLVM for
  // llvmpipe) under the dynamic loader's lock, which loading the module holds throughout. So
  // does libepoxy at the first call of each GL function: those calls wait for the load too.
  preload_image_io();
  std::cerr << "plantview: rendering on " << session.context->description() << "\n";
  session.renderer = Renderer::create(store, options, error);
  return session.renderer != nullptr;
}

void report_first_image(std::chrono::steady_clock::time_point t_start) {
  const double since_process = seconds_since_process_start();
  if (since_process >= 0) {
    std::cerr << "plantview: first image written " << since_process << " s after start\n";
  } else {
    std::cerr << "plantview: first image written " << ms_since(t_start) / 1000.0
              << " s after the command started (no process start time in /proc)\n";
  }
}

// `render` with --camera (or none) or --path: one image, or a directory of numbered images.
int render_cameras(const RenderArgs& a, const RenderPlan& plan) {
  const auto t_start = std::chrono::steady_clock::now();
  std::string error;
  const bool many = plan.mode == RenderPlan::Mode::path;
  std::vector<Camera> cameras;
  if (many) {
    std::string json;
    if (!read_text(a.path, json, error) || !parse_camera_path(json, cameras, error))
      return fail(a.path + ": " + error);
  } else if (plan.camera) {
    cameras.push_back(*plan.camera);
  }
  if (!(many ? farm::prepare_output_dir(a.out, error) : check_image_destination(a.out, error)))
    return fail(error);

  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  RenderSession session;
  if (!start_rendering(a.device, *store, plan.options, session, error)) return fail(error);
  if (cameras.empty())
    cameras.push_back(default_camera(overview_boxes(session.renderer->read_view()), double(plan.width) / plan.height));

  std::ofstream stats_file;
  if (many) {
    stats_file.open(fs::path(a.out) / "stats.jsonl");
    if (!stats_file) return fail("cannot write " + (fs::path(a.out) / "stats.jsonl").string());
  }
  Progress progress("render");
  FrameStats stats;
  size_t done = 0, total = 0;
  for (size_t i = plan.shard_index; i < cameras.size(); i += plan.shard_count) ++total;
  // Each image is encoded and written while the next view renders; its stats line follows
  // in view order once it is written. The first image that cannot be written stops the run.
  std::string write_error;
  ImageWriter writer(plan.format, a.quality);
  for (size_t i = plan.shard_index; i < cameras.size() && write_error.empty(); i += plan.shard_count) {
    Image image = writer.take_buffer();
    if (i + plan.shard_count < cameras.size()) session.renderer->expect(cameras[i + plan.shard_count]);
    if (!session.renderer->render(cameras[i], plan.width, plan.height, false, image, stats, error))
      return fail("view " + std::to_string(i) + ": " + error);
    std::string file = a.out;
    if (many) {
      char name[64];
      std::snprintf(name, sizeof name, "%06zu.%s", i, plan.format == ImageFormat::png ? "png" : "jpg");
      file = (fs::path(a.out) / name).string();
    }
    writer.write(file, std::move(image), stats, [&, i, file](ImageToWrite& written) {
      if (!write_error.empty()) return;
      if (!written.ok) {
        write_error = written.error;
        return;
      }
      std::string line = written.stats.to_json();
      line.insert(1, "\"view\":" + std::to_string(i) + ",\"file\":\"" + file + "\",");
      if (many) stats_file << line << "\n";
      else std::cout << line << "\n";
      if (done == 0 && !many) report_first_image(t_start);
      ++done;
      progress.update(double(done) / double(total), std::to_string(done) + "/" + std::to_string(total));
    });
  }
  writer.finish();
  progress.finish();
  if (!write_error.empty()) return fail(write_error);
  return 0;
}

// ---------------------------------------------------------------------------------------------
// render --views: the farm's shard (farm/scheduler.h states the contract).

// The caption lines of a view: each attribute as "Key value" ("Tag P-101A", "Type PUMP").
std::vector<std::string> caption_lines(const ReviewView& view) {
  std::vector<std::string> lines;
  for (const auto& [key, value] : view.attributes) {
    if (value.empty()) continue;
    std::string label = key;
    if (!label.empty()) label[0] = char(std::toupper(static_cast<unsigned char>(label[0])));
    lines.push_back(label + " " + value);
  }
  return lines;
}

// The options one view renders with: its subject highlighted, the rest ghosted (an overview's
// empty subject highlights nothing).
RenderOptions review_render_options(const RenderOptions& base, const ReviewView& view) {
  RenderOptions options = base;
  options.highlight_ids = view.subject;
  return options;
}

// Draws the view's caption strip (title, then caption_lines) into the image.
bool add_review_caption(Image& image, const ReviewView& view, std::string& error) {
  return add_caption(image, view.title, caption_lines(view), error);
}

// What, besides the view and the store's content, an image depends on (the settings hash).
std::string render_settings_text(const RenderArgs& a, const RenderPlan& plan) {
  const nlohmann::json settings = {
      {"program", PLANTVIEW_VERSION},
      {"size", std::to_string(plan.width) + "x" + std::to_string(plan.height)},
      {"format", plan.format == ImageFormat::png ? "png" : "jpeg"},
      {"quality", plan.format == ImageFormat::jpeg ? a.quality : 0},
      {"lod_policy", std::string(lod_policy_name(plan.options.lod_policy))},
      {"pixel_error", plan.options.pixel_error},
      {"vertex_budget_bytes", plan.options.vertex_budget_bytes},
      {"centrelines", plan.options.centrelines},
      {"hlod", plan.options.hlod},
      {"subpixel_culling", plan.options.subpixel_culling},
      {"samples", plan.options.samples},
      {"antialias", plan.options.antialias},
      {"antialias_method", std::string(antialias_method_name(plan.options.antialias_method))},
      {"ground", plan.options.ground},
      {"ambient_occlusion", plan.options.ambient_occlusion},
      {"caption", true}};
  return settings.dump();
}

nlohmann::json vec3_json(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

nlohmann::json view_record(const ReviewView& view, const std::string& file, const std::string& hash,
                           const RenderPlan& plan) {
  return {{"name", view.name},
          {"title", view.title},
          {"kind", view.kind},
          {"file", file},
          {"camera",
           {{"eye", vec3_json(view.camera.eye_m)},
            {"target", vec3_json(view.camera.target_m)},
            {"up", vec3_json(view.camera.up)},
            {"fov_deg", view.camera.fov_deg}}},
          {"aspect", view.aspect},
          {"subject", view.subject},
          {"settings_hash", hash},
          {"shard", std::to_string(plan.shard_index) + "/" + std::to_string(plan.shard_count)}};
}

int render_views(const RenderArgs& a, const RenderPlan& plan) {
  std::string error, text;
  const fs::path out = a.out;
  std::vector<ReviewView> views;
  // Everything that can be refused is checked before the first image.
  if (!farm::read_views_file(a.views, views, text, error)) return fail(error);
  if (!farm::prepare_output_dir(out, error)) return fail(error);
  const auto t_open = std::chrono::steady_clock::now();
  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  auto read = store->read(error);
  if (!read) return fail(error);
  const double store_open_ms = ms_since(t_open);
  if (!farm::check_subjects(views, *read, error)) return fail(a.views + ": " + error);
  std::error_code ec;
  if (!fs::equivalent(a.views, out / farm::kViewsCopyName, ec) &&
      !farm::write_file_atomically(out / farm::kViewsCopyName, text, error))
    return fail(error);

  // Which of this shard's views are done already with the same settings.
  std::map<std::string, nlohmann::json> previous;
  if (!farm::read_newest_records(out, previous, error)) return fail(error);
  const std::string identity = farm::store_identity(*read) + "\n" + render_settings_text(a, plan) + "\n";
  read.reset();
  const char* extension = plan.format == ImageFormat::png ? ".png" : ".jpg";
  std::vector<nlohmann::json> records;
  std::vector<size_t> to_render;
  std::vector<std::string> hashes(views.size());
  for (size_t i = plan.shard_index; i < views.size(); i += plan.shard_count) {
    hashes[i] = farm::hash_hex(identity + review_views_json({views[i]}, views[i].kind));
    const auto found = previous.find(views[i].name);
    if (!a.force && found != previous.end() && found->second.value("status", "") == "done" &&
        found->second.value("settings_hash", "") == hashes[i] &&
        fs::is_regular_file(out / found->second.value("file", ""), ec)) {
      records.push_back(found->second);  // kept in this shard's part when it is written again
    } else {
      to_render.push_back(i);
    }
  }
  const size_t skipped = records.size();

  size_t failed = 0;
  if (!to_render.empty()) {
    const auto t_context = std::chrono::steady_clock::now();
    RenderSession session;
    if (!start_rendering(a.device, *store, plan.options, session, error)) return fail(error);
    const double context_ms = ms_since(t_context);
    Progress progress("render");
    // Each view's image is encoded and written while the next renders; its record follows in
    // the shard's order once written.
    std::string manifest_error;
    ImageWriter writer(plan.format, a.quality);
    for (size_t n = 0; n < to_render.size() && manifest_error.empty(); ++n) {
      const ReviewView& view = views[to_render[n]];
      const auto t_view = std::chrono::steady_clock::now();
      const std::string file = view.name + extension;
      auto record = std::make_shared<nlohmann::json>(view_record(view, file, hashes[to_render[n]], plan));
      FrameStats stats;
      Image image = writer.take_buffer();
      session.renderer->set_options(review_render_options(plan.options, view));
      if (n + 1 < to_render.size()) session.renderer->expect(views[to_render[n + 1]].camera);
      bool ok = session.renderer->render(view.camera, plan.width, plan.height, false, image, stats, error);
      const auto t_caption = std::chrono::steady_clock::now();
      ok = ok && add_review_caption(image, view, error);
      const double caption_ms = ms_since(t_caption);
      // Recorded once written (or at once, failed).
      const auto finish_view = [&, n, t_view, caption_ms, record](bool written, const std::string& why,
                                                                 const FrameStats& frame) {
        (*record)["status"] = written ? "done" : "failed";
        if (!written) {
          (*record)["error"] = why;
          std::cerr << "plantview: view '" << views[to_render[n]].name << "': " << why << "\n";
          ++failed;
        }
        (*record)["stats"] = nlohmann::json::parse(frame.to_json());
        (*record)["ms"] = {{"store_open", store_open_ms},  {"context", context_ms},
                           {"first_in_process", n == 0}, {"frame", frame.ms.total},
                           {"caption", caption_ms},       {"encode", frame.ms.encode},
                           {"total", ms_since(t_view)}};
        (*record)["finished_unix_ms"] = farm::unix_ms_now();
        records.push_back(std::move(*record));
        // The part lists every view this shard finished, so a killed task loses only the
        // views it was rendering and writing.
        if (manifest_error.empty() &&
            !farm::write_manifest_part(out, plan.shard_index, plan.shard_count, records, manifest_error) &&
            manifest_error.empty())
          manifest_error = "cannot write the manifest part";
        progress.update(double(n + 1) / double(to_render.size()),
                        std::to_string(n + 1) + "/" + std::to_string(to_render.size()) + " " +
                            views[to_render[n]].name);
      };
      if (!ok) {
        writer.finish();  // the views before it first, in order
        finish_view(false, error, stats);
        continue;
      }
      writer.write(out / file, std::move(image), stats, [finish_view](ImageToWrite& written) {
        finish_view(written.ok, written.error, written.stats);
      });
    }
    writer.finish();
    progress.finish();
    if (!manifest_error.empty()) return fail(manifest_error);
  } else if (!farm::write_manifest_part(out, plan.shard_index, plan.shard_count, records, error)) {
    return fail(error);
  }
  farm::FarmSummary summary;
  if (!farm::merge_manifests(out, summary, error)) return fail(error);
  std::cout << nlohmann::json{{"shard", std::to_string(plan.shard_index) + "/" + std::to_string(plan.shard_count)},
                              {"views", to_render.size() + skipped},
                              {"rendered", to_render.size() - failed},
                              {"skipped", skipped},
                              {"failed", failed},
                              {"job", farm::summary_json(summary)}}
                   .dump()
            << "\n";
  return failed == 0 ? 0 : 1;
}

int run_render(const RenderArgs& a) {
  RenderPlan plan;
  if (const int status = plan_render(a, plan); status != 0) return status;
  return plan.mode == RenderPlan::Mode::views ? render_views(a, plan) : render_cameras(a, plan);
}

int run_path(const std::string& store_dir, const std::string& kind_name, int frames,
             const std::string& out) {
  std::string error;
  PathKind kind;
  if (!parse_path_kind(kind_name, kind))
    return usage_error("--kind: '" + kind_name + "' is not walkthrough or orbit");
  if (frames < 1 || frames > 1000000)
    return usage_error("--frames: " + std::to_string(frames) + " is outside 1..1000000");
  if (!check_image_destination(out, error)) return fail(error);
  auto store = Store::open(store_dir, Store::Mode::read_only, error);
  if (!store) return fail(error);
  std::vector<Camera> cameras;
  {
    Progress progress("path: reading the equipment");
    const auto shown = [&](double fraction) { progress.update(fraction); };
    if (!make_camera_path(kind, frames, *store, cameras, error, shown)) return fail(error);
  }
  if (!farm::write_file_atomically(out, camera_path_json(cameras), error)) return fail(error);
  return 0;
}

// The options of `plantview render` onto `render`, into `args`.
void add_render_options(CLI::App* render, RenderArgs* args) {
  render->add_option("--store", args->store, "Store directory")->required();
  render->add_option("--camera", args->camera,
                     "eye=X,Y,Z,target=X,Y,Z[,up=X,Y,Z][,fov=DEG] (default: the whole plant)");
  render->add_option("--path", args->path, "Camera path JSON (from `plantview path`)");
  render->add_option("--views", args->views,
                     "Views file (from `plantview views`): named review images, a manifest and a "
                     "contact sheet into the --out directory");
  render->add_option("--out", args->out, "Image file (.png/.jpg), or a directory with --path or --views")
      ->required();
  render->add_option("--size", args->size, "Image size WxH")->capture_default_str();
  render->add_option("--lod-policy", args->lod_policy, "screen-space, distance or none")->capture_default_str();
  render->add_option("--pixel-error", args->pixel_error, "Allowed screen-space error (pixels)")->capture_default_str();
  render->add_option("--vertex-budget", args->vertex_budget_mb, "GPU vertex arena (MB)")->capture_default_str();
  render->add_option("--shard", args->shard, "Render views I, I+N, I+2N... of a path or views file")
      ->capture_default_str();
  render->add_option("--format", args->format, "Image format with --path or --views: png or jpeg")
      ->capture_default_str();
  render->add_flag("--force", args->force,
                   "With --views: render every view again, also those done with the same settings");
  render->add_option("--quality", args->quality, "JPEG quality 1..100")->capture_default_str();
  render->add_option("--device", args->device, "EGL device index (default: the first GPU, else software)");
  render->add_flag("--no-centrelines", args->no_centrelines, "Never draw thin pipes as lines");
  render->add_flag("--no-hlod", args->no_hlod, "Never merge pipeline runs");
  render->add_flag("--no-subpixel-culling", args->no_subpixel, "Draw objects under the pixel error too");
  render->add_option("--antialias", args->antialias,
                     "automatic (multisampling on a GPU, 2x2 supersampling on a software renderer), "
                     "multisampling, supersampling, edge-filter or off")
      ->capture_default_str();
  render->add_option("--occlusion", args->occlusion, "Leave out objects hidden behind large ones: on or off")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  render->add_option("--occlusion-test", args->occlusion_test,
                     "How what the first phase did not draw is tested: automatic (exact on a GPU, "
                     "coarse on a software renderer), coarse or exact")
      ->capture_default_str();
  render->add_option("--samples", args->samples,
                     "Multisampling samples per pixel (1: none; default 4 where multisampling is used)")
      ->check(CLI::Range(1u, 16u));
  render->add_flag("--no-ground", args->no_ground, "No ground grid under the plant");
  render->add_flag("--no-ambient-occlusion", args->no_ambient_occlusion, "No screen-space ambient occlusion");
  render->add_option("--highlight", args->highlight,
                     "ID,...: draw these objects in their colours and the rest ghosted, see-through "
                     "where it hides them (with --views: each view's subject)");
}

}  // namespace

int check_render_options(const std::vector<std::string>& passed, const std::string& views,
                         const std::string& out) {
  CLI::App render("render options");
  RenderArgs args;
  add_render_options(&render, &args);
  std::vector<std::string> words = {"--store", "-", "--views", views, "--out", out};
  words.insert(words.end(), passed.begin(), passed.end());
  std::reverse(words.begin(), words.end());  // (CLI11 takes the words last first)
  try {
    render.parse(words);
  } catch (const CLI::ParseError& e) {
    return usage_error(e.what());
  }
  RenderPlan plan;
  return plan_render(args, plan);
}

Action add_render_commands(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  auto* render = app.add_subcommand("render", "Render review images of a store");
  add_render_options(render, args.get());

  auto path_store = std::make_shared<std::string>(), path_kind = std::make_shared<std::string>("walkthrough"),
       path_out = std::make_shared<std::string>();
  auto frames = std::make_shared<int>(120);
  auto* path = app.add_subcommand("path", "Make a camera path through a store's plant");
  path->add_option("--store", *path_store, "Store directory")->required();
  path->add_option("--kind", *path_kind, "walkthrough or orbit")->capture_default_str();
  path->add_option("--frames", *frames, "Number of views")->capture_default_str();
  path->add_option("--out", *path_out, "Camera path JSON file")->required();

  return [=]() -> int {
    if (render->parsed()) return run_render(*args);
    if (path->parsed()) return run_path(*path_store, *path_kind, *frames, *path_out);
    return -1;
  };
}

}  // namespace plantview::cli
