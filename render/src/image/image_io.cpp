// Image files and comparison: checks the caller's images here, and leaves the files themselves to
// the image module (OpenImageIO, image_oiio.cpp), loaded on first use or by preload_image_io().
#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <mutex>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "image_module_api.h"
#include "plantview/image.h"

namespace plantview {

namespace {

// --- the module ---------------------------------------------------------------------------------

struct LoadedModule {
  const PlantviewImageApiV2* api = nullptr;  // null: not loaded, `error` says why
  std::string error;
};

// dlerror() usually starts with the path; the path is already said.
std::string without_path(std::string why, const std::string& path) {
  if (why.rfind(path + ": ", 0) == 0) why.erase(0, path.size() + 2);
  return why;
}

// Loads the module from the first place where it loads, in order:
//   1. $PLANTVIEW_IMAGE_MODULE when set, and then only there (the operator or a test chose it);
//   2. beside the running executable (an installed program);
//   3. where the build wrote it (the build tree).
// The module is never unloaded: OpenImageIO keeps threads and static state to the end.
LoadedModule load_module_from_paths() {
  std::vector<std::string> paths;
  const char* chosen = std::getenv("PLANTVIEW_IMAGE_MODULE");
  if (chosen && *chosen) {
    paths.push_back(chosen);
  } else {
    std::error_code ec;
    const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) paths.push_back((exe.parent_path() / PLANTVIEW_IMAGE_MODULE_NAME).string());
    if (paths.empty() || paths.back() != PLANTVIEW_IMAGE_MODULE_PATH)
      paths.push_back(PLANTVIEW_IMAGE_MODULE_PATH);
  }
  std::string tried;
  for (const auto& path : paths) {
    std::string why;
    // Lazy binding: the module's ~260 libraries' function references are bound when first
    // called, not all at load (70 ms of the first image). A missing library still fails here.
    if (void* handle = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL); !handle) {
      const char* e = dlerror();
      why = without_path(e ? e : "cannot be loaded", path);
    } else if (auto entry = reinterpret_cast<PlantviewImageApiV2Entry>(
                   dlsym(handle, PLANTVIEW_IMAGE_API_SYMBOL));
               !entry) {
      why = "no symbol " PLANTVIEW_IMAGE_API_SYMBOL " (not a plantview image module)";
      dlclose(handle);
    } else if (const PlantviewImageApiV2* api = entry();
               !api || api->version != PLANTVIEW_IMAGE_API_VERSION ||
               api->struct_size != sizeof(PlantviewImageApiV2)) {
      why = "interface version " + std::to_string(api ? api->version : 0) + ", size " +
            std::to_string(api ? api->struct_size : 0) + "; this program needs version " +
            std::to_string(PLANTVIEW_IMAGE_API_VERSION) + ", size " +
            std::to_string(sizeof(PlantviewImageApiV2)) + " (a module from another build?)";
      dlclose(handle);
    } else {
      return {api, {}};
    }
    if (!tried.empty()) tried += "; ";
    tried += (chosen && *chosen ? "PLANTVIEW_IMAGE_MODULE=" : "") + path + ": " + why;
  }
  return {nullptr, "image: cannot load the image module (OpenImageIO); tried " + tried};
}

// The same, for a thread of its own: no exception leaves it.
LoadedModule load_module() noexcept {
  try {
    return load_module_from_paths();
  } catch (const std::exception& e) {
    return {nullptr, std::string("image: cannot load the image module: ") + e.what()};
  }
}

// The module, loaded once per process: on a background thread after start(), else by the first
// image call. Thread-safe; image calls wait for a load in progress.
class ImageModule {
 public:
  static ImageModule& instance() {
    static ImageModule module;
    return module;
  }

  void start() {
    std::lock_guard lock(mutex_);
    if (state_ != State::idle) return;
    try {
      loader_ = std::thread([this] { finish(load_module()); });
      state_ = State::loading;
    } catch (const std::system_error&) {
      // No thread to spare: the first image call loads it instead.
    }
  }

  // The module's functions, or null with `error` set when it cannot be loaded.
  const PlantviewImageApiV2* api(std::string& error) {
    std::unique_lock lock(mutex_);
    if (state_ == State::idle) {
      state_ = State::loading;
      lock.unlock();
      finish(load_module());
      lock.lock();
    }
    loaded_.wait(lock, [this] { return state_ == State::loaded; });
    if (!module_.api) error = module_.error;
    return module_.api;
  }

  // At exit, a load still in progress is waited for: its thread uses this object.
  ~ImageModule() {
    if (loader_.joinable()) loader_.join();
  }

 private:
  enum class State { idle, loading, loaded };

