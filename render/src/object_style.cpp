// Object styling in the renderer: hide/only, colour-by values, a frame's colours and legend
// (rules in object_style.h).
#include "object_style.h"

#include <fnmatch.h>

#include <algorithm>
#include <charconv>
#include <cmath>

#include "decoded_objects.h"
#include "plantview/store.h"

namespace plantview::detail {

namespace {

const std::string* attribute(const Object& o, std::string_view key) {
  for (const Attribute& a : o.attributes)
    if (a.key == key) return &a.value;
  return nullptr;
}

bool glob(const std::string& pattern, const std::string& text) {
  return fnmatch(pattern.c_str(), text.c_str(), 0) == 0;
}

// 64-bit FNV-1a: a value's preferred palette entry, the same in every view and process.
uint64_t fnv1a(std::string_view text) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (const char c : text) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ull;
  }
  return h;
}

}  // namespace

bool parse_numeric_value(std::string_view text, double& number, std::string& unit) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), number);
  if (ec != std::errc() || !std::isfinite(number)) return false;
  std::string_view rest = text.substr(size_t(end - text.data()));
  while (!rest.empty() && rest.front() == ' ') rest.remove_prefix(1);
  // A unit: up to 16 bytes, no digits, not starting with punctuation ("DN150", "1/2 in" and
  // "3, 4" are not numbers with units; "150mm" and "150 mm" are).
  if (rest.size() > 16 ||
      std::any_of(rest.begin(), rest.end(), [](char c) { return c >= '0' && c <= '9'; }) ||
      (!rest.empty() && (rest.front() == ',' || rest.front() == '.' || rest.front() == '-' ||
                         rest.front() == '/')))
    return false;
  unit.assign(rest);
  return true;
}

Colour ramp_colour(double t) {
  t = std::clamp(std::isfinite(t) ? t : 0.5, 0.0, 1.0);
  const double x = t * double(std::size(kRampStops) - 1);
  const size_t i = std::min(size_t(x), std::size(kRampStops) - 2);
  const double f = x - double(i);
  const Colour a = kRampStops[i], b = kRampStops[i + 1];
  const auto mix = [f](uint8_t p, uint8_t q) {
    return uint8_t(std::lround(double(p) + (double(q) - double(p)) * f));
  };
  return {mix(a.r, b.r), mix(a.g, b.g), mix(a.b, b.b), 255};
}

// --- compiled style ------------------------------------------------------------------------------

CompiledStyle::CompiledStyle(const ObjectStyle& style) : style_(style) {
  const auto compile = [](const std::vector<std::string>& words, uint8_t& classes,
                          std::vector<std::string>& globs) {
    for (const std::string& w : words) {
      ObjectClass c;
      if (class_from_name(w, c))
        classes |= uint8_t(1u << unsigned(c));
      else
        globs.push_back(w);
    }
  };
  compile(style.hide, hide_classes_, hide_globs_);
  compile(style.only, only_classes_, only_globs_);
  needs_record_ = !style.colour_by.empty() || !hide_globs_.empty() || !only_globs_.empty();
}

bool CompiledStyle::matches(const std::vector<std::string>& globs, const Object& o) const {
  if (globs.empty()) return false;
  const std::string* tag = attribute(o, "Tag");
  for (const std::string& g : globs)
    if (glob(g, o.name) || (tag && glob(g, *tag))) return true;
  return false;
}

bool CompiledStyle::hides_class(ObjectClass c) const {
  const uint8_t bit = uint8_t(1u << unsigned(c));
  if (!style_.only.empty() && !(only_classes_ & bit)) return true;
  return (hide_classes_ & bit) != 0;
}

bool CompiledStyle::hides(const Object& o) const {
  const uint8_t bit = uint8_t(1u << unsigned(o.object_class));
  if (!style_.only.empty() && !(only_classes_ & bit) && !matches(only_globs_, o)) return true;
  return (hide_classes_ & bit) || matches(hide_globs_, o);
}

const std::string* CompiledStyle::value(const Object& o) const {
  return style_.colour_by.empty() ? nullptr : attribute(o, style_.colour_by);
}

// --- values --------------------------------------------------------------------------------------

int32_t StyleValues::intern(const std::string& text) {
  const auto [it, added] = index_.try_emplace(text, int32_t(values_.size()));
  if (added) {
    Value& v = values_.emplace_back();
    v.text = text;
    v.numeric = parse_numeric_value(text, v.number, v.unit);
  }
  return it->second;
}

