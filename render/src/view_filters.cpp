// Sections and object styling as values: parsing and the half-space tests that culling uses
// (plantview/view_filters.h).
#include "plantview/view_filters.h"

#include <charconv>
#include <cmath>
#include <string>

namespace plantview {

namespace {

// Signed distance of `p` into the removed side of `plane` (> 0: removed).
double removed_side(const ClipPlane& plane, const glm::dvec3& p) {
  return glm::dot(p - plane.point_m, plane.normal);
}

bool parse_numbers(std::string_view text, std::string_view what, const char* shape, double* out,
                   size_t count, std::string& error) {
  size_t n = 0;
  size_t pos = 0;
  while (true) {
    const size_t comma = text.find(',', pos);
    const std::string_view word =
        text.substr(pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
    double value = 0;
    const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
    if (word.empty() || ec != std::errc() || end != word.data() + word.size() ||
        !std::isfinite(value) || n == count) {
      error = std::string(what) + ": expected " + shape + " (" + std::to_string(count) +
              " numbers separated by commas), got '" + std::string(text) + "'";
      return false;
    }
    out[n++] = value;
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  if (n != count) {
    error = std::string(what) + ": expected " + shape + " (" + std::to_string(count) +
            " numbers separated by commas), got '" + std::string(text) + "'";
    return false;
  }
  return true;
}

}  // namespace

bool section_removes(const Section& section, const glm::dvec3& point_m) {
  if (section.has_box &&
      (glm::any(glm::lessThan(point_m, section.box.min)) ||
       glm::any(glm::greaterThan(point_m, section.box.max))))
    return true;
  for (const ClipPlane& plane : section.planes)
    if (removed_side(plane, point_m) > 0.0) return true;
  return false;
}

bool section_removes_all(const Section& section, const DAabb& bounds) {
  if (bounds.empty()) return false;
  if (section.has_box &&
      (glm::any(glm::lessThan(bounds.max, section.box.min)) ||
       glm::any(glm::greaterThan(bounds.min, section.box.max))))
    return true;
  const glm::dvec3 centre = 0.5 * (bounds.min + bounds.max);
  const glm::dvec3 half = 0.5 * (bounds.max - bounds.min);
  for (const ClipPlane& plane : section.planes) {
    // The box's nearest point to the kept side lies `radius` from its centre along the normal.
    const double radius = glm::dot(half, glm::abs(plane.normal));
    if (removed_side(plane, centre) - radius > 0.0) return true;
  }
  return false;
}

bool section_keeps_all(const Section& section, const DAabb& bounds) {
  if (bounds.empty()) return true;
  if (section.has_box &&
      (glm::any(glm::lessThan(bounds.min, section.box.min)) ||
       glm::any(glm::greaterThan(bounds.max, section.box.max))))
    return false;
  const glm::dvec3 centre = 0.5 * (bounds.min + bounds.max);
  const glm::dvec3 half = 0.5 * (bounds.max - bounds.min);
  for (const ClipPlane& plane : section.planes) {
    const double radius = glm::dot(half, glm::abs(plane.normal));
    if (removed_side(plane, centre) + radius > 0.0) return false;
  }
  return true;
}

bool parse_clip_plane(std::string_view text, std::string_view what, ClipPlane& out,
                      std::string& error) {
  double v[6];
  if (!parse_numbers(text, what, "PX,PY,PZ,NX,NY,NZ", v, 6, error)) return false;
  const glm::dvec3 normal{v[3], v[4], v[5]};
  const double length = glm::length(normal);
  if (!(length > 1e-12) || !std::isfinite(length)) {
    error = std::string(what) + ": the plane's normal (" + std::to_string(v[3]) + ", " +
            std::to_string(v[4]) + ", " + std::to_string(v[5]) + ") has no direction, in '" +
            std::string(text) + "'";
    return false;
  }
  out.point_m = {v[0], v[1], v[2]};
  out.normal = normal / length;
  return true;
}

bool parse_section_box(std::string_view text, std::string_view what, DAabb& out,
                       std::string& error) {
  double v[6];
  if (!parse_numbers(text, what, "MINX,MINY,MINZ,MAXX,MAXY,MAXZ", v, 6, error)) return false;
  static const char* const kAxes[] = {"x", "y", "z"};
  for (int axis = 0; axis < 3; ++axis) {
    if (v[axis] > v[axis + 3]) {
      error = std::string(what) + ": the box's min " + kAxes[axis] + " (" +
              std::to_string(v[axis]) + ") is above its max (" + std::to_string(v[axis + 3]) +
              "), in '" + std::string(text) + "'";
      return false;
    }
  }
  out.min = {v[0], v[1], v[2]};
  out.max = {v[3], v[4], v[5]};
  return true;
}

bool parse_section_options(const std::vector<std::string>& clips, std::string_view box, Section& out,
                           std::string& error) {
  if (clips.size() > kMaxClipPlanes) {
    error = "--clip: at most " + std::to_string(kMaxClipPlanes) + " planes, got " +
            std::to_string(clips.size());
    return false;
  }
  Section section = out;
  section.planes.clear();
  for (const std::string& text : clips) {
    ClipPlane plane;
    if (!parse_clip_plane(text, "--clip", plane, error)) return false;
    section.planes.push_back(plane);
  }
  section.has_box = !box.empty();
  if (section.has_box && !parse_section_box(box, "--section-box", section.box, error)) return false;
  out = std::move(section);
  return true;
}

bool validate_section(const Section& section, std::string& error) {
  if (section.planes.size() > kMaxClipPlanes) {
    error = "a section has at most " + std::to_string(kMaxClipPlanes) + " clip planes, not " +
            std::to_string(section.planes.size());
    return false;
  }
  for (size_t i = 0; i < section.planes.size(); ++i) {
    const ClipPlane& p = section.planes[i];
    const double length = glm::length(p.normal);
    if (!std::isfinite(length) || std::abs(length - 1.0) > 1e-6 ||
        !std::isfinite(p.point_m.x + p.point_m.y + p.point_m.z)) {
      error = "clip plane " + std::to_string(i) +
              ": needs a finite point and a normal of unit length";
      return false;
    }
  }
  if (section.has_box) {
    const DAabb& b = section.box;
    if (!std::isfinite(b.min.x + b.min.y + b.min.z + b.max.x + b.max.y + b.max.z) ||
        b.min.x > b.max.x || b.min.y > b.max.y || b.min.z > b.max.z) {
      error = "the section box needs finite corners with min <= max on every axis";
      return false;
    }
  }
  return true;
}

bool parse_word_list(std::string_view text, std::string_view what, std::vector<std::string>& out,
                     std::string& error) {
  std::vector<std::string> words;
  size_t pos = 0;
  while (pos <= text.size()) {
    const size_t comma = text.find(',', pos);
    std::string_view word =
        text.substr(pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
    while (!word.empty() && word.front() == ' ') word.remove_prefix(1);
    while (!word.empty() && word.back() == ' ') word.remove_suffix(1);
    if (!word.empty()) words.emplace_back(word);
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  if (words.empty()) {
    error = std::string(what) + ": expected words separated by commas, got '" +
            std::string(text) + "'";
    return false;
  }
  out = std::move(words);
  return true;
}

namespace {

// `s` is a whole number, all of it.
bool whole_number(std::string_view s, uint32_t& v) {
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return !s.empty() && ec == std::errc() && end == s.data() + s.size();
}

}  // namespace

bool parse_change_range(std::string_view text, ChangeRange& out, std::string& error) {
  const size_t dots = text.find("..");
  ChangeRange range;
  const bool ok = dots == std::string_view::npos
                      ? whole_number(text, range.from)
                      : whole_number(text.substr(0, dots), range.from) &&
                            whole_number(text.substr(dots + 2), range.to);
  if (!ok) {
    error = "expected a revision R1 or a range R1..R2 (whole numbers), got '" + std::string(text) + "'";
    return false;
  }
  if (dots != std::string_view::npos && range.from >= range.to) {
    error = "'" + std::string(text) + "': the first revision must come before the second";
    return false;
  }
  out = range;
  return true;
}

std::string change_range_text(const ChangeRange& range) {
  return std::to_string(range.from) + (range.to ? ".." + std::to_string(range.to) : "");
}

}  // namespace plantview
