// glTF export: select, then per group read, tessellate (once per distinct mesh) and write
// (rules in plantview/gltf.h).
#include "plantview/gltf.h"

#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>

#include "gltf_file.h"
#include "gltf_text.h"
#include "object_mesh.h"
#include "plantview/store.h"
#include "selection.h"

namespace plantview {

using namespace detail::gltf;

std::string_view gltf_split_name(GltfSplit split) {
  switch (split) {
    case GltfSplit::none: return "none";
    case GltfSplit::site: return "site";
    case GltfSplit::zone: return "zone";
    case GltfSplit::pipeline: return "pipeline";
    case GltfSplit::equipment: return "equipment";
  }
  return "?";
}

bool parse_gltf_split(std::string_view name, GltfSplit& split) {
  for (GltfSplit s : {GltfSplit::none, GltfSplit::site, GltfSplit::zone, GltfSplit::pipeline, GltfSplit::equipment}) {
    if (gltf_split_name(s) == name) {
      split = s;
      return true;
    }
  }
  return false;
}

bool parse_box(std::string_view text, DAabb& box, std::string& error) {
  double v[6];
  size_t at = 0;
  for (int i = 0; i < 6; ++i) {
    const size_t end = std::min(text.find(',', at), text.size());
    const std::string_view field = text.substr(at, end - at);
    const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), v[i]);
    if (field.empty() || ec != std::errc() || ptr != field.data() + field.size() || !std::isfinite(v[i])) {
      error = "box: value " + std::to_string(i + 1) + " ('" + std::string(field) +
              "') is not a number; expected X0,Y0,Z0,X1,Y1,Z1 in metres";
      return false;
    }
    if (i < 5 && end == text.size()) {
      error = "box: " + std::to_string(i + 1) + " values given, 6 needed (X0,Y0,Z0,X1,Y1,Z1)";
      return false;
    }
    at = end + 1;
  }
  if (at <= text.size()) {
    error = "box: more than 6 values; expected X0,Y0,Z0,X1,Y1,Z1";
    return false;
  }
  box = DAabb{};
  box.extend(glm::dvec3(v[0], v[1], v[2]));
  box.extend(glm::dvec3(v[3], v[4], v[5]));
  return true;
}

namespace {

// The files of a split: <stem>-<group><ext> beside the destination, unique.
std::string group_path(const std::filesystem::path& destination, const std::string& group,
                       std::map<std::string, int>& used, bool binary) {
  std::string name = destination.stem().string() + "-" + file_safe(group);
  if (const int n = ++used[name]; n > 1) name += "-" + std::to_string(n);
  return (destination.parent_path() / (name + (binary ? ".glb" : ".gltf"))).string();
}

// The worst quantization error allowed (gltf.h): a tenth of the tolerance, else 0.05 mm.
double quantization_error_m(const GltfExportOptions& options) {
  if (!options.quantize) return 0;
  return options.tolerance_m > 0 && !options.camera ? options.tolerance_m * kQuantizationShare : kQuantizationErrorM;
}

// Writes one group's file. False with a message (the file's temporaries removed).
bool write_group(const ReadView& view, const GltfExportOptions& options, const ExportGroup& group,
                 const std::string& path, const glm::dvec3& origin_m, GltfFile& file,
                 GltfFileSummary& summary, uint64_t& done, uint64_t total, std::string& error) {
  if (!file.open(path, origin_m, options.gpu_instancing, quantization_error_m(options), options.share_meshes,
                 error))
    return false;
  if (options.gpu_instancing) {
    // Objects, and room for site, zone and pipeline nodes (about 4 % of a plant's objects are
    // pipelines).
    const size_t objects = group.objects.size() + group.runs.size();
    file.reserve(objects + objects / 16 + 64);
  }
  Object object;
  CanonicalObject canonical;
  MeshBuilder builder;
  MeshData data;
  PrimitiveLevels levels;
  uint64_t unshared = 0;
  auto place = [&](const CanonicalObject& c, uint8_t level, Colour colour) {
    if (level == kLevelByTolerance) levels_for_tolerance(c, options.tolerance_m, levels);
    else levels_for_object(c, level, levels);
    MeshKey key = mesh_key(c, levels, colour);
    if (!options.share_meshes) key.b ^= ++unshared;  // every object a mesh of its own
    int mesh = file.find_mesh(key);
    if (mesh == GltfFile::kUnknownMesh) {
      builder.build(c, levels, data);
      mesh = file.add_mesh(key, data, colour, c.unit_shape, error);
    }
    return mesh;
  };
  for (const SelectedObject& s : group.objects) {
    if (!view.object(s.slot, object, true, error)) return false;
    canonicalise(object, canonical);
    const int mesh = place(canonical, s.level, object.colour);
    if (mesh == GltfFile::kUnknownMesh) return false;
    file.add_object(object, zone_of(object), canonical.position_m, canonical.rotation, canonical.scale, mesh);
    if (options.progress && (++done & 255) == 0) options.progress(0.1 + 0.9 * double(done) / double(total), "writing");
  }
  for (const SelectedRun& run : group.runs) {
    if (!view.object(run.first_member, object, true, error)) return false;
    Object merged;
    merged.origin_m = run.origin_m;
    merged.colour = run.colour;
    merged.primitives.push_back(run.cylinder);
    canonicalise(merged, canonical);
    const int mesh = place(canonical, run.level, run.colour);
    if (mesh == GltfFile::kUnknownMesh) return false;
    file.add_run(object.name + " (merged run)", run.pipeline_id, object.source, zone_of(object),
                 canonical.position_m, canonical.rotation, canonical.scale, mesh);
    ++done;
  }
  // Pipelines whose members were written but which were not selected themselves.
  for (const uint64_t id : file.unnamed_pipelines()) {
    std::optional<uint32_t> slot;
    if (!view.slot_of(id, slot, error)) return false;
    if (slot && view.object(*slot, object, true, error)) file.name_pipeline(object);
    else if (slot) return false;
  }
  if (!file.finish(summary, error)) return false;
  summary.group = group.name;
  return true;
}

bool write_index(const std::string& path, const GltfExportSummary& summary, GltfSplit split,
                 std::string& error) {
  auto vec = [](const glm::dvec3& v) {
    char text[96];
    std::snprintf(text, sizeof text, "[%.4f,%.4f,%.4f]", v.x, v.y, v.z);
    return std::string(text);
  };
  std::string json = "{\"version\":1,\"split\":\"" + std::string(gltf_split_name(split)) +
                     "\",\"origin_m\":" + vec(summary.origin_m) + ",\"files\":[";
  for (size_t i = 0; i < summary.files.size(); ++i) {
    const GltfFileSummary& f = summary.files[i];
    json += (i ? ",\n" : "\n") + std::string("{\"file\":") +
            json_string(utf8_text(std::filesystem::path(f.path).filename().string())) +
            ",\"group\":" + json_string(utf8_text(f.group)) + ",\"objects\":" + std::to_string(f.objects) +
            ",\"triangles\":" + std::to_string(f.triangles) + ",\"bytes\":" + std::to_string(f.bytes);
    if (!f.bounds.empty()) json += ",\"bounds_m\":{\"min\":" + vec(f.bounds.min) + ",\"max\":" + vec(f.bounds.max) + "}";
    json += "}";
  }
  json += "\n]}\n";
  const std::string temp = path + ".tmp-" + std::to_string(::getpid());
  std::FILE* out = std::fopen(temp.c_str(), "wb");
  bool ok = out && std::fwrite(json.data(), 1, json.size(), out) == json.size();
  if (out) ok = std::fclose(out) == 0 && ok;
  std::error_code ec;
  if (ok) std::filesystem::rename(temp, path, ec);
  if (!ok || ec) {
    error = "cannot write " + path + ": " + (ec ? ec.message() : std::string(std::strerror(errno)));
    std::filesystem::remove(temp, ec);
    return false;
  }
  return true;
}

}  // namespace

