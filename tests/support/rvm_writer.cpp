#include "support/rvm_writer.h"

#include <bit>
#include <cassert>
#include <cstdlib>
#include <fstream>

namespace plantview::testing {

RvmMatrix rvm_matrix(glm::mat3 basis, glm::vec3 translation_m) {
  RvmMatrix m{};
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) m[3 * c + r] = basis[c][r] * 0.001f;
  }
  m[9] = translation_m.x;
  m[10] = translation_m.y;
  m[11] = translation_m.z;
  return m;
}

void RvmWriter::u32(uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) {
    bytes_.push_back(static_cast<std::byte>(value >> shift));
  }
}

void RvmWriter::f32(float value) { u32(std::bit_cast<uint32_t>(value)); }

void RvmWriter::string(std::string_view text) {
  const size_t words = (text.size() + 3) / 4;
  u32(static_cast<uint32_t>(words));
  for (char c : text) bytes_.push_back(static_cast<std::byte>(c));
  bytes_.resize(bytes_.size() + (words * 4 - text.size()), std::byte{0});
}

void RvmWriter::patch_u32(size_t offset, uint32_t value) {
  assert(offset + 4 <= bytes_.size());
  for (int i = 0; i < 4; ++i) bytes_[offset + i] = static_cast<std::byte>(value >> (24 - 8 * i));
}

size_t RvmWriter::begin_chunk(std::string_view id) {
  assert(id.size() == 4);
  chunk_start_ = bytes_.size();
  for (char c : id) u32(static_cast<uint8_t>(c));
  u32(0);  // next-chunk offset: filled in by end_chunk
  u32(1);  // the word of unknown meaning (1 in real files)
  return chunk_start_;
}

void RvmWriter::end_chunk() {
  const size_t body = chunk_start_ + 24;
  const size_t next = next_field == NextField::absolute ? bytes_.size() : bytes_.size() - body;
  patch_u32(chunk_start_ + 16, static_cast<uint32_t>(next));
}

void RvmWriter::head(uint32_t version, std::string_view info, std::string_view note,
                     std::string_view date, std::string_view user, std::string_view encoding) {
  begin_chunk("HEAD");
  u32(version);
  string(info);
  string(note);
  string(date);
  string(user);
  if (version >= 2) string(encoding);
  end_chunk();
}

void RvmWriter::model(uint32_t version, std::string_view project, std::string_view name) {
  begin_chunk("MODL");
  u32(version);
  string(project);
  string(name);
  end_chunk();
}

void RvmWriter::begin_group(uint32_t version, std::string_view name, glm::vec3 translation_mm,
                            uint32_t material, uint8_t transparency_percent) {
  begin_chunk("CNTB");
  u32(version);
  string(name);
  f32(translation_mm.x);
  f32(translation_mm.y);
  f32(translation_mm.z);
  u32(material);
  if (version > 2) u32(uint32_t(transparency_percent) << 24);
  end_chunk();
}

void RvmWriter::end_group(uint32_t version) {
  begin_chunk("CNTE");
  u32(version);
  end_chunk();
}

namespace {
void geometry_header(RvmWriter& w, std::string_view id, uint32_t kind, const RvmMatrix& matrix,
                     const std::array<float, 6>& bounds_mm, uint8_t transparency_percent) {
  w.begin_chunk(id);
  w.u32(1);
  w.u32(kind);
  for (float f : matrix) w.f32(f);
  for (float f : bounds_mm) w.f32(f);
  if (id != "PRIM") w.u32(uint32_t(transparency_percent) << 24);
}
}  // namespace

void RvmWriter::primitive(std::string_view id, uint32_t kind, const RvmMatrix& matrix,
                          const std::array<float, 6>& bounds_mm, std::span<const float> parameters,
                          uint8_t transparency_percent) {
  geometry_header(*this, id, kind, matrix, bounds_mm, transparency_percent);
  for (float f : parameters) f32(f);
  end_chunk();
}

void RvmWriter::facet_group(std::string_view id, const RvmMatrix& matrix,
                            const std::array<float, 6>& bounds_mm,
                            const std::vector<RvmPolygon>& polygons, uint8_t transparency_percent) {
  geometry_header(*this, id, 11, matrix, bounds_mm, transparency_percent);
  u32(static_cast<uint32_t>(polygons.size()));
  for (const RvmPolygon& polygon : polygons) {
    u32(static_cast<uint32_t>(polygon.size()));
    for (const RvmContour& contour : polygon) {
      u32(static_cast<uint32_t>(contour.size()));
      for (const RvmFacetVertex& v : contour) {
        for (int i = 0; i < 3; ++i) f32(v.position_mm[i]);
        for (int i = 0; i < 3; ++i) f32(v.normal[i]);
      }
    }
  }
  end_chunk();
}

void RvmWriter::colour(uint32_t kind, uint32_t index, uint8_t r, uint8_t g, uint8_t b) {
  begin_chunk("COLR");
  u32(kind);
  u32(index);
  u32(uint32_t(r) << 24 | uint32_t(g) << 16 | uint32_t(b) << 8);
  end_chunk();
}

void RvmWriter::end() {
  begin_chunk("END:");
  u32(1);
  end_chunk();
}

void maybe_write_fuzz_seed(std::string_view name, std::span<const std::byte> bytes) {
  const char* dir = std::getenv("PLANTVIEW_FUZZ_SEED_DIR");
  if (dir == nullptr || *dir == '\0') return;
  std::ofstream out(std::string(dir) + "/" + std::string(name), std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace plantview::testing
