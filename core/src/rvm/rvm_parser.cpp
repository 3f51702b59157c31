// The RVM parser: a flat walk over the chunks with an explicit stack of open groups (no recursion,
// so nesting depth costs no stack). Contract and error rules: plantview/rvm.h; format notes:
// ../shared/docs/rvm-format.md.
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include "plantview/rvm.h"

namespace plantview {
namespace {

// A chunk id as the four characters read from the low bytes of its four words.
constexpr uint32_t chunk_id(const char (&name)[5]) {
  return uint32_t(uint8_t(name[0])) << 24 | uint32_t(uint8_t(name[1])) << 16 |
         uint32_t(uint8_t(name[2])) << 8 | uint32_t(uint8_t(name[3]));
}
constexpr uint32_t kHead = chunk_id("HEAD"), kModl = chunk_id("MODL"), kCntb = chunk_id("CNTB"),
                   kCnte = chunk_id("CNTE"), kPrim = chunk_id("PRIM"), kObst = chunk_id("OBST"),
                   kInsu = chunk_id("INSU"), kColr = chunk_id("COLR"), kEnd = chunk_id("END:");

constexpr uint64_t kChunkHeaderBytes = 24;
constexpr uint64_t kMatrixBytes = 12 * 4, kBoundsBytes = 6 * 4;
constexpr uint64_t kFacetVertexBytes = 6 * 4;

// Parameter floats per RVM primitive kind 1..11 (a facet group: its polygon count word).
constexpr uint32_t kParameterWords[12] = {0, 7, 3, 4, 3, 2, 2, 9, 2, 1, 2, 1};

std::string id_text(uint32_t id) {
  std::string text;
  for (int shift = 24; shift >= 0; shift -= 8) {
    const auto c = static_cast<unsigned char>(id >> shift);
    if (c >= 0x20 && c < 0x7f) {
      text += static_cast<char>(c);
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\x%02x", c);
      text += escaped;
    }
  }
  return text;
}

std::string offset_text(uint64_t offset) {
  char text[64];
  std::snprintf(text, sizeof text, "offset %llu (0x%llx)", static_cast<unsigned long long>(offset),
                static_cast<unsigned long long>(offset));
  return text;
}

// Millimetres to metres, rounded once.
float metres(float millimetres) { return static_cast<float>(millimetres * 0.001); }

struct ChunkHeader {
  uint32_t id = 0;
  uint32_t next_offset = 0;
  uint64_t offset = 0;  // of the header
};

class RvmParser {
 public:
  RvmParser(std::span<const std::byte> bytes, std::string_view source,
            const RvmParseOptions& options)
      : data_(reinterpret_cast<const uint8_t*>(bytes.data())), size_(bytes.size()),
        source_(source), options_(options) {}

  ParseResult<RvmFile> run();

 private:
  // Stages, one per chunk kind. Each returns false after recording the error.
  bool parse_head();
  bool parse_model();
  bool begin_group();
  bool end_group();
  bool parse_geometry(RvmGeometryRole role);
  bool parse_facet_group(FacetGroup& group);
  bool parse_colour();
  bool parse_end();
  bool skip_unknown();
  bool read_chunk_header(ChunkHeader& header);
  bool finish_chunk();

  // Reading. need() guards every read: it fails the parse when fewer than n bytes remain.
  uint64_t remaining() const { return size_ - pos_; }
  bool need(uint64_t n, const char* what);
  uint32_t u32() {
    const uint8_t* p = data_ + pos_;
    pos_ += 4;
    return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | uint32_t(p[3]);
  }
  float f32() { return std::bit_cast<float>(u32()); }
  bool read_u32(uint32_t& value, const char* what);
  bool read_string(std::string& out, const char* what);
  bool read_finite(float* out, uint32_t count, const char* what);

  bool fail(uint64_t offset, const std::string& what);
  void warn(uint64_t offset, const std::string& what);
  std::string where(uint64_t offset) const;

