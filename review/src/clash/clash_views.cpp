// Review views of clashes (plantview/clash.h: clash_views): one fitted, sectioned view a clash,
// and which clashes get one (clash_view_selected).
#include <fnmatch.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <unordered_map>

#include "plantview/camera.h"
#include "plantview/clash.h"
#include "plantview/primitives.h"
#include "plantview/store.h"

namespace plantview {

namespace {

std::string hex(uint64_t v) {
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

std::string fixed(double v, const char* format) {
  char buf[96];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string name_of(const ClashObject& o) {
  return o.tag.empty() ? std::to_string(o.id) : std::string(std::string_view(o.tag));
}

std::string side(const ClashObject& o) {
  return name_of(o) + " (" + std::string(class_name(o.object_class)) + ")";
}

// What the views need of an object: its model bounds, and each primitive's model bounds with
// its thickness across (the middle of its three local extents, scaled by its placement: a
// cylinder's diameter, a column's width, whatever way it is turned).
struct Sizes {
  DAabb bounds;  // empty: the snapshot does not hold it
  std::vector<std::pair<DAabb, double>> parts;
};
// An object's sizes by id. False with a message on a read error.
using SizesOf = std::function<bool(uint64_t id, const Sizes*& out, std::string& error)>;

Sizes sizes_of(const Object& object) {
  Sizes s;
  s.bounds = object_bounds(object);
  for (const Primitive& p : object.primitives) {
    const Aabb box = model_bounds(p), local = local_bounds(p.shape);
    if (box.empty() || local.empty()) continue;
    std::array<double, 3> e;
    for (int i = 0; i < 3; ++i)
      e[size_t(i)] = double(local.max[i] - local.min[i]) * double(glm::length(p.placement.linear[i]));
    std::sort(e.begin(), e.end());
    s.parts.emplace_back(DAabb{object.origin_m + glm::dvec3(box.min), object.origin_m + glm::dvec3(box.max)}, e[1]);
  }
  return s;
}

double distance_m(const DAabb& box, const glm::dvec3& p) {
  return glm::length(glm::max(glm::max(box.min - p, p - box.max), glm::dvec3(0.0)));
}

bool overlap(const DAabb& a, const DAabb& b) {
  return glm::all(glm::lessThanEqual(a.min, b.max + kClashViewThinM)) &&
         glm::all(glm::lessThanEqual(b.min, a.max + kClashViewThinM));
}

// How thick each object is where the two meet (clash.h): of its parts within
// kClashViewMarginM of the point whose bounds meet one of the other's there, the thickest;
// failing any, its part nearest the point. 0 without parts.
std::array<double, 2> thickness_where_they_meet_m(const Sizes& a, const Sizes& b, const glm::dvec3& p) {
  const Sizes* sizes[2] = {&a, &b};
  std::vector<const std::pair<DAabb, double>*> near[2];
  std::array<double, 2> out{0.0, 0.0};
  for (size_t i = 0; i < 2; ++i) {
    double nearest_distance = INFINITY;
    for (const auto& part : sizes[i]->parts) {
      const double d = distance_m(part.first, p);
      if (d <= kClashViewMarginM) near[i].push_back(&part);
      if (d < nearest_distance) {
        nearest_distance = d;
        out[i] = part.second;
      }
    }
  }
  for (size_t i = 0; i < 2; ++i) {
    double thickest = 0;
    for (const auto* mine : near[i]) {
      if (mine->second <= thickest) continue;
      for (const auto* theirs : near[1 - i]) {
        if (overlap(mine->first, theirs->first)) {
          thickest = mine->second;
          break;
        }
      }
    }
    if (thickest > 0) out[i] = thickest;
  }
  return out;
}

DAabb intersection(const DAabb& a, const DAabb& b) {
  DAabb out;
  if (a.empty() || b.empty()) return out;
  out.min = glm::max(a.min, b.min);
  out.max = glm::min(a.max, b.max);
  return out;
}

bool make_views(const ClashReport& report, double aspect, const SizesOf& sizes_of_id,
                std::vector<ReviewView>& out, std::string& error) {
  std::vector<ReviewView> views;
  for (const Clash& c : report.clashes) {
    if (c.status == ClashStatus::resolved) continue;
    ReviewView v;
    v.name = "clash-" + hex(c.id);
    v.kind = "clash";
    v.title = "Clash " + name_of(c.a) + " x " + name_of(c.b);
    v.aspect = aspect;
    v.subject = {c.a.id, c.b.id};
    v.colours = {{c.a.id, kClashFirstColour, "first: " + name_of(c.a)},
                 {c.b.id, kClashSecondColour, "second: " + name_of(c.b)}};
    // The region: the points, centred on the first (the deepest), grown by the margin.
    const glm::dvec3& p = c.points_m.front();
    glm::dvec3 reach(0.0);
    for (const glm::dvec3& q : c.points_m) reach = glm::max(reach, glm::abs(q - p));
    double margin_m = kClashViewMarginM;
    DAabb bounds[2];  // (empty without the store)
    if (sizes_of_id) {
      // Which of the two is thicker where they meet (a column's width against
      // a pipe's diameter), by kClashViewContainerRatio at least: it would hide the other.
      // (Parts of a size, a valve on a pipe, stay opaque.)
      const Sizes* sizes[2] = {nullptr, nullptr};
      if (!sizes_of_id(c.a.id, sizes[0], error) || !sizes_of_id(c.b.id, sizes[1], error)) return false;
      const std::array<double, 2> thickness = thickness_where_they_meet_m(*sizes[0], *sizes[1], p);
      bounds[0] = sizes[0]->bounds;
      bounds[1] = sizes[1]->bounds;
      const size_t container = thickness[0] > thickness[1] ? 0 : 1;
      if (thickness[0] > 0 && thickness[1] > 0) {
        if (thickness[container] >= kClashViewContainerRatio * thickness[1 - container]) {
          SubjectColour& see_through = v.colours[container];
          see_through.see_through = true;
          see_through.label += " (see-through)";
        }
        // The margin: kClashViewMarginSizes of the thinner one's thickness.
        margin_m = std::clamp(kClashViewMarginSizes * thickness[1 - container], kClashViewMinMarginM,
                              kClashViewMarginM);
      }
    }
    const DAabb region{p - reach - glm::dvec3(margin_m), p + reach + glm::dvec3(margin_m)};
    // Framed on what of the opaque one(s) lies in the region, and the points, centred on the
    // first: small parts fill the frame, not the region's air or the container (at least
    // kClashViewMinFrameM each way). Without their bounds: the region.
    DAabb shown;
    for (size_t i = 0; i < 2; ++i)
      if (!v.colours[i].see_through) shown.extend(intersection(bounds[i], region));
    if (shown.empty()) {
      shown = region;
    } else {
      for (const glm::dvec3& q : c.points_m) shown.extend(q);
    }
    const glm::dvec3 half = glm::max(glm::max(shown.max - p, p - shown.min), glm::dvec3(kClashViewMinFrameM));
    v.camera = fit_camera(DAabb{p - half, p + half}, isometric_direction(), aspect, 50.0, kReviewFill);
    // Aimed at the point itself (the fit centres the box's perspective projection, a little
    // beside it), from the same distance.
    const double distance_to_target_m = glm::length(v.camera.target_m - v.camera.eye_m);
    v.camera.target_m = p;
    v.camera.eye_m = p - glm::normalize(isometric_direction()) * distance_to_target_m;
    v.section.has_box = true;
    v.section.box.min = region.min - glm::dvec3(0.5 * margin_m);
    v.section.box.max = region.max + glm::dvec3(0.5 * margin_m);
    v.attributes = {
        {"clash", hex(c.id) + " " + std::string(clash_status_name(c.status))},
        {"a", side(c.a)},
        {"b", side(c.b)},
        c.kind == ClashKind::hard ? std::pair<std::string, std::string>{"depth", fixed(c.depth_m * 1000, "%.1f mm")}
                                  : std::pair<std::string, std::string>{"distance", fixed(c.distance_m * 1000, "%.1f mm")},
        {"point", fixed(p.x, "%.3f") + ", " + fixed(p.y, "%.3f") + ", " + fixed(p.z, "%.3f") + " m"},
        {"group", c.group.str()}};
    if (c.changed_id)
      v.attributes.emplace_back("changed", c.changed_tag().empty() ? std::to_string(c.changed_id)
                                                                   : std::string(std::string_view(c.changed_tag())));
    views.push_back(std::move(v));
  }
  out = std::move(views);
  return true;
}

}  // namespace

bool clash_view_selected(const Clash& c, const ClashViewSelection& selection) {
  if (c.status == ClashStatus::resolved || (c.status == ClashStatus::new_clash && !selection.new_clashes) ||
      (c.status == ClashStatus::active && !selection.active))
    return false;
  if (selection.select.empty()) return true;
  const auto matches = [&](const std::string& text) { return fnmatch(selection.select.c_str(), text.c_str(), 0) == 0; };
  return matches("clash-" + hex(c.id)) || matches(name_of(c.a)) || matches(name_of(c.b)) ||
         (!c.group.empty() && matches(c.group.str()));
}

std::vector<ReviewView> clash_views(const ClashReport& report, double aspect) {
  std::vector<ReviewView> out;
  std::string unused;
  make_views(report, aspect, {}, out, unused);
  return out;
}

bool clash_views(const ClashReport& report, double aspect, const ReadView& view,
                 std::vector<ReviewView>& out, std::string& error) {
  std::unordered_map<uint64_t, Sizes> known;  // (objects recur across a plant's clashes)
  Object object;
  const SizesOf sizes_of_id = [&](uint64_t id, const Sizes*& sizes, std::string& why) {
    auto k = known.find(id);
    if (k == known.end()) {
      std::optional<uint32_t> slot;
      if (!view.slot_of(id, slot, why)) return false;
      Sizes made;
      if (slot) {
        if (!view.object(*slot, object, false, why)) {
          why = "clash views: object " + std::to_string(id) + ": " + why;
          return false;
        }
        made = sizes_of(object);
      }
      k = known.emplace(id, std::move(made)).first;
    }
    sizes = &k->second;
    return true;
  };
  return make_views(report, aspect, sizes_of_id, out, error);
}

}  // namespace plantview
