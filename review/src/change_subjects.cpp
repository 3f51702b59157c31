// Subjects of change views (review.h: per "change"): what a range of revisions changed, an
// object, a pipeline or an equipment item each, fitted on the shapes before and after.
#include <algorithm>
#include <map>

#include "views_internal.h"

namespace plantview::views {

namespace {

const std::string* find_attribute(const Object& o, std::string_view key) {
  for (const Attribute& a : o.attributes)
    if (a.key == key) return &a.value;
  return nullptr;
}

// As the plant names it: its Tag, else its name without the path's leading '/'.
std::string tag_of(const Object& o) {
  if (const std::string* tag = find_attribute(o, "Tag"); tag && !tag->empty()) return *tag;
  std::string_view name = o.name;
  if (!name.empty() && name.front() == '/') name.remove_prefix(1);
  return std::string(name);
}

std::string capitalised(std::string_view word) {
  std::string out(word);
  if (!out.empty() && out[0] >= 'a' && out[0] <= 'z') out[0] = char(out[0] - 'a' + 'A');
  return out;
}

// A changed object as it is and as it was (either may be missing: added, removed).
struct Changed {
  ObjectChange change;
  Object now, before;
  bool has_now = false, has_before = false;
  const Object& either() const { return has_now ? now : before; }
};

void add_shape(Subject& s, const Changed& c) {
  if (c.has_now) {
    s.ids.push_back(c.change.id);
    s.slots.push_back(*c.change.slot);
  }
  for (const Object* o : {c.has_now ? &c.now : nullptr, c.has_before ? &c.before : nullptr}) {
    if (!o) continue;
    const DAabb bounds = object_bounds(*o);
    if (bounds.empty()) continue;
    s.bounds.extend(bounds);
    s.boxes.push_back(bounds);
  }
}

std::string counts_text(uint64_t added, uint64_t modified, uint64_t removed) {
  std::string out;
  const auto part = [&](uint64_t n, const char* what) {
    if (n) out += (out.empty() ? "" : ", ") + std::to_string(n) + " " + what;
  };
  part(added, "added");
  part(modified, "modified");
  part(removed, "removed");
  return out;
}

}  // namespace

bool read_change_subjects(const ReadView& view, const ChangeRange& range, std::string_view group,
                          std::vector<Subject>& out, std::string& error) {
  const uint32_t revision = view.info().revision;
  const uint32_t to = range.to ? range.to : revision;
  std::vector<ObjectChange> changes;
  if (range.from >= to) {
    error = "--from " + std::to_string(range.from) + ": the store is at revision " +
            std::to_string(revision) + " (nothing after it)";
    return false;
  }
  if (!view.changes(range.from, to, changes, error)) return false;
  const std::string since = "since " + std::to_string(range.from) + " (to " + std::to_string(to) + ")";

  // Each changed object as it is and as it was.
  std::vector<Changed> changed(changes.size());
  for (size_t i = 0; i < changes.size(); ++i) {
    Changed& c = changed[i];
    c.change = changes[i];
    if (c.change.slot) {
      if (!view.object(*c.change.slot, c.now, true, error)) return false;
      c.has_now = true;
    }
    if (c.change.kind != ChangeKind::added &&
        !view.object_at(range.from, c.change.id, c.before, c.has_before, true, error))
      return false;
  }

  std::vector<Subject> subjects;
  if (group == "object" || group == "equipment") {
    for (const Changed& c : changed) {
      const Object& o = c.either();
      if (group == "equipment" && o.object_class != ObjectClass::equipment) continue;
      Subject s;
      s.kind = "change";
      s.key = tag_of(o);
      const std::string kind(change_kind_name(c.change.kind));
      s.title = capitalised(kind) + " " + std::string(class_name(o.object_class)) + " " + s.key;
      s.attributes = {{"tag", s.key},
                      {"class", std::string(class_name(o.object_class))},
                      {"change", kind},
                      {"revision", since}};
      add_shape(s, c);
      subjects.push_back(std::move(s));
    }
  } else {
    // Per pipeline: every changed object that is a pipeline or names one.
    std::map<uint64_t, size_t> of_line;
    std::vector<std::array<uint64_t, 3>> counts;  // added, modified, removed
    for (const Changed& c : changed) {
      const Object& o = c.either();
      const uint64_t line = o.object_class == ObjectClass::pipeline ? o.id : o.pipeline_id;
      if (line == 0) continue;
      auto [it, added] = of_line.try_emplace(line, subjects.size());
      if (added) {
        subjects.emplace_back().kind = "change";
        counts.push_back({0, 0, 0});
      }
      add_shape(subjects[it->second], c);
      ++counts[it->second][c.change.kind == ChangeKind::added      ? 0
                           : c.change.kind == ChangeKind::modified ? 1
                                                                   : 2];
    }
    for (const auto& [line, index] : of_line) {
      // The pipeline's name as it is now, else as it was.
      Object pipeline;
      bool found = false;
      std::optional<uint32_t> slot;
      if (!view.slot_of(line, slot, error)) return false;
      if (slot) {
        if (!view.object(*slot, pipeline, true, error)) return false;
        found = true;
      } else if (!view.object_at(range.from, line, pipeline, found, true, error)) {
        return false;
      }
      Subject& s = subjects[index];
      const std::string* number = found ? find_attribute(pipeline, "Line number") : nullptr;
      s.key = number && !number->empty() ? *number
              : found                    ? tag_of(pipeline)
                                         : "pipeline-" + std::to_string(line);
      const auto& n = counts[index];
      s.title = "Changed pipeline " + s.key + ": " + counts_text(n[0], n[1], n[2]);
      s.attributes = {{"tag", s.key},
                      {"class", "pipeline"},
                      {"change", counts_text(n[0], n[1], n[2])},
                      {"revision", since}};
    }
  }
  for (Subject& s : subjects) {
    // Slots ascending, as the placement's occluder exclusion reads them.
    std::vector<size_t> order(s.slots.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return s.slots[a] < s.slots[b]; });
    std::vector<uint32_t> slots;
    std::vector<uint64_t> ids;
    for (const size_t i : order) {
      slots.push_back(s.slots[i]);
      ids.push_back(s.ids[i]);
    }
    s.slots = std::move(slots);
    s.ids = std::move(ids);
  }
  std::erase_if(subjects, [](const Subject& s) { return s.bounds.empty(); });
  std::sort(subjects.begin(), subjects.end(), [](const Subject& a, const Subject& b) {
    return a.key != b.key ? a.key < b.key : a.title < b.title;
  });
  out = std::move(subjects);
  return true;
}

}  // namespace plantview::views
