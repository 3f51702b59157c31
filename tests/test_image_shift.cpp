// compare_images_shifted (image.h): the share of pixels a shift of up to R pixels does not
// explain, on images built here whose answer is known by construction.
#include <gtest/gtest.h>

#include <algorithm>

#include "plantview/image.h"

namespace plantview {
namespace {

// A width x height grey image with a white rectangle [x0, x0 + side) x [y0, y0 + tall) (clipped;
// tall 0: as tall as it is wide).
Image square(uint32_t width, uint32_t height, int x0, int y0, int side, int tall = 0) {
  if (tall == 0) tall = side;
  Image image;
  image.width = width;
  image.height = height;
  image.rgba.assign(size_t(width) * height * 4, 60);
  for (int y = y0; y < std::min(y0 + tall, int(height)); ++y)
    for (int x = x0; x < std::min(x0 + side, int(width)); ++x)
      for (int c = 0; c < 3; ++c) image.rgba[(size_t(y) * width + x) * 4 + c] = 250;
  return image;
}

TEST(CompareShifted, AnEdgeMovedByThreePixelsIsExplainedByAShiftOfThreeNotTwo) {
  // A white stripe over every row, columns 20..35 in A and 23..38 in B.
  const Image a = square(64, 48, 20, 0, 16, 48), b = square(64, 48, 23, 0, 16, 48);
  ShiftComparison c;
  std::string error;
  ASSERT_TRUE(compare_images_shifted(a, b, 3, 0.05, c, error)) << error;
  EXPECT_EQ(c.unexplained_pixels, 0u);
  ASSERT_TRUE(compare_images_shifted(a, b, 2, 0.05, c, error)) << error;
  // Three columns from the nearest match: A's 20 (white) and 36 (grey), B's 38 (white) and
  // 22 (grey).
  EXPECT_EQ(c.unexplained_pixels, 4u * 48u);
  EXPECT_DOUBLE_EQ(c.unexplained_share, 4.0 * 48.0 / (64.0 * 48.0));
  ASSERT_TRUE(compare_images_shifted(a, b, 0, 0.05, c, error)) << error;
  EXPECT_EQ(c.unexplained_pixels, 6u * 48u);  // every pixel that differs: columns 20-22, 36-38
}

TEST(CompareShifted, ToleranceDecidesWhetherAChannelMatches) {
  Image a = square(16, 16, 0, 0, 0), b = a;
  for (size_t i = 0; i < b.rgba.size(); i += 4) b.rgba[i] = uint8_t(60 + 10);  // red +10 levels
  ShiftComparison c;
  std::string error;
  ASSERT_TRUE(compare_images_shifted(a, b, 1, 10.0 / 255.0, c, error)) << error;
  EXPECT_EQ(c.unexplained_pixels, 0u);
  ASSERT_TRUE(compare_images_shifted(a, b, 1, 9.0 / 255.0, c, error)) << error;
  EXPECT_EQ(c.unexplained_pixels, 256u);
}

TEST(CompareShifted, RefusesImagesOfDifferentSizesAndShiftsOutOfRange) {
  ShiftComparison c;
  std::string error;
  EXPECT_FALSE(compare_images_shifted(square(8, 8, 0, 0, 1), square(8, 9, 0, 0, 1), 1, 0.05, c, error));
  EXPECT_NE(error.find("same size"), std::string::npos) << error;
  EXPECT_FALSE(compare_images_shifted(square(8, 8, 0, 0, 1), square(8, 8, 0, 0, 1), 17, 0.05, c, error));
  EXPECT_NE(error.find("0..16"), std::string::npos) << error;
}

}  // namespace
}  // namespace plantview
