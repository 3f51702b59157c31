// Object styling in the renderer (view_filters.h: ObjectStyle): which objects a style hides,
// each object's colour-by value, and a frame's legend and colours from the values drawn.
//
// Rules
//   - A style is compiled once per change (set_options): class words become a class mask, the
//     others shell globs (fnmatch, case-sensitive) on the object's name and its Tag attribute.
//   - An object is evaluated once, when it is decoded (DecodedObjects::add), and again only when
//     the style changes (DecodedObjects::set_style: the objects known then are read again with
//     their attributes the next time they are visible; nothing is tessellated again).
//   - Values: the attribute's value text, interned per style (StyleValues); -1 for an object
//     without the key.
//   - Numeric values: a number, then optionally spaces and a unit without digits ("260 degC",
//     "12.5 barg", "90 deg", "3"); "DN150" or "Hot, 50 mm" are not. A frame's key is a ramp when
//     every value drawn is numeric with one unit, else categories.
//   - Categories: each value's colour is kCategoryColours[hash(value) % N], the next free one on a
//     collision, values taken in text order: views that show the same values agree on their
//     colours, and most views that share a value agree on its colour. More values than colours:
//     the most frequent get colours (ties by text), the rest kOtherColour ("other_objects").
//   - A frame's colours and legend follow from the objects in view (frustum and pixel error;
//     occlusion does not change them, and they are fixed before anything is drawn), those the
//     style hides left out. A merged pipeline run takes the value of the member that decided it.
//   - Ramp: viridis (5 stops) over the min..max of the values in view.
//   - Objects without the key: kMissingColour. Alpha stays the model colour's.
// Threads: the renderer's thread; a compiled style is read by the decode workers (const).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "plantview/model.h"
#include "plantview/render.h"
#include "plantview/view_filters.h"

namespace plantview::detail {

struct Known;

inline constexpr Colour kMissingColour = FrameLegend::kMissingColour;
inline constexpr Colour kOtherColour = FrameLegend::kOtherColour;
// Distinct hues (Trubetskoy's 20 simple distinct colours, less white, black, grey and beige).
inline constexpr Colour kCategoryColours[] = {
    {230, 25, 75, 255},  {60, 180, 75, 255},   {255, 225, 25, 255},  {67, 99, 216, 255},
    {245, 130, 49, 255}, {145, 30, 180, 255},  {66, 212, 244, 255},  {240, 50, 230, 255},
    {191, 239, 69, 255}, {250, 190, 212, 255}, {70, 153, 144, 255},  {220, 190, 255, 255},
    {154, 99, 36, 255},  {128, 0, 0, 255},     {170, 255, 195, 255}, {128, 128, 0, 255},
    {255, 216, 177, 255}, {0, 0, 117, 255}};
inline constexpr size_t kCategoryCount = std::size(kCategoryColours);
// Viridis at 0, 1/4, 1/2, 3/4, 1.
inline constexpr Colour kRampStops[] = {
    {68, 1, 84, 255}, {59, 82, 139, 255}, {33, 145, 140, 255}, {94, 201, 98, 255},
    {253, 231, 37, 255}};

// A number with an optional unit (see the rules); false if `text` is not one.
bool parse_numeric_value(std::string_view text, double& number, std::string& unit);
// The ramp's colour at t in [0, 1].
Colour ramp_colour(double t);

// A style compiled for evaluation.
class CompiledStyle {
 public:
  CompiledStyle() = default;
  explicit CompiledStyle(const ObjectStyle& style);
  const ObjectStyle& style() const { return style_; }
  // Whether evaluating needs the object's record with its attributes (name, Tag, colour-by
  // value); a style of class words alone does not.
  bool needs_record() const { return needs_record_; }
  bool active() const { return !style_.empty(); }
  // Hidden by hide/only. `o` holds its attributes when needs_record().
  bool hides(const Object& o) const;
  bool hides_class(ObjectClass c) const;  // class words alone (needs_record() false)
  // The colour-by value of `o`, null if it has none (or colour_by is empty).
  const std::string* value(const Object& o) const;

 private:
  bool matches(const std::vector<std::string>& globs, const Object& o) const;
  ObjectStyle style_;
  bool needs_record_ = false;
  uint8_t hide_classes_ = 0, only_classes_ = 0;  // bit per ObjectClass
  std::vector<std::string> hide_globs_, only_globs_;
};

// The colour-by values met under one style, interned: index -> text, parsed once.
class StyleValues {
 public:
  int32_t intern(const std::string& text);
  void clear();
  struct Value {
    std::string text;
    bool numeric = false;
    double number = 0;
    std::string unit;
  };
  const Value& at(int32_t i) const { return values_[size_t(i)]; }
  size_t size() const { return values_.size(); }
  // Attribute keys of the objects read under this style (for the unknown-key message).
  void note_keys(const Object& o);
  std::vector<std::string> keys() const;

 private:
  std::vector<Value> values_;
  std::unordered_map<std::string, int32_t> index_;
  std::unordered_map<std::string, uint32_t> keys_;
};

// A frame's colours by value index (and the legend), from the values of what it draws.
class FrameColouring {
 public:
  // From the style values of the objects in view (`known`: those with geometry that the
  // style does not hide count). False when there are such objects and none has the key:
  // `error` names the key and lists the keys found (StyleValues::keys).
  bool make(const std::string& key, std::span<Known* const> known, const StyleValues& values,
            FrameLegend& legend, std::string& error);
  // The colour for an object of value `value` (-1: none) and model colour `model`.
  Colour colour(int32_t value, Colour model) const {
    Colour c = value < 0 ? kMissingColour : by_value_[size_t(value)];
    c.a = model.a;
    return c;
  }

 private:
  std::vector<Colour> by_value_;
  std::vector<uint32_t> counts_;
  std::vector<int32_t> seen_;
};

}  // namespace plantview::detail
