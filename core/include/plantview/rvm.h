// plantview/rvm.h: parsers for AVEVA PDMS / E3D review models (.rvm) and their attribute files
// (.txt / .att). The format is described in ../shared/docs/rvm-format.md.
//
// Both parsers are pure: they read a byte or text buffer that the caller owns and return values
// that own all their data (nothing points back into the input). They do no I/O; load_file() is
// the one helper that reads a file. Every function here is safe to call from any thread.
//
// Errors
//   Every byte of input is untrusted. Malformed, truncated or hostile input never crashes, never
//   reads outside the buffer, never loops forever, and never allocates more than a small multiple
//   of the input size: every count read from a file is checked against the bytes that remain
//   before anything is allocated for it. A parser returns either its result or one ParseError
//   whose message names the source, the chunk or line, the field, and the byte offset (binary) or
//   line (text). Problems that a reader can safely step over (known exporter variants) are
//   returned as warnings alongside the result instead.
//
// Units
//   Everything a parser returns is in metres and radians, whatever the file used: RVM local
//   parameters are millimetres and are converted here (see RvmPrimitive).
#pragma once

#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <variant>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/primitives.h"

namespace plantview {

// ---------------------------------------------------------------------------------------------
// Results and diagnostics.

// Why a parse failed. `message` is complete on its own, e.g.
//   "WD1-PSUP.RVM: offset 652 (0x28c): PRIM chunk at offset 524 (0x20c): unknown primitive kind 12"
//   "WD1-PSUP.txt:812: 'END' without an open block"
struct ParseError {
  std::string message;
  uint64_t offset = 0;  // byte offset into the input where the problem was found
  uint32_t line = 0;    // 1-based line for text inputs; 0 for binary ones
};

// Something a parser stepped over; the result is still complete and usable.
struct ParseWarning {
  std::string message;  // same form as ParseError::message
  uint64_t offset = 0;  // byte offset into the input
};

// A parse result: either a value or the error that stopped the parse. value() and error() assert
// that the result holds what is asked for.
template <class T>
class ParseResult {
 public:
  ParseResult(T value) : state_(std::move(value)) {}            // NOLINT: implicit by design
  ParseResult(ParseError error) : state_(std::move(error)) {}   // NOLINT: implicit by design

  bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & { assert(ok()); return *std::get_if<0>(&state_); }
  const T& value() const& { assert(ok()); return *std::get_if<0>(&state_); }
  T&& value() && { assert(ok()); return std::move(*std::get_if<0>(&state_)); }
  const ParseError& error() const { assert(!ok()); return *std::get_if<1>(&state_); }

