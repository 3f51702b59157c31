// plantview import FILE... --store DIR
//   Adds each file's objects to the store, replacing what the same file brought before: RVM files
//   (with their attribute file: one given among FILE..., or found beside the RVM under the same
//   name with .txt or .att) and plantview XML files. All files go in one transaction: on any
//   error nothing is committed and the store stays as it was.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include "commands.h"
#include "plantview/rvm.h"
#include "plantview/rvm_import.h"
#include "plantview/store.h"
#include "plantview/xml.h"
#include "progress.h"

namespace plantview::cli {

namespace {

namespace fs = std::filesystem;

struct ImportOptions {
  std::vector<std::string> files;
  std::string store;
};

std::string lower_extension(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

// The attribute file of an RVM: one given on the command line with the same stem, else a .txt
// or .att beside it (either case). Empty if there is none.
fs::path attributes_for(const fs::path& rvm, const std::vector<fs::path>& given) {
  for (const fs::path& g : given) {
    if (g.stem() == rvm.stem()) return g;
  }
  for (const char* ext : {".txt", ".TXT", ".att", ".ATT"}) {
    fs::path candidate = rvm;
    candidate.replace_extension(ext);
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

int fail(const std::string& message) {
  std::cerr << "plantview import: " << message << " (the store is unchanged)\n";
  return 1;
}

int run(const ImportOptions& o) {
  std::vector<fs::path> models, attribute_files;
  for (const std::string& f : o.files) {
    const std::string ext = lower_extension(f);
    if (ext == ".rvm" || ext == ".xml") {
      models.emplace_back(f);
    } else if (ext == ".txt" || ext == ".att") {
      attribute_files.emplace_back(f);
    } else {
      std::cerr << "plantview import: " << f << ": not an .rvm, .xml, .txt or .att file\n";
      return 2;
    }
  }
  for (const fs::path& a : attribute_files) {
    const bool paired = std::any_of(models.begin(), models.end(), [&](const fs::path& m) {
      return m.stem() == a.stem() && lower_extension(m) == ".rvm";
    });
    if (!paired) {
      std::cerr << "plantview import: " << a.string() << ": attribute file without an RVM file of the same name\n";
      return 2;
    }
  }
  if (models.empty()) {
    std::cerr << "plantview import: no .rvm or .xml file given\n";
    return 2;
  }

  const auto start = std::chrono::steady_clock::now();
  std::string error;
  auto store = Store::open(o.store, Store::Mode::read_write, error);
  if (!store) return fail(error);
  auto import = store->begin_import(error);
  if (!import) return fail(error);

  uint64_t objects = 0;
  for (size_t i = 0; i < models.size(); ++i) {
    const fs::path& path = models[i];
    std::error_code ec;
    const fs::path canonical = fs::weakly_canonical(path, ec);
    const std::string source = ec ? path.string() : canonical.string();
    Progress progress("importing " + path.filename().string());
    if (!import->remove_source(source, error)) return fail(error);

    if (lower_extension(path) == ".xml") {
      XmlError xml_error;
      bool put_failed = false;
      const bool ok = read_xml_file(path, [&](Object&& obj) {
        if (put_failed) return;
        obj.source = source;
        if (!import->put(obj, error)) put_failed = true;
        ++objects;
      }, xml_error);
      if (!ok) return fail(xml_error.message);
      if (put_failed) return fail(error);
      continue;
    }

    auto bytes = load_file(path);
    if (!bytes) return fail(bytes.error().message);
    progress.update(0.1, "parsing");
    auto rvm = parse_rvm(bytes.value(), path.string());
    if (!rvm) return fail(rvm.error().message);
    std::unique_ptr<AttributeFile> attributes;
    const fs::path attribute_path = attributes_for(path, attribute_files);
    if (!attribute_path.empty()) {
      auto text = load_file(attribute_path);
      if (!text) return fail(text.error().message);
      const auto& b = text.value();
      auto parsed = parse_attributes(
          std::string_view(reinterpret_cast<const char*>(b.data()), b.size()), attribute_path.string());
      if (!parsed) return fail(parsed.error().message);
      attributes = std::make_unique<AttributeFile>(std::move(parsed).value());
    }
    progress.update(0.5, "classifying");
    RvmImportSummary summary;
    const std::vector<Object> converted = rvm_to_objects(rvm.value(), attributes.get(), source, summary);
    for (size_t k = 0; k < converted.size(); ++k) {
      if (!import->put(converted[k], error)) return fail(error);
      progress.update(0.5 + 0.5 * double(k + 1) / double(converted.size()), "storing");
    }
    objects += converted.size();
    progress.finish();
    for (const std::string& w : summary.warnings) std::cerr << "plantview import: warning: " << w << "\n";
    std::fprintf(stderr, "plantview import: %s: %llu groups, %llu primitives -> %llu objects%s\n",
                 path.string().c_str(), (unsigned long long)summary.groups,
                 (unsigned long long)summary.primitives, (unsigned long long)summary.objects,
                 attribute_path.empty() ? " (no attribute file: every group is of class other)"
                                        : (" with attributes from " + attribute_path.string()).c_str());
  }
  if (!import->commit(error)) return fail(error);
  std::fprintf(stderr, "plantview import: %llu objects committed to %s in %.2f s\n",
               (unsigned long long)objects, o.store.c_str(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}

}  // namespace

Action add_import_command(CLI::App& app) {
  auto options = std::make_shared<ImportOptions>();
  CLI::App* sub = app.add_subcommand(
      "import", "Import RVM (with attribute files) or plantview XML files into a store");
  sub->add_option("files", options->files, "RVM, attribute (.txt/.att) and XML files")->required();
  sub->add_option("--store", options->store, "Store directory (created if missing)")->required();
  return [options, sub]() { return sub->parsed() ? run(*options) : -1; };
}

}  // namespace plantview::cli
