// Shift-tolerant image comparison (image.h: compare_images_shifted). Plain C++ over the RGBA
// bytes: no image module needed.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "plantview/image.h"

namespace plantview {

namespace {

// Marks the pixels of `from` that no pixel of `to` within the offsets explains.
void mark_unexplained(const Image& from, const Image& to,
                      const std::vector<std::pair<int, int>>& offsets, int tolerance_levels,
                      std::vector<uint8_t>& unexplained) {
  const int w = int(from.width), h = int(from.height);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const uint8_t* p = &from.rgba[(size_t(y) * w + x) * 4];
      bool explained = false;
      for (const auto& [dx, dy] : offsets) {
        const int qx = x + dx, qy = y + dy;
        if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
        const uint8_t* q = &to.rgba[(size_t(qy) * w + qx) * 4];
        if (std::abs(int(p[0]) - int(q[0])) <= tolerance_levels &&
            std::abs(int(p[1]) - int(q[1])) <= tolerance_levels &&
            std::abs(int(p[2]) - int(q[2])) <= tolerance_levels) {
          explained = true;
          break;
        }
      }
      if (!explained) unexplained[size_t(y) * w + x] = 1;
    }
  }
}

}  // namespace

bool compare_images_shifted(const Image& a, const Image& b, uint32_t shift_px, double tolerance,
                            ShiftComparison& out, std::string& error) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != size_t(a.width) * a.height * 4 ||
      b.rgba.size() != a.rgba.size()) {
    error = "compare: the images must have the same size (" + std::to_string(a.width) + "x" +
            std::to_string(a.height) + " and " + std::to_string(b.width) + "x" +
            std::to_string(b.height) + ")";
    return false;
  }
  if (shift_px > 16) {
    error = "compare: the shift tolerance must be 0..16 pixels, not " + std::to_string(shift_px);
    return false;
  }
  if (!(tolerance >= 0 && tolerance <= 1)) {
    error = "compare: the tolerance must be 0..1";
    return false;
  }
  // Offsets within the disc, nearest first (the unshifted pixel explains most).
  std::vector<std::pair<int, int>> offsets;
  const int r = int(shift_px);
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      if (dx * dx + dy * dy <= r * r) offsets.emplace_back(dx, dy);
  std::stable_sort(offsets.begin(), offsets.end(), [](const auto& p, const auto& q) {
    return p.first * p.first + p.second * p.second < q.first * q.first + q.second * q.second;
  });
  const int levels = int(std::floor(tolerance * 255.0 + 1e-9));
  std::vector<uint8_t> unexplained(size_t(a.width) * a.height, 0);
  mark_unexplained(a, b, offsets, levels, unexplained);
  mark_unexplained(b, a, offsets, levels, unexplained);
  out.unexplained_pixels = 0;
  for (const uint8_t u : unexplained) out.unexplained_pixels += u;
  out.unexplained_share = unexplained.empty() ? 0.0 : double(out.unexplained_pixels) / double(unexplained.size());
  return true;
}

}  // namespace plantview
