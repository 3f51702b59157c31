// `plantview bcf export --views V.json --images DIR --out FILE.bcf [--store S]` and
// `plantview bcf import FILE.bcf --out VIEWS.json [--store S] [--aspect A] [--json]`: review
// views as BCF 2.1 files and back (plantview/bcf.h).
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "cli/bcf_export.h"
#include "cli/commands.h"
#include "cli/farm/job_inputs.h"
#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"
#include "plantview/bcf.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace fs = std::filesystem;

namespace {

struct BcfArgs {
  std::string views, images, out, store, file;
  double aspect = 16.0 / 9.0;
  bool json = false;
};

int fail(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 1;
}

int run_export(const BcfArgs& a) {
  std::string error, text;
  std::vector<ReviewView> views;
  if (!farm::read_views_file(a.views, views, text, error)) return fail(error);
  std::error_code ec;
  if (!fs::is_directory(a.images, ec)) return fail("--images " + a.images + ": not a directory");
  std::unique_ptr<Store> store;
  std::unique_ptr<ReadView> read;
  // GUIDs: from the store's identity (as `render --views --bcf` makes them), else from the
  // views file's content.
  std::string seed = "views " + farm::hash_hex(text);
  if (!a.store.empty()) {
    store = Store::open(a.store, Store::Mode::read_only, error);
    if (!store) return fail(error);
    read = store->read(error);
    if (!read) return fail(error);
    if (!farm::check_subjects(views, *read, error)) return fail(a.views + ": " + error);
    seed = farm::store_identity(*read);
  }
  if (!export_views_bcf(views, a.images, seed, read.get(), a.out, error)) return fail(error);
  std::cout << "{\"topics\":" << views.size() << ",\"out\":" << nlohmann::json(a.out).dump() << "}\n";
  return 0;
}

int run_import(const BcfArgs& a) {
  if (!(a.aspect > 0.0) || !std::isfinite(a.aspect)) return usage_error("--aspect must be a positive number");
  std::string error;
  std::unique_ptr<Store> store;
  std::unique_ptr<ReadView> read;
  if (!a.store.empty()) {
    store = Store::open(a.store, Store::Mode::read_only, error);
    if (!store) return fail(error);
    read = store->read(error);
    if (!read) return fail(error);
  }
  BcfReadOptions options;
  options.aspect = a.aspect;
  std::vector<ReviewView> views;
  BcfReadReport report;
  if (!read_bcf(a.file, read.get(), options, views, report, error)) return fail(error);
  // `per`: equipment when every view is of one item, else area.
  bool all_equipment = true;
  for (const ReviewView& v : views) all_equipment = all_equipment && v.kind == "equipment";
  if (!farm::write_file_atomically(a.out, review_views_json(views, all_equipment ? "equipment" : "area"),
                                   error))
    return fail(error);
  std::cerr << "plantview: bcf import " << a.file << ": " << report.to_text() << "\n";
  if (a.json) std::cout << report.to_json() << "\n";
  return 0;
}

}  // namespace

bool export_views_bcf(const std::vector<ReviewView>& views, const fs::path& images, const std::string& seed,
                      const ReadView* store, const fs::path& out, std::string& error) {
  std::vector<fs::path> snapshots;
  std::error_code ec;
  for (const ReviewView& v : views) {
    fs::path image = images / (v.name + ".png");
    if (!fs::is_regular_file(image, ec)) image = images / (v.name + ".jpg");
    if (!fs::is_regular_file(image, ec)) {
      error = "view '" + v.name + "': no rendered image " + (images / (v.name + ".png")).string() +
              " (or .jpg) for its snapshot";
      return false;
    }
    snapshots.push_back(image);
  }
  BcfWriteOptions options;
  options.seed = seed;
  // Each coloured view's legend, as its render recorded it in the manifest parts of `images`, so
  // that Coloring says the colours the snapshot shows (none recorded: BCF's own palette).
  std::map<std::string, nlohmann::json> records;
  std::string manifest_error;
  if (farm::read_newest_records(images, records, manifest_error)) {
    options.legends.resize(views.size());
    for (size_t i = 0; i < views.size(); ++i) {
      const auto record = records.find(views[i].name);
      if (views[i].style.colour_by.empty() || record == records.end() ||
          !record->second.contains("stats") || !record->second["stats"].contains("legend"))
        continue;
      std::string why;
      if (!FrameLegend::from_json(record->second["stats"]["legend"].dump(), options.legends[i], why))
        std::cerr << "plantview: bcf " << out.string() << ": view '" << views[i].name << "': " << why
                  << " (its Coloring uses BCF's own palette)\n";
    }
  }
  BcfWriteReport report;
  if (!write_bcf(out, views, snapshots, store, options, report, error)) return false;
  for (const std::string& note : report.notes)
    std::cerr << "plantview: bcf " << out.string() << ": " << note << "\n";
  if (report.snapshots_converted)
    std::cerr << "plantview: bcf " << out.string() << ": " << report.snapshots_converted
              << " JPEG image(s) converted to PNG snapshots\n";
  return true;
}

Action add_bcf_command(CLI::App& app) {
  auto args = std::make_shared<BcfArgs>();
  auto* bcf = app.add_subcommand("bcf", "Review views as BCF 2.1 files (BIM Collaboration Format) and back");
  bcf->require_subcommand(1);
  auto* exp = bcf->add_subcommand("export", "Write a BCF file of a views file and its rendered images");
  exp->add_option("--views", args->views, "Views JSON file (from plantview views)")->required();
  exp->add_option("--images", args->images, "The directory render --views wrote the images into")->required();
  exp->add_option("--out", args->out, "BCF file to write")->required();
  exp->add_option("--store", args->store,
                  "Store directory (tags of components, hide/only/colour_by lists, GUIDs)");
  auto* imp = bcf->add_subcommand("import", "Turn a BCF file's viewpoints into review views");
  imp->add_option("file", args->file, "BCF file")->required();
  imp->add_option("--out", args->out, "Views JSON file to write")->required();
  imp->add_option("--store", args->store, "Store directory (matches components to objects)");
  imp->add_option("--aspect", args->aspect, "Width / height of the images to come")->capture_default_str();
  imp->add_flag("--json", args->json, "The report as JSON on stdout too");
  return [=]() -> int {
    if (exp->parsed()) return run_export(*args);
    if (imp->parsed()) return run_import(*args);
    return -1;
  };
}

}  // namespace plantview::cli
