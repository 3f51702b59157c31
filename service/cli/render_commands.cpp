// `plantview render` and `path`: review images and camera paths.
#include <cstdio>
#include <fstream>
#include <iostream>

#include "cli/commands.h"
#include "cli/farm/output_dir.h"
#include "cli/progress.h"
#include "cli/render_run.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

using namespace rendering;

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
  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  RenderOptions options = plan.options;
  if (!plan.highlight.empty()) {
    auto read = store->read(error);
    if (!read) return fail(error);
    bool usage = false;
    if (!resolve_highlight(*read, plan.highlight, options.highlight_ids, error, usage))
      return usage ? usage_error(error) : fail(error);
  }
  if (!(many ? farm::prepare_output_dir(a.out, error) : check_image_destination(a.out, error)))
    return fail(error);

  RenderSession session;
  if (!start_rendering(a.device, *store, options, session, error)) return fail(error);
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
    if (stats.changes.shown) {
      // A change image: what it shows, with its legend, in a strip along the bottom.
      std::vector<CaptionColumn> columns;
      add_legend_columns(stats.legend, 3, columns, false);
      std::string why;
      if (!add_caption_columns(image, change_caption(stats.changes), columns, why))
        std::cerr << "plantview: view " << i << ": no caption: " << why << "\n";
    } else if (!stats.legend.key.empty()) {
      // Coloured by an attribute: its legend in a strip along the bottom (a still without it
      // would not say what its colours mean). An image too small for it goes without.
      // In columns of 4 lines, the key's name as the title.
      std::vector<CaptionColumn> columns;
      add_legend_columns(stats.legend, 4, columns, false);
      std::string why;
      if (!add_caption_columns(image, "Colour by " + stats.legend.key, columns, why))
        std::cerr << "plantview: view " << i << ": no legend: " << why << "\n";
    }
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
