// plantview/image.h: rendered images, image files, encoding, comparison and captions.
//
// Image files, encoding, comparison and captions go through OpenImageIO in a loadable module
// (plantview_image_oiio), loaded once per process by the first call below that needs it, or
// earlier by preload_image_io(). Looked for at $PLANTVIEW_IMAGE_MODULE when that is set (and
// only there), else beside the running executable, else where the build wrote it. When it
// cannot be loaded, every call that needs it fails with a message naming each path tried and
// why.
//
// Pixels: RGBA8 holding sRGB values, row 0 at the top.
// Threads: every function here may be called from any thread; an Image is a plain value.
// Errors: fallible calls return false and fill `error` with what and where (the file, the size).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace plantview {

// A rendered frame. Row 0 is the top. `object_ids` holds, per pixel, the id (model.h) of the
// object drawn there, 0 where there is none.
struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;          // width * height * 4
  std::vector<uint64_t> object_ids;   // width * height (empty if not asked for)
};

// Largest image the renderer and encoders accept in either direction.
inline constexpr uint32_t kMaxImageSide = 16384;

// Starts loading the image module on a background thread and returns at once (loading it
// takes about half a second on Debian, where OpenImageIO brings some 260 libraries). Image calls
// made meanwhile wait for it; a second call does nothing; a failed load is reported by the first
// image call. The load holds the dynamic loader's lock throughout, so other threads' dlopen and
// dlsym wait for it meanwhile: EGL initialisation, and libepoxy at the first call of each GL
// function. Call it once images are sure to be needed, after GpuContext::create.
void preload_image_io();

enum class ImageFormat { png, jpeg };
// From a file name's extension (.png, .jpg, .jpeg) or a format name ("png", "jpeg", "jpg").
bool image_format_from_name(std::string_view name, ImageFormat& format);
// Encodes RGB (alpha dropped) into memory; jpeg_quality 1..100.
bool encode_image(const Image& image, ImageFormat format, int jpeg_quality,
                  std::vector<uint8_t>& out, std::string& error);
bool write_image(const std::string& path, const Image& image, int jpeg_quality,
                 std::string& error);
// Reads an image file as RGBA8.
bool read_image(const std::string& path, Image& out, std::string& error);

struct ImageComparison {
  double psnr_db = 0;          // over RGB, 8-bit; +infinity for identical images
  double max_difference = 0;   // largest channel difference, 0..1
  double differing_share = 0;  // share of pixels with any channel differing by more than 1/255
};
// Compares two images of the same size (error otherwise).
bool compare_images(const Image& a, const Image& b, ImageComparison& out, std::string& error);
// Writes an image of the per-channel absolute differences of a and b (same size), times 8, to
// `path` (its format from the extension).
bool write_difference_image(const Image& a, const Image& b, const std::string& path,
                            std::string& error);

// Draws a caption strip along the bottom of `image` (inside it; the size is unchanged): the
// title in bold on the first line, then each of `lines` (e.g. "Tag P-101A", "Type PUMP"),
// with DejaVu Sans through OpenImageIO (the image module), dark text on a light strip. The text
// is UTF-8; a line too long for the width is cut with an ellipsis; lines that do not fit in
// half the image's height are left out. The object ids, if any, are left as they are. False
// with a message if the font cannot be found (fonts-dejavu-core:
// /usr/share/fonts/truetype/dejavu), the module cannot be loaded or the image is malformed.
bool add_caption(Image& image, std::string_view title, const std::vector<std::string>& lines,
                 std::string& error);
// A colour key before a caption line (legends): one colour, a square; several, a bar ramping
// through them left to right; none, nothing.
struct CaptionSwatch {
  std::vector<std::array<uint8_t, 3>> rgb;
};
// The same caption, lines[i] after swatches[i] (swatches may be shorter than lines): every line
// and the title move right by the widest key's room. Lines left out (half the height) leave
// out their keys too.
bool add_caption(Image& image, std::string_view title, const std::vector<std::string>& lines,
                 const std::vector<CaptionSwatch>& swatches, std::string& error);
// How much of a difference a small shift explains: a pixel is explained when a pixel of the
// other image within shift_px of it (Euclidean, in pixels) has every channel (RGB) within
// tolerance (0..1) of it; checked both ways (A's pixels in B, B's in A). Shows where a LOD moves
// edges by more than it promises. Same sizes, shift_px 0..16, tolerance 0..1 (error otherwise).
struct ShiftComparison {
  double unexplained_share = 0;  // pixels not explained in one direction or the other
  uint64_t unexplained_pixels = 0;
};
bool compare_images_shifted(const Image& a, const Image& b, uint32_t shift_px, double tolerance,
                            ShiftComparison& out, std::string& error);

}  // namespace plantview
