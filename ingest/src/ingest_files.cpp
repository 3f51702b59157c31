// Files into a store: sorting the names (plan_import), then per model file the stages of an RVM
// (parse the file and its attributes, classify groups into objects, store them) or of an XML
// file (read and store objects as they come), then one commit.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "plantview/ingest.h"
#include "plantview/rvm.h"
#include "plantview/rvm_import.h"
#include "plantview/xml.h"
#include "transaction.h"

namespace plantview {

namespace {

namespace fs = std::filesystem;
using ingest_detail::Abandon;
using ingest_detail::Transaction;

constexpr size_t kXmlBlockBytes = size_t(1) << 20;

std::string lower_extension(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

// The store's name for a file: its canonical path, or the path as given if that fails.
std::string source_of(const fs::path& path) {
  std::error_code ec;
  const fs::path canonical = fs::weakly_canonical(path, ec);
  return ec ? path.string() : canonical.string();
}

// An RVM's attribute file when none was given: a .txt or .att beside it (either case).
fs::path attributes_beside(const fs::path& rvm) {
  for (const char* ext : {".txt", ".TXT", ".att", ".ATT"}) {
    fs::path candidate = rvm;
    candidate.replace_extension(ext);
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

// Parsing and classifying one RVM, then storing its objects.
bool ingest_rvm(Transaction& t, const ImportPlan::Model& model, IngestedFile& file) {
  const std::string path = model.path.string();
  const fs::path attribute_path = model.attributes.empty() ? attributes_beside(model.path) : model.attributes;
  // Sizes for progress only: a file that cannot be measured counts 0 (loading it names the error).
  const auto size_of = [](const fs::path& p) -> uint64_t {
    std::error_code ec;
    const uint64_t size = p.empty() ? 0 : uint64_t(fs::file_size(p, ec));
    return ec ? 0 : size;
  };
  const uint64_t rvm_bytes = size_of(model.path), total_bytes = rvm_bytes + size_of(attribute_path);
  t.report(IngestStage::parsing, 0, total_bytes, path);
  auto bytes = load_file(model.path);
  if (!bytes) return t.fail_input(bytes.error().message, path), false;
  if (!t.check_stop()) return false;
  auto rvm = parse_rvm(bytes.value(), path);
  if (!rvm) return t.fail_input(rvm.error().message, path), false;
  bytes = std::vector<std::byte>{};  // the parsed file owns everything it needs
  t.report(IngestStage::parsing, rvm_bytes, total_bytes, path);
  if (!t.check_stop()) return false;

  std::unique_ptr<AttributeFile> attributes;
  if (!attribute_path.empty()) {
    file.attributes_path = attribute_path.string();
    auto text = load_file(attribute_path);
    if (!text) return t.fail_input(text.error().message, file.attributes_path), false;
    const auto& b = text.value();
    auto parsed = parse_attributes(std::string_view(reinterpret_cast<const char*>(b.data()), b.size()),
                                   file.attributes_path);
    if (!parsed) return t.fail_input(parsed.error().message, file.attributes_path), false;
    attributes = std::make_unique<AttributeFile>(std::move(parsed).value());
  }
  t.report(IngestStage::parsing, total_bytes, total_bytes, path);
  if (!t.check_stop()) return false;

  const uint64_t groups = rvm_statistics(rvm.value()).groups;
  t.report(IngestStage::classifying, 0, groups, path);
  RvmImportSummary summary;
  std::vector<Object> objects = rvm_to_objects(rvm.value(), attributes.get(), file.source, summary);
  t.report(IngestStage::classifying, groups, groups, path);
  // The objects own copies of what they need: the parse and the attributes go before storing.
  rvm.value() = RvmFile{};
  attributes.reset();

  for (size_t k = 0; k < objects.size(); ++k) {
    if (!t.put(objects[k])) return false;
    objects[k] = Object{};  // stored: its memory goes back while the transaction grows
    t.report(IngestStage::storing, k + 1, objects.size(), path);
  }
  file.groups = summary.groups;
  file.primitives = summary.primitives;
  file.objects = summary.objects;
  file.warnings = std::move(summary.warnings);
  return true;
}

// Reading one XML file in blocks, storing each object as it is read.
bool ingest_xml(Transaction& t, const ImportPlan::Model& model, IngestedFile& file) {
  const std::string path = model.path.string();
  std::error_code ec;
  const uint64_t size = fs::file_size(model.path, ec);
  t.report(IngestStage::reading, 0, ec ? 0 : size, path);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return t.fail_input(path + ": cannot open: " + std::strerror(errno), path), false;
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(f, &std::fclose);

  XmlReader reader(path, [&](Object&& object) {
    object.source = file.source;
    if (!t.put(object)) throw Abandon{};
    ++file.objects;
    file.primitives += object.primitives.size();
  });
  XmlError error;
  bool ok = true;
  std::vector<char> block(kXmlBlockBytes);
  uint64_t done = 0;
  try {
    while (ok) {
      const size_t n = std::fread(block.data(), 1, block.size(), f);
      if (n > 0 && !reader.feed(std::string_view(block.data(), n), error)) {
        ok = false;
        break;
      }
      done += n;
      if (n < block.size()) {
        if (std::ferror(f)) {
          error = {path + ": cannot read: " + std::strerror(errno), 0};
          ok = false;
        } else {
          ok = reader.finish(error);
        }
        break;
      }
      t.report(IngestStage::reading, done, size, path);
      if (!t.check_stop()) return false;
    }
  } catch (const Abandon&) {
    return false;
  }
  if (!ok) return t.fail_input(error.message, path), false;
  t.report(IngestStage::reading, done, done, path);
  return true;
}

}  // namespace

std::optional<ImportPlan> plan_import(std::span<const std::string> files, std::string& error) {
  ImportPlan plan;
  std::vector<fs::path> attribute_files;
  for (const std::string& f : files) {
    const std::string ext = lower_extension(f);
    if (ext == ".rvm" || ext == ".xml") {
      plan.models.push_back({fs::path(f), ext == ".xml", {}});
    } else if (ext == ".txt" || ext == ".att") {
      attribute_files.emplace_back(f);
    } else {
      error = f + ": not an .rvm, .xml, .txt or .att file";
      return std::nullopt;
    }
  }
  for (const fs::path& a : attribute_files) {
    const bool paired = std::any_of(plan.models.begin(), plan.models.end(), [&](const ImportPlan::Model& m) {
      return !m.xml && m.path.stem() == a.stem();
    });
    if (!paired) {
      error = a.string() + ": attribute file without an RVM file of the same name";
      return std::nullopt;
    }
  }
  if (plan.models.empty()) {
    error = "no .rvm or .xml file given";
    return std::nullopt;
  }
  // Each RVM takes the first attribute file given under its stem.
  for (ImportPlan::Model& m : plan.models) {
    if (m.xml) continue;
    const auto it = std::find_if(attribute_files.begin(), attribute_files.end(),
                                 [&](const fs::path& a) { return a.stem() == m.path.stem(); });
    if (it != attribute_files.end()) m.attributes = *it;
  }
  return plan;
}

IngestResult ingest_files(Store& store, const ImportPlan& plan, const IngestControl& control,
                          const std::function<void(const IngestedFile&)>& file_done) {
  Transaction t(store, control);
  if (!t.begin()) return t.failure();
  const auto count = uint32_t(plan.models.size());
  for (uint32_t i = 0; i < count; ++i) {
    const ImportPlan::Model& model = plan.models[i];
    t.set_file(i, count);
    IngestedFile& file = t.summary().files.emplace_back();
    file.path = model.path.string();
    file.source = source_of(model.path);
    file.xml = model.xml;
    if (!t.remove_source(file.source)) return t.failure();
    if (!(model.xml ? ingest_xml(t, model, file) : ingest_rvm(t, model, file))) return t.failure();
    if (file_done) file_done(file);
  }
  return t.commit();
}

}  // namespace plantview
