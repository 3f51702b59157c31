// The image module: image files and comparison through OpenImageIO, behind the C interface of
// image_module_api.h. Built as a loadable module so that only runs that touch images load
// OpenImageIO and its libraries.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "image_module_api.h"

namespace {

void set_error(char* error, size_t error_size, const std::string& message) {
  if (!error || error_size == 0) return;
  const size_t n = std::min(message.size(), error_size - 1);
  std::memcpy(error, message.data(), n);
  error[n] = '\0';
}

// Runs `body`, turning any exception into a failure: none may cross the C interface.
template <class Body>
int guarded(char* error, size_t error_size, Body&& body) noexcept {
  try {
    std::string message;
    if (body(message)) return 1;
    set_error(error, error_size, message);
  } catch (const std::exception& e) {
    set_error(error, error_size, std::string("image: OpenImageIO failed: ") + e.what());
  } catch (...) {
    set_error(error, error_size, "image: OpenImageIO failed with an unknown exception");
  }
  return 0;
}

OIIO::ImageBuf as_buffer(const uint8_t* rgba, uint32_t width, uint32_t height) {
  OIIO::ImageSpec spec(int(width), int(height), 4, OIIO::TypeDesc::UINT8);
  // Wraps the caller's pixels without a copy; the buffer must not outlive them.
  return OIIO::ImageBuf(spec, const_cast<uint8_t*>(rgba));
}

// Writes RGB to an opened-by-name output, to a file or through an in-memory proxy.
bool write_rgb(const uint8_t* rgba, uint32_t width, uint32_t height, int format,
               int jpeg_quality, const std::string& name, OIIO::Filesystem::IOProxy* proxy,
               std::string& error) {
  const bool png = format == PLANTVIEW_IMAGE_PNG;
  if (!png && format != PLANTVIEW_IMAGE_JPEG) {
    error = "image: unknown format " + std::to_string(format) + " for " + name;
    return false;
  }
  if (!png && (jpeg_quality < 1 || jpeg_quality > 100)) {
    error = "image: JPEG quality must be 1..100, got " + std::to_string(jpeg_quality);
    return false;
  }
  auto out = OIIO::ImageOutput::create(png ? "png" : "jpg");
  if (!out) {
    error = std::string("image: no ") + (png ? "PNG" : "JPEG") + " writer (" +
            OIIO::geterror() + ")";
    return false;
  }
  OIIO::ImageSpec spec(int(width), int(height), 3, OIIO::TypeDesc::UINT8);
  if (png) {
    // Fast, for review images that are large: zlib level 3, rows unfiltered (libpng's
    // PNG_FILTER_NONE). Its adaptive choice of a filter per row took twice the time for about
    // the same size on rendered frames (1280x720, 2026-12-04: 37-67 -> 22-38 ms; -22% to +20%
    // in bytes, sky and ground compressing better unfiltered, textured views worse).
    spec.attribute("png:compressionLevel", 3);
    spec.attribute("png:filter", 0x08);
  } else {
    spec.attribute("Compression", "jpeg:" + std::to_string(jpeg_quality));
    spec.attribute("CompressionQuality", jpeg_quality);
  }
  if (proxy && !out->set_ioproxy(proxy)) {
    error = "image: the encoder cannot write to memory";
    return false;
  }
  if (!out->open(name, spec)) {
    error = "image: cannot write " + name + ": " + out->geterror();
    return false;
  }
  // RGBA pixels, 4 bytes apart: the writer reads the first three channels of each.
  const bool ok = out->write_image(OIIO::TypeDesc::UINT8, rgba, 4);
  const bool closed = out->close();
  if (!ok || !closed) {
    error = "image: writing " + name + " failed: " + out->geterror();
    return false;
  }
  return true;
}

int encode_to_memory(const uint8_t* rgba, uint32_t width, uint32_t height, int format,
                     int jpeg_quality, PlantviewImageAllocate allocate, void* context,
                     char* error, size_t error_size) noexcept {
  return guarded(error, error_size, [&](std::string& message) {
    std::vector<uint8_t> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    if (!write_rgb(rgba, width, height, format, jpeg_quality,
                   format == PLANTVIEW_IMAGE_PNG ? "frame.png" : "frame.jpg", &proxy, message))
      return false;
    uint8_t* out = allocate(context, bytes.size());
    if (!out) {
      message = "image: no memory for " + std::to_string(bytes.size()) + " encoded bytes";
      return false;
    }
    if (!bytes.empty()) std::memcpy(out, bytes.data(), bytes.size());
    return true;
  });
}

int write_file(const char* path, const uint8_t* rgba, uint32_t width, uint32_t height,
               int format, int jpeg_quality, char* error, size_t error_size) noexcept {
  return guarded(error, error_size, [&](std::string& message) {
    return write_rgb(rgba, width, height, format, jpeg_quality, path, nullptr, message);
  });
}

int read_file(const char* path, uint32_t max_side, uint32_t* width, uint32_t* height,
              PlantviewImageAllocate allocate, void* context, char* error,
              size_t error_size) noexcept {
  return guarded(error, error_size, [&](std::string& message) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
      message = std::string("image: cannot read ") + path + ": " + OIIO::geterror();
      return false;
    }
    const auto& spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || uint64_t(spec.width) > max_side ||
        uint64_t(spec.height) > max_side || spec.nchannels < 1) {
      message = std::string("image: ") + path + ": unsupported size " +
                std::to_string(spec.width) + "x" + std::to_string(spec.height);
      return false;
    }
    const size_t channels = size_t(spec.nchannels);
    const size_t count = size_t(spec.width) * size_t(spec.height);
    std::vector<uint8_t> pixels(count * channels);
    if (!in->read_image(0, 0, 0, int(channels), OIIO::TypeDesc::UINT8, pixels.data())) {
      message = std::string("image: ") + path + ": " + in->geterror();
      return false;
    }
    uint8_t* rgba = allocate(context, count * 4);
    if (!rgba) {
      message = std::string("image: ") + path + ": no memory for " + std::to_string(count * 4) +
                " bytes of pixels";
      return false;
    }
    for (size_t p = 0; p < count; ++p) {
      const uint8_t* from = &pixels[p * channels];
      for (size_t c = 0; c < 3; ++c) rgba[p * 4 + c] = from[std::min(c, channels - 1)];
      rgba[p * 4 + 3] = channels >= 4 ? from[3] : 255;
    }
    *width = uint32_t(spec.width);
    *height = uint32_t(spec.height);
    return true;
  });
}

