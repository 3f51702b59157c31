// `plantview render`: writing image files, the renderer's session, timings (render_run.h).
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include "cli/farm/output_dir.h"
#include "cli/render_run.h"

namespace plantview::cli::rendering {

bool read_text(const std::string& path, std::string& out, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot read " + path;
    return false;
  }
  std::ostringstream s;
  s << in.rdbuf();
  out = s.str();
  return true;
}

int fail(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 1;
}

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// The directory a single image goes into must exist and take files, checked before rendering.
bool check_image_destination(const std::string& out, std::string& error) {
  const fs::path parent = fs::path(out).parent_path().empty() ? fs::path(".") : fs::path(out).parent_path();
  std::error_code ec;
  if (!fs::is_directory(parent, ec)) {
    error = "--out: the directory " + parent.string() + " (of " + out + ") does not exist";
    return false;
  }
  return farm::prepare_output_dir(parent, error);
}

// Encodes `image` and writes it atomically (farm/output_dir.h); stats.ms.encode gets the time.
bool write_image_file(const fs::path& path, const Image& image, ImageFormat format, int quality,
                      FrameStats& stats, std::string& error) {
  const auto t_encode = std::chrono::steady_clock::now();
  std::vector<uint8_t> bytes;
  if (!encode_image(image, format, quality, bytes, error)) return false;
  if (!farm::write_file_atomically(
          path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), error))
    return false;
  stats.ms.encode = ms_since(t_encode);
  return true;
}

namespace {

// Seconds since this process was created, or a negative number when /proc cannot be read. The
// kernel's start time (/proc/self/stat, field 22) is taken at fork, in clock ticks (10 ms) of
// CLOCK_BOOTTIME, rounded down; so this includes exec, loading the program's libraries and
// their constructors (the user's wait before main), and reads up to one tick too much.
double seconds_since_process_start() {
  std::ifstream in("/proc/self/stat");
  std::string stat;
  std::getline(in, stat);
  // Field 2, the command name, is in parentheses and may hold spaces: count from its end.
  const size_t name_end = stat.rfind(')');
  if (name_end == std::string::npos) return -1;
  std::istringstream fields(stat.substr(name_end + 1));
  std::string field;
  for (int i = 3; i <= 22 && fields >> field; ++i) {}  // fields 3 (state) .. 22 (starttime)
  unsigned long long start_ticks = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), start_ticks);
  const long ticks_per_s = ::sysconf(_SC_CLK_TCK);
  timespec now{};
  if (ec != std::errc() || end != field.data() + field.size() || ticks_per_s <= 0 ||
      ::clock_gettime(CLOCK_BOOTTIME, &now) != 0)
    return -1;
  return double(now.tv_sec) + double(now.tv_nsec) * 1e-9 -
         double(start_ticks) / double(ticks_per_s);
}

}  // namespace

bool start_rendering(int device, const Store& store, const RenderOptions& options,
                     RenderSession& session, std::string& error) {
  session.context = GpuContext::create(device, error);
  if (!session.context) return false;
  // Images are needed from here on. Not before the context: EGL loads its drivers (libLLVM for
  // llvmpipe) under the dynamic loader's lock, which loading the module holds throughout. So
  // does libepoxy at the first call of each GL function: those calls wait for the load too.
  preload_image_io();
  std::cerr << "plantview: rendering on " << session.context->description() << "\n";
  session.renderer = Renderer::create(store, options, error);
  return session.renderer != nullptr;
}

void report_first_image(std::chrono::steady_clock::time_point t_start) {
  const double since_process = seconds_since_process_start();
  if (since_process >= 0) {
    std::cerr << "plantview: first image written " << since_process << " s after start\n";
  } else {
    std::cerr << "plantview: first image written " << ms_since(t_start) / 1000.0
              << " s after the command started (no process start time in /proc)\n";
  }
}

namespace {

CaptionSwatch swatch(Colour c) { return {{{c.r, c.g, c.b}}}; }

std::string number_text(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.6g", v);
  return s;
}

}  // namespace

