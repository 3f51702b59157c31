// Objects named by words, as --highlight (plantview render) and highlight= (the service) name
// them: a decimal word is an id if an object has it; else the word is a tag, an object's name as
// stored or with the leading '/' plant names carry ("P-101A" finds "/P-101A"); a tag naming
// several objects names them all.
// Threads: the ReadView's (the look-ups read through it).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/store.h"

namespace plantview {

// Appends the ids the words name to `ids`, in the words' order. False with a message when a word
// names nothing ("<what>: no object has the id or the tag 'P-9'", and `unknown` set: the
// caller's mistake), or the store cannot be read (its message, `unknown` false). `what` names the
// option in the message ("--highlight", "highlight").
bool ids_of_words(const ReadView& view, const std::vector<std::string>& words, std::string_view what,
                  std::vector<uint64_t>& ids, std::string& error, bool& unknown);

}  // namespace plantview
