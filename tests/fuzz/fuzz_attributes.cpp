// Fuzz harness for parse_attributes (plantview/rvm.h): any input must either parse into blocks
// whose lines increase in file order, or fail with a message that names a line.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "plantview/rvm.h"

namespace {

void check(bool condition) {
  if (!condition) __builtin_trap();
}

void check_block(const plantview::AttributeBlock& block, uint32_t min_line, uint32_t depth) {
  check(depth <= plantview::kMaxAttributeDepth);
  check(block.line >= min_line && !block.name.empty());
  for (const auto& [key, value] : block.attributes) check(!key.empty());
  for (const auto& child : block.children) check_block(child, block.line + 1, depth + 1);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto parsed = plantview::parse_attributes(text, "fuzz");
  if (!parsed) {
    check(parsed.error().line >= 1 && parsed.error().offset <= size);
    return 0;
  }
  for (const auto& block : parsed.value().blocks) check_block(block, 2, 1);
  const auto index = plantview::index_attribute_blocks(parsed.value());
  check(index.size() <= size);
  return 0;
}