  const uint8_t* data_;
  uint64_t size_;
  uint64_t pos_ = 0;
  std::string_view source_;
  RvmParseOptions options_;
  std::optional<ChunkHeader> chunk_;  // the chunk being parsed, for messages
  std::optional<ParseError> error_;
  RvmFile file_;
  std::vector<RvmGroup> open_;        // groups begun and not yet ended, outermost first
};

std::string RvmParser::where(uint64_t offset) const {
  std::string text(source_);
  text += ": " + offset_text(offset) + ": ";
  if (chunk_) text += id_text(chunk_->id) + " chunk at " + offset_text(chunk_->offset) + ": ";
  return text;
}

bool RvmParser::fail(uint64_t offset, const std::string& what) {
  error_ = ParseError{where(offset) + what, offset, 0};
  return false;
}

void RvmParser::warn(uint64_t offset, const std::string& what) {
  if (file_.warnings.size() < kMaxRvmWarnings) {
    file_.warnings.push_back({where(offset) + what, offset});
  } else {
    ++file_.warnings_dropped;
  }
}

bool RvmParser::need(uint64_t n, const char* what) {
  if (n <= remaining()) return true;
  return fail(pos_, std::string("truncated: ") + what + " needs " + std::to_string(n) +
                        " bytes, " + std::to_string(remaining()) + " remain");
}

bool RvmParser::read_u32(uint32_t& value, const char* what) {
  if (!need(4, what)) return false;
  value = u32();
  return true;
}

bool RvmParser::read_string(std::string& out, const char* what) {
  const uint64_t start = pos_;
  uint32_t words = 0;
  if (!read_u32(words, what)) return false;
  const uint64_t bytes = uint64_t(words) * 4;
  if (bytes > remaining()) {
    return fail(start, std::string(what) + ": string of " + std::to_string(words) +
                           " words needs " + std::to_string(bytes) + " bytes, " +
                           std::to_string(remaining()) + " remain");
  }
  const std::string_view text(reinterpret_cast<const char*>(data_ + pos_), bytes);
  out.assign(text.substr(0, text.find('\0')));  // NUL padding is not part of the string
  pos_ += bytes;
  return true;
}

// Reads `count` floats (the caller has checked they are there) and rejects non-finite ones.
bool RvmParser::read_finite(float* out, uint32_t count, const char* what) {
  for (uint32_t i = 0; i < count; ++i) {
    const uint64_t at = pos_;
    out[i] = f32();
    if (!std::isfinite(out[i])) {
      return fail(at, std::string("non-finite value in ") + what + " (float " +
                          std::to_string(i + 1) + " of " + std::to_string(count) + ")");
    }
  }
  return true;
}

bool RvmParser::read_chunk_header(ChunkHeader& header) {
  chunk_.reset();
  header.offset = pos_;
  if (pos_ == size_) return fail(pos_, "file ends without an END: chunk");
  if (!need(kChunkHeaderBytes, "chunk header")) return false;
  header.id = 0;
  for (int i = 0; i < 4; ++i) {
    const uint64_t at = pos_;
    const uint32_t word = u32();
    if (word > 0xff) {
      char text[96];
      std::snprintf(text, sizeof text,
                    "malformed chunk id: word %d is 0x%08x, expected one character in its low byte",
                    i + 1, word);
      return fail(at, text);
    }
    header.id = header.id << 8 | word;
  }
  header.next_offset = u32();
  pos_ += 4;  // a word of unknown meaning
  chunk_ = header;
  return true;
}

// The next-chunk field names where the chunk's body should have ended (files over 4 GiB wrap it,
// hence the comparison modulo 2^32).
bool RvmParser::finish_chunk() {
  if (chunk_->next_offset == static_cast<uint32_t>(pos_)) return true;
  const std::string what = "next-chunk offset field is " + std::to_string(chunk_->next_offset) +
                           ", but the body ends at " + std::to_string(pos_);
  if (options_.next_chunk_offsets == RvmNextChunkOffsets::must_match) {
    return fail(chunk_->offset + 16, what);
  }
  warn(chunk_->offset + 16, what + "; continuing from the end of the body");
  return true;
}

bool RvmParser::parse_head() {
  RvmHeader& h = file_.header;
  if (!read_u32(h.version, "HEAD version") || !read_string(h.info, "HEAD info") ||
      !read_string(h.note, "HEAD note") || !read_string(h.date, "HEAD date") ||
      !read_string(h.user, "HEAD user")) {
    return false;
  }
  if (h.version >= 2 && !read_string(h.encoding, "HEAD encoding")) return false;
  return finish_chunk();
}

bool RvmParser::parse_model() {
  RvmModel& m = file_.model;
  return read_u32(m.version, "MODL version") && read_string(m.project, "MODL project") &&
         read_string(m.name, "MODL name") && finish_chunk();
}

bool RvmParser::begin_group() {
  RvmGroup group;
  group.file_offset = chunk_->offset;
  uint32_t version = 0;
  float translation_mm[3];
  if (!read_u32(version, "CNTB version") || !read_string(group.name, "CNTB name") ||
      !need(16, "CNTB translation and material") ||
      !read_finite(translation_mm, 3, "CNTB translation")) {
    return false;
  }
  group.translation_m = {metres(translation_mm[0]), metres(translation_mm[1]),
                         metres(translation_mm[2])};
  group.material = u32();
  group.transparency_percent = open_.empty() ? 0 : open_.back().transparency_percent;
  if (version > 2) {
    if (!need(4, "CNTB transparency")) return false;
    const uint64_t at = pos_;
    uint8_t percent = static_cast<uint8_t>(u32() >> 24);
    if (percent > 100) {
      warn(at, "transparency " + std::to_string(percent) + " is above 100; clamped");
      percent = 100;
    }
    group.transparency_percent = percent;
    group.has_own_transparency = true;
  }
  if (open_.size() >= kMaxRvmGroupDepth) {
    return fail(chunk_->offset, "groups nest deeper than " + std::to_string(kMaxRvmGroupDepth));
  }
  if (!finish_chunk()) return false;
  open_.push_back(std::move(group));
  return true;
}

bool RvmParser::end_group() {
  uint32_t version = 0;
  if (!read_u32(version, "CNTE version") || !finish_chunk()) return false;
  if (open_.empty()) {
    warn(chunk_->offset, "CNTE closes no group (a known exporter variant); ignored");
    return true;
  }
  RvmGroup group = std::move(open_.back());
  open_.pop_back();
  (open_.empty() ? file_.roots : open_.back().children).push_back(std::move(group));
  return true;
}

bool RvmParser::parse_geometry(RvmGeometryRole role) {
  std::vector<RvmPrimitive>& siblings = open_.empty() ? file_.root_primitives : open_.back().primitives;
  RvmPrimitive& out = siblings.emplace_back();
  out.role = role;
  out.file_offset = chunk_->offset;
  out.transparency_percent = open_.empty() ? 0 : open_.back().transparency_percent;

  // Stage 1: version and kind, which fix the size of everything but a facet group's polygons.
  if (!need(8, "primitive version and kind")) return false;
  u32();  // version: every known version has the same layout
  const uint64_t kind_at = pos_;
  const uint32_t kind = u32();
  if (kind < 1 || kind > 11) {
    return fail(kind_at, "unknown primitive kind " + std::to_string(kind) + " (expected 1..11)");
  }
  const bool has_transparency = role != RvmGeometryRole::primitive;
  if (!need(kMatrixBytes + kBoundsBytes + (has_transparency ? 4 : 0) + 4 * kParameterWords[kind],
            "primitive matrix, bounds and parameters")) {
    return false;
  }

  // Stage 2: placement. M maps local millimetres to metres; scale its 3x3 so it takes metres.
  float m[12], box[6];
  if (!read_finite(m, 12, "matrix") || !read_finite(box, 6, "bounding box")) return false;
  Placement& placement = out.primitive.placement;
  placement.linear = glm::mat3(glm::vec3(m[0], m[1], m[2]), glm::vec3(m[3], m[4], m[5]),
                               glm::vec3(m[6], m[7], m[8])) * 1000.0f;
  placement.translation_m = glm::vec3(m[9], m[10], m[11]);
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      if (!std::isfinite(placement.linear[c][r])) {
        return fail(kind_at + 4 + 4 * (3 * c + r), "matrix value overflows when scaled to metres");
      }
    }
  }
  out.local_bounds_m = {{metres(box[0]), metres(box[1]), metres(box[2])},
                        {metres(box[3]), metres(box[4]), metres(box[5])}};

