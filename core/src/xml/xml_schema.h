// The parts of the plantview XML schema that the writer and the reader share: element and
// attribute names, each shape kind's fields, and which bytes may appear as text.
// docs/xml-format.md is the schema for people; this file must agree with it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <type_traits>

#include "plantview/primitives.h"

namespace plantview::xml_schema {

inline constexpr std::string_view kRoot = "plantview";
inline constexpr std::string_view kFormatVersion = "format_version";
// encoding="bytes" on an element: its string attributes are percent-escaped (%XX for a byte).
inline constexpr std::string_view kEncoding = "encoding";
inline constexpr std::string_view kBytes = "bytes";

// A float field of a shape, written as an attribute of the same name.
template <class S>
struct FloatField {
  std::string_view name;
  float S::*member;
};

// Each shape's float fields in struct order. Prism's integer `sides` and FacetGroup's lists are
// handled apart.
template <class S>
std::span<const FloatField<S>> float_fields() {
  if constexpr (std::is_same_v<S, Box>) {
    static constexpr FloatField<Box> f[] = {
        {"size_x_m", &Box::size_x_m}, {"size_y_m", &Box::size_y_m}, {"size_z_m", &Box::size_z_m}};
    return f;
  } else if constexpr (std::is_same_v<S, Pyramid>) {
    static constexpr FloatField<Pyramid> f[] = {
        {"bottom_x_m", &Pyramid::bottom_x_m}, {"bottom_y_m", &Pyramid::bottom_y_m},
        {"top_x_m", &Pyramid::top_x_m},       {"top_y_m", &Pyramid::top_y_m},
        {"offset_x_m", &Pyramid::offset_x_m}, {"offset_y_m", &Pyramid::offset_y_m},
        {"height_m", &Pyramid::height_m}};
    return f;
  } else if constexpr (std::is_same_v<S, Prism>) {
    static constexpr FloatField<Prism> f[] = {{"radius_m", &Prism::radius_m},
                                              {"height_m", &Prism::height_m}};
    return f;
  } else if constexpr (std::is_same_v<S, Cylinder>) {
    static constexpr FloatField<Cylinder> f[] = {{"radius_m", &Cylinder::radius_m},
                                                 {"height_m", &Cylinder::height_m}};
    return f;
  } else if constexpr (std::is_same_v<S, Snout>) {
    static constexpr FloatField<Snout> f[] = {{"radius_bottom_m", &Snout::radius_bottom_m},
                                              {"radius_top_m", &Snout::radius_top_m},
                                              {"height_m", &Snout::height_m},
                                              {"offset_x_m", &Snout::offset_x_m},
                                              {"offset_y_m", &Snout::offset_y_m},
                                              {"bottom_shear_x_rad", &Snout::bottom_shear_x_rad},
                                              {"bottom_shear_y_rad", &Snout::bottom_shear_y_rad},
                                              {"top_shear_x_rad", &Snout::top_shear_x_rad},
                                              {"top_shear_y_rad", &Snout::top_shear_y_rad}};
    return f;
  } else if constexpr (std::is_same_v<S, SquareToRound>) {
    static constexpr FloatField<SquareToRound> f[] = {
        {"bottom_x_m", &SquareToRound::bottom_x_m},     {"bottom_y_m", &SquareToRound::bottom_y_m},
        {"top_radius_m", &SquareToRound::top_radius_m}, {"height_m", &SquareToRound::height_m},
        {"offset_x_m", &SquareToRound::offset_x_m},     {"offset_y_m", &SquareToRound::offset_y_m}};
    return f;
  } else if constexpr (std::is_same_v<S, CircularTorus>) {
    static constexpr FloatField<CircularTorus> f[] = {
        {"bend_radius_m", &CircularTorus::bend_radius_m},
        {"tube_radius_m", &CircularTorus::tube_radius_m},
        {"angle_rad", &CircularTorus::angle_rad}};
    return f;
  } else if constexpr (std::is_same_v<S, RectangularTorus>) {
    static constexpr FloatField<RectangularTorus> f[] = {
        {"inner_radius_m", &RectangularTorus::inner_radius_m},
        {"outer_radius_m", &RectangularTorus::outer_radius_m},
        {"height_m", &RectangularTorus::height_m},
        {"angle_rad", &RectangularTorus::angle_rad}};
    return f;
  } else if constexpr (std::is_same_v<S, Sphere>) {
    static constexpr FloatField<Sphere> f[] = {{"radius_m", &Sphere::radius_m}};
    return f;
  } else if constexpr (std::is_same_v<S, EllipticalDish>) {
    static constexpr FloatField<EllipticalDish> f[] = {
        {"base_radius_m", &EllipticalDish::base_radius_m}, {"height_m", &EllipticalDish::height_m}};
    return f;
  } else if constexpr (std::is_same_v<S, SphericalDish>) {
    static constexpr FloatField<SphericalDish> f[] = {
        {"base_radius_m", &SphericalDish::base_radius_m}, {"height_m", &SphericalDish::height_m}};
    return f;
  } else if constexpr (std::is_same_v<S, Saddle>) {
    static constexpr FloatField<Saddle> f[] = {{"length_m", &Saddle::length_m},
                                               {"width_m", &Saddle::width_m},
                                               {"height_m", &Saddle::height_m},
                                               {"cradle_radius_m", &Saddle::cradle_radius_m}};
    return f;
  } else if constexpr (std::is_same_v<S, Line>) {
    static constexpr FloatField<Line> f[] = {{"start_x_m", &Line::start_x_m},
                                             {"end_x_m", &Line::end_x_m}};
    return f;
  } else {
    static_assert(std::is_same_v<S, FacetGroup>);
    return {};
  }
}

// The longest field list (Snout) plus kind, sides, linear and translation_m: a bit mask of
// attributes seen fits in 32 bits.
inline constexpr size_t kMaxPrimitiveAttributes = 13;

// One UTF-8 sequence at the start of `s`: its length and code point, or length 0 when it is not
// well-formed UTF-8 (overlong forms, surrogates and code points above U+10FFFF are not).
struct Utf8Char {
  uint32_t length = 0;
  uint32_t code_point = 0;
};
inline Utf8Char decode_utf8(std::string_view s) {
  const auto byte = [&](size_t i) { return static_cast<uint8_t>(s[i]); };
  const uint8_t b0 = byte(0);
  if (b0 < 0x80) return {1, b0};
  uint32_t length = 0, cp = 0, min = 0;
  if (b0 >= 0xC2 && b0 <= 0xDF) {
    length = 2, cp = b0 & 0x1Fu, min = 0x80;
  } else if (b0 >= 0xE0 && b0 <= 0xEF) {
    length = 3, cp = b0 & 0x0Fu, min = 0x800;
  } else if (b0 >= 0xF0 && b0 <= 0xF4) {
    length = 4, cp = b0 & 0x07u, min = 0x10000;
  } else {
    return {};
  }
  if (s.size() < length) return {};
  for (uint32_t i = 1; i < length; ++i) {
    if ((byte(i) & 0xC0u) != 0x80u) return {};
    cp = (cp << 6) | (byte(i) & 0x3Fu);
  }
  if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return {};
  return {length, cp};
}

// XML 1.0 Char: what a document may contain, literally or as a character reference.
inline bool is_xml_char(uint32_t cp) {
  return cp == 0x9 || cp == 0xA || cp == 0xD || (cp >= 0x20 && cp <= 0xD7FF) ||
         (cp >= 0xE000 && cp <= 0xFFFD) || (cp >= 0x10000 && cp <= 0x10FFFF);
}

inline bool is_xml_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

}  // namespace plantview::xml_schema
