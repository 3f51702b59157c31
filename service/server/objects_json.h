// Objects as the service's JSON: {"id": "<decimal>", "name", "class", "colour", "attributes":
// [{"key", "value"}], "bounds": {"min", "max"}, "pipeline_id"?}. Ids are strings because they are
// 64-bit and JavaScript numbers are not. A pipeline's bounds are its members' (the first 100,000).
// Threads: a ReadView's (the calls read through it); nothing else is shared.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "plantview/store.h"

namespace plantview::service {

// Looks the object up in `view` (on the view's thread). False with a message when there is no
// such object ("no object <id>") or it cannot be read (the store's message).
bool object_json(const ReadView& view, uint64_t id, std::string& json, std::string& error);

// The object as it was at `revision` (ReadView::object_at: a removed object's ghost on a change
// image), with "revision": that revision. False with a message when it did not exist then, or
// its records cannot be read (pruned: the store's message).
bool object_at_json(const ReadView& view, uint32_t revision, uint64_t id, std::string& json,
                    std::string& error);

// The answer to /api/objects/{tag-or-id} (routes.h: ObjectLookup): by `id` when it is not zero,
// then by `name` (a tag as stored, then with the leading '/' plant names carry, unless it has
// one). status 200: body is the object's JSON; 404: no such object (the message names what was
// looked for); 409: the name belongs to several objects (body {"error", "ids": [...]}, to ask by
// id); 500: the store could not be read (its message). Bodies end with a newline.
struct ObjectAnswer {
  int status = 200;
  std::string body;
};
ObjectAnswer object_answer(const ReadView& view, uint64_t id, std::string_view name);

}  // namespace plantview::service
