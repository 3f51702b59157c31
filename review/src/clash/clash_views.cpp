// Review views of clashes (plantview/clash.h: clash_views): one fitted, sectioned view a clash.
#include <cstdio>

#include "plantview/camera.h"
#include "plantview/clash.h"

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

std::string side(const ClashObject& o) {
  return (o.tag.empty() ? std::to_string(o.id) : o.tag.str()) + " (" + std::string(class_name(o.object_class)) + ")";
}

}  // namespace

std::vector<ReviewView> clash_views(const ClashReport& report, double aspect) {
  std::vector<ReviewView> out;
  for (const Clash& c : report.clashes) {
    if (c.status == ClashStatus::resolved) continue;
    ReviewView v;
    v.name = "clash-" + hex(c.id);
    v.kind = "clash";
    v.title = "Clash " + (c.a.tag.empty() ? std::to_string(c.a.id) : c.a.tag.str()) + " x " +
              (c.b.tag.empty() ? std::to_string(c.b.id) : c.b.tag.str());
    v.aspect = aspect;
    v.subject = {c.a.id, c.b.id};
    v.colours = {{c.a.id, kClashFirstColour, "first: " + (c.a.tag.empty() ? std::to_string(c.a.id) : c.a.tag.str())},
                 {c.b.id, kClashSecondColour, "second: " + (c.b.tag.empty() ? std::to_string(c.b.id) : c.b.tag.str())}};
    DAabb region;
    for (const glm::dvec3& p : c.points_m) region.extend(p);
    region.min -= glm::dvec3(kClashViewMarginM);
    region.max += glm::dvec3(kClashViewMarginM);
    v.camera = fit_camera(region, isometric_direction(), aspect, 50.0, kReviewFill);
    v.section.has_box = true;
    v.section.box.min = region.min - glm::dvec3(0.5 * kClashViewMarginM);
    v.section.box.max = region.max + glm::dvec3(0.5 * kClashViewMarginM);
    const glm::dvec3& p = c.points_m.front();
    v.attributes = {
        {"clash", hex(c.id) + " " + std::string(clash_status_name(c.status))},
        {"a", side(c.a)},
        {"b", side(c.b)},
        c.kind == ClashKind::hard ? std::pair<std::string, std::string>{"depth", fixed(c.depth_m * 1000, "%.1f mm")}
                                  : std::pair<std::string, std::string>{"distance", fixed(c.distance_m * 1000, "%.1f mm")},
        {"point", fixed(p.x, "%.3f") + ", " + fixed(p.y, "%.3f") + ", " + fixed(p.z, "%.3f") + " m"},
        {"group", c.group.str()}};
    if (c.changed_id)
      v.attributes.emplace_back("changed", c.changed_tag().empty() ? std::to_string(c.changed_id) : c.changed_tag().str());
    out.push_back(std::move(v));
  }
  return out;
}

}  // namespace plantview
