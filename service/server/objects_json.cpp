// Rules: objects_json.h.
#include "server/objects_json.h"

#include <nlohmann/json.hpp>
#include <vector>

#include "server/http.h"

namespace plantview::service {

namespace {

// Members a pipeline's bounds are gathered from, at most (a lookup and a decode each).
constexpr size_t kMaxPipelineMembersBounded = 100000;

// `o` as JSON (a pipeline without geometry bounded by its members in `view`); false with the
// store's message if a member cannot be read.
bool json_of(const ReadView& view, const Object& o, nlohmann::json& j, std::string& error) {
  nlohmann::json attributes = nlohmann::json::array();
  for (const auto& a : o.attributes) attributes.push_back({{"key", a.key}, {"value", a.value}});
  j = {{"id", std::to_string(o.id)},
                      {"name", o.name},
                      {"class", std::string(class_name(o.object_class))},
                      {"colour", {o.colour.r, o.colour.g, o.colour.b, o.colour.a}},
                      {"attributes", attributes}};
  DAabb b = object_bounds(o);
  if (b.empty() && o.object_class == ObjectClass::pipeline) {
    // A pipeline has no geometry of its own: its bounds are its members' (a client flies to it).
    Object member;
    size_t looked_up = 0;
    for (const Branch& branch : o.branches) {
      for (const uint64_t id : branch.members) {
        if (++looked_up > kMaxPipelineMembersBounded) break;
        std::optional<uint32_t> member_slot;
        if (!view.slot_of(id, member_slot, error)) return false;
        if (!member_slot) continue;
        if (!view.object(*member_slot, member, false, error)) return false;
        b.extend(object_bounds(member));
      }
    }
  }
  if (!b.empty()) j["bounds"] = {{"min", {b.min.x, b.min.y, b.min.z}}, {"max", {b.max.x, b.max.y, b.max.z}}};
  if (o.pipeline_id) j["pipeline_id"] = std::to_string(o.pipeline_id);
  return true;
}

// The object in `slot` as JSON; false with the store's message if it cannot be read.
bool slot_json(const ReadView& view, uint32_t slot, std::string& json, std::string& error) {
  Object o;
  nlohmann::json j;
  if (!view.object(slot, o, true, error) || !json_of(view, o, j, error)) return false;
  // Attribute values are bytes as the source gave them: invalid UTF-8 is replaced, not refused.
  json = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return true;
}

ObjectAnswer error_answer(int status, std::string_view message) { return {status, error_body(message)}; }

// The object in `slot`, as object_json() gives it.
ObjectAnswer slot_answer(const ReadView& view, uint32_t slot) {
  std::string error, json;
  if (!slot_json(view, slot, json, error)) return error_answer(500, error);
  return {200, json + "\n"};
}

}  // namespace

bool object_json(const ReadView& view, uint64_t id, std::string& json, std::string& error) {
  const auto slot = view.slot_of(id);
  if (!slot) {
    error = "no object " + std::to_string(id);
    return false;
  }
  return slot_json(view, *slot, json, error);
}

bool object_at_json(const ReadView& view, uint32_t revision, uint64_t id, std::string& json,
                    std::string& error) {
  Object o;
  bool found = false;
  if (!view.object_at(revision, id, o, found, true, error)) return false;
  nlohmann::json j;
  if (!found) {
    error = "no object " + std::to_string(id) + " at revision " + std::to_string(revision);
    return false;
  }
  if (!json_of(view, o, j, error)) return false;
  j["revision"] = revision;
  json = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return true;
}

ObjectAnswer object_answer(const ReadView& view, uint64_t id, std::string_view name) {
  std::string error;
  if (id != 0) {
    std::optional<uint32_t> slot;
    if (!view.slot_of(id, slot, error)) return error_answer(500, error);
    if (slot) return slot_answer(view, *slot);
  }
  std::vector<uint32_t> slots;
  std::string as_stored(name);
  if (!view.slots_named(as_stored, slots, error)) return error_answer(500, error);
  if (slots.empty() && !name.empty() && name.front() != '/') {
    as_stored = "/" + as_stored;
    if (!view.slots_named(as_stored, slots, error)) return error_answer(500, error);
  }
  if (slots.empty()) {
    const std::string what = "'" + std::string(name.substr(0, 128)) + "'";
    return error_answer(404, (id != 0 ? "no object has the id or the tag " : "no object has the tag ") + what);
  }
  if (slots.size() > 1) {
    nlohmann::json ids = nlohmann::json::array();
    for (const uint32_t slot : slots) {
      Object o;
      if (!view.object(slot, o, false, error)) return error_answer(500, error);
      ids.push_back(std::to_string(o.id));
    }
    const nlohmann::json body = {
        {"error", "the tag " + as_stored + " names " + std::to_string(slots.size()) + " objects: ask by id"},
        {"ids", ids}};
    return {409, body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n"};
  }
  return slot_answer(view, slots.front());
}

}  // namespace plantview::service
