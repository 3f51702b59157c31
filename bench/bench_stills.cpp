// Stills: what each part of the look costs. One renderer renders the same views with each
// setting, round robin (the first round warms the arena and is not counted): aliased with the
// extras off (an interactive frame), antialiasing by each method, ambient occlusion, the
// ground, everything together (the still's defaults), and a highlight; and colour by an
// attribute (Material) against the still, each on a renderer of its own, then the first frame
// after a style change on a warm renderer (issue 41's goal: colour by adds at most 10%).
//
// Usage: bench_stills [--quick] [--section] [--store DIR] [--preset P] [--size WxH] [--repeats N]
//                     [--out DIR]
//   default   preset c (generated into a temporary directory unless --store names a store),
//             1280x720, the default camera and an interior view, 3 repeats each.
//   --quick   preset a, 320x180, 1 repeat (the CTest smoke run).
//   --section the section's frames alone (no table of settings).
//   --out     also writes each setting's image of each view there (view<N>-<setting>.png).
// Per setting: each view's fastest draw (draw + read back, ms) and frame (ms) over the repeats,
// averaged over the views, and the ratio of the frame time to the aliased one. Prints a table, then one "json: " line.
// Then a section: the default overview with the still's defaults, whole and cut to a 2 m plan
// slab (clip planes 1 m and 3 m above the plant's lowest point), the same renderer warm, the
// fastest frame of each over the repeats and their ratio (the goal: at most 0.5).
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace {

namespace fs = std::filesystem;
using namespace plantview;

struct Setting {
  const char* name;
  RenderOptions options;
  bool own_renderer = false;  // rendered by a renderer of its own, made with these options
};

// Colour by an attribute (RenderOptions::style) is measured on a renderer of its own: switching
// the style on the shared one would read every known object's attributes again each round
// (measured apart: the first frame after a style change).
constexpr const char* kColourByKey = "Material";

std::vector<Setting> settings(const std::vector<uint64_t>& subject) {
  RenderOptions plain;
  plain.antialias = false;
  plain.ground = false;
  plain.ambient_occlusion = false;
  std::vector<Setting> out;
  out.push_back({"aliased, no ground, no AO", plain});
  for (const auto& [name, method, samples] :
       {std::tuple{"multisampling x2", AntialiasMethod::multisampling, 2u},
        std::tuple{"multisampling x4", AntialiasMethod::multisampling, 4u},
        std::tuple{"supersampling 2x2", AntialiasMethod::supersampling, 0u},
        std::tuple{"edge filter", AntialiasMethod::edge_filter, 0u}}) {
    RenderOptions o = plain;
    o.antialias = true;
    o.antialias_method = method;
    o.samples = samples;
    out.push_back({name, o});
  }
  RenderOptions ao = plain;
  ao.ambient_occlusion = true;
  out.push_back({"ambient occlusion", ao});
  RenderOptions ground = plain;
  ground.ground = true;
  out.push_back({"ground", ground});
  out.push_back({"still (defaults)", RenderOptions{}});
  RenderOptions highlight;
  highlight.highlight_ids = subject;
  out.push_back({"still + highlight", highlight});
  // Both on renderers of their own (one that switches between settings pays for it).
  out.push_back({"still, own renderer", RenderOptions{}, true});
  RenderOptions coloured;
  coloured.style.colour_by = kColourByKey;
  out.push_back({"still + colour by", coloured, true});
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::string store_dir, out_dir;
  char preset = 'c';
  uint32_t width = 1280, height = 720;
  int repeats = 3;
  bool section_only = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_stills: %s needs a value\n", arg.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--section") {
      section_only = true;
    } else if (arg == "--quick") {
      preset = 'a';
      width = 320;
      height = 180;
      repeats = 1;
    } else if (arg == "--store") {
      store_dir = value();
    } else if (arg == "--preset") {
      preset = value()[0];
    } else if (arg == "--size") {
      if (std::sscanf(value().c_str(), "%ux%u", &width, &height) != 2) {
        std::fprintf(stderr, "bench_stills: --size wants WxH\n");
        return 2;
      }
    } else if (arg == "--repeats") {
      repeats = std::max(1, std::atoi(value().c_str()));
    } else if (arg == "--out") {
      out_dir = value();
    } else {
      std::fprintf(stderr, "bench_stills: unknown argument %s\n", arg.c_str());
      return 2;
    }
  }

  std::string error;
  fs::path temp;
  if (store_dir.empty()) {
    temp = fs::temp_directory_path() / ("plantview-bench-stills-" + std::to_string(::getpid()));
    store_dir = temp.string();
  }
  auto store = Store::open(store_dir, Store::Mode::read_write, error);
  if (!store) {
    std::fprintf(stderr, "bench_stills: %s\n", error.c_str());
    return 1;
  }
  if (!temp.empty()) {
    GenerateOptions generate;
    generate.preset = preset;
    const IngestResult result = ingest_generated(*store, generate);
    if (!result) {
      std::fprintf(stderr, "bench_stills: %s\n", result.error().message.c_str());
      return 1;
    }
  }
  auto context = GpuContext::create(-1, error);
  if (!context) {
    std::fprintf(stderr, "bench_stills: %s\n", error.c_str());
    return 1;
  }
  std::printf("device: %s\n", context->description().c_str());
  auto renderer = Renderer::create(*store, RenderOptions{}, error);
  if (!renderer) {
    std::fprintf(stderr, "bench_stills: %s\n", error.c_str());
    return 1;
  }
  const DAabb bounds = renderer->model_bounds();
  const double aspect = double(width) / height;
  std::vector<Camera> views = {default_camera(bounds, aspect)};
  // An interior view: from inside the plant's first fifth, at a third of its height, looking
  // along it and down.
  const glm::dvec3 size = bounds.max - bounds.min;
  Camera inside;
  inside.eye_m = bounds.min + glm::dvec3(0.17, 0.1, 0.3) * size;
  inside.target_m = bounds.min + glm::dvec3(0.27, 0.5, 0.07) * size;
  views.push_back(inside);

  // The subject of the highlight: the object under the centre of the interior view.
  std::vector<uint64_t> subject;
  {
    Image image;
    FrameStats stats;
    if (!renderer->render(inside, width, height, true, image, stats, error)) {
      std::fprintf(stderr, "bench_stills: %s\n", error.c_str());
      return 1;
    }
    const uint64_t id = image.object_ids[size_t(height / 2) * width + width / 2];
    if (id) subject.push_back(id);
  }

  // Round robin (each repeat renders every setting once), keeping each view's fastest frame:
  // the machine's other load then weighs on every setting alike.
  const std::vector<Setting> all = settings(subject);
  std::vector<std::unique_ptr<Renderer>> own(all.size());
  for (size_t s = 0; s < all.size(); ++s) {
    if (!all[s].own_renderer) continue;
    own[s] = Renderer::create(*store, all[s].options, error);
    if (!own[s]) {
      std::fprintf(stderr, "bench_stills: %s\n", error.c_str());
      return 1;
    }
  }
  std::vector<std::vector<double>> best_draw(all.size(), std::vector<double>(views.size(), 1e300));
  std::vector<std::vector<double>> best_frame = best_draw;
  for (int r = 0; r <= (section_only ? -1 : repeats); ++r) {
    for (size_t s = 0; s < all.size(); ++s) {
      Renderer& rendering = own[s] ? *own[s] : *renderer;
      if (!own[s]) renderer->set_options(all[s].options);
      for (size_t v = 0; v < views.size(); ++v) {
        Image image;
        FrameStats stats;
        if (!rendering.render(views[v], width, height, false, image, stats, error)) {
          std::fprintf(stderr, "bench_stills: %s: %s\n", all[s].name, error.c_str());
          return 1;
        }
        if (r == 0) {  // warm-up; its image is the one written
          if (!out_dir.empty()) {
            std::string file = all[s].name;
            for (char& c : file)
              if (!std::isalnum(static_cast<unsigned char>(c))) c = '-';
            const std::string path = out_dir + "/view" + std::to_string(v) + "-" + file + ".png";
            if (!write_image(path, image, 90, error)) std::fprintf(stderr, "bench_stills: %s\n", error.c_str());
          }
          continue;
        }
        best_draw[s][v] = std::min(best_draw[s][v], stats.ms.draw + stats.ms.read_back);
        best_frame[s][v] = std::min(best_frame[s][v], stats.ms.total);
      }
    }
  }
  // The section: the overview whole and as a plan slab, alternately (the first round warms).
  RenderOptions whole;
  whole.pixel_error = kStillPixelError;
  RenderOptions slab = whole;
  slab.section.planes.push_back({{0, 0, bounds.min.z + 3.0}, {0, 0, 1}});
  slab.section.planes.push_back({{0, 0, bounds.min.z + 1.0}, {0, 0, -1}});
  RenderOptions open_slab = slab;  // what capping costs
  open_slab.section.capped = false;
  // And both as interactive frames (aliased, no ambient occlusion, no ground), where the
  // finishing passes that cost the same whatever is drawn are left out.
  RenderOptions whole_fast = whole;
  whole_fast.antialias = false;
  whole_fast.ambient_occlusion = false;
  whole_fast.ground = false;
  whole_fast.pixel_error = kInteractivePixelError;
  RenderOptions slab_fast = whole_fast;
  slab_fast.section = slab.section;
  double whole_ms = 1e300, slab_ms = 1e300, open_ms = 1e300;
  double whole_fast_ms = 1e300, slab_fast_ms = 1e300;
  uint64_t slab_clipped = 0, whole_triangles = 0, slab_triangles = 0;
  std::string whole_json, slab_json;  // the last frame of each, for where the time goes
  for (int r = 0; r <= repeats; ++r) {
    for (const int part : {0, 1, 2, 3, 4}) {
      const bool cut = part > 0;
      renderer->set_options(part == 0   ? whole
                            : part == 1 ? slab
                            : part == 2 ? open_slab
                            : part == 3 ? whole_fast
                                        : slab_fast);
      Image image;
      FrameStats stats;
      if (!renderer->render(views[0], width, height, false, image, stats, error)) {
        std::fprintf(stderr, "bench_stills: section: %s\n", error.c_str());
        return 1;
      }
      if (r == 0) {
        if (!out_dir.empty() && part < 2)
          write_image(out_dir + (cut ? "/section-slab.png" : "/section-whole.png"), image, 90, error);
        continue;
      }
      double& best = part == 0   ? whole_ms
                     : part == 1 ? slab_ms
                     : part == 2 ? open_ms
                     : part == 3 ? whole_fast_ms
                                 : slab_fast_ms;
      best = std::min(best, stats.ms.total);
      if (part >= 2) continue;
      (cut ? slab_json : whole_json) = stats.to_json();
      (cut ? slab_triangles : whole_triangles) = stats.triangles;
      if (cut) slab_clipped = stats.objects_clipped;
    }
  }

  nlohmann::json json = nlohmann::json::array();
  double aliased_ms = 0;
  std::printf("%-28s %12s %12s %8s   (fastest of %d, mean over %zu views)\n", "setting",
              "draw ms", "frame ms", "x frame", repeats, views.size());
  for (size_t s = 0; !section_only && s < all.size(); ++s) {
    double draw_ms = 0, frame_ms = 0;
    for (size_t v = 0; v < views.size(); ++v) {
      draw_ms += best_draw[s][v] / double(views.size());
      frame_ms += best_frame[s][v] / double(views.size());
    }
    if (aliased_ms == 0) aliased_ms = frame_ms;
    std::printf("%-28s %12.1f %12.1f %8.2f\n", all[s].name, draw_ms, frame_ms, frame_ms / aliased_ms);
    json.push_back({{"setting", all[s].name}, {"draw_ms", draw_ms}, {"frame_ms", frame_ms},
                    {"frame_ratio", frame_ms / aliased_ms}});
  }
  // Colour by against the still it colours, and the first frame after a style change on a
  // warm renderer (every known object's attributes read again), each view once.
  double still_ms = 0, coloured_ms = 0, switched_ms = 0;
  for (size_t s = 0; !section_only && s < all.size(); ++s) {
    for (size_t v = 0; v < views.size(); ++v) {
      if (std::string(all[s].name) == "still, own renderer") still_ms += best_frame[s][v];
      if (std::string(all[s].name) == "still + colour by") coloured_ms += best_frame[s][v];
    }
  }
  for (size_t v = 0; !section_only && v < views.size(); ++v) {
    RenderOptions coloured;
    coloured.style.colour_by = kColourByKey;
    Image image;
    FrameStats stats;
    renderer->set_options(RenderOptions{});
    if (!renderer->render(views[v], width, height, false, image, stats, error)) return 1;
    renderer->set_options(coloured);
    if (!renderer->render(views[v], width, height, false, image, stats, error)) {
      std::fprintf(stderr, "bench_stills: colour by: %s\n", error.c_str());
      return 1;
    }
    switched_ms += stats.ms.total;
  }
  nlohmann::json summary{{"width", width}, {"height", height}, {"views", views.size()},
                         {"repeats", repeats}, {"settings", json}};
  if (!section_only) {
    std::printf("colour by %s: x%.3f the still's frame (%.1f against %.1f ms); first frame after "
                "the style changed: %.1f ms\n",
                kColourByKey, coloured_ms / still_ms, coloured_ms / double(views.size()),
                still_ms / double(views.size()), switched_ms / double(views.size()));
    summary["colour_by_ratio"] = coloured_ms / still_ms;
    summary["style_change_frame_ms"] = switched_ms / double(views.size());
  }
  std::printf("section: overview %.1f ms (%llu triangles), 2 m plan slab %.1f ms (%llu triangles, "
              "%llu objects clipped): ratio %.2f; uncapped %.1f ms\n",
              whole_ms, (unsigned long long)whole_triangles, slab_ms,
              (unsigned long long)slab_triangles, (unsigned long long)slab_clipped,
              slab_ms / whole_ms, open_ms);
  std::printf("section, interactive frames (aliased, no ambient occlusion, no ground, 1 px): "
              "overview %.1f ms, slab %.1f ms: ratio %.2f\n",
              whole_fast_ms, slab_fast_ms, slab_fast_ms / whole_fast_ms);
  std::printf("section frames:\n  overview %s\n  slab %s\n", whole_json.c_str(), slab_json.c_str());
  summary["section"] = {{"overview_ms", whole_ms},
                        {"slab_ms", slab_ms},
                        {"ratio", slab_ms / whole_ms},
                        {"uncapped_ms", open_ms},
                        {"interactive_overview_ms", whole_fast_ms},
                        {"interactive_slab_ms", slab_fast_ms},
                        {"interactive_ratio", slab_fast_ms / whole_fast_ms},
                        {"objects_clipped", slab_clipped}};
  std::printf("json: %s\n", summary.dump().c_str());
  own.clear();
  renderer.reset();
  store.reset();
  if (!temp.empty()) fs::remove_all(temp);
  return 0;
}