  ImageModule() = default;
  void finish(LoadedModule module) {
    {
      std::lock_guard lock(mutex_);
      module_ = std::move(module);
      state_ = State::loaded;
    }
    loaded_.notify_all();
  }

  std::mutex mutex_;
  std::condition_variable loaded_;
  State state_ = State::idle;
  LoadedModule module_;
  std::thread loader_;
};

// Error text from the module: a message of a line or two.
struct ErrorText {
  char text[4096] = {};
};

// The module's `allocate` for a std::vector<uint8_t>.
uint8_t* resize_vector(void* context, size_t bytes) noexcept {
  try {
    auto& v = *static_cast<std::vector<uint8_t>*>(context);
    v.resize(bytes);
    return v.data();
  } catch (...) {
    return nullptr;
  }
}

// --- checks -------------------------------------------------------------------------------------

bool check_image(const Image& image, std::string& error) {
  if (image.width == 0 || image.height == 0 || image.width > kMaxImageSide ||
      image.height > kMaxImageSide ||
      image.rgba.size() != size_t(image.width) * image.height * 4) {
    error = "image: bad size " + std::to_string(image.width) + "x" + std::to_string(image.height);
    return false;
  }
  return true;
}

bool check_quality(ImageFormat format, int jpeg_quality, std::string& error) {
  if (format == ImageFormat::jpeg && (jpeg_quality < 1 || jpeg_quality > 100)) {
    error = "image: JPEG quality must be 1..100, got " + std::to_string(jpeg_quality);
    return false;
  }
  return true;
}

int module_format(ImageFormat format) {
  return format == ImageFormat::png ? PLANTVIEW_IMAGE_PNG : PLANTVIEW_IMAGE_JPEG;
}

}  // namespace

void preload_image_io() { ImageModule::instance().start(); }

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
  if (!check_image(image, error) || !check_quality(format, jpeg_quality, error)) return false;
  const PlantviewImageApiV2* api = ImageModule::instance().api(error);
  if (!api) return false;
  ErrorText why;
  if (!api->encode(image.rgba.data(), image.width, image.height, module_format(format),
                   jpeg_quality, resize_vector, &out, why.text, sizeof why.text)) {
    out.clear();
    error = why.text;
    return false;
  }
  return true;
}

bool write_image(const std::string& path, const Image& image, int jpeg_quality,
                 std::string& error) {
  ImageFormat format;
  if (!image_format_from_name(path, format)) {
    error = "image: " + path + ": unknown format (use .png, .jpg or .jpeg)";
    return false;
  }
  if (!check_image(image, error) || !check_quality(format, jpeg_quality, error)) return false;
  const PlantviewImageApiV2* api = ImageModule::instance().api(error);
  if (!api) return false;
  ErrorText why;
  if (!api->write(path.c_str(), image.rgba.data(), image.width, image.height,
                  module_format(format), jpeg_quality, why.text, sizeof why.text)) {
    error = why.text;
    return false;
  }
  return true;
}

bool read_image(const std::string& path, Image& out, std::string& error) {
  const PlantviewImageApiV2* api = ImageModule::instance().api(error);
  if (!api) return false;
  Image image;
  ErrorText why;
  if (!api->read(path.c_str(), kMaxImageSide, &image.width, &image.height, resize_vector,
                 &image.rgba, why.text, sizeof why.text)) {
    error = why.text;
    return false;
  }
  out = std::move(image);
  return true;
}