bool add_caption_columns(Image& image, std::string_view title,
                         const std::vector<CaptionColumn>& columns, std::string& error) {
  size_t rows = 0;
  for (const CaptionColumn& c : columns) rows = std::max(rows, c.lines.size());
  if (columns.size() <= 1) {
    const CaptionColumn none;
    const CaptionColumn& c = columns.empty() ? none : columns.front();
    return add_caption(image, title, c.lines, c.swatches, error);
  }
  // The title over the whole width: a caption of the title over empty lines, drawn on a copy,
  // whose title band (the strip's top down to the first line, image_oiio.cpp's layout) is
  // copied in once the columns are drawn.
  Image titled = image;
  if (!add_caption(titled, title, std::vector<std::string>(rows), error)) return false;
  uint32_t top = 0;
  while (top < image.height &&
         std::equal(image.rgba.begin() + ptrdiff_t(top) * image.width * 4,
                    image.rgba.begin() + ptrdiff_t(top + 1) * image.width * 4,
                    titled.rgba.begin() + ptrdiff_t(top) * image.width * 4))
    ++top;
  const uint32_t title_px = std::clamp(image.height / 32, 9u, 64u);
  const uint32_t band_end =
      std::min(image.height, top + std::max(3u, title_px / 2) + title_px * 5 / 4);
  // Each column a caption of its own over its part of the width, every one `rows` lines high
  // (so that their strips line up).
  const uint32_t n = uint32_t(columns.size());
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t x0 = image.width * i / n, x1 = image.width * (i + 1) / n;
    Image part;
    part.width = x1 - x0;
    part.height = image.height;
    part.rgba.resize(size_t(part.width) * part.height * 4);
    for (uint32_t y = 0; y < image.height; ++y)
      std::copy_n(image.rgba.begin() + (ptrdiff_t(y) * image.width + x0) * 4, size_t(part.width) * 4,
                  part.rgba.begin() + ptrdiff_t(y) * part.width * 4);
    std::vector<std::string> lines = columns[i].lines;
    lines.resize(rows);
    if (!add_caption(part, std::string_view(), lines, columns[i].swatches, error)) return false;
    for (uint32_t y = 0; y < image.height; ++y)
      std::copy_n(part.rgba.begin() + ptrdiff_t(y) * part.width * 4, size_t(part.width) * 4,
                  image.rgba.begin() + (ptrdiff_t(y) * image.width + x0) * 4);
  }
  std::copy(titled.rgba.begin() + ptrdiff_t(top) * image.width * 4,
            titled.rgba.begin() + ptrdiff_t(band_end) * image.width * 4,
            image.rgba.begin() + ptrdiff_t(top) * image.width * 4);
  return true;
}

void add_legend_columns(const FrameLegend& legend, size_t rows, std::vector<CaptionColumn>& columns,
                        bool heading) {
  CaptionColumn all;
  add_legend_lines(legend, all.lines, all.swatches, heading);
  rows = std::max<size_t>(rows, 1);
  for (size_t first = 0; first < all.lines.size(); first += rows) {
    CaptionColumn& c = columns.emplace_back();
    const size_t end = std::min(all.lines.size(), first + rows);
    c.lines.assign(all.lines.begin() + ptrdiff_t(first), all.lines.begin() + ptrdiff_t(end));
    c.swatches.assign(all.swatches.begin() + ptrdiff_t(first), all.swatches.begin() + ptrdiff_t(end));
  }
}

void add_legend_lines(const FrameLegend& legend, std::vector<std::string>& lines,
                      std::vector<CaptionSwatch>& swatches, bool heading) {
  if (legend.key.empty()) return;
  swatches.resize(lines.size());
  if (heading) {
    lines.push_back("Colour by " + legend.key);
    swatches.emplace_back();
  }
  if (legend.kind == FrameLegend::Kind::ramp && legend.min == legend.max && !legend.colours.empty()) {
    // One value: drawn in the ramp's middle colour, named once.
    const std::string unit = legend.unit.empty() ? "" : " " + legend.unit;
    lines.push_back(number_text(legend.min) + unit + "  (" + std::to_string(legend.objects) + ")");
    swatches.push_back(swatch(legend.colours[legend.colours.size() / 2]));
  } else if (legend.kind == FrameLegend::Kind::ramp) {
    CaptionSwatch bar;
    for (const Colour& c : legend.colours) bar.rgb.push_back({c.r, c.g, c.b});
    const std::string unit = legend.unit.empty() ? "" : " " + legend.unit;
    lines.push_back(number_text(legend.min) + unit + " to " + number_text(legend.max) + unit +
                    "  (" + std::to_string(legend.objects) + ")");
    swatches.push_back(std::move(bar));
  } else {
    for (const FrameLegend::Entry& e : legend.entries) {
      // (Subject colours name one object each: no count.)
      lines.push_back(legend.key == "subjects" ? e.value
                                               : e.value + "  (" + std::to_string(e.objects) + ")");
      swatches.push_back(swatch(e.colour));
    }
    if (legend.other_objects > 0) {
      lines.push_back("other values  (" + std::to_string(legend.other_objects) + ")");
      swatches.push_back(swatch(FrameLegend::kOtherColour));
    }
  }
  if (legend.missing_objects > 0) {
    lines.push_back("no " + legend.key + "  (" + std::to_string(legend.missing_objects) + ")");
    swatches.push_back(swatch(FrameLegend::kMissingColour));
  }
}

}  // namespace plantview::cli::rendering
