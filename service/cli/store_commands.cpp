// The store's subcommands:
//   plantview gen --preset P [--scale K] [--seed S] (--store DIR | --xml FILE)
//   plantview info --store DIR [--json]
//   plantview export --store DIR --xml FILE
//   plantview export --store DIR --gltf FILE.glb|FILE.gltf [--tolerance MM | --pixel-error PX --camera ...]
//                    [--select GLOB]... [--class C,...] [--box X0,Y0,Z0,X1,Y1,Z1] [--no-hlod]
//                    [--split site|zone|pipeline|equipment] [--gpu-instancing] [--size WxH]
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "plantview/generate.h"
#include "plantview/gltf.h"
#include "plantview/ingest.h"
#include "plantview/store.h"
#include "plantview/xml.h"
#include "progress.h"

namespace plantview::cli {

namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// ---- gen

constexpr unsigned kMaxImportThreads = 256;

struct GenOptions {
  std::string preset = "c";
  uint32_t scale = 1;
  uint64_t seed = 1;
  unsigned threads = 0;  // 0: the machine's hardware threads
  std::string store, xml;
  RevisionOptions revision;  // --store only
};

int run_gen(const GenOptions& o) {
  GenerateOptions g;
  if (!parse_preset(o.preset, g.preset)) {
    std::cerr << "plantview gen: unknown --preset '" << o.preset << "' (a, b or c)\n";
    return 2;
  }
  if (o.scale < 1 || o.scale > kMaxGenerateScale) {
    std::cerr << "plantview gen: --scale must be 1.." << kMaxGenerateScale << ", got " << o.scale << "\n";
    return 2;
  }
  if (o.store.empty() == o.xml.empty()) {
    std::cerr << "plantview gen: give exactly one of --store DIR or --xml FILE\n";
    return 2;
  }
  if (o.threads > kMaxImportThreads) {
    std::cerr << "plantview gen: --threads must be 0.." << kMaxImportThreads << ", got " << o.threads << "\n";
    return 2;
  }
  if (const int status = apply_revision_options("gen", o.revision); status != 0) return status;
  set_import_threads(o.threads);
  g.scale = o.scale;
  g.seed = o.seed;
  const auto start = std::chrono::steady_clock::now();
  Progress progress("generating preset " + std::string(1, g.preset));
  std::string error;
  bool failed = false;

  if (!o.xml.empty()) {
    XmlWriter writer;
    XmlError xml_error;
    if (!writer.open(o.xml, xml_error)) {
      std::cerr << "plantview gen: " << xml_error.message << "\n";
      return 1;
    }
    const GenerateSummary summary = generate_plant(
        g,
        [&](Object&& obj) {
          if (!writer.write_object(obj)) failed = true;
        },
        [&](double f) { progress.update(f); });
    if (!writer.close(xml_error) || failed) {
      std::cerr << "plantview gen: " << xml_error.message << "\n";
      return 1;
    }
    progress.finish();
    std::fprintf(stderr, "plantview gen: %llu objects, %llu primitives written to %s in %.2f s\n",
                 (unsigned long long)summary.objects, (unsigned long long)summary.primitives,
                 o.xml.c_str(), seconds_since(start));
    return 0;
  }

  auto store = Store::open(o.store, Store::Mode::read_write, error);
  if (!store) {
    std::cerr << "plantview gen: " << error << "\n";
    return 1;
  }
  IngestControl control;
  control.note = o.revision.note;
  control.keep_revisions = uint32_t(o.revision.keep_revisions);
  control.progress = [&](const IngestProgress& p) {
    if (p.stage == IngestStage::generating) progress.update(double(p.done) / double(p.total));
    // The commit (indexes, spatial tree) takes a while on a big plant: say so.
    if (p.stage == IngestStage::committing && p.done == 0) progress.update(1.0, "committing");
  };
  const IngestResult result = ingest_generated(*store, g, control);
  if (!result) {
    std::cerr << "plantview gen: " << result.error().message << " (the store is unchanged)\n";
    return 1;
  }
  progress.finish();
  const GenerateSummary& summary = result.summary().generated;
  const double seconds = seconds_since(start);
  store.reset();
  const std::string revision = newest_revision_summary(o.store);
  std::fprintf(stderr, "plantview gen: %llu objects, %llu primitives committed to %s in %.2f s%s\n",
               (unsigned long long)summary.objects, (unsigned long long)summary.primitives,
               o.store.c_str(), seconds, revision.empty() ? "" : (" (" + revision + ")").c_str());
  return 0;
}

// ---- info

struct InfoOptions {
  std::string store;
  bool json = false;
};

int run_info(const InfoOptions& o) {
  std::string error;
  auto store = Store::open(o.store, Store::Mode::read_only, error);
  std::unique_ptr<ReadView> view = store ? store->read(error) : nullptr;
  if (!view) {
    std::cerr << "plantview info: " << error << "\n";
    return 1;
  }
  const StoreInfo info = view->info();
  const ModelStatistics& s = info.statistics;
  if (o.json) {
    nlohmann::json j = nlohmann::json::parse(statistics_json(s));
    j["store"] = o.store;
    j["format_version"] = info.format_version;
    j["store_bytes"] = info.store_bytes;
    char commit_id[17];
    std::snprintf(commit_id, sizeof commit_id, "%016llx", (unsigned long long)info.commit_id);
    j["commit_id"] = commit_id;
    j["revision"] = info.revision;
    j["revision_time"] = info.revision == 0 ? "" : revision_time_text(info.revision_time_unix_ms);
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::printf("store %s (format %u), %.2f MB on disk\n", o.store.c_str(), info.format_version,
              double(info.store_bytes) / 1e6);
  if (info.revision != 0) {
    std::printf("revision %u, committed %s (plantview revisions --store %s)\n", info.revision,
                revision_time_text(info.revision_time_unix_ms).c_str(), o.store.c_str());
  }
  std::printf("%llu objects, %llu primitives, %llu triangles at full resolution\n",
              (unsigned long long)s.objects, (unsigned long long)s.primitives,
              (unsigned long long)s.triangles);
  std::printf("\n%-12s %10s %12s %14s\n", "class", "objects", "primitives", "triangles");
  for (int c = 0; c < kObjectClassCount; ++c) {
    std::printf("%-12s %10llu %12llu %14llu\n", std::string(class_name(ObjectClass(c))).c_str(),
                (unsigned long long)s.objects_by_class[c], (unsigned long long)s.primitives_by_class[c],
                (unsigned long long)s.triangles_by_class[c]);
  }
  std::printf("\n%-18s %12s %14s\n", "kind", "primitives", "triangles");
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    if (s.primitives_by_kind[k] == 0) continue;
    std::printf("%-18s %12llu %14llu\n", std::string(kind_name(PrimitiveKind(k))).c_str(),
                (unsigned long long)s.primitives_by_kind[k], (unsigned long long)s.triangles_by_kind[k]);
  }
  if (!s.bounds.empty()) {
    const glm::dvec3 size = s.bounds.max - s.bounds.min;
    std::printf("\nbounds (m): min (%.3f, %.3f, %.3f) max (%.3f, %.3f, %.3f), %.2f x %.2f x %.2f\n",
                s.bounds.min.x, s.bounds.min.y, s.bounds.min.z, s.bounds.max.x, s.bounds.max.y,
                s.bounds.max.z, size.x, size.y, size.z);
  }
  return 0;
}

// ---- export

struct ExportOptions {
  std::string store, xml, gltf;
  // glTF only.
  double tolerance_mm = 0, pixel_error = 0;
  std::string camera, size = "1920x1080", classes, box, split = "none";
  std::vector<std::string> select;
  std::vector<std::string> clip;  // sections (view_filters.h)
  std::string section_box;
  bool no_hlod = false, gpu_instancing = false, no_sharing = false, no_quantization = false;
};

// The glTF options checked and typed; a usage error (exit 2) otherwise.
int gltf_options(const ExportOptions& o, GltfExportOptions& g) {
  const std::filesystem::path path(o.gltf);
  if (path.extension() != ".glb" && path.extension() != ".gltf")
    return usage_error("export: --gltf needs a .glb or .gltf file name, got '" + o.gltf + "'");
  g.path = o.gltf;
  if (o.tolerance_mm != 0 && (!std::isfinite(o.tolerance_mm) || o.tolerance_mm <= 0))
    return usage_error("export: --tolerance must be a positive number of millimetres");
  if (o.tolerance_mm > 0 && (!o.camera.empty() || o.pixel_error != 0))
    return usage_error("export: give --tolerance or --pixel-error with --camera, not both");
  if (o.pixel_error != 0 && o.camera.empty())
    return usage_error("export: --pixel-error needs --camera (the view the levels are chosen for)");
  if (o.pixel_error != 0 && (!std::isfinite(o.pixel_error) || o.pixel_error <= 0))
    return usage_error("export: --pixel-error must be a positive number of pixels");
  g.tolerance_m = o.tolerance_mm / 1000.0;
  std::string error;
  if (!o.camera.empty()) {
    Camera camera;
    if (!parse_camera(o.camera, camera, error)) return usage_error("export: --camera: " + error);
    g.camera = camera;
    g.pixel_error = o.pixel_error != 0 ? o.pixel_error : 1.0;
    const size_t x = o.size.find('x');
    uint32_t w = 0, h = 0;
    auto number = [](std::string_view t, uint32_t& v) {
      const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
      return !t.empty() && ec == std::errc() && end == t.data() + t.size();
    };
    if (x == std::string::npos || !number(std::string_view(o.size).substr(0, x), w) ||
        !number(std::string_view(o.size).substr(x + 1), h) || w < 1 || h < 1 || w > 16384 || h > 16384)
      return usage_error("export: --size: expected WxH (1..16384 each), got '" + o.size + "'");
    g.width = w;
    g.height = h;
  }
  g.hlod = !o.no_hlod;
  g.gpu_instancing = o.gpu_instancing;
  g.share_meshes = !o.no_sharing;
  g.quantize = !o.no_quantization;
  for (const std::string& glob : o.select) {
    if (glob.empty()) return usage_error("export: --select needs a non-empty pattern");
    g.selection.globs.push_back(glob);
  }
  for (size_t at = 0; !o.classes.empty() && at <= o.classes.size();) {
    const size_t end = std::min(o.classes.find(',', at), o.classes.size());
    ObjectClass c;
    if (!class_from_name(o.classes.substr(at, end - at), c))
      return usage_error("export: --class: unknown class '" + o.classes.substr(at, end - at) +
                         "' (equipment, pipeline, pipe, component, structure, other)");
    g.selection.classes.push_back(c);
    at = end + 1;
  }
  if (!o.box.empty()) {
    DAabb box;
    if (!parse_box(o.box, box, error)) return usage_error("export: --" + error);
    g.selection.box = box;
  }
  if (!parse_section_options(o.clip, o.section_box, g.selection.section, error))
    return usage_error("export: " + error);
  if (!parse_gltf_split(o.split, g.split))
    return usage_error("export: --split must be site, zone, pipeline or equipment, got '" + o.split + "'");
  return 0;
}

int run_export_gltf(const ExportOptions& o) {
  GltfExportOptions g;
  if (const int status = gltf_options(o, g); status != 0) return status;
  std::string error;
  auto store = Store::open(o.store, Store::Mode::read_only, error);
  if (!store) {
    std::cerr << "plantview export: " << error << "\n";
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  Progress progress("exporting glTF");
  g.progress = [&](double f, std::string_view stage) { progress.update(f, std::string(stage)); };
  GltfExportSummary summary;
  const GltfExportStatus status = export_gltf(*store, g, summary, error);
  progress.finish();
  if (status != GltfExportStatus::ok) {
    std::cerr << "plantview export: " << error << " (nothing written)\n";
    return 1;
  }
  // The summary as JSON on stdout (machine output); files and their bounds.
  nlohmann::json j;
  j["origin_m"] = {summary.origin_m.x, summary.origin_m.y, summary.origin_m.z};
  j["objects"] = summary.objects;
  j["triangles"] = summary.triangles;
  j["lines"] = summary.lines;
  j["meshes"] = summary.meshes;
  j["bytes"] = summary.bytes;
  j["seconds"] = seconds_since(start);
  for (const GltfFileSummary& f : summary.files) {
    nlohmann::json file = {{"path", f.path}, {"objects", f.objects}, {"triangles", f.triangles},
                           {"meshes", f.meshes}, {"instanced_objects", f.instanced_objects}, {"bytes", f.bytes}};
    if (!f.group.empty()) file["group"] = f.group;
    if (!f.bounds.empty())
      file["bounds_m"] = {{"min", {f.bounds.min.x, f.bounds.min.y, f.bounds.min.z}},
                          {"max", {f.bounds.max.x, f.bounds.max.y, f.bounds.max.z}}};
    j["files"].push_back(std::move(file));
  }
  std::cout << j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  return 0;
}

int run_export(const ExportOptions& o) {
  if (o.xml.empty() == o.gltf.empty()) return usage_error("export: give exactly one of --xml FILE or --gltf FILE");
  if (!o.gltf.empty()) return run_export_gltf(o);
  if (o.tolerance_mm != 0 || o.pixel_error != 0 || !o.camera.empty() || !o.select.empty() || !o.classes.empty() ||
      !o.box.empty() || o.split != "none" || o.no_hlod || o.gpu_instancing || o.no_sharing ||
      o.no_quantization)
    return usage_error("export: --xml writes the whole model; selection and level options are for --gltf");
  std::string error;
  auto store = Store::open(o.store, Store::Mode::read_only, error);
  std::unique_ptr<ReadView> view = store ? store->read(error) : nullptr;
  if (!view) {
    std::cerr << "plantview export: " << error << "\n";
    return 1;
  }
  const uint64_t total = view->info().objects;
  XmlWriter writer;
  XmlError xml_error;
  if (!writer.open(o.xml, xml_error)) {
    std::cerr << "plantview export: " << xml_error.message << "\n";
    return 1;
  }
  Progress progress("exporting");
  uint64_t done = 0;
  bool write_failed = false;
  const bool ok = view->for_each_object(
      [&](uint32_t, Object&& obj) {
        if (!writer.write_object(obj)) {
          write_failed = true;
          return false;
        }
        progress.update(total ? double(++done) / double(total) : 1.0);
        return true;
      },
      true, error);
  const bool closed = writer.close(xml_error);
  if (!ok || write_failed || !closed) {
    std::cerr << "plantview export: " << (ok ? xml_error.message : error) << "\n";
    std::error_code ec;
    std::filesystem::remove(o.xml, ec);  // no half-written file left behind
    return 1;
  }
  progress.finish();
  return 0;
}

}  // namespace

Action add_store_commands(CLI::App& app) {
  auto gen = std::make_shared<GenOptions>();
  CLI::App* gen_cmd = app.add_subcommand("gen", "Generate a synthetic plant into a store or an XML file");
  gen_cmd->add_option("--preset", gen->preset, "a, b or c: the plants of Su et al. Fig. 1 (default c)");
  gen_cmd->add_option("--scale", gen->scale, "Plant units laid out side by side (default 1)");
  gen_cmd->add_option("--seed", gen->seed, "Random seed (default 1)");
  gen_cmd->add_option("--threads", gen->threads,
                      "Threads that generate and compress (default 0: every core; 1: one thread). "
                      "The store is the same whatever the count");
  gen_cmd->add_option("--store", gen->store, "Store directory to add the plant to");
  gen_cmd->add_option("--xml", gen->xml, "plantview XML file to write instead");
  add_revision_options(*gen_cmd, gen->revision);

  auto info = std::make_shared<InfoOptions>();
  CLI::App* info_cmd = app.add_subcommand("info", "Objects, primitives, triangles, bounds and size of a store");
  info_cmd->add_option("--store", info->store, "Store directory")->required();
  info_cmd->add_flag("--json", info->json, "Write JSON to stdout");

  auto exp = std::make_shared<ExportOptions>();
  CLI::App* export_cmd = app.add_subcommand(
      "export", "Write a store's whole model as plantview XML, or any part of it as glTF 2.0");
  export_cmd->add_option("--store", exp->store, "Store directory")->required();
  export_cmd->add_option("--xml", exp->xml, "XML file to write (the whole model)");
  export_cmd->add_option("--gltf", exp->gltf, "glTF file to write: .glb (binary) or .gltf (+ .bin)");
  export_cmd->add_option("--tolerance", exp->tolerance_mm,
                         "glTF: each object's coarsest level whose error is at most this (millimetres); "
                         "default full resolution");
  export_cmd->add_option("--pixel-error", exp->pixel_error,
                         "glTF: with --camera, the levels the renderer draws for that view (pixels, default 1)");
  export_cmd->add_option("--camera", exp->camera, "glTF: eye=X,Y,Z,target=X,Y,Z[,up=..][,fov=DEG]");
  export_cmd->add_option("--size", exp->size, "glTF: with --camera, the image size WxH the levels are for")
      ->capture_default_str();
  export_cmd->add_option("--select", exp->select,
                         "glTF: objects whose name (or pipeline's name) matches this glob; repeatable");
  export_cmd->add_option("--class", exp->classes, "glTF: only these classes, comma-separated");
  export_cmd->add_option("--box", exp->box, "glTF: only objects meeting this box X0,Y0,Z0,X1,Y1,Z1 (metres)");
  export_cmd->add_option("--clip", exp->clip,
                         "glTF: leave out objects wholly beyond this plane PX,PY,PZ,NX,NY,NZ "
                         "(the normal points into the side removed; repeatable, at most 6)");
  export_cmd->add_option("--section-box", exp->section_box,
                         "glTF: leave out objects wholly outside this box MINX,MINY,MINZ,MAXX,MAXY,MAXZ");
  export_cmd->add_flag("--no-hlod", exp->no_hlod, "glTF: with --camera, pipeline runs unmerged");
  export_cmd->add_option("--split", exp->split, "glTF: one file per site, zone, pipeline or equipment item");
  export_cmd->add_flag("--gpu-instancing", exp->gpu_instancing,
                       "glTF: EXT_mesh_gpu_instancing (then required) for meshes repeated 16 times or more");
  export_cmd->add_flag("--no-quantization", exp->no_quantization,
                       "glTF: float32 vertices only, no KHR_mesh_quantization (for readers without it)");
  export_cmd->add_flag("--no-sharing", exp->no_sharing,
                       "glTF: a mesh per object, none shared (to measure what sharing saves)");

  return [=]() {
    if (gen_cmd->parsed()) return run_gen(*gen);
    if (info_cmd->parsed()) return run_info(*info);
    if (export_cmd->parsed()) return run_export(*exp);
    return -1;
  };
}

}  // namespace plantview::cli