bool compare_images(const Image& a, const Image& b, ImageComparison& out, std::string& error) {
  if (!check_image(a, error) || !check_image(b, error)) return false;
  if (a.width != b.width || a.height != b.height) {
    error = "compare: sizes differ (" + std::to_string(a.width) + "x" + std::to_string(a.height) +
            " and " + std::to_string(b.width) + "x" + std::to_string(b.height) + ")";
    return false;
  }
  const PlantviewImageApiV2* api = ImageModule::instance().api(error);
  if (!api) return false;
  // A pixel "differs" when any channel is more than one 8-bit step apart.
  const double step = 1.5 / 255.0;
  PlantviewImageDifference d{};
  ErrorText why;
  if (!api->compare(a.rgba.data(), b.rgba.data(), a.width, a.height, step, &d, why.text,
                    sizeof why.text)) {
    error = why.text;
    return false;
  }
  out.max_difference = d.max_error;
  out.differing_share = double(d.failing_pixels) / (double(a.width) * a.height);
  out.psnr_db = d.rms_error > 0 ? 20.0 * std::log10(1.0 / d.rms_error)
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

bool add_caption(Image& image, std::string_view title, const std::vector<std::string>& lines,
                 std::string& error) {
  if (!check_image(image, error)) return false;
  const PlantviewImageApiV2* api = ImageModule::instance().api(error);
  if (!api) return false;
  const std::string title_text(title);
  std::vector<const char*> line_texts;
  line_texts.reserve(lines.size());
  for (const std::string& line : lines) line_texts.push_back(line.c_str());
  ErrorText why;
  if (!api->caption(image.rgba.data(), image.width, image.height, title_text.c_str(),
                    line_texts.data(), line_texts.size(), why.text, sizeof why.text)) {
    error = why.text;
    return false;
  }
  return true;
}

bool add_caption(Image& image, std::string_view title, const std::vector<std::string>& lines,
                 const std::vector<CaptionSwatch>& swatches, std::string& error) {
  bool any = false, bars = false;
  for (size_t i = 0; i < swatches.size() && i < lines.size(); ++i) {
    any |= !swatches[i].rgb.empty();
    bars |= swatches[i].rgb.size() > 1;
  }
  if (!any) return add_caption(image, title, lines, error);
  if (!check_image(image, error)) return false;
  // The strip's layout, as the image module lays it out (image_oiio.cpp: caption_rgba; the
  // caption tests check that the keys land on their lines).
  const int height = int(image.height), width = int(image.width);
  const int title_px = std::clamp(height / 32, 9, 64);
  const int line_px = std::max(8, title_px * 4 / 5);
  const int pad_px = std::max(3, title_px / 2);
  const int title_step = title_px * 5 / 4, line_step = line_px * 5 / 4;
  const int room = height / 2 - 2 * pad_px - title_step;
  const int key_px = line_px * 3 / 4;                    // a square's side, a bar's height
  const int bar_px = 4 * line_px;                        // a bar's length
  const int indent = pad_px + (bars ? bar_px : key_px);  // the keys' room, left of the text
  if (room < 0 || indent + 4 * pad_px >= width) return add_caption(image, title, lines, error);
  const size_t shown = std::min(lines.size(), size_t(room / line_step));
  const int strip_px = 2 * pad_px + title_step + int(shown) * line_step;
  const int top = height - strip_px;
  // The caption drawn into the image right of the keys' room, then that room made a strip too.
  Image right;
  right.width = uint32_t(width - indent);
  right.height = image.height;
  right.rgba.resize(size_t(right.width) * right.height * 4);
  for (int y = 0; y < height; ++y)
    std::copy_n(image.rgba.begin() + (ptrdiff_t(y) * width + indent) * 4, size_t(right.width) * 4,
                right.rgba.begin() + ptrdiff_t(y) * right.width * 4);
  if (!add_caption(right, title, lines, error)) return false;
  for (int y = 0; y < height; ++y)
    std::copy_n(right.rgba.begin() + ptrdiff_t(y) * right.width * 4, size_t(right.width) * 4,
                image.rgba.begin() + (ptrdiff_t(y) * width + indent) * 4);
  for (int y = top; y < height; ++y) {
    uint8_t* row = image.rgba.data() + size_t(y) * size_t(width) * 4;
    for (int x = 0; x < indent; ++x) {
      for (int c = 0; c < 3; ++c)
        row[x * 4 + c] = y == top ? uint8_t(90) : uint8_t((row[x * 4 + c] * 12 + 248 * 88) / 100);
      row[x * 4 + 3] = 255;
    }
  }
  // Each key on its line: from the text's cap height down to its baseline.
  int baseline = top + pad_px + title_px + title_step - title_px + line_px;
  for (size_t i = 0; i < shown; ++i, baseline += line_step) {
    if (i >= swatches.size() || swatches[i].rgb.empty()) continue;
    const auto& rgb = swatches[i].rgb;
    const int length = rgb.size() > 1 ? bar_px - pad_px / 2 : key_px;
    for (int y = std::max(0, baseline - key_px); y < std::min(height, baseline); ++y) {
      uint8_t* row = image.rgba.data() + size_t(y) * size_t(width) * 4;
      for (int x = 0; x < length; ++x) {
        uint8_t* p = row + size_t(pad_px + x) * 4;
        if (rgb.size() == 1) {
          std::copy_n(rgb[0].begin(), 3, p);
        } else {
          const double t = double(x) / std::max(1, length - 1) * double(rgb.size() - 1);
          const size_t k = std::min(size_t(t), rgb.size() - 2);
          const double f = t - double(k);
          for (int c = 0; c < 3; ++c)
            p[c] = uint8_t(std::lround(rgb[k][c] + (double(rgb[k + 1][c]) - rgb[k][c]) * f));
        }
        p[3] = 255;
      }
    }
  }
  return true;
}

}  // namespace plantview