void StyleValues::clear() {
  values_.clear();
  index_.clear();
  keys_.clear();
}

void StyleValues::note_keys(const Object& o) {
  for (const Attribute& a : o.attributes) ++keys_[a.key];
}

std::vector<std::string> StyleValues::keys() const {
  std::vector<std::string> out;
  out.reserve(keys_.size());
  for (const auto& [key, count] : keys_) out.push_back(key);
  std::sort(out.begin(), out.end());
  return out;
}

// --- a frame's colours ---------------------------------------------------------------------------

bool FrameColouring::make(const std::string& key, std::span<Known* const> known,
                          const StyleValues& values, FrameLegend& legend, std::string& error) {
  legend = FrameLegend{};
  legend.key = key;
  counts_.assign(values.size(), 0);
  by_value_.assign(values.size(), kOtherColour);
  seen_.clear();
  uint64_t missing = 0;
  for (const Known* k : known) {
    if (k->hidden || k->vertex_count == 0) continue;
    const int32_t v = k->style_value;
    if (v < 0) {
      ++missing;
      continue;
    }
    if (counts_[size_t(v)]++ == 0) seen_.push_back(v);
  }
  legend.missing_objects = missing;
  if (seen_.empty()) {
    if (missing == 0) return true;  // nothing drawn
    const std::vector<std::string> keys = values.keys();
    error = "colour by '" + key + "': none of the " + std::to_string(missing) +
            " objects in view has that attribute; keys of the objects read (" +
            std::to_string(keys.size()) + "): ";
    for (size_t i = 0; i < keys.size(); ++i) error += (i ? ", " : "") + keys[i];
    if (keys.empty()) error += "none";
    return false;
  }
  // Ramp: every value numeric, in one unit.
  const StyleValues::Value& first = values.at(seen_.front());
  bool ramp = true;
  double lo = INFINITY, hi = -INFINITY;
  for (const int32_t v : seen_) {
    const StyleValues::Value& value = values.at(v);
    if (!value.numeric || value.unit != first.unit) {
      ramp = false;
      break;
    }
    lo = std::min(lo, value.number);
    hi = std::max(hi, value.number);
  }
  if (ramp) {
    legend.kind = FrameLegend::Kind::ramp;
    legend.unit = first.unit;
    legend.min = lo;
    legend.max = hi;
    legend.colours.assign(std::begin(kRampStops), std::end(kRampStops));
    for (const int32_t v : seen_) {
      const double t = hi > lo ? (values.at(v).number - lo) / (hi - lo) : 0.5;
      by_value_[size_t(v)] = ramp_colour(t);
      legend.objects += counts_[size_t(v)];
    }
    return true;
  }
  // Categories: the most frequent kCategoryCount values get colours (ties by text), each its
  // hash's entry or the next free one, taken in text order.
  std::sort(seen_.begin(), seen_.end(), [&](int32_t a, int32_t b) {
    if (counts_[size_t(a)] != counts_[size_t(b)]) return counts_[size_t(a)] > counts_[size_t(b)];
    return values.at(a).text < values.at(b).text;
  });
  const size_t coloured = std::min(seen_.size(), kCategoryCount);
  for (size_t i = coloured; i < seen_.size(); ++i) legend.other_objects += counts_[size_t(seen_[i])];
  seen_.resize(coloured);
  std::sort(seen_.begin(), seen_.end(),
            [&](int32_t a, int32_t b) { return values.at(a).text < values.at(b).text; });
  bool taken[kCategoryCount] = {};
  for (const int32_t v : seen_) {
    size_t slot = size_t(fnv1a(values.at(v).text) % kCategoryCount);
    while (taken[slot]) slot = (slot + 1) % kCategoryCount;
    taken[slot] = true;
    by_value_[size_t(v)] = kCategoryColours[slot];
    legend.entries.push_back({values.at(v).text, kCategoryColours[slot], counts_[size_t(v)]});
  }
  return true;
}

}  // namespace plantview::detail

namespace plantview {

std::optional<Colour> FrameLegend::colour_of(std::string_view value) const {
  if (kind == Kind::categories) {
    for (const Entry& e : entries)
      if (e.value == value) return e.colour;
    return std::nullopt;
  }
  double number = 0;
  std::string value_unit;
  if (!detail::parse_numeric_value(value, number, value_unit) || value_unit != unit)
    return std::nullopt;
  return detail::ramp_colour(max > min ? (number - min) / (max - min) : 0.5);
}

}  // namespace plantview
