// Test support: a small big-endian RVM writer, so that tests (and fuzz seeds) can build exactly
// the input they need: valid files of every chunk and primitive kind, known exporter variants, and
// hostile ones (raw chunks, patched fields). Lengths are written in the file's own units
// (millimetres), as an exporter would.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

namespace plantview::testing {

// A 3x4 matrix as RVM stores it: three basis columns, then the translation (metres).
using RvmMatrix = std::array<float, 12>;
// Local millimetres to model metres: 0.001 times the given basis, then the translation.
RvmMatrix rvm_matrix(glm::mat3 basis, glm::vec3 translation_m);

// One facet-group vertex as written: position (millimetres) and normal.
struct RvmFacetVertex {
  glm::vec3 position_mm{0};
  glm::vec3 normal{0, 0, 1};
};
using RvmContour = std::vector<RvmFacetVertex>;
using RvmPolygon = std::vector<RvmContour>;  // outer contour first, then holes

class RvmWriter {
 public:
  // What each chunk's next-chunk field holds: the absolute offset after its body (correct), or
  // the body's length (the variant some older readers assumed).
  enum class NextField { absolute, body_length };
  NextField next_field = NextField::absolute;

  void head(uint32_t version, std::string_view info, std::string_view note, std::string_view date,
            std::string_view user, std::string_view encoding);
  void model(uint32_t version, std::string_view project, std::string_view name);
  // version > 2 writes the transparency word.
  void begin_group(uint32_t version, std::string_view name, glm::vec3 translation_mm,
                   uint32_t material, uint8_t transparency_percent = 0);
  void end_group(uint32_t version = 2);
  // `id` is "PRIM", "OBST" or "INSU" (the latter two write the transparency word). Kinds 1..10.
  void primitive(std::string_view id, uint32_t kind, const RvmMatrix& matrix,
                 const std::array<float, 6>& bounds_mm, std::span<const float> parameters,
                 uint8_t transparency_percent = 0);
  void facet_group(std::string_view id, const RvmMatrix& matrix,
                   const std::array<float, 6>& bounds_mm, const std::vector<RvmPolygon>& polygons,
                   uint8_t transparency_percent = 0);
  void colour(uint32_t kind, uint32_t index, uint8_t r, uint8_t g, uint8_t b);
  void end();

  // Raw building blocks. begin_chunk returns the chunk's offset; end_chunk fills in its
  // next-chunk field.
  size_t begin_chunk(std::string_view id);
  void end_chunk();
  void u32(uint32_t value);
  void f32(float value);
  void string(std::string_view text);  // word count, then the bytes NUL-padded to whole words
  void patch_u32(size_t offset, uint32_t value);

  const std::vector<std::byte>& bytes() const { return bytes_; }
  size_t size() const { return bytes_.size(); }

 private:
  std::vector<std::byte> bytes_;
  size_t chunk_start_ = 0;
};

// Writes `bytes` as <dir>/<name> when the environment variable PLANTVIEW_FUZZ_SEED_DIR names a
// directory: the parser tests thereby provide the fuzzers' seed corpus.
void maybe_write_fuzz_seed(std::string_view name, std::span<const std::byte> bytes);

}  // namespace plantview::testing
