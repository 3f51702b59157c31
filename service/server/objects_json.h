// Objects as the service's JSON: {"id": "<decimal>", "name", "class", "colour", "attributes":
// [{"key", "value"}], "bounds": {"min", "max"}, "pipeline_id"?}. Ids are strings because they are
// 64-bit and JavaScript numbers are not.
#pragma once

#include <cstdint>
#include <string>

#include "plantview/store.h"

namespace plantview::service {

// Looks the object up in a fresh read view of the store (any thread). False with a message when
// there is no such object or it cannot be read.
bool object_json(const Store& store, uint64_t id, std::string& json, std::string& error);

}  // namespace plantview::service