int compare_rgb(const uint8_t* a, const uint8_t* b, uint32_t width, uint32_t height,
                double threshold, PlantviewImageDifference* out, char* error,
                size_t error_size) noexcept {
  return guarded(error, error_size, [&](std::string& message) {
    const OIIO::ImageBuf A = as_buffer(a, width, height), B = as_buffer(b, width, height);
    OIIO::ROI rgb = A.roi();
    rgb.chbegin = 0;
    rgb.chend = 3;
    const auto result =
        OIIO::ImageBufAlgo::compare(A, B, float(threshold), float(threshold), rgb);
    // result.error is also set when pixels fail the threshold; only a message means failure.
    if (const std::string why = OIIO::geterror(); result.error && !why.empty()) {
      message = "compare: " + why;
      return false;
    }
    out->max_error = result.maxerror;
    out->rms_error = result.rms_error;
    out->failing_pixels = uint64_t(result.nfail);
    return true;
  });
}

// --- captions ------------------------------------------------------------------------------------

constexpr const char* kFontRegular = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
constexpr const char* kFontBold = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf";

// Width in pixels of `text` set in `font` at `size_px` (0 when it cannot be measured).
int text_width(const std::string& text, int size_px, const char* font) {
  const OIIO::ROI r = OIIO::ImageBufAlgo::text_size(text, size_px, font);
  return r.defined() ? r.width() : 0;
}

