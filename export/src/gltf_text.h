// Text for glTF documents: JSON requires UTF-8, while names and attribute values are bytes as
// the source gave them.
#pragma once

#include <string>
#include <string_view>

#include "plantview/model.h"

namespace plantview::detail::gltf {

// `bytes` where they are valid UTF-8; every byte of an invalid sequence read as Latin-1.
std::string utf8_text(std::string_view bytes);
// A JSON string literal (quotes included) of UTF-8 text.
std::string json_string(std::string_view utf8);
// An object's node extras as JSON text: {"id": "<16 hex digits>", "class": "...", then each
// attribute as key: value} (a key repeated: its first value); attributes named "id" or "class"
// go to {"attributes": {...}} instead.
std::string object_extras(const Object& object);
// A number as JSON text: the shortest form that reads back as `value` rounded to `decimals`.
std::string json_number(double value, int decimals);
std::string json_number(float value);  // exactly
// A name safe as part of a file name: [A-Za-z0-9._-] kept, runs of anything else as one '_',
// no leading '.' or '_'; "group" when nothing is left.
std::string file_safe(std::string_view name);

}  // namespace plantview::detail::gltf
