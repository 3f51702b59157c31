// Image files and comparison through OpenImageIO.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "plantview/render.h"

namespace plantview {

namespace {

bool check_image(const Image& image, std::string& error) {
  if (image.width == 0 || image.height == 0 || image.width > kMaxImageSide ||
      image.height > kMaxImageSide ||
      image.rgba.size() != size_t(image.width) * image.height * 4) {
    error = "image: bad size " + std::to_string(image.width) + "x" + std::to_string(image.height);
    return false;
  }
  return true;
}

OIIO::ImageBuf as_buffer(const Image& image) {
  OIIO::ImageSpec spec(int(image.width), int(image.height), 4, OIIO::TypeDesc::UINT8);
  // Wraps the caller's pixels without a copy; the buffer must not outlive `image`.
  return OIIO::ImageBuf(spec, const_cast<uint8_t*>(image.rgba.data()));
}

// Writes RGB to an opened-by-name output, to a file or through an in-memory proxy.
bool write_rgb(const Image& image, ImageFormat format, int jpeg_quality, const std::string& name,
               OIIO::Filesystem::IOProxy* proxy, std::string& error) {
  if (!check_image(image, error)) return false;
  if (format == ImageFormat::jpeg && (jpeg_quality < 1 || jpeg_quality > 100)) {
    error = "image: JPEG quality must be 1..100, got " + std::to_string(jpeg_quality);
    return false;
  }
  auto out = OIIO::ImageOutput::create(format == ImageFormat::png ? "png" : "jpg");
  if (!out) {
    error = "image: no " + std::string(format == ImageFormat::png ? "PNG" : "JPEG") +
            " writer (" + OIIO::geterror() + ")";
    return false;
  }
  OIIO::ImageSpec spec(int(image.width), int(image.height), 3, OIIO::TypeDesc::UINT8);
  if (format == ImageFormat::jpeg) {
    spec.attribute("Compression", "jpeg:" + std::to_string(jpeg_quality));
    spec.attribute("CompressionQuality", jpeg_quality);
  } else {
    spec.attribute("png:compressionLevel", 3);  // fast; review images are large
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
  const bool ok = out->write_image(OIIO::TypeDesc::UINT8, image.rgba.data(), 4);
  const bool closed = out->close();
  if (!ok || !closed) {
    error = "image: writing " + name + " failed: " + out->geterror();
    return false;
  }
  return true;
}

}  // namespace

bool image_format_from_name(std::string_view name, ImageFormat& format) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  const auto ends = [&](std::string_view suffix) {
    return lower.size() >= suffix.size() &&
           lower.compare(lower.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  if (lower == "png" || ends(".png")) format = ImageFormat::png;
  else if (lower == "jpeg" || lower == "jpg" || ends(".jpg") || ends(".jpeg"))
    format = ImageFormat::jpeg;
  else return false;
  return true;
}

bool encode_image(const Image& image, ImageFormat format, int jpeg_quality,
                  std::vector<uint8_t>& out, std::string& error) {
  out.clear();
  OIIO::Filesystem::IOVecOutput proxy(out);
  return write_rgb(image, format, jpeg_quality,
                   format == ImageFormat::png ? "frame.png" : "frame.jpg", &proxy, error);
}

bool write_image(const std::string& path, const Image& image, int jpeg_quality,
                 std::string& error) {
  ImageFormat format;
  if (!image_format_from_name(path, format)) {
    error = "image: " + path + ": unknown format (use .png, .jpg or .jpeg)";
    return false;
  }
  return write_rgb(image, format, jpeg_quality, path, nullptr, error);
}

bool read_image(const std::string& path, Image& out, std::string& error) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    error = "image: cannot read " + path + ": " + OIIO::geterror();
    return false;
  }
  const auto& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.width > int(kMaxImageSide) ||
      spec.height > int(kMaxImageSide) || spec.nchannels < 1) {
    error = "image: " + path + ": unsupported size " + std::to_string(spec.width) + "x" +
            std::to_string(spec.height);
    return false;
  }
  const int channels = spec.nchannels;
  std::vector<uint8_t> pixels(size_t(spec.width) * spec.height * size_t(channels));
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::UINT8, pixels.data())) {
    error = "image: " + path + ": " + in->geterror();
    return false;
  }
  out.width = uint32_t(spec.width);
  out.height = uint32_t(spec.height);
  out.rgba.assign(size_t(out.width) * out.height * 4, 255);
  out.object_ids.clear();
  for (size_t p = 0; p < size_t(out.width) * out.height; ++p) {
    for (int c = 0; c < 4; ++c) {
      if (c < 3) out.rgba[p * 4 + size_t(c)] = pixels[p * size_t(channels) + size_t(std::min(c, channels - 1))];
      else if (channels >= 4) out.rgba[p * 4 + 3] = pixels[p * size_t(channels) + 3];
    }
  }
  return true;
}

bool compare_images(const Image& a, const Image& b, ImageComparison& out, std::string& error) {
  if (!check_image(a, error) || !check_image(b, error)) return false;
  if (a.width != b.width || a.height != b.height) {
    error = "compare: sizes differ (" + std::to_string(a.width) + "x" + std::to_string(a.height) +
            " and " + std::to_string(b.width) + "x" + std::to_string(b.height) + ")";
    return false;
  }
  const OIIO::ImageBuf A = as_buffer(a), B = as_buffer(b);
  OIIO::ROI rgb = A.roi();
  rgb.chbegin = 0;
  rgb.chend = 3;
  // A pixel "differs" when any channel is more than one 8-bit step apart.
  const float step = 1.5f / 255.0f;
  const auto result = OIIO::ImageBufAlgo::compare(A, B, step, step, rgb);
  // result.error is also set when pixels fail the threshold; only a message means failure.
  if (const std::string why = OIIO::geterror(); result.error && !why.empty()) {
    error = "compare: " + why;
    return false;
  }
  out.max_difference = result.maxerror;
  out.differing_share = double(result.nfail) / (double(a.width) * a.height);
  out.psnr_db = result.rms_error > 0 ? 20.0 * std::log10(1.0 / result.rms_error)
                                     : std::numeric_limits<double>::infinity();
  return true;
}

bool write_difference_image(const Image& a, const Image& b, const std::string& path,
                            std::string& error) {
  if (!check_image(a, error) || !check_image(b, error)) return false;
  if (a.width != b.width || a.height != b.height) {
    error = "compare: sizes differ";
    return false;
  }
  Image diff;
  diff.width = a.width;
  diff.height = a.height;
  diff.rgba.resize(a.rgba.size());
  for (size_t i = 0; i < a.rgba.size(); ++i) {
    const int d = std::abs(int(a.rgba[i]) - int(b.rgba[i]));
    diff.rgba[i] = (i % 4 == 3) ? 255 : uint8_t(std::min(255, d * 8));
  }
  return write_image(path, diff, 90, error);
}

}  // namespace plantview
