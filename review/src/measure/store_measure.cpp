// Measuring two objects of a store: looking them up by id or tag, and the answer's JSON
// (plantview/measure.h).
#include <charconv>

#include <nlohmann/json.hpp>

#include "plantview/measure.h"
#include "plantview/store.h"

namespace plantview {

namespace {

using Outcome = StoreMeasurement::Outcome;

// The object a word names (see measure.h), or the outcome that says why not.
Outcome find_object(const ReadView& view, std::string_view word, Object& out, std::string& message) {
  std::string error;
  uint64_t id = 0;
  const auto [last, ec] = std::from_chars(word.data(), word.data() + word.size(), id);
  if (!word.empty() && ec == std::errc() && last == word.data() + word.size()) {
    std::optional<uint32_t> slot;
    if (!view.slot_of(id, slot, error)) {
      message = error;
      return Outcome::failed;
    }
    if (slot) {
      if (!view.object(*slot, out, false, error)) {
        message = error;
        return Outcome::failed;
      }
      return Outcome::measured;
    }
  }
  std::vector<uint32_t> slots;
  std::string as_stored(word);
  if (!word.empty() && !view.slots_named(as_stored, slots, error)) {
    message = error;
    return Outcome::failed;
  }
  if (slots.empty() && !word.empty() && word.front() != '/') {
    as_stored = "/" + as_stored;
    if (!view.slots_named(as_stored, slots, error)) {
      message = error;
      return Outcome::failed;
    }
  }
  if (slots.empty()) {
    message = "no object has the id or the tag '" + std::string(word.substr(0, 128)) + "'";
    return Outcome::unknown;
  }
  if (slots.size() > 1) {
    message = "the tag " + as_stored + " names " + std::to_string(slots.size()) + " objects: give an id";
    return Outcome::ambiguous;
  }
  if (!view.object(slots.front(), out, false, error)) {
    message = error;
    return Outcome::failed;
  }
  return Outcome::measured;
}

nlohmann::json point(const glm::dvec3& p) { return nlohmann::json::array({p.x, p.y, p.z}); }

}  // namespace

StoreMeasurement measure_in_store(const ReadView& view, std::string_view a, std::string_view b) {
  StoreMeasurement m;
  m.outcome = find_object(view, a, m.a, m.message);
  if (m.outcome != Outcome::measured) return m;
  m.outcome = find_object(view, b, m.b, m.message);
  if (m.outcome != Outcome::measured) return m;
  if (!measure_objects(m.a, m.b, m.clearance, m.message)) m.outcome = Outcome::no_geometry;
  return m;
}

std::string clearance_json(const Object& a, const Object& b, const Clearance& c) {
  const glm::dvec3 d = c.point_b_m - c.point_a_m;
  nlohmann::json j = {
      {"a", {{"id", std::to_string(a.id)}, {"tag", a.name}, {"point_m", point(c.point_a_m)}}},
      {"b", {{"id", std::to_string(b.id)}, {"tag", b.name}, {"point_m", point(c.point_b_m)}}},
      {"distance_m", c.distance_m},
      {"dx_m", d.x},
      {"dy_m", d.y},
      {"dz_m", d.z},
      {"error_m", c.error_m},
      {"method", c.analytic ? "analytic" : "tessellated"},
      {"overlapping", c.overlapping}};
  if (c.overlapping) j["penetration_m"] = c.penetration_m;
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace plantview
