// plantview import FILE... --store DIR
//   Adds each file's objects to the store, replacing what the same file brought before: RVM files
//   (with their attribute file: one given among FILE..., or found beside the RVM under the same
//   name with .txt or .att) and plantview XML files. All files go in one transaction: on any
//   error nothing is committed and the store stays as it was.
// The pipeline is ingest's (plantview/ingest.h); this file checks the arguments, shows progress
// on a terminal, prints the per-file lines and the outcome, and sets the exit status: 2 for bad
// arguments, 1 when the import fails.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

#include "commands.h"
#include "plantview/ingest.h"
#include "plantview/store.h"
#include "progress.h"

namespace plantview::cli {

namespace {

struct ImportOptions {
  std::vector<std::string> files;
  std::string store;
  RevisionOptions revision;
};

int fail(const std::string& message) {
  std::cerr << "plantview import: " << message << " (the store is unchanged)\n";
  return 1;
}

// One progress line per file: parsing is its first half, storing the second (XML: reading).
double file_fraction(const IngestProgress& p) {
  const double f = double(p.done) / double(p.total);
  switch (p.stage) {
    case IngestStage::parsing: return 0.1 + 0.4 * f;
    case IngestStage::classifying: return 0.5;
    case IngestStage::storing: return 0.5 + 0.5 * f;
    default: return f;
  }
}

int run(const ImportOptions& o) {
  std::string error;
  const std::optional<ImportPlan> plan = plan_import(o.files, error);
  if (!plan) {
    std::cerr << "plantview import: " << error << "\n";
    return 2;
  }

  if (const int status = apply_revision_options("import", o.revision); status != 0) return status;

  const auto start = std::chrono::steady_clock::now();
  auto store = Store::open(o.store, Store::Mode::read_write, error);
  if (!store) return fail(error);

  std::optional<Progress> progress;
  uint32_t progress_file = 0;
  IngestControl control;
  control.note = o.revision.note;
  control.keep_revisions = uint32_t(o.revision.keep_revisions);
  control.progress = [&](const IngestProgress& p) {
    if (p.path.empty()) return;
    if (!progress || progress_file != p.file_index) {
      progress.reset();
      progress.emplace("importing " + std::filesystem::path(p.path).filename().string());
      progress_file = p.file_index;
    }
    progress->update(file_fraction(p), std::string(stage_name(p.stage)));
  };
  const IngestResult result = ingest_files(*store, *plan, control, [&](const IngestedFile& f) {
    if (progress) progress->finish();
    if (f.xml) return;
    for (const std::string& w : f.warnings) std::cerr << "plantview import: warning: " << w << "\n";
    std::fprintf(stderr, "plantview import: %s: %llu groups, %llu primitives -> %llu objects%s\n",
                 f.path.c_str(), (unsigned long long)f.groups, (unsigned long long)f.primitives,
                 (unsigned long long)f.objects,
                 f.attributes_path.empty() ? " (no attribute file: every group is of class other)"
                                           : (" with attributes from " + f.attributes_path).c_str());
  });
  progress.reset();
  if (!result) return fail(result.error().message);
  uint64_t objects = 0;
  for (const IngestedFile& f : result.summary().files) objects += f.objects;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  store.reset();
  const std::string revision = newest_revision_summary(o.store);
  std::fprintf(stderr, "plantview import: %llu objects committed to %s in %.2f s%s\n",
               (unsigned long long)objects, o.store.c_str(), seconds,
               revision.empty() ? "" : (" (" + revision + ")").c_str());
  return 0;
}

}  // namespace

Action add_import_command(CLI::App& app) {
  auto options = std::make_shared<ImportOptions>();
  CLI::App* sub = app.add_subcommand(
      "import", "Import RVM (with attribute files) or plantview XML files into a store");
  sub->add_option("files", options->files, "RVM, attribute (.txt/.att) and XML files")->required();
  sub->add_option("--store", options->store, "Store directory (created if missing)")->required();
  add_revision_options(*sub, options->revision);
  return [options, sub]() { return sub->parsed() ? run(*options) : -1; };
}

}  // namespace plantview::cli