// `text` cut at a UTF-8 character boundary, with an ellipsis, to fit `width_px`.
std::string fitted(std::string text, int size_px, const char* font, int width_px) {
  if (text_width(text, size_px, font) <= width_px) return text;
  while (!text.empty()) {
    do text.pop_back();  // whole characters: drop continuation bytes with their lead byte
    while (!text.empty() && (uint8_t(text.back()) & 0xC0) == 0x80);
    if (!text.empty()) text.pop_back();
    if (text_width(text + "\u2026", size_px, font) <= width_px) return text + "\u2026";
  }
  return text;
}

int caption_rgba(uint8_t* rgba, uint32_t width, uint32_t height, const char* title,
                 const char* const* lines, size_t line_count, char* error,
                 size_t error_size) noexcept {
  return guarded(error, error_size, [&](std::string& message) {
    for (const char* font : {kFontRegular, kFontBold}) {
      if (!OIIO::Filesystem::exists(font)) {
        message = std::string("caption: font ") + font + " not found (install fonts-dejavu-core)";
        return false;
      }
    }
    // Sizes follow the image's height: 1280x720 gets a 22 px title and 18 px lines.
    const int title_px = std::clamp(int(height) / 32, 9, 64);
    const int line_px = std::max(8, title_px * 4 / 5);
    const int pad_px = std::max(3, title_px / 2);
    const int title_step = title_px * 5 / 4, line_step = line_px * 5 / 4;
    // As many lines as fit in half the image, after the title.
    const int room = int(height) / 2 - 2 * pad_px - title_step;
    if (room < 0) {
      message = "caption: the image (" + std::to_string(width) + "x" + std::to_string(height) +
                ") is too small for a caption";
      return false;
    }
    const size_t shown = std::min(line_count, size_t(room / line_step));
    const int strip_px = 2 * pad_px + title_step + int(shown) * line_step;
    const int top = int(height) - strip_px;

    // A light strip over the image (the image shows faintly through it) with a dark rule on top.
    for (int y = top; y < int(height); ++y) {
      uint8_t* row = rgba + size_t(y) * width * 4;
      for (uint32_t x = 0; x < width; ++x) {
        for (int c = 0; c < 3; ++c)
          row[x * 4 + c] = y == top ? uint8_t(90) : uint8_t((row[x * 4 + c] * 12 + 248 * 88) / 100);
        row[x * 4 + 3] = 255;
      }
    }
    OIIO::ImageSpec spec(int(width), int(height), 4, OIIO::TypeDesc::UINT8);
    OIIO::ImageBuf buffer(spec, rgba);  // wraps the caller's pixels: drawn in place
    const float ink[4] = {0.08f, 0.09f, 0.11f, 1.0f};
    const int text_width_px = int(width) - 2 * pad_px;
    const auto draw = [&](const std::string& text, int baseline, int size_px, const char* font) {
      if (text.empty()) return true;
      if (OIIO::ImageBufAlgo::render_text(buffer, pad_px, baseline,
                                          fitted(text, size_px, font, text_width_px), size_px,
                                          font, ink))
        return true;
      message = "caption: cannot draw text with " + std::string(font) + ": " + buffer.geterror();
      return false;
    };
    int baseline = top + pad_px + title_px;
    if (!draw(title ? title : "", baseline, title_px, kFontBold)) return false;
    baseline += title_step - title_px + line_px;
    for (size_t i = 0; i < shown; ++i, baseline += line_step)
      if (!draw(lines[i] ? lines[i] : "", baseline, line_px, kFontRegular)) return false;
    return true;
  });
}

constexpr PlantviewImageApiV2 kApi = {
    .version = PLANTVIEW_IMAGE_API_VERSION,
    .struct_size = sizeof(PlantviewImageApiV2),
    .encode = encode_to_memory,
    .write = write_file,
    .read = read_file,
    .compare = compare_rgb,
    .caption = caption_rgba,
};

}  // namespace

extern "C" __attribute__((visibility("default"))) const PlantviewImageApiV2*
plantview_image_api_v2(void) {
  return &kApi;
}
