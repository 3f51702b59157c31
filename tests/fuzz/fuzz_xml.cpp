// Fuzz harness for the plantview XML reader (plantview/xml.h). For any input:
//   - reading it whole and reading it fed in small pieces give the same objects or the same error;
//   - a failure names a line inside the input;
//   - whatever is accepted is written back without refusal, and that text reads back to the same
//     objects, bit for bit, and writes again to the same text.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "../support/object_bits.h"
#include "plantview/xml.h"

namespace {

void check(bool condition) {
  if (!condition) __builtin_trap();
}

struct Outcome {
  bool ok = false;
  plantview::XmlError error;
  std::vector<plantview::Object> objects;
};

Outcome read_whole(std::string_view text) {
  Outcome o;
  o.ok = plantview::read_xml(
      text, "fuzz", [&](plantview::Object&& object) { o.objects.push_back(std::move(object)); },
      o.error);
  return o;
}

Outcome read_in_pieces(std::string_view text, size_t piece) {
  Outcome o;
  plantview::XmlReader reader(
      "fuzz", [&](plantview::Object&& object) { o.objects.push_back(std::move(object)); });
  o.ok = true;
  for (size_t at = 0; o.ok && at < text.size(); at += piece)
    o.ok = reader.feed(text.substr(at, piece), o.error);
  o.ok = o.ok && reader.finish(o.error);
  return o;
}

void check_same(const Outcome& a, const Outcome& b) {
  check(a.ok == b.ok);
  check(a.error.message == b.error.message && a.error.line == b.error.line);
  check(a.objects.size() == b.objects.size());
  for (size_t i = 0; i < a.objects.size(); ++i) {
    check(plantview::test::object_difference(a.objects[i], b.objects[i]).empty());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const Outcome whole = read_whole(text);
  check_same(whole, read_in_pieces(text, size == 0 ? 1 : 1 + data[0] % 17));

  if (!whole.ok) {
    size_t lines = 1;
    for (char c : text) lines += c == '\n';
    check(whole.error.line >= 1 && whole.error.line <= lines);
    check(whole.error.message.rfind("fuzz:" + std::to_string(whole.error.line) + ": ", 0) == 0);
    return 0;
  }

  std::string written;
  plantview::XmlError error;
  check(plantview::write_xml(whole.objects, written, error));
  const Outcome again = read_whole(written);
  check(again.ok);
  check_same(whole, again);
  std::string rewritten;
  check(plantview::write_xml(again.objects, rewritten, error));
  check(rewritten == written);
  return 0;
}