 private:
  std::variant<T, ParseError> state_;
};

// Reads a whole file into memory. Errors name the path and the system's reason (a directory is
// refused as such).
ParseResult<std::vector<std::byte>> load_file(const std::filesystem::path& path);

// ---------------------------------------------------------------------------------------------
// RVM: the binary review model.
//
// Strings (names, header fields) are the file's bytes up to the first NUL, with no encoding
// conversion (RvmHeader::encoding says what the exporter used, usually UTF-8).

// What a geometry chunk was: PRIM (design geometry), OBST (obstruction volume), INSU (insulation).
enum class RvmGeometryRole : uint8_t { primitive, obstruction, insulation };

// One geometry chunk, converted to a plantview primitive.
//   - Shape parameters are metres (the file's millimetres times 0.001); angles stay radians; an
//     RVM sphere's diameter becomes Sphere::radius_m. RVM kinds 1..11 map to Pyramid, Box,
//     RectangularTorus, CircularTorus, EllipticalDish, SphericalDish, Snout, Cylinder, Sphere,
//     Line and FacetGroup; parameters are copied as they are (zero or negative sizes included:
//     the tessellator makes them empty, see primitives.h).
//   - Placement: the file's 3x4 matrix M maps local millimetres to model metres; here
//     placement.linear = 1000 * M's 3x3 so that it maps local metres to model metres, and
//     placement.translation_m = M's translation column (already metres).
//   - A FacetGroup's polygons are filled in file order and, unless the options say otherwise,
//     triangulated once (FacetGroup::triangulate).
struct RvmPrimitive {
  Primitive primitive;
  Aabb local_bounds_m;          // the file's bounding box, in the shape's local frame, metres
  RvmGeometryRole role = RvmGeometryRole::primitive;
  uint8_t transparency_percent = 0;  // 0 opaque .. 100 invisible: own for OBST/INSU, else the group's
  uint64_t file_offset = 0;          // offset of its chunk header
};

// A CNTB ... CNTE group: an element of the plant hierarchy (site, zone, equipment, pipe, ...).
// Its name matches an AttributeBlock's name in the attribute file.
struct RvmGroup {
  std::string name;
  glm::vec3 translation_m{0.0f};  // the group's reference point, metres; NOT applied to primitives
  uint32_t material = 0;          // the exporter's material (colour) index, see RvmFile::colours
  // 0 opaque .. 100 invisible. Own when the chunk carries it (CNTB version > 2), else inherited
  // from the parent group (0 at the root). Values above 100 are clamped, with a warning.
  uint8_t transparency_percent = 0;
  bool has_own_transparency = false;
  std::vector<RvmPrimitive> primitives;  // in file order
  std::vector<RvmGroup> children;        // in file order
  uint64_t file_offset = 0;              // offset of its CNTB chunk header
};

// A COLR chunk: one entry of the exporter's colour table.
struct RvmColour {
  uint32_t kind = 0;
  uint32_t index = 0;
  uint8_t r = 0, g = 0, b = 0;
  uint64_t file_offset = 0;
};

struct RvmHeader {  // the HEAD chunk
  uint32_t version = 0;
  std::string info, note, date, user;
  std::string encoding;  // empty before version 2
};

struct RvmModel {  // the MODL chunk
  uint32_t version = 0;
  std::string project, name;
};

struct RvmFile {
  RvmHeader header;
  RvmModel model;
  std::vector<RvmGroup> roots;                  // top-level groups, in file order
  std::vector<RvmPrimitive> root_primitives;    // geometry chunks outside any group
  std::vector<RvmColour> colours;               // COLR chunks, in file order
  std::vector<ParseWarning> warnings;           // the first kMaxRvmWarnings, in file order
  uint64_t warnings_dropped = 0;                // how many more there were
};

inline constexpr size_t kMaxRvmWarnings = 100;
// Groups nest at most this deep (real files: about 10); deeper input is an error, which keeps
// recursion over the returned tree (destruction included) bounded.
inline constexpr uint32_t kMaxRvmGroupDepth = 512;

// How the "next chunk" offset in every chunk header is used. The parser always reads a chunk's
// body from its content (bodies are self-delimiting), then compares where it ended with the field.
enum class RvmNextChunkOffsets : uint8_t {
  // A disagreement is an error naming the chunk and both offsets. The field is trusted, so a
  // chunk with an unknown id is skipped (with a warning) when its field points inside the file,
  // at or after the end of its header.
  must_match,
  // For exporters whose field is something else (e.g. a length): a disagreement is a warning and
  // parsing goes on from where the body ended. The field is not trusted, so an unknown chunk id
  // is an error.
  warn,
};

struct RvmParseOptions {
  RvmNextChunkOffsets next_chunk_offsets = RvmNextChunkOffsets::must_match;
  bool triangulate_facet_groups = true;  // call FacetGroup::triangulate on each facet group
};

// Parses a whole RVM file. `source_name` only prefixes messages (e.g. the file name).
//
// Errors (the first one found ends the parse): truncation anywhere (missing END: included); a
// chunk id that is not four characters in the low bytes of four words; HEAD or MODL missing or
// out of place; an unknown id that cannot be skipped (see RvmNextChunkOffsets); an unknown
// primitive kind; a count (string words, polygons, contours, vertices) larger than the bytes
// left could hold; a non-finite float anywhere in a primitive or group (matrix, bounding box,
// parameter, vertex) or one that overflows when converted; END: while groups are still open;
// groups nested deeper than kMaxRvmGroupDepth.
// Warnings: a CNTE at the root that closes no group (an AVEVA Marine variant; ignored); next-chunk
// disagreements in `warn` mode; skipped unknown chunks; transparency above 100 (clamped);
// facet-group polygons that triangulation skipped. Bytes after the END: chunk are ignored.
// Allocation is linear in bytes.size(); the parse takes time linear in it as well, facet-group
// triangulation included (a work budget linear in each polygon's points: a polygon that spends
// it is left partly triangulated, with the warning above).
ParseResult<RvmFile> parse_rvm(std::span<const std::byte> bytes, std::string_view source_name,
                               const RvmParseOptions& options = {});

// Counts over a parsed file (root_primitives included).
struct RvmStatistics {
  uint64_t groups = 0;
  uint64_t primitives = 0;
  std::array<uint64_t, kPrimitiveKindCount> primitives_by_kind{};  // indexed by PrimitiveKind
  uint32_t max_depth = 0;  // 1 when there are only root groups, 0 when none
};
RvmStatistics rvm_statistics(const RvmFile& file);

// ---------------------------------------------------------------------------------------------
// Attribute files: text, one block per element, nested like the RVM groups.
//
//   CADC_Attributes_File v1.0 , start: NEW , end: END , name_end: := , sep: &end&
//   NEW /PIPE-100
//     Name:= '/PIPE-100' &end& Type:= 'PIPE'
//     NEW /PIPE-100/B1
//       Type:= 'BRAN'
//     END
//   END
//
// Rules:
//   - An optional UTF-8 byte order mark, then the header line: comma-separated fields, the first
//     is the format tag ("CADC_Attributes_File v1.0"), the others `key: value`. `start`, `end`
//     and `name_end` are required; `sep` is optional (without it a line holds one attribute).
//   - Lines end with LF, CR LF or CR. Leading and trailing blanks (spaces, tabs) are not part of
//     anything. Blank lines are ignored.
//   - `<start> <name>` opens a block; a line that is exactly `<end>` closes the innermost one.
//     Every other line inside a block holds attributes: `key <name_end> value`, several joined by
//     `<sep>`. A value wrapped in single quotes loses them; a quoted value extends to the first
//     quote that is followed (after blanks) by the separator or the end of the line, so it may
//     contain the separator. Keys and values keep their bytes (non-UTF-8 included).
//   - Blocks nest at most kMaxAttributeDepth deep.
// Errors name the line: a missing or incomplete header, an attribute line outside a block or
// without `<name_end>` or with an empty key, a block without a name, an `<end>` without a block,
// blocks still open at the end of the text (naming the line that opened the innermost one), and
// nesting deeper than the limit.

struct AttributeBlock {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;  // (key, value), in file order
  std::vector<AttributeBlock> children;                          // in file order
  uint32_t line = 0;  // 1-based line of its `<start>` line

  // The value of the first attribute named `key`, or null. Valid while this block is unchanged.
  const std::string* find(std::string_view key) const;
};

struct AttributeKeywords {
  std::string start = "NEW", end = "END", name_end = ":=", separator = "&end&";
};

struct AttributeFile {
  std::string format;           // the header's first field, e.g. "CADC_Attributes_File v1.0"
  AttributeKeywords keywords;   // as the header declared them (separator empty when absent)
  std::vector<AttributeBlock> blocks;  // top-level blocks, in file order
};

inline constexpr uint32_t kMaxAttributeDepth = 512;

// Parses a whole attribute file. `source_name` only prefixes messages. Allocation and time are
// linear in text.size().
ParseResult<AttributeFile> parse_attributes(std::string_view text, std::string_view source_name);

// Every block of `file` (nested ones included) by name; where names repeat, the first in file
// order wins. The pointers and keys stay valid while `file` lives unchanged.
using AttributeIndex = std::unordered_map<std::string_view, const AttributeBlock*>;
AttributeIndex index_attribute_blocks(const AttributeFile& file);

}  // namespace plantview