  // Stage 3: OBST and INSU carry their own transparency.
  if (has_transparency) {
    const uint64_t at = pos_;
    uint8_t percent = static_cast<uint8_t>(u32() >> 24);
    if (percent > 100) {
      warn(at, "transparency " + std::to_string(percent) + " is above 100; clamped");
      percent = 100;
    }
    out.transparency_percent = percent;
  }

  // Stage 4: the shape, millimetres to metres.
  if (kind == 11) {
    if (!parse_facet_group(out.primitive.shape.emplace<FacetGroup>())) return false;
    return finish_chunk();
  }
  float p[9];
  if (!read_finite(p, kParameterWords[kind], "primitive parameters")) return false;
  Shape& shape = out.primitive.shape;
  switch (kind) {
    case 1:
      shape = Pyramid{metres(p[0]), metres(p[1]), metres(p[2]), metres(p[3]),
                      metres(p[4]), metres(p[5]), metres(p[6])};
      break;
    case 2: shape = Box{metres(p[0]), metres(p[1]), metres(p[2])}; break;
    case 3: shape = RectangularTorus{metres(p[0]), metres(p[1]), metres(p[2]), p[3]}; break;
    case 4: shape = CircularTorus{metres(p[0]), metres(p[1]), p[2]}; break;
    case 5: shape = EllipticalDish{metres(p[0]), metres(p[1])}; break;
    case 6: shape = SphericalDish{metres(p[0]), metres(p[1])}; break;
    case 7:
      shape = Snout{metres(p[0]), metres(p[1]), metres(p[2]), metres(p[3]), metres(p[4]),
                    p[5], p[6], p[7], p[8]};
      break;
    case 8: shape = Cylinder{metres(p[0]), metres(p[1])}; break;
    case 9: shape = Sphere{metres(p[0]) * 0.5f}; break;
    case 10: shape = Line{metres(p[0]), metres(p[1])}; break;
    default: break;  // unreachable: kind was checked above
  }
  return finish_chunk();
}

