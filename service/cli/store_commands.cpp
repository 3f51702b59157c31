// The store's subcommands:
//   plantview gen --preset P [--scale K] [--seed S] (--store DIR | --xml FILE)
//   plantview info --store DIR [--json]
//   plantview export --store DIR --xml FILE
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "plantview/generate.h"
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

struct GenOptions {
  std::string preset = "c";
  uint32_t scale = 1;
  uint64_t seed = 1;
  std::string store, xml;
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
  control.progress = [&](const IngestProgress& p) {
    if (p.stage == IngestStage::generating) progress.update(double(p.done) / double(p.total));
  };
  const IngestResult result = ingest_generated(*store, g, control);
  if (!result) {
    std::cerr << "plantview gen: " << result.error().message << " (the store is unchanged)\n";
    return 1;
  }
  progress.finish();
  const GenerateSummary& summary = result.summary().generated;
  std::fprintf(stderr, "plantview gen: %llu objects, %llu primitives committed to %s in %.2f s\n",
               (unsigned long long)summary.objects, (unsigned long long)summary.primitives,
               o.store.c_str(), seconds_since(start));
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
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::printf("store %s (format %u), %.2f MB on disk\n", o.store.c_str(), info.format_version,
              double(info.store_bytes) / 1e6);
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
  std::string store, xml;
};

int run_export(const ExportOptions& o) {
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
  gen_cmd->add_option("--store", gen->store, "Store directory to add the plant to");
  gen_cmd->add_option("--xml", gen->xml, "plantview XML file to write instead");

  auto info = std::make_shared<InfoOptions>();
  CLI::App* info_cmd = app.add_subcommand("info", "Objects, primitives, triangles, bounds and size of a store");
  info_cmd->add_option("--store", info->store, "Store directory")->required();
  info_cmd->add_flag("--json", info->json, "Write JSON to stdout");

  auto exp = std::make_shared<ExportOptions>();
  CLI::App* export_cmd = app.add_subcommand("export", "Write a store's whole model as plantview XML");
  export_cmd->add_option("--store", exp->store, "Store directory")->required();
  export_cmd->add_option("--xml", exp->xml, "XML file to write")->required();

  return [=]() {
    if (gen_cmd->parsed()) return run_gen(*gen);
    if (info_cmd->parsed()) return run_info(*info);
    if (export_cmd->parsed()) return run_export(*exp);
    return -1;
  };
}

}  // namespace plantview::cli
