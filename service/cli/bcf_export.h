// BCF files of rendered review views, shared by `plantview bcf export` and `render --views
// --bcf` (plantview/bcf.h states the format).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "plantview/review.h"

namespace plantview {
class ReadView;
}

namespace plantview::cli {

// Writes `out` (atomically: bcf.h) with one topic per view, each view's snapshot the image
// `render --views` wrote into `images` (NAME.png, else NAME.jpg converted). `seed` makes the
// GUIDs (the store's identity). `store` may be null. Notes on what BCF could not say go to
// stderr. False with a message naming the view or file: a view without an image, a failed
// write.
bool export_views_bcf(const std::vector<ReviewView>& views, const std::filesystem::path& images,
                      const std::string& seed, const ReadView* store, const std::filesystem::path& out,
                      std::string& error);

}  // namespace plantview::cli