GltfExportStatus export_gltf(const Store& store, const GltfExportOptions& options,
                             GltfExportSummary& summary, std::string& error) {
  summary = GltfExportSummary{};
  // 1. A snapshot, and what goes where at which level.
  const std::unique_ptr<ReadView> view = store.read(error);
  if (!view) return GltfExportStatus::failed;
  ExportPlan plan;
  const auto pass_progress = [&](double f) {
    if (options.progress) options.progress(0.1 * f, "selecting");
  };
  if (!plan_export(*view, options, plan, pass_progress, error)) return GltfExportStatus::failed;
  if (plan.objects == 0) {
    error = "the selection is empty: no object of the store passes the filters";
    return GltfExportStatus::empty_selection;
  }
  // 2. One origin for every file: the selection's centre, in whole metres.
  summary.origin_m = plan.bounds.empty() ? glm::dvec3(0.0) : glm::round((plan.bounds.min + plan.bounds.max) * 0.5);
  // 3. The files, group by group; on an error every file made so far goes.
  const std::filesystem::path destination(options.path);
  const bool binary = destination.extension() == ".glb" || destination.extension() == ".GLB";
  const std::filesystem::path index = destination.parent_path() / (destination.stem().string() + ".json");
  std::map<std::string, int> used;
  std::vector<std::unique_ptr<GltfFile>> files;
  uint64_t done = 0;
  bool ok = true;
  for (const ExportGroup& group : plan.groups) {
    const std::string path = options.split == GltfSplit::none ? options.path : group_path(destination, group.name, used, binary);
    files.push_back(std::make_unique<GltfFile>());
    GltfFileSummary& f = summary.files.emplace_back();
    if (!write_group(*view, options, group, path, summary.origin_m, *files.back(), f, done, plan.objects, error)) {
      ok = false;
      break;
    }
    summary.objects += f.objects;
    summary.triangles += f.triangles;
    summary.lines += f.lines;
    summary.bytes += f.bytes;
    summary.meshes += f.meshes;
    summary.bounds.extend(f.bounds);
  }
  if (ok && options.split != GltfSplit::none) ok = write_index(index.string(), summary, options.split, error);
  if (!ok) {
    for (auto& f : files) f->abandon();
    return GltfExportStatus::failed;
  }
  if (options.progress) options.progress(1.0, "done");
  return GltfExportStatus::ok;
}

}  // namespace plantview
