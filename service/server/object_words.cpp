// Rules: object_words.h.
#include "server/object_words.h"

#include <charconv>
#include <optional>

namespace plantview {

bool ids_of_words(const ReadView& view, const std::vector<std::string>& words, std::string_view what,
                  std::vector<uint64_t>& ids, std::string& error, bool& unknown) {
  unknown = false;
  for (const std::string& word : words) {
    uint64_t id = 0;
    const auto [last, ec] = std::from_chars(word.data(), word.data() + word.size(), id);
    if (ec == std::errc() && last == word.data() + word.size()) {
      std::optional<uint32_t> slot;
      if (!view.slot_of(id, slot, error)) return false;
      if (slot) {
        ids.push_back(id);
        continue;
      }
    }
    std::vector<uint32_t> slots;
    if (!view.slots_named(word, slots, error)) return false;
    if (slots.empty() && !word.empty() && word.front() != '/' && !view.slots_named("/" + word, slots, error))
      return false;
    if (slots.empty()) {
      error = std::string(what) + ": no object has the id or the tag '" + word.substr(0, 128) + "'";
      unknown = true;
      return false;
    }
    for (const uint32_t slot : slots) {
      Object o;
      if (!view.object(slot, o, false, error)) return false;
      ids.push_back(o.id);
    }
  }
  return true;
}

}  // namespace plantview
