// What is not a clash (plantview/clash.h): the named rules, and the sets of --between / --and.
#include <fnmatch.h>

#include <algorithm>
#include <cmath>

#include "clash/clash_internal.h"

namespace plantview {

std::string_view clash_rule_name(ClashRule rule) {
  switch (rule) {
    case ClashRule::same_pipeline: return "same_pipeline";
    case ClashRule::connected: return "connected";
    case ClashRule::support: return "support";
    case ClashRule::nozzle: return "nozzle";
  }
  return "?";
}

std::string_view clash_status_name(ClashStatus status) {
  switch (status) {
    case ClashStatus::new_clash: return "new";
    case ClashStatus::active: return "active";
    case ClashStatus::resolved: return "resolved";
  }
  return "?";
}

namespace {

const std::string* attribute(const Object& o, std::string_view key) {
  for (const Attribute& a : o.attributes)
    if (a.key == key) return &a.value;
  return nullptr;
}

bool glob(const std::string& pattern, const std::string& text) {
  return !text.empty() && fnmatch(pattern.c_str(), text.c_str(), 0) == 0;
}

}  // namespace

bool ClashSet::contains(const Object& object) const {
  if (word.empty()) return true;
  ObjectClass c;
  if (class_from_name(word, c)) return object.object_class == c;
  if (glob(word, object.name)) return true;
  if (!object.name.empty() && object.name.front() == '/' && glob(word, object.name.substr(1))) return true;
  const std::string* tag = attribute(object, "Tag");
  return tag && glob(word, *tag);
}

namespace clash_detail {

bool is_support(const Object& object) {
  if (const std::string* type = attribute(object, "Type"); type && *type == "SUPP") return true;
  const size_t slash = object.name.rfind('/');
  const std::string_view last = slash == std::string::npos ? std::string_view(object.name)
                                                           : std::string_view(object.name).substr(slash + 1);
  return last.starts_with("SUPP");
}

namespace {

bool piping(const Object& o) {
  return o.object_class == ObjectClass::pipe || o.object_class == ObjectClass::component;
}

// A connection point in common: positions within 2 mm, directions opposite.
bool connected(const Object& a, const Object& b) {
  for (const ConnectionPoint& ca : a.connections) {
    const glm::dvec3 pa = a.origin_m + glm::dvec3(ca.position_m);
    for (const ConnectionPoint& cb : b.connections) {
      const glm::dvec3 pb = b.origin_m + glm::dvec3(cb.position_m);
      if (glm::length(pa - pb) <= 0.002 && glm::dot(ca.direction, cb.direction) < -0.9f) return true;
    }
  }
  return false;
}

double segment_distance(const glm::dvec3& p, const glm::dvec3& s, const glm::dvec3& e) {
  const glm::dvec3 d = e - s;
  const double l2 = glm::dot(d, d);
  const double t = l2 > 0 ? std::clamp(glm::dot(p - s, d) / l2, 0.0, 1.0) : 0.0;
  return glm::length(p - (s + d * t));
}

// The support's connection point lies on the other's centreline (clash.h).
bool carries(const Object& support, const Object& piece) {
  if (!is_support(support) || !piping(piece)) return false;
  for (const ConnectionPoint& c : support.connections) {
    const glm::dvec3 p = support.origin_m + glm::dvec3(c.position_m);
    for (const CentrelineSegment& s : piece.centreline) {
      const double reach = std::max(0.5 * double(s.diameter_m), 0.05) + 0.002;
      if (segment_distance(p, piece.origin_m + glm::dvec3(s.start_m), piece.origin_m + glm::dvec3(s.end_m)) <= reach)
        return true;
    }
  }
  return false;
}

}  // namespace

std::optional<ClashRule> exempting_rule(const Object& a, const Object& b) {
  if (a.pipeline_id != 0 && a.pipeline_id == b.pipeline_id && piping(a) && piping(b))
    return ClashRule::same_pipeline;
  if (connected(a, b)) return ClashRule::connected;
  if (carries(a, b) || carries(b, a)) return ClashRule::support;
  return std::nullopt;
}

}  // namespace clash_detail
}  // namespace plantview
