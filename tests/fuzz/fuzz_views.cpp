// Fuzz harness for the views file (plantview/review.h: parse_review_views). For any input:
//   - a failure leaves the output alone and says "views file" and what is wrong;
//   - whatever is accepted holds the file's rules (safe, unique names; known kinds; cameras
//     validate_camera accepts; a positive aspect; sections validate_section accepts), and written back it reads back the same, bit
//     for bit, and writes again to the same text.
#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/camera.h"
#include "plantview/review.h"

namespace {

void check(bool condition) {
  if (!condition) __builtin_trap();
}

bool same(const plantview::ReviewView& a, const plantview::ReviewView& b) {
  return a.name == b.name && a.title == b.title && a.kind == b.kind && a.camera == b.camera &&
         a.aspect == b.aspect && a.subject == b.subject && a.attributes == b.attributes &&
         a.section == b.section && a.style == b.style;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::vector<plantview::ReviewView> views(1);
  views[0].name = "untouched";
  std::string error;
  if (!plantview::parse_review_views(text, views, error)) {
    check(error.rfind("views file", 0) == 0 && error.size() > 12);
    check(views.size() == 1 && views[0].name == "untouched");
    return 0;
  }
  check(!views.empty());
  std::set<std::string> names;
  for (const auto& v : views) {
    check(plantview::is_safe_view_name(v.name) && names.insert(v.name).second);
    check(plantview::is_review_kind(v.kind));
    std::string why;
    check(plantview::validate_camera(v.camera, why));
    check(v.aspect > 0);
    check(plantview::validate_section(v.section, why));
  }
  const std::string written = plantview::review_views_json(views, "area");
  std::vector<plantview::ReviewView> again;
  check(plantview::parse_review_views(written, again, error));
  check(again.size() == views.size());
  for (size_t i = 0; i < views.size(); ++i) check(same(views[i], again[i]));
  check(plantview::review_views_json(again, "area") == written);
  return 0;
}