// Polygons of contours of (position, normal) vertices. Each count is checked against the bytes
// left before anything is reserved for it, so a hostile count fails instead of allocating.
bool RvmParser::parse_facet_group(FacetGroup& group) {
  const uint64_t polygons_at = pos_;
  const uint32_t polygons = u32();
  if (uint64_t(polygons) * 4 > remaining()) {
    return fail(polygons_at, "facet group polygon count " + std::to_string(polygons) +
                                 " needs at least " + std::to_string(uint64_t(polygons) * 4) +
                                 " bytes, " + std::to_string(remaining()) + " remain");
  }
  group.polygon_ends.reserve(polygons);
  for (uint32_t polygon = 0; polygon < polygons; ++polygon) {
    const uint64_t contours_at = pos_;
    uint32_t contours = 0;
    if (!read_u32(contours, "facet group contour count")) return false;
    if (uint64_t(contours) * 4 > remaining()) {
      return fail(contours_at, "facet group contour count " + std::to_string(contours) +
                                   " needs at least " + std::to_string(uint64_t(contours) * 4) +
                                   " bytes, " + std::to_string(remaining()) + " remain");
    }
    for (uint32_t contour = 0; contour < contours; ++contour) {
      const uint64_t vertices_at = pos_;
      uint32_t vertices = 0;
      if (!read_u32(vertices, "facet group vertex count")) return false;
      const uint64_t bytes = uint64_t(vertices) * kFacetVertexBytes;
      if (bytes > remaining()) {
        return fail(vertices_at, "facet group vertex count " + std::to_string(vertices) +
                                     " needs " + std::to_string(bytes) + " bytes, " +
                                     std::to_string(remaining()) + " remain");
      }
      const size_t first = group.vertices.size();
      if (first + vertices > std::numeric_limits<uint32_t>::max() ||
          group.contour_ends.size() >= std::numeric_limits<uint32_t>::max()) {
        return fail(vertices_at, "facet group has more than 2^32 vertices or contours");
      }
      group.vertices.resize(first + vertices);
      for (uint32_t v = 0; v < vertices; ++v) {
        float f[6];
        if (!read_finite(f, 6, "facet group vertex")) return false;
        group.vertices[first + v] = {{metres(f[0]), metres(f[1]), metres(f[2])},
                                     {f[3], f[4], f[5]}};
      }
      group.contour_ends.push_back(static_cast<uint32_t>(group.vertices.size()));
    }
    group.polygon_ends.push_back(static_cast<uint32_t>(group.contour_ends.size()));
  }
  if (options_.triangulate_facet_groups) {
    const uint32_t skipped = group.triangulate();
    if (skipped > 0) {
      warn(chunk_->offset, "facet group: triangulation skipped " + std::to_string(skipped) +
                               " of " + std::to_string(polygons) + " polygons (degenerate)");
    }
  }
  return true;
}

