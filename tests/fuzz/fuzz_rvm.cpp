// Fuzz harness for parse_rvm (plantview/rvm.h): any input must either parse into a consistent
// tree of finite primitives, or fail with a message that names an offset inside the input.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include "plantview/rvm.h"

namespace {

void check(bool condition) {
  if (!condition) __builtin_trap();
}

void check_primitive(const plantview::RvmPrimitive& p) {
  const plantview::Placement& placement = p.primitive.placement;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) check(std::isfinite(placement.linear[c][r]));
    check(std::isfinite(placement.translation_m[c]));
  }
  check(p.transparency_percent <= 100);
  if (const auto* f = std::get_if<plantview::FacetGroup>(&p.primitive.shape)) {
    uint32_t previous = 0;
    for (uint32_t end : f->contour_ends) {
      check(end >= previous && end <= f->vertices.size());
      previous = end;
    }
    previous = 0;
    for (uint32_t end : f->polygon_ends) {
      check(end >= previous && end <= f->contour_ends.size());
      previous = end;
    }
    for (uint32_t index : f->triangles) check(index < f->vertices.size());
  }
}

void check_group(const plantview::RvmGroup& group, uint32_t depth) {
  check(depth <= plantview::kMaxRvmGroupDepth);
  check(group.transparency_percent <= 100);
  for (const auto& p : group.primitives) check_primitive(p);
  for (const auto& child : group.children) check_group(child, depth + 1);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data), size);
  for (const auto mode : {plantview::RvmNextChunkOffsets::must_match,
                          plantview::RvmNextChunkOffsets::warn}) {
    plantview::RvmParseOptions options;
    options.next_chunk_offsets = mode;
    const auto parsed = plantview::parse_rvm(bytes, "fuzz", options);
    if (!parsed) {
      check(!parsed.error().message.empty() && parsed.error().offset <= size);
      continue;
    }
    const plantview::RvmFile& file = parsed.value();
    check(file.warnings.size() <= plantview::kMaxRvmWarnings);
    for (const auto& w : file.warnings) check(w.offset <= size);
    for (const auto& p : file.root_primitives) check_primitive(p);
    for (const auto& g : file.roots) check_group(g, 1);
    check(plantview::rvm_statistics(file).max_depth <= plantview::kMaxRvmGroupDepth);
  }
  return 0;
}
