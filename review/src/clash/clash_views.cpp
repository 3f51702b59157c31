// Review views of clashes (plantview/clash.h: clash_views): one fitted, sectioned view a clash.
#include <algorithm>
#include <array>
#include <cstdio>
#include <unordered_map>

#include "plantview/camera.h"
#include "plantview/clash.h"
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

std::string name_of(const ClashObject& o) { return o.tag.empty() ? std::to_string(o.id) : o.tag; }

std::string side(const ClashObject& o) {
  return name_of(o) + " (" + std::string(class_name(o.object_class)) + ")";
}

// An object's model bounds by id: empty when the snapshot does not hold it. False with a
// message on a read error.
using BoundsOf = std::function<bool(uint64_t id, DAabb& out, std::string& error)>;

DAabb intersection(const DAabb& a, const DAabb& b) {
  DAabb out;
  if (a.empty() || b.empty()) return out;
  out.min = glm::max(a.min, b.min);
  out.max = glm::min(a.max, b.max);
  return out;
}

// The box's extents, each at least kClashViewThinM (a plate has a volume), 0 when empty.
glm::dvec3 extents_m(const DAabb& box) {
  if (box.empty()) return glm::dvec3(0.0);
  return glm::max(box.max - box.min, glm::dvec3(kClashViewThinM));
}

bool make_views(const ClashReport& report, double aspect, const BoundsOf& bounds_of,
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
    if (bounds_of) {
      // Which of the two is the thicker across in the widest region (its middle extent: a
      // column's width, a pipe's diameter, a deck's width), by kClashViewContainerRatio at
      // least: it would hide the other. (Parts of a size, a valve on a pipe, stay opaque.)
      const DAabb widest{p - reach - glm::dvec3(1.5 * kClashViewMarginM),
                         p + reach + glm::dvec3(1.5 * kClashViewMarginM)};
      if (!bounds_of(c.a.id, bounds[0], error) || !bounds_of(c.b.id, bounds[1], error)) return false;
      std::array<double, 3> inside[2];
      for (size_t i = 0; i < 2; ++i) {
        const glm::dvec3 e = extents_m(intersection(bounds[i], widest));
        inside[i] = {e.x, e.y, e.z};
        std::sort(inside[i].begin(), inside[i].end());
      }
      const size_t container = inside[0][1] > inside[1][1] ? 0 : 1;
      if (inside[0][0] > 0 && inside[1][0] > 0) {
        if (inside[container][1] >= kClashViewContainerRatio * inside[1 - container][1]) {
          SubjectColour& see_through = v.colours[container];
          see_through.see_through = true;
          see_through.label += " (see-through)";
        }
        // The margin: kClashViewMarginSizes of the thinner one's middle extent there.
        margin_m = std::clamp(kClashViewMarginSizes * inside[1 - container][1], kClashViewMinMarginM,
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
        {"group", c.group}};
    if (c.changed_id)
      v.attributes.emplace_back("changed", c.changed_tag().empty() ? std::to_string(c.changed_id) : c.changed_tag());
    views.push_back(std::move(v));
  }
  out = std::move(views);
  return true;
}

}  // namespace

std::vector<ReviewView> clash_views(const ClashReport& report, double aspect) {
  std::vector<ReviewView> out;
  std::string unused;
  make_views(report, aspect, {}, out, unused);
  return out;
}

bool clash_views(const ClashReport& report, double aspect, const ReadView& view,
                 std::vector<ReviewView>& out, std::string& error) {
  std::unordered_map<uint64_t, DAabb> known;  // (objects recur across a plant's clashes)
  Object object;
  const BoundsOf bounds_of = [&](uint64_t id, DAabb& bounds, std::string& why) {
    if (const auto k = known.find(id); k != known.end()) {
      bounds = k->second;
      return true;
    }
    std::optional<uint32_t> slot;
    if (!view.slot_of(id, slot, why)) return false;
    bounds = DAabb{};
    if (slot) {
      if (!view.object(*slot, object, false, why)) {
        why = "clash views: object " + std::to_string(id) + ": " + why;
        return false;
      }
      bounds = object_bounds(object);
    }
    known.emplace(id, bounds);
    return true;
  };
  return make_views(report, aspect, bounds_of, out, error);
}

}  // namespace plantview
