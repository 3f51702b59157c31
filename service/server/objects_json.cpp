#include "server/objects_json.h"

#include <nlohmann/json.hpp>

namespace plantview::service {

bool object_json(const ReadView& view, uint64_t id, std::string& json, std::string& error) {
  const auto slot = view.slot_of(id);
  if (!slot) {
    error = "no object " + std::to_string(id);
    return false;
  }
  Object o;
  if (!view.object(*slot, o, true, error)) return false;
  nlohmann::json attributes = nlohmann::json::array();
  for (const auto& a : o.attributes) attributes.push_back({{"key", a.key}, {"value", a.value}});
  nlohmann::json j = {{"id", std::to_string(o.id)},
                      {"name", o.name},
                      {"class", std::string(class_name(o.object_class))},
                      {"colour", {o.colour.r, o.colour.g, o.colour.b, o.colour.a}},
                      {"attributes", attributes}};
  const DAabb b = object_bounds(o);
  if (!b.empty()) j["bounds"] = {{"min", {b.min.x, b.min.y, b.min.z}}, {"max", {b.max.x, b.max.y, b.max.z}}};
  if (o.pipeline_id) j["pipeline_id"] = std::to_string(o.pipeline_id);
  // Attribute values are bytes as the source gave them: invalid UTF-8 is replaced, not refused.
  json = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return true;
}

}  // namespace plantview::service
