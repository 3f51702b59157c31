// Objects as the service's JSON: {"id": "<decimal>", "name", "class", "colour", "attributes":
// [{"key", "value"}], "bounds": {"min", "max"}, "pipeline_id"?}. Ids are strings because they are
// 64-bit and JavaScript numbers are not.
#pragma once

#include <cstdint>
#include <string>

#include "plantview/store.h"

namespace plantview::service {

// Looks the object up in `view` (on the view's thread). False with a message when there is no
// such object ("no object <id>") or it cannot be read (the store's message).
bool object_json(const ReadView& view, uint64_t id, std::string& json, std::string& error);

}  // namespace plantview::service
