// `plantview render` and `path`: review images and camera paths.
#include <time.h>
#include <unistd.h>

#include <charconv>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "cli/commands.h"
#include "cli/progress.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

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

struct RenderArgs {
  std::string store, camera, path, out, size = "1280x720", lod_policy = "screen-space",
                                        shard = "0/1", format = "png", occlusion = "on";
  double pixel_error = 1.0;
  uint64_t vertex_budget_mb = 512;
  int device = -1, quality = 90;
  uint32_t samples = 0;
  bool no_centrelines = false, no_hlod = false, no_subpixel = false;
};

int run_render(const RenderArgs& a) {
  const auto t_start = std::chrono::steady_clock::now();
  std::string error;
  uint32_t width = 0, height = 0, shard_index = 0, shard_count = 1;
  RenderOptions options;
  if (!parse_size(a.size, width, height, error) || !parse_shard(a.shard, shard_index, shard_count, error))
    return fail(error);
  if (!parse_lod_policy(a.lod_policy, options.lod_policy))
    return fail("--lod-policy: '" + a.lod_policy + "' is not one of screen-space, distance, none");
  options.pixel_error = a.pixel_error;
  options.vertex_budget_bytes = a.vertex_budget_mb << 20;
  options.centrelines = !a.no_centrelines;
  options.hlod = !a.no_hlod;
  options.subpixel_culling = !a.no_subpixel;
  options.occlusion = a.occlusion == "on";
  options.samples = a.samples;
  if (!a.camera.empty() && !a.path.empty()) return fail("give --camera or --path, not both");

  std::vector<Camera> cameras;
  if (!a.path.empty()) {
    std::string json;
    if (!read_text(a.path, json, error) || !parse_camera_path(json, cameras, error))
      return fail(a.path + ": " + error);
  } else if (!a.camera.empty()) {
    Camera c;
    if (!parse_camera(a.camera, c, error)) return fail("--camera: " + error);
    cameras.push_back(c);
  }
  ImageFormat format = ImageFormat::png;
  const bool many = !a.path.empty();
  if (many) {
    if (!image_format_from_name(a.format, format)) return fail("--format: png or jpeg");
    std::error_code ec;
    std::filesystem::create_directories(a.out, ec);
    if (ec) return fail("cannot create " + a.out + ": " + ec.message());
  } else if (!image_format_from_name(a.out, format)) {
    return fail("--out: " + a.out + ": use a .png, .jpg or .jpeg name (or --path with a directory)");
  }

  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  auto context = GpuContext::create(a.device, error);
  if (!context) return fail(error);
  // Images are needed from here on. Not before the context: EGL loads its drivers (libLLVM for
  // llvmpipe) under the dynamic loader's lock, which loading the module holds throughout. So
  // does libepoxy at the first call of each GL function: those calls wait for the load too.
  preload_image_io();
  std::cerr << "plantview: rendering on " << context->description() << "\n";
  auto renderer = Renderer::create(*store, options, error);
  if (!renderer) return fail(error);
  if (cameras.empty()) cameras.push_back(default_camera(renderer->model_bounds(), double(width) / height));

  std::ofstream stats_file;
  if (many) {
    stats_file.open(std::filesystem::path(a.out) / "stats.jsonl");
    if (!stats_file) return fail("cannot write " + (std::filesystem::path(a.out) / "stats.jsonl").string());
  }
  Progress progress("render");
  Image image;
  FrameStats stats;
  size_t done = 0, total = 0;
  for (size_t i = shard_index; i < cameras.size(); i += shard_count) ++total;
  for (size_t i = shard_index; i < cameras.size(); i += shard_count) {
    if (!renderer->render(cameras[i], width, height, false, image, stats, error))
      return fail("view " + std::to_string(i) + ": " + error);
    const auto t_encode = std::chrono::steady_clock::now();
    std::string file = a.out;
    if (many) {
      char name[64];
      std::snprintf(name, sizeof name, "%06zu.%s", i, format == ImageFormat::png ? "png" : "jpg");
      file = (std::filesystem::path(a.out) / name).string();
    }
    if (!write_image(file, image, a.quality, error)) return fail(error);
    stats.ms.encode = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_encode).count();
    std::string line = stats.to_json();
    line.insert(1, "\"view\":" + std::to_string(i) + ",\"file\":\"" + file + "\",");
    if (many) stats_file << line << "\n";
    else std::cout << line << "\n";
    if (done == 0 && !many) {
      const double since_process = seconds_since_process_start();
      if (since_process >= 0) {
        std::cerr << "plantview: first image written " << since_process << " s after start\n";
      } else {
        const double since_command =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
        std::cerr << "plantview: first image written " << since_command
                  << " s after the command started (no process start time in /proc)\n";
      }
    }
    ++done;
    progress.update(double(done) / double(total), std::to_string(done) + "/" + std::to_string(total));
  }
  progress.finish();
  return 0;
}

int run_path(const std::string& store_dir, const std::string& kind_name, int frames,
             const std::string& out) {
  std::string error;
  PathKind kind;
  if (!parse_path_kind(kind_name, kind)) return fail("--kind: walkthrough or orbit");
  if (frames < 1 || frames > 1000000) return fail("--frames: 1..1000000");
  auto store = Store::open(store_dir, Store::Mode::read_only, error);
  if (!store) return fail(error);
  std::vector<Camera> cameras;
  if (!make_camera_path(kind, frames, *store, cameras, error)) return fail(error);
  std::ofstream file(out);
  if (!file) return fail("cannot write " + out);
  file << camera_path_json(cameras);
  if (!file.flush()) return fail("writing " + out + " failed");
  return 0;
}

}  // namespace

Action add_render_commands(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  auto* render = app.add_subcommand("render", "Render review images of a store");
  render->add_option("--store", args->store, "Store directory")->required();
  render->add_option("--camera", args->camera,
                     "eye=X,Y,Z,target=X,Y,Z[,up=X,Y,Z][,fov=DEG] (default: the whole plant)");
  render->add_option("--path", args->path, "Camera path JSON (from `plantview path`)");
  render->add_option("--out", args->out, "Image file (.png/.jpg), or a directory with --path")->required();
  render->add_option("--size", args->size, "Image size WxH")->capture_default_str();
  render->add_option("--lod-policy", args->lod_policy, "screen-space, distance or none")->capture_default_str();
  render->add_option("--pixel-error", args->pixel_error, "Allowed screen-space error (pixels)")->capture_default_str();
  render->add_option("--vertex-budget", args->vertex_budget_mb, "GPU vertex arena (MB)")->capture_default_str();
  render->add_option("--shard", args->shard, "Render views I, I+N, I+2N... of a path")->capture_default_str();
  render->add_option("--format", args->format, "Image format with --path: png or jpeg")->capture_default_str();
  render->add_option("--quality", args->quality, "JPEG quality 1..100")->capture_default_str();
  render->add_option("--device", args->device, "EGL device index (default: the first GPU, else software)");
  render->add_flag("--no-centrelines", args->no_centrelines, "Never draw thin pipes as lines");
  render->add_flag("--no-hlod", args->no_hlod, "Never merge pipeline runs");
  render->add_flag("--no-subpixel-culling", args->no_subpixel, "Draw objects under the pixel error too");
  render->add_option("--occlusion", args->occlusion, "Leave out objects hidden behind large ones: on or off")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  render->add_option("--samples", args->samples,
                     "Multisampling per pixel (1: off; default: 4 on a GPU, 1 on a software renderer)")
      ->check(CLI::Range(1u, 16u));

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
