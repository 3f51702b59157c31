// The parts of the BCF library (plantview/bcf.h): zip archives (zip_io.cpp, libzip), topic
// markup (markup.cpp) and viewpoints (viewpoint.cpp) as XML (pugixml), and the mapping of
// review views to topics and back (bcf.cpp).
// Errors: false with a message naming what is wrong; callers add the file and entry.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "plantview/view_filters.h"

struct zip;

namespace plantview::bcf {

// A zip archive being written to `path` (replaced if it exists): entries are added, then
// close() writes it. Destroying it unclosed discards what was added (and leaves `path` as it
// was before open).
class ZipWriter {
 public:
  ZipWriter() = default;
  ~ZipWriter();
  ZipWriter(const ZipWriter&) = delete;
  ZipWriter& operator=(const ZipWriter&) = delete;
  bool open(const std::filesystem::path& path, std::string& error);
  // Bytes to store deflated (XML, JSON).
  bool add_bytes(const std::string& name, std::string bytes, std::string& error);
  // A file's bytes, read at close(), stored as they are (PNG is compressed already).
  bool add_file(const std::string& name, const std::filesystem::path& file, std::string& error);
  bool close(std::string& error);

 private:
  ::zip* archive_ = nullptr;
  std::filesystem::path path_;
};

// A zip archive read whole-entry at a time, each entry's name checked when opened: no absolute
// path, drive letter or '..' part (backslashes count as separators), and sizes capped.
class ZipReader {
 public:
  ZipReader() = default;
  ~ZipReader();
  ZipReader(const ZipReader&) = delete;
  ZipReader& operator=(const ZipReader&) = delete;
  bool open(const std::filesystem::path& path, uint64_t max_entry_bytes, uint64_t max_total_bytes,
            std::string& error);
  // Entry names with '\' turned into '/', in archive order (directories left out).
  const std::vector<std::string>& names() const { return names_; }
  bool has(const std::string& name) const;
  bool read(const std::string& name, std::string& out, std::string& error);

 private:
  ::zip* archive_ = nullptr;
  std::vector<std::string> names_;
  std::vector<int64_t> indices_;
  uint64_t max_entry_bytes_ = 0, max_total_bytes_ = 0, total_read_ = 0;
};

// A topic's markup.bcf, as far as plantview writes and reads it.
struct ViewpointRef {
  std::string guid, viewpoint, snapshot;  // file names relative to the topic folder
};
struct DocumentRef {
  std::string file, description;  // file: in the topic folder (not external)
};
struct Markup {
  std::string guid, title, description, date, author, topic_type;
  std::vector<ViewpointRef> viewpoints;
  std::vector<DocumentRef> documents;
};
std::string write_markup(const Markup& markup);
bool parse_markup(const std::string& xml, Markup& out, std::string& error);

// A component reference: at least one of the three set.
struct Component {
  std::string ifc_guid, originating_system, authoring_tool_id;
};
struct ColourGroup {
  std::string rgb_hex;  // "RRGGBB" or "AARRGGBB"
  std::vector<Component> components;
};
struct Viewpoint {
  std::string guid;
  enum class CameraKind { none, perspective, orthogonal } camera = CameraKind::none;
  glm::dvec3 eye{0.0}, direction{0.0}, up{0.0};
  double fov_deg = 0;             // perspective
  double view_scale_m = 0;        // orthogonal: ViewToWorldScale
  std::vector<ClipPlane> planes;  // Direction as the normal (not normalised when read)
  std::vector<Component> selection;
  bool default_visibility = true;
  std::vector<Component> exceptions;
  std::vector<ColourGroup> colours;
};
std::string write_viewpoint(const Viewpoint& viewpoint);
bool parse_viewpoint(const std::string& xml, Viewpoint& out, std::string& error);

// Shortest text that reads back as the same double.
std::string number_text(double value);

}  // namespace plantview::bcf
