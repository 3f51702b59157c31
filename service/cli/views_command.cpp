// `plantview views --store DIR --per overview|equipment|pipeline|area|change|clash [--select GLOB]
// [--from R1 [--to R2] [--group object|pipeline|equipment]] [--clashes CLASHES.json [--status new|active]]
// [--sides 1|4] [--size WxH] [--section none|subject [--section-margin M]] --out VIEWS.json`:
// named, fitted review views of a store's subjects (review.h: make_review_views), for
// `render --views`.

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "cli/farm/output_dir.h"
#include "cli/progress.h"
#include "plantview/camera.h"
#include "plantview/clash.h"
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
  std::string clashes;                // --per clash: the clashes file (clash.h)
  std::string status;                 // --per clash: new, active or both ("": both)
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
  ClashViewSelection selection;  // --per clash
  selection.select = a.select;
  if (a.per == "clash") {
    if (a.clashes.empty()) return usage_error("views --per clash: --clashes FILE (from plantview clash --out)");
    if (!a.status.empty()) {
      std::vector<std::string> statuses;
      if (!parse_word_list(a.status, "--status", statuses, error)) return usage_error(error);
      selection.new_clashes = selection.active = false;
      for (const std::string& s : statuses) {
        if (s == "new") selection.new_clashes = true;
        else if (s == "active") selection.active = true;
        else return usage_error("--status: '" + s + "' is not one of new, active (resolved clashes have no view)");
      }
    }
  } else if (!a.status.empty() || !a.clashes.empty()) {
    return usage_error("--status and --clashes go with --per clash");
  }
  ObjectStyle style;
  style.colour_by = a.colour_by;
  if ((!a.hide.empty() && !parse_word_list(a.hide, "--hide", style.hide, error)) ||
      (!a.only.empty() && !parse_word_list(a.only, "--only", style.only, error)))
    return usage_error(error);
  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  std::vector<ReviewView> views;
  ReviewViewsSummary summary;
  if (options.per == "clash") {  // one view a clash of the clashes file (clash.h)
    std::ifstream file(a.clashes, std::ios::binary);
    if (!file) return fail("cannot read " + a.clashes);
    // Only the selected clashes are kept as the file is read (a run at millions of clashes).
    ClashReport report;
    const auto keep = [&](const Clash& c) {
      summary.subjects += c.status != ClashStatus::resolved;
      return clash_view_selected(c, selection);
    };
    if (!read_clash_report(file, report, error, keep)) return fail(a.clashes + ": " + error);
    if (!a.select.empty() && report.clashes.empty() && summary.subjects > 0)
      return fail("--select '" + a.select + "' matches none of the " + std::to_string(summary.subjects) +
                  " unresolved clashes" + (a.status.empty() ? "" : " (--status " + a.status + ")"));
    const auto view = store->read(error);
    if (!view) return fail(error);
    if (!clash_views(report, options.aspect, *view, views, error)) return fail(error);
    if (views.empty())  // (not an error: after a revision, no new clash is good news)
      std::cerr << "plantview: views: no clash to review in " << a.clashes << " ("
                << summary.subjects << " unresolved" << (a.status.empty() ? "" : ", --status " + a.status)
                << "); the views file is empty, and render --views refuses an empty one\n";
  } else {
    Progress progress("views");
    if (!make_review_views(*store, options, views, summary, error,
                           [&](double f) { progress.update(f); }))
      return fail(error);
  }
  for (ReviewView& view : views) view.style = style;
  if (!farm::write_file_atomically(a.out, review_views_json(views, options.per), error)) return fail(error);
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
  views->add_option("--per", args->per, "overview, equipment, pipeline, area, change or clash")
      ->required()
      ->check(CLI::IsMember({"overview", "equipment", "pipeline", "area", "change", "clash"}));
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
  views->add_option("--clashes", args->clashes, "--per clash: the clashes.json of plantview clash");
  views->add_option("--status", args->status,
                    "--per clash: new, active or new,active (the default): the clashes of these statuses");
  views->add_option("--select", args->select,
                    "Only subjects whose view name or tag/path matches this shell glob (--per clash: the "
                    "view name, either object's tag or the group)");
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
