// Review views of a store: subjects from the model, a fitted camera each, stable safe names.
#include <fnmatch.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <set>

#include "views_internal.h"

namespace plantview {

namespace {

// One side of a subject: the suffix of its views' names and the directions (eye to target) to
// try, the preferred first.
struct Side {
  std::string suffix;
  std::vector<glm::dvec3> directions;
};

// Views from above: the isometric quadrants, the preferred (eye at -x, -y) first, then the same
// from higher up (55 degrees down), which sees over racks and walls.
std::vector<Side> isometric_sides() {
  Side side;
  for (const double steep : {1.0, 2.0})
    for (const glm::dvec2 q : {glm::dvec2(1, 1), glm::dvec2(-1, 1), glm::dvec2(1, -1), glm::dvec2(-1, -1)})
      side.directions.push_back(glm::dvec3(q.x, q.y, -steep));  // steep 1: isometric_direction()
  return {side};
}

// The four sides: the eye north, east, south and west of the subject, 17 degrees above the
// horizon; then 30 degrees either way round, then from 45 degrees up.
std::vector<Side> four_sides() {
  std::vector<Side> sides;
  const std::pair<const char*, double> eyes[] = {{"N", 90.0}, {"E", 0.0}, {"S", 270.0}, {"W", 180.0}};
  for (const auto& [suffix, azimuth_deg] : eyes) {
    Side side{std::string("-") + suffix, {}};
    for (const auto& [turn_deg, drop] : {std::pair{0.0, 0.3}, std::pair{30.0, 0.3},
                                         std::pair{-30.0, 0.3}, std::pair{0.0, 1.0}}) {
      const double a = glm::radians(azimuth_deg + turn_deg);
      side.directions.push_back(glm::dvec3(-std::cos(a), -std::sin(a), -drop));
    }
    sides.push_back(std::move(side));
  }
  return sides;
}

bool selected(const std::string& glob, const std::string& name, const std::string& key) {
  return glob.empty() || fnmatch(glob.c_str(), name.c_str(), 0) == 0 ||
         fnmatch(glob.c_str(), key.c_str(), 0) == 0;
}

std::string plural(std::string_view per) {
  return per == "equipment" ? "equipment" : per == "change" ? "changes" : std::string(per) + "s";
}

// Leaves room for a repeat's "-NNN" and a side's "-N" within the 200 characters of a name.
constexpr size_t kMaxBaseNameChars = 190;

}  // namespace

bool make_review_views(const Store& store, const ReviewViewOptions& options,
                       std::vector<ReviewView>& out, ReviewViewsSummary& summary,
                       std::string& error, const std::function<void(double)>& progress) {
  assert(is_review_kind(options.per) && (options.sides == 1 || options.sides == 4));
  assert(options.aspect > 0 && options.fov_deg > 0 && options.fov_deg < 179);
  assert(options.fill > 0 && options.fill <= 1);
  assert((options.section == "none" || options.section == "subject") &&
         options.section_margin_m >= 0);
  summary = {};
  const auto report = [&](double fraction) {
    if (progress) progress(fraction);
  };

  // Stages: the subjects the model offers; those selected; a camera per subject and side,
  // placed clear of other objects; names made safe and unique in a stable order.
  const auto view = store.read(error);
  if (!view) return false;
  std::vector<views::Subject> subjects;
  std::optional<ChangeRange> changes;
  if (options.per == "change") {
    assert(options.group == "object" || options.group == "pipeline" || options.group == "equipment");
    changes = options.changes;
    if (!changes->to) changes->to = view->info().revision;
    if (!views::read_change_subjects(*view, *changes, options.group, subjects, error)) return false;
    if (subjects.empty()) {
      error = store.directory() + ": nothing " +
              (options.group == "object" ? std::string() : "of a " + options.group + " ") +
              "changed between revisions " + std::to_string(changes->from) + " and " +
              std::to_string(changes->to);
      return false;
    }
  } else if (!views::read_subjects(*view, options.per, subjects, error,
                                   [&](double f) { report(0.5 * f); })) {
    return false;
  }
  summary.subjects = subjects.size();
  if (subjects.empty()) {
    error = store.directory() + ": the store has no " +
            (options.per == "overview" ? std::string("geometry") : plural(options.per));
    return false;
  }
  std::vector<std::string> bases;
  std::vector<views::Subject> chosen;
  for (views::Subject& s : subjects) {
    std::string base = views::safe_name(s.key, kMaxBaseNameChars);
    if (!selected(options.select, base, s.key)) continue;
    bases.push_back(std::move(base));
    chosen.push_back(std::move(s));
  }
  if (chosen.empty()) {
    error = "--select '" + options.select + "' matches none of the " +
            std::to_string(summary.subjects) + " " + plural(options.per) + " in " + store.directory();
    return false;
  }

  const std::vector<Side> sides = options.sides == 4 ? four_sides() : isometric_sides();
  const views::Occluders occluders(*view);
  std::vector<ReviewView> views_out;
  std::set<std::string, std::less<>> used;
  for (size_t i = 0; i < chosen.size(); ++i) {
    const views::Subject& s = chosen[i];
    // A repeated base name takes the first free -2, -3, ... (for every side alike).
    std::string base = bases[i];
    for (int n = 2; std::any_of(sides.begin(), sides.end(),
                                [&](const Side& side) { return used.count(base + side.suffix) > 0; });
         ++n)
      base = bases[i] + "-" + std::to_string(n);
    for (const Side& side : sides) {
      ReviewView v;
      v.name = base + side.suffix;
      used.insert(v.name);
      v.title = s.title;
      if (options.sides == 4) v.title += " (" + side.suffix.substr(1) + ")";
      v.kind = s.kind;
      v.aspect = options.aspect;
      v.subject = s.ids;
      v.attributes = s.attributes;
      v.changes = changes;
      if (options.section == "subject" && s.kind != "overview") {
        v.section.has_box = true;
        v.section.box.min = s.bounds.min - glm::dvec3(options.section_margin_m);
        v.section.box.max = s.bounds.max + glm::dvec3(options.section_margin_m);
      }
      if (s.kind == "overview") {
        v.camera = fit_camera(s.boxes, side.directions.front(), options.aspect, options.fov_deg,
                              kOverviewFill);
      } else {
        const views::Placement p = views::place_camera(occluders, s, side.directions,
                                                       options.aspect, options.fov_deg, options.fill);
        v.camera = p.camera;
        summary.moved += p.moved ? 1 : 0;
        summary.obstructed += p.clear ? 0 : 1;
      }
      views_out.push_back(std::move(v));
    }
    report(0.5 + 0.5 * double(i + 1) / double(chosen.size()));
  }
  if (!occluders.error().empty()) {
    error = occluders.error();
    return false;
  }
  out = std::move(views_out);
  return true;
}

}  // namespace plantview
