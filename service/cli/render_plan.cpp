// `plantview render`'s command line: its options, typed and checked before anything is read or
// written (render_run.h); --highlight's words resolved against the store.
#include <charconv>

#include "cli/commands.h"
#include "cli/render_run.h"
#include "server/object_words.h"

namespace plantview::cli::rendering {

namespace {

// `s` is a whole number, all of it.
bool number(std::string_view s, uint32_t& v) {
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size();
}

bool parse_size(const std::string& text, uint32_t& w, uint32_t& h, std::string& error) {
  const size_t x = text.find('x');
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
  if (slash == std::string::npos || !number(std::string_view(text).substr(0, slash), index) ||
      !number(std::string_view(text).substr(slash + 1), count) || count == 0 || index >= count) {
    error = "--shard: expected I/N with 0 <= I < N, got '" + text + "'";
    return false;
  }
  return true;
}

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

// "WORD,WORD,...": ids or tags, none empty.
bool split_highlight(const std::string& text, std::vector<std::string>& words, std::string& error) {
  size_t begin = 0;
  while (begin <= text.size()) {
    const size_t end = std::min(text.find(',', begin), text.size());
    if (end == begin) {
      error = "--highlight: expected object ids or tags separated by commas, got '" + text + "'";
      return false;
    }
    words.push_back(text.substr(begin, end - begin));
    begin = end + 1;
  }
  return true;
}

}  // namespace

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
  if (!a.highlight.empty() && !split_highlight(a.highlight, plan.highlight, error))
    return usage_error(error);
  plan.options.style.colour_by = a.colour_by;
  if ((!a.hide.empty() && !parse_word_list(a.hide, "--hide", plan.options.style.hide, error)) ||
      (!a.only.empty() && !parse_word_list(a.only, "--only", plan.options.style.only, error)))
    return usage_error(error);
  if (!parse_section_options(a.clip, a.section_box, plan.options.section, error)) return usage_error(error);
  if (!a.changes.empty()) {
    ChangeRange range;
    if (!parse_change_range(a.changes, range, error)) return usage_error("--changes: " + error);
    plan.options.changes = range;
  }
  plan.options.section.capped = !a.no_caps;
  if (int(!a.camera.empty()) + int(!a.path.empty()) + int(!a.views.empty()) > 1)
    return usage_error("give one of --camera, --path and --views");
  if (!a.camera.empty()) {
    Camera camera;
    if (!parse_camera(a.camera, camera, error)) return usage_error("--camera: " + error);
    plan.camera = camera;
  }
  if (!a.bcf.empty() && a.views.empty()) return usage_error("--bcf goes with --views");
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

bool resolve_highlight(const ReadView& view, const std::vector<std::string>& words,
                       std::vector<uint64_t>& ids, std::string& error, bool& usage) {
  return ids_of_words(view, words, "--highlight", ids, error, usage);
}

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
  render->add_option("--clip", args->clip,
                     "Clip plane PX,PY,PZ,NX,NY,NZ: removes what lies on the side the normal "
                     "points into (repeatable, at most 6; a leading minus: --clip=-5,...)");
  render->add_option("--section-box", args->section_box,
                     "Section box MINX,MINY,MINZ,MAXX,MAXY,MAXZ: keeps what lies inside");
  render->add_flag("--no-caps", args->no_caps, "Leave the cut faces of sectioned solids open");
  render->add_option("--highlight", args->highlight,
                     "ID or TAG,...: draw these objects in their colours and the rest ghosted, "
                     "see-through where it hides them (with --views: each view's subject)");
  render->add_option("--bcf", args->bcf,
                     "With --views: a BCF 2.1 file of the views and their images, written once every "
                     "view of the job is rendered");
  render->add_option("--colour-by", args->colour_by,
                     "KEY: colour objects by this attribute (categories, or a ramp for numbers "
                     "with a unit), with a legend strip; with --views it replaces the views' own");
  render->add_option("--changes", args->changes,
                     "R1 or R1..R2: a change image of what changed after revision R1 (added green, "
                     "modified amber over their previous shape, removed as red ghosts), with a "
                     "caption; R2, if given, must be the store's revision (with --views: replaces "
                     "the views' own)");
  render->add_option("--hide", args->hide,
                     "CLASS|GLOB,...: leave out these classes (equipment, pipeline, pipe, component, "
                     "structure, other) and objects whose name or Tag matches a glob");
  render->add_option("--only", args->only,
                     "CLASS|GLOB,...: show only these classes and objects whose name or Tag matches");
}

}  // namespace plantview::cli::rendering