bool RvmParser::parse_colour() {
  if (!need(12, "COLR body")) return false;
  RvmColour& colour = file_.colours.emplace_back();
  colour.file_offset = chunk_->offset;
  colour.kind = u32();
  colour.index = u32();
  const uint32_t rgb = u32();
  colour.r = static_cast<uint8_t>(rgb >> 24);
  colour.g = static_cast<uint8_t>(rgb >> 16);
  colour.b = static_cast<uint8_t>(rgb >> 8);
  return finish_chunk();
}

bool RvmParser::parse_end() {
  uint32_t version = 0;
  if (!read_u32(version, "END: version") || !finish_chunk()) return false;
  if (!open_.empty()) {
    return fail(chunk_->offset, std::to_string(open_.size()) +
                                    " groups are still open; the innermost, \"" +
                                    open_.back().name + "\", began at " +
                                    offset_text(open_.back().file_offset));
  }
  return true;
}

// Only a trusted next-chunk field lets the parser step over a chunk it does not know.
bool RvmParser::skip_unknown() {
  const uint64_t next = chunk_->next_offset;
  if (options_.next_chunk_offsets == RvmNextChunkOffsets::must_match && next >= pos_ &&
      next <= size_) {
    warn(chunk_->offset, "unknown chunk id; skipped to its next-chunk offset " +
                             std::to_string(next));
    pos_ = next;
    return true;
  }
  return fail(chunk_->offset, "unknown chunk id");
}

ParseResult<RvmFile> RvmParser::run() {
  // Stage 1: HEAD then MODL, always first.
  ChunkHeader header;
  if (!read_chunk_header(header)) return *error_;
  if (header.id != kHead) {
    fail(header.offset, "not an RVM file: expected a HEAD chunk");
    return *error_;
  }
  if (!parse_head() || !read_chunk_header(header)) return *error_;
  if (header.id != kModl) {
    fail(header.offset, "expected a MODL chunk after HEAD");
    return *error_;
  }
  if (!parse_model()) return *error_;

  // Stage 2: groups, geometry and colours up to END:.
  for (;;) {
    if (!read_chunk_header(header)) return *error_;
    bool ok = false;
    switch (header.id) {
      case kCntb: ok = begin_group(); break;
      case kCnte: ok = end_group(); break;
      case kPrim: ok = parse_geometry(RvmGeometryRole::primitive); break;
      case kObst: ok = parse_geometry(RvmGeometryRole::obstruction); break;
      case kInsu: ok = parse_geometry(RvmGeometryRole::insulation); break;
      case kColr: ok = parse_colour(); break;
      case kEnd:
        if (!parse_end()) return *error_;
        return std::move(file_);
      case kHead:
      case kModl: ok = fail(header.offset, "chunk out of place: only one may begin the file"); break;
      default: ok = skip_unknown(); break;
    }
    if (!ok) return *error_;
  }
}

void count_group(const RvmGroup& group, uint32_t depth, RvmStatistics& stats) {
  ++stats.groups;
  stats.max_depth = std::max(stats.max_depth, depth);
  for (const RvmPrimitive& p : group.primitives) {
    ++stats.primitives;
    ++stats.primitives_by_kind[static_cast<size_t>(p.primitive.kind())];
  }
  for (const RvmGroup& child : group.children) count_group(child, depth + 1, stats);
}

}  // namespace

ParseResult<RvmFile> parse_rvm(std::span<const std::byte> bytes, std::string_view source_name,
                               const RvmParseOptions& options) {
  return RvmParser(bytes, source_name, options).run();
}

RvmStatistics rvm_statistics(const RvmFile& file) {
  RvmStatistics stats;
  for (const RvmPrimitive& p : file.root_primitives) {
    ++stats.primitives;
    ++stats.primitives_by_kind[static_cast<size_t>(p.primitive.kind())];
  }
  for (const RvmGroup& group : file.roots) count_group(group, 1, stats);
  return stats;
}

}  // namespace plantview
