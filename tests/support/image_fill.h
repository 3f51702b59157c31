// How much of a rendered frame its content fills: the bounding box of what an image shows, as
// a reviewer judges framing ("the plant fills 75% of the height"), measured on the pixels.
//
// Content is, when the image has an id buffer, every pixel holding an object (or one of the
// given objects); otherwise every pixel whose colour differs from the background's (the top-left
// pixel's) by more than `tolerance` in some channel. Pure functions on plain values.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <set>

#include "plantview/image.h"

namespace plantview::test {

struct ContentBox {
  bool empty = true;
  uint32_t min_x = 0, min_y = 0, max_x = 0, max_y = 0;  // pixels, inclusive
  uint64_t pixels = 0;                                   // content pixels counted
  double width_share = 0, height_share = 0;              // of the frame, 0..1
  // What framing rules speak of: the share of the width or the height, whichever is larger.
  double fill() const { return std::max(width_share, height_share); }
};

namespace detail {
template <typename IsContent>
ContentBox content_box_where(const Image& image, const IsContent& is_content) {
  ContentBox box;
  for (uint32_t y = 0; y < image.height; ++y) {
    for (uint32_t x = 0; x < image.width; ++x) {
      if (!is_content(size_t(y) * image.width + x)) continue;
      if (box.empty) {
        box.min_x = box.max_x = x;
        box.min_y = box.max_y = y;
        box.empty = false;
      }
      box.min_x = std::min(box.min_x, x);
      box.max_x = std::max(box.max_x, x);
      box.min_y = std::min(box.min_y, y);
      box.max_y = std::max(box.max_y, y);
      ++box.pixels;
    }
  }
  if (!box.empty) {
    box.width_share = double(box.max_x - box.min_x + 1) / image.width;
    box.height_share = double(box.max_y - box.min_y + 1) / image.height;
  }
  return box;
}
}  // namespace detail

// Every object's pixels (by ids), else every pixel off the background colour.
inline ContentBox content_box(const Image& image, int tolerance = 8) {
  if (!image.object_ids.empty())
    return detail::content_box_where(image, [&](size_t i) { return image.object_ids[i] != 0; });
  const uint8_t* bg = image.rgba.data();
  return detail::content_box_where(image, [&](size_t i) {
    const uint8_t* p = image.rgba.data() + 4 * i;
    for (int c = 0; c < 3; ++c)
      if (std::abs(int(p[c]) - int(bg[c])) > tolerance) return true;
    return false;
  });
}

// The pixels of the given objects only (the image must have ids).
inline ContentBox content_box_of(const Image& image, const std::set<uint64_t>& ids) {
  return detail::content_box_where(image, [&](size_t i) { return ids.count(image.object_ids[i]) > 0; });
}

// True if every pixel has the first pixel's colour (within `tolerance` per channel).
inline bool is_one_colour(const Image& image, int tolerance = 2) {
  const uint8_t* first = image.rgba.data();
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i)
    for (int c = 0; c < 3; ++c)
      if (std::abs(int(image.rgba[4 * i + c]) - int(first[c])) > tolerance) return false;
  return true;
}

}  // namespace plantview::test
