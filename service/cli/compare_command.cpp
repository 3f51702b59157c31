// `plantview compare A B [--json] [--diff D.png] [--min-psnr DB] [--shift-tolerance R
// [--tolerance T]]`: how far apart two images are (PSNR, largest channel difference, share of
// differing pixels; with --shift-tolerance, the share of pixels that no pixel within R pixels of
// the other image matches within T per channel). Exit 1 below --min-psnr.
#include <cmath>
#include <iostream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "plantview/image.h"

namespace plantview::cli {

namespace {

int fail(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 1;
}

int run_compare(const std::string& a, const std::string& b, bool json, const std::string& diff,
                double min_psnr, int shift_px, double tolerance) {
  std::string error;
  preload_image_io();  // nothing to overlap here: reading waits for it
  Image ia, ib;
  if (!read_image(a, ia, error) || !read_image(b, ib, error)) return fail(error);
  ImageComparison c;
  if (!compare_images(ia, ib, c, error)) return fail(error);
  if (!diff.empty() && !write_difference_image(ia, ib, diff, error)) return fail(error);
  ShiftComparison shifted;
  if (shift_px >= 0 && !compare_images_shifted(ia, ib, uint32_t(shift_px), tolerance, shifted, error))
    return fail(error);
  const std::string psnr = std::isinf(c.psnr_db) ? (json ? "null" : "inf") : std::to_string(c.psnr_db);
  if (json) {
    std::cout << "{\"psnr_db\":" << psnr << ",\"max_difference\":" << c.max_difference
              << ",\"differing_share\":" << c.differing_share;
    if (shift_px >= 0)
      std::cout << ",\"shift_tolerance_px\":" << shift_px << ",\"tolerance\":" << tolerance
                << ",\"unexplained_share\":" << shifted.unexplained_share;
    std::cout << "}\n";
  } else {
    std::cout << "PSNR " << psnr << " dB, largest difference " << c.max_difference
              << ", differing pixels " << 100.0 * c.differing_share << "%";
    if (shift_px >= 0)
      std::cout << ", not explained by a shift of up to " << shift_px << " px "
                << 100.0 * shifted.unexplained_share << "%";
    std::cout << "\n";
  }
  if (min_psnr > 0 && c.psnr_db < min_psnr) return 1;
  return 0;
}

}  // namespace

Action add_compare_command(CLI::App& app) {
  auto compare_a = std::make_shared<std::string>(), compare_b = std::make_shared<std::string>(),
       diff = std::make_shared<std::string>();
  auto compare_json = std::make_shared<bool>(false);
  auto min_psnr = std::make_shared<double>(0.0);
  auto shift_px = std::make_shared<int>(-1);
  auto tolerance = std::make_shared<double>(0.05);
  auto* compare = app.add_subcommand("compare", "Compare two images (PSNR, largest difference)");
  compare->add_option("A", *compare_a, "First image")->required();
  compare->add_option("B", *compare_b, "Second image")->required();
  compare->add_flag("--json", *compare_json, "Print JSON");
  compare->add_option("--diff", *diff, "Write a difference image here");
  compare->add_option("--min-psnr", *min_psnr, "Exit 1 when the PSNR is below this (dB)");
  auto* shift = compare->add_option("--shift-tolerance", *shift_px,
                                    "Also report the share of pixels no pixel within R px of the other image matches")
                    ->check(CLI::Range(0, 16));
  compare->add_option("--tolerance", *tolerance, "Per-channel tolerance (0..1) of --shift-tolerance")
      ->check(CLI::Range(0.0, 1.0))->needs(shift)->capture_default_str();

  return [=]() -> int {
    return compare->parsed() ? run_compare(*compare_a, *compare_b, *compare_json, *diff, *min_psnr, *shift_px, *tolerance) : -1;
  };
}

}  // namespace plantview::cli
