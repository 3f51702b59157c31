// `plantview views --store DIR --per overview|equipment|pipeline|area|change [--select GLOB]
// [--from R1 [--to R2] [--group object|pipeline|equipment]]
// [--sides 1|4] [--size WxH] [--section none|subject [--section-margin M]] --out VIEWS.json`:
// named, fitted review views of a store's subjects (review.h: make_review_views), for
// `render --views`.
#include <unistd.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "cli/progress.h"
#include "plantview/camera.h"
#include "plantview/review.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

struct ViewsArgs {
  std::string store, per, select, size = "1280x720", out, section = "none";
  double section_margin_m = 1.0;
  int sides = 1;
  std::string colour_by, hide, only;  // written into every view (view_filters.h: ObjectStyle)
  // --per change: the range and the grouping (review.h: ReviewViewOptions).
  int64_t from = -1, to = 0;
  std::string group = "object";
};

int fail(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 1;
}

// "WxH" -> width / height; false for anything but two positive integers.
bool parse_aspect(const std::string& text, double& aspect) {
  const size_t x = text.find('x');
  if (x == std::string::npos) return false;
  uint32_t w = 0, h = 0;
  const auto number = [](std::string_view s, uint32_t& v) {
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && end == s.data() + s.size() && v > 0;
  };
  if (!number(std::string_view(text).substr(0, x), w) || !number(std::string_view(text).substr(x + 1), h))
    return false;
  aspect = double(w) / double(h);
  return true;
}

// Writes `text` to `path` through a temporary file beside it and a rename, so that a reader
// never sees half a views file.
bool write_atomically(const std::string& path, const std::string& text, std::string& error) {
  const std::string temporary = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream file(temporary, std::ios::binary | std::ios::trunc);
    if (!file) {
      error = "cannot write " + path + " (creating " + temporary + " failed)";
      return false;
    }
    file << text;
    if (!file.flush()) {
      error = "writing " + temporary + " failed";
      std::filesystem::remove(temporary);
      return false;
    }
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) {
    error = "cannot write " + path + ": " + ec.message();
    std::filesystem::remove(temporary, ec);
    return false;
  }
  return true;
}

int run_views(const ViewsArgs& a) {
  ReviewViewOptions options;
  options.per = a.per;
  options.select = a.select;
  options.sides = a.sides;
  if (!parse_aspect(a.size, options.aspect))
    return usage_error("--size: expected WxH with W and H positive integers, got '" + a.size + "'");
  if (a.section != "none" && a.section != "subject")
    return usage_error("--section: '" + a.section + "' is not one of none, subject");
  if (!(a.section_margin_m >= 0) || !std::isfinite(a.section_margin_m))
    return usage_error("--section-margin: expected metres >= 0, got " +
                       std::to_string(a.section_margin_m));
  options.section = a.section;
  options.section_margin_m = a.section_margin_m;
  if (a.per == "change") {
    if (a.from < 0) return usage_error("--per change needs --from R1 (the revision the changes are since)");
    if (a.to != 0 && a.to <= a.from)
      return usage_error("--to " + std::to_string(a.to) + " must come after --from " + std::to_string(a.from));
    if (a.from > int64_t(UINT32_MAX) || a.to > int64_t(UINT32_MAX) || a.to < 0)
      return usage_error("--from and --to are revision numbers");
    options.changes.from = uint32_t(a.from);
    options.changes.to = uint32_t(a.to);
    options.group = a.group;
  } else if (a.from >= 0 || a.to != 0) {
    return usage_error("--from and --to go with --per change");
  }

  std::string error;
  ObjectStyle style;
  style.colour_by = a.colour_by;
  if ((!a.hide.empty() && !parse_word_list(a.hide, "--hide", style.hide, error)) ||
      (!a.only.empty() && !parse_word_list(a.only, "--only", style.only, error)))
    return usage_error(error);
  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  std::vector<ReviewView> views;
  ReviewViewsSummary summary;
  {
    Progress progress("views");
    if (!make_review_views(*store, options, views, summary, error,
                           [&](double f) { progress.update(f); }))
      return fail(error);
  }
  for (ReviewView& view : views) view.style = style;
  if (!write_atomically(a.out, review_views_json(views, options.per), error)) return fail(error);
  std::cout << "{\"views\":" << views.size() << ",\"subjects\":" << summary.subjects
            << ",\"moved\":" << summary.moved << ",\"obstructed\":" << summary.obstructed
            << ",\"per\":\"" << options.per << "\",\"sides\":" << options.sides << "}\n";
  return 0;
}

}  // namespace

Action add_views_command(CLI::App& app) {
  auto args = std::make_shared<ViewsArgs>();
  auto* views = app.add_subcommand("views", "Make named, fitted review views of a store's subjects");
  views->add_option("--store", args->store, "Store directory")->required();
  views->add_option("--per", args->per, "overview, equipment, pipeline, area or change")
      ->required()
      ->check(CLI::IsMember({"overview", "equipment", "pipeline", "area", "change"}));
  views->add_option("--from", args->from,
                    "With --per change: the revision the changes are since (each view a change image)");
  views->add_option("--to", args->to,
                    "With --per change: the later revision (default: the store's); the store must be at it "
                    "when the views are rendered");
  views->add_option("--group", args->group,
                    "With --per change: a view per changed object, per pipeline holding a change, or per "
                    "changed equipment item")
      ->check(CLI::IsMember({"object", "pipeline", "equipment"}))
      ->capture_default_str();
  views->add_option("--select", args->select,
                    "Only subjects whose view name or tag/path matches this shell glob");
  views->add_option("--sides", args->sides, "1: isometric; 4: from north, east, south and west")
      ->check(CLI::IsMember({1, 4}))
      ->capture_default_str();
  views->add_option("--size", args->size, "The image size WxH the cameras are fitted for")
      ->capture_default_str();
  views->add_option("--out", args->out, "Views JSON file (for render --views)")->required();
  views->add_option("--colour-by", args->colour_by,
                    "KEY: every view coloured by this attribute (render --views draws a legend)");
  views->add_option("--hide", args->hide, "CLASS|GLOB,...: every view leaves these out");
  views->add_option("--only", args->only, "CLASS|GLOB,...: every view shows only these");
  views->add_option("--section", args->section,
                    "none, or subject: each view (not the overview) cut to a box around its "
                    "subject, grown by --section-margin")
      ->capture_default_str();
  views->add_option("--section-margin", args->section_margin_m,
                    "Metres the subject's section box reaches beyond it")
      ->capture_default_str();
  return [=]() -> int { return views->parsed() ? run_views(*args) : -1; };
}

}  // namespace plantview::cli
