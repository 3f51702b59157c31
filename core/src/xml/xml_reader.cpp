// plantview XML reader (docs/xml-format.md).
//
// Stages, so that memory stays bounded by one object rather than the file:
//   1. split: a small scanner walks the document's top level (declaration, comments, the root's
//      start and end tags) and cuts out each child of the root, whole, as soon as its end tag has
//      arrived. It tracks only nesting depth, quotes and comment/CDATA/PI boundaries.
//   2. parse: pugixml parses that one object in place, with no entity or whitespace conversion,
//      so that every name and value pointer maps back to a byte offset, hence a line.
//   3. check: each element and attribute is checked against the schema; attribute values are
//      decoded here (references, whitespace, UTF-8, percent escapes) and numbers read with
//      std::from_chars, which gives back the writer's floats bit for bit.
//   4. hand over: facet groups are triangulated and the object goes to the sink.
#include <algorithm>
#include <array>
#include <cassert>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <pugixml.hpp>
#include <span>
#include <string>
#include <system_error>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <variant>
#include <vector>

#include "plantview/xml.h"
#include "xml/xml_schema.h"

namespace plantview {

namespace {

namespace schema = xml_schema;

// Raw attribute values (no reference, end-of-line or whitespace conversion), CDATA kept so that
// text inside an object is seen and refused.
constexpr unsigned kParseOptions = pugi::parse_cdata;
// Deeper than any valid document (object > primitive > polygon > contour): refused early.
constexpr uint32_t kMaxDepth = 64;
constexpr size_t kReadBlockBytes = size_t(1) << 20;
constexpr size_t kNone = std::string_view::npos;

// A piece of untrusted text for a message: at most 40 bytes, non-printable bytes as \xNN.
std::string printable(std::string_view s) {
  std::string out;
  const size_t n = std::min<size_t>(s.size(), 40);
  for (size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7F && c != '"' && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", c);
      out += hex;
    }
  }
  if (n < s.size()) out += "...";
  return out;
}

std::string quoted(std::string_view s) { return "\"" + printable(s) + "\""; }

// An element name from the input, for a message.
std::string tag(std::string_view name) { return "<" + printable(name) + ">"; }

void append_utf8(std::string& out, uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (cp >> 18));
    out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Decodes one reference at the start of `s` (which begins with '&'): returns its length and
// appends its character, or returns 0.
size_t decode_reference(std::string_view s, std::string& out) {
  const size_t semicolon = s.substr(0, 12).find(';');
  if (semicolon == kNone) return 0;
  const std::string_view body = s.substr(1, semicolon - 1);
  static constexpr std::pair<std::string_view, char> kEntities[] = {
      {"amp", '&'}, {"lt", '<'}, {"gt", '>'}, {"quot", '"'}, {"apos", '\''}};
  for (const auto& [name, c] : kEntities) {
    if (body == name) {
      out += c;
      return semicolon + 1;
    }
  }
  if (body.size() < 2 || body[0] != '#') return 0;
  const bool hex = body[1] == 'x';
  const std::string_view digits = body.substr(hex ? 2 : 1);
  uint32_t cp = 0;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), cp, hex ? 16 : 10);
  if (digits.empty() || r.ec != std::errc() || r.ptr != digits.data() + digits.size() ||
      !schema::is_xml_char(cp)) {
    return 0;
  }
  append_utf8(out, cp);
  return semicolon + 1;
}

// An attribute value as an XML processor must deliver it: references replaced, each literal tab
// or line break (CR LF counting as one) made a space. Returns an empty `why` on success; `value`
// then views either `raw` itself or `storage`.
void decode_attribute(std::string_view raw, std::string& storage, std::string_view& value,
                      std::string& why) {
  why.clear();
  const bool plain = std::all_of(raw.begin(), raw.end(), [](char ch) {
    const auto c = static_cast<unsigned char>(ch);
    return c >= 0x20 && c < 0x80 && c != '&' && c != '<';
  });
  if (plain) {
    value = raw;
    return;
  }
  storage.clear();
  for (size_t i = 0; i < raw.size();) {
    const auto c = static_cast<unsigned char>(raw[i]);
    if (c == '<') {
      why = "'<' is not allowed in an attribute value";
      return;
    }
    if (c == '&') {
      const size_t n = decode_reference(raw.substr(i), storage);
      if (n == 0) {
        why = "unknown entity or bad character reference " + quoted(raw.substr(i, 12));
        return;
      }
      i += n;
    } else if (c == '\r') {
      storage += ' ';
      i += (i + 1 < raw.size() && raw[i + 1] == '\n') ? 2 : 1;
    } else if (c == '\n' || c == '\t') {
      storage += ' ';
      ++i;
    } else if (c < 0x20) {
      char text[64];
      std::snprintf(text, sizeof text, "control character 0x%02X is not allowed in XML", c);
      why = text;
      return;
    } else if (c < 0x80) {
      storage += static_cast<char>(c);
      ++i;
    } else {
      const schema::Utf8Char u = schema::decode_utf8(raw.substr(i));
      if (u.length == 0 || !schema::is_xml_char(u.code_point)) {
        char text[96];
        std::snprintf(text, sizeof text,
                      "byte 0x%02X is not UTF-8 text (other bytes need encoding=\"bytes\")", c);
        why = text;
        return;
      }
      storage.append(raw.substr(i, u.length));
      i += u.length;
    }
  }
  value = storage;
}

// encoding="bytes": %XX is one byte, any other character stands for itself.
bool percent_decode(std::string_view in, std::string& out, std::string& why) {
  out.clear();
  out.reserve(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] != '%') {
      out += in[i];
      continue;
    }
    const int hi = i + 1 < in.size() ? hex_digit(in[i + 1]) : -1;
    const int lo = i + 2 < in.size() ? hex_digit(in[i + 2]) : -1;
    if (hi < 0 || lo < 0) {
      why = "'%' not followed by two hexadecimal digits at " + quoted(in.substr(i, 3));
      return false;
    }
    out += static_cast<char>(hi * 16 + lo);
    i += 2;
  }
  return true;
}

// Reads one number token in full. Returns an empty string or why not.
template <class T>
std::string parse_number(std::string_view token, T& out) {
  const auto r = std::from_chars(token.data(), token.data() + token.size(), out);
  if (r.ec == std::errc::result_out_of_range) return "out of range: " + quoted(token);
  if (r.ec != std::errc() || r.ptr != token.data() + token.size()) {
    return "not a number: " + quoted(token);
  }
  if (!std::isfinite(out)) return "not finite: " + quoted(token);
  return {};
}

// Calls `each(token)` for each white-space separated token; stops at the first that returns
// false. Returns the number of tokens seen (including a failing one).
template <class F>
size_t for_each_token(std::string_view text, F&& each) {
  size_t count = 0;
  size_t i = 0;
  while (true) {
    while (i < text.size() && schema::is_xml_space(text[i])) ++i;
    if (i == text.size()) return count;
    size_t j = i;
    while (j < text.size() && !schema::is_xml_space(text[j])) ++j;
    ++count;
    if (!each(text.substr(i, j - i))) return count;
    i = j;
  }
}

// Exactly out.size() numbers. Returns an empty string or why not.
template <class T>
std::string parse_numbers(std::string_view text, std::span<T> out) {
  std::string why;
  size_t n = 0;
  const size_t seen = for_each_token(text, [&](std::string_view token) {
    if (n < out.size()) why = parse_number(token, out[n]);
    ++n;
    return why.empty();
  });
  if (!why.empty()) return why;
  if (seen != out.size()) {
    return "expected " + std::to_string(out.size()) + (out.size() == 1 ? " number" : " numbers") +
           ", found " + std::to_string(seen);
  }
  return {};
}

std::string parse_float_list(std::string_view text, std::vector<float>& out) {
  out.clear();
  std::string why;
  for_each_token(text, [&](std::string_view token) {
    float v = 0;
    why = parse_number(token, v);
    out.push_back(v);
    return why.empty();
  });
  return why;
}

// 1 to 16 hexadecimal digits, no prefix.
bool parse_hex_id(std::string_view text, uint64_t& id) {
  if (text.empty() || text.size() > 16) return false;
  id = 0;
  for (char c : text) {
    const int d = hex_digit(c);
    if (d < 0) return false;
    id = id << 4 | static_cast<uint64_t>(d);
  }
  return true;
}

template <size_t... I>
Shape default_shape(size_t kind, std::index_sequence<I...>) {
  Shape shape;
  ((kind == I ? (void)shape.emplace<I>() : void()), ...);
  return shape;
}

// Attribute names a primitive of each kind must carry, in this order: kind, linear,
// translation_m, then sides (prism), then the shape's float fields.
constexpr size_t kFirstShapeAttribute = 3;
const std::vector<std::string_view>& primitive_attribute_names(PrimitiveKind kind) {
  static const auto tables = [] {
    std::array<std::vector<std::string_view>, kPrimitiveKindCount> t;
    for (size_t k = 0; k < t.size(); ++k) {
      t[k] = {"kind", "linear", "translation_m"};
      std::visit(
          [&](const auto& shape) {
            using S = std::decay_t<decltype(shape)>;
            if constexpr (std::is_same_v<S, Prism>) t[k].push_back("sides");
            for (const auto& f : schema::float_fields<S>()) t[k].push_back(f.name);
          },
          default_shape(k, std::make_index_sequence<kPrimitiveKindCount>()));
      assert(t[k].size() <= schema::kMaxPrimitiveAttributes);
    }
    return t;
  }();
  return tables[static_cast<size_t>(kind)];
}

// Checks one element tree that pugixml parsed in place from `text` (whose first byte is on line
// `first_line`) and turns it into model values. Every failure sets `error` and returns false.
class TreeReader {
 public:
  TreeReader(std::string_view source, std::string_view text, const char* parsed,
             uint64_t first_line, XmlError& error)
      : source_(source), text_(text), parsed_(parsed), first_line_(first_line), error_(error) {}

  uint64_t line_at_offset(size_t offset) const {
    offset = std::min(offset, text_.size());
    return first_line_ +
           static_cast<uint64_t>(std::count(text_.begin(), text_.begin() + offset, '\n'));
  }
  // `at` points into the parsed copy of text (a name or value pointer from pugixml).
  uint64_t line_at(const char* at) const {
    const bool inside = at >= parsed_ && at <= parsed_ + text_.size();
    return line_at_offset(inside ? static_cast<size_t>(at - parsed_) : 0);
  }
  bool fail(const char* at, std::string_view element, std::string_view field,
            std::string_view what) {
    error_.line = line_at(at);
    error_.message = std::string(source_) + ":" + std::to_string(error_.line) + ": ";
    error_.message += element;
    error_.message += ": ";
    if (!field.empty()) {
      error_.message += field;
      error_.message += ": ";
    }
    error_.message += what;
    return false;
  }

  bool read_root(pugi::xml_node root);
  bool read_object(pugi::xml_node node, Object& object);

 private:
  static constexpr size_t kMaxFields = 16;
  // The attributes of one element, by position in the list of names it may carry.
  struct Fields {
    std::string_view raw[kMaxFields];
    const char* at[kMaxFields] = {};
    uint32_t seen = 0;
    bool has(size_t i) const { return (seen >> i) & 1u; }
  };

  // Every attribute must be one of `names`, at most once; those in `required` (bit i for
  // names[i]) must be there.
  bool collect(pugi::xml_node node, std::string_view element,
               std::span<const std::string_view> names, uint32_t required, Fields& fields);
  // Fails on text or CDATA directly inside `node`; returns its element children through `each`.
  template <class F>
  bool for_each_child(pugi::xml_node node, std::string_view element, F&& each);

  bool value(const Fields& f, size_t i, std::string_view element, std::string_view name,
             std::string_view& out);
  bool text(const Fields& f, size_t i, std::string_view element, std::string_view name, bool bytes,
            std::string& out);
  template <class T>
  bool numbers(const Fields& f, size_t i, std::string_view element, std::string_view name,
               std::span<T> out);
  bool hex_id(const Fields& f, size_t i, std::string_view element, std::string_view name,
              uint64_t& out);
  bool bytes_encoding(const Fields& f, size_t i, std::string_view element, bool& bytes);

  bool read_primitive(pugi::xml_node node, Primitive& primitive);
  bool read_facet_group(pugi::xml_node node, std::string_view element, FacetGroup& group);
  bool read_attribute(pugi::xml_node node, Attribute& attribute);
  bool read_connection(pugi::xml_node node, ConnectionPoint& connection);
  bool read_segment(pugi::xml_node node, CentrelineSegment& segment);
  bool read_branch(pugi::xml_node node, Branch& branch);

  std::string_view source_;
  std::string_view text_;
  const char* parsed_;
  uint64_t first_line_;
  XmlError& error_;

  std::string decoded_, why_;
  std::vector<float> positions_, normals_;
};

bool TreeReader::collect(pugi::xml_node node, std::string_view element,
                         std::span<const std::string_view> names, uint32_t required,
                         Fields& fields) {
  assert(names.size() <= kMaxFields);
  fields.seen = 0;
  for (pugi::xml_attribute a : node.attributes()) {
    const std::string_view name = a.name();
    const size_t i =
        static_cast<size_t>(std::find(names.begin(), names.end(), name) - names.begin());
    if (i == names.size()) return fail(a.name(), element, {}, "unknown attribute " + quoted(name));
    if (fields.has(i)) return fail(a.name(), element, name, "attribute given twice");
    fields.seen |= 1u << i;
    fields.raw[i] = a.value();
    fields.at[i] = a.name();
  }
  for (size_t i = 0; i < names.size(); ++i) {
    if (((required >> i) & 1u) && !fields.has(i)) {
      return fail(node.name(), element, names[i], "missing attribute");
    }
  }
  return true;
}

template <class F>
bool TreeReader::for_each_child(pugi::xml_node node, std::string_view element, F&& each) {
  for (pugi::xml_node child : node.children()) {
    if (child.type() != pugi::node_element) {
      return fail(child.value(), element, {}, "unexpected text " + quoted(child.value()));
    }
    if (!each(child)) return false;
  }
  return true;
}

bool TreeReader::value(const Fields& f, size_t i, std::string_view element, std::string_view name,
                       std::string_view& out) {
  decode_attribute(f.raw[i], decoded_, out, why_);
  return why_.empty() || fail(f.at[i], element, name, why_);
}

bool TreeReader::text(const Fields& f, size_t i, std::string_view element, std::string_view name,
                      bool bytes, std::string& out) {
  std::string_view v;
  if (!value(f, i, element, name, v)) return false;
  if (!bytes) {
    out.assign(v);
    return true;
  }
  return percent_decode(v, out, why_) || fail(f.at[i], element, name, why_);
}

template <class T>
bool TreeReader::numbers(const Fields& f, size_t i, std::string_view element, std::string_view name,
                         std::span<T> out) {
  std::string_view v;
  if (!value(f, i, element, name, v)) return false;
  why_ = parse_numbers(v, out);
  return why_.empty() || fail(f.at[i], element, name, why_);
}

bool TreeReader::hex_id(const Fields& f, size_t i, std::string_view element, std::string_view name,
                        uint64_t& out) {
  std::string_view v;
  if (!value(f, i, element, name, v)) return false;
  return parse_hex_id(v, out) ||
         fail(f.at[i], element, name, "not an id of 1 to 16 hexadecimal digits: " + quoted(v));
}

bool TreeReader::bytes_encoding(const Fields& f, size_t i, std::string_view element, bool& bytes) {
  bytes = false;
  if (!f.has(i)) return true;
  std::string_view v;
  if (!value(f, i, element, schema::kEncoding, v)) return false;
  if (v != schema::kBytes) {
    return fail(f.at[i], element, schema::kEncoding,
                "unknown encoding " + quoted(v) + " (only \"bytes\")");
  }
  bytes = true;
  return true;
}

bool TreeReader::read_root(pugi::xml_node root) {
  const std::string element = "<" + std::string(schema::kRoot) + ">";
  static constexpr std::string_view names[] = {schema::kFormatVersion};
  Fields f;
  if (!collect(root, element, names, 1, f)) return false;
  std::string_view v;
  if (!value(f, 0, element, names[0], v)) return false;
  if (v != std::to_string(kXmlFormatVersion)) {
    return fail(f.at[0], element, names[0],
                "version " + quoted(v) + " is not supported (this reader reads " +
                    std::to_string(kXmlFormatVersion) + ")");
  }
  return true;
}

bool TreeReader::read_object(pugi::xml_node node, Object& object) {
  const std::string_view element = "<object>";
  enum { kId, kName, kClass, kColour, kOrigin, kSource, kPipeline, kEncoding };
  static constexpr std::string_view names[] = {
      "id", "name", "class", "colour", "origin_m", "source", "pipeline_id", schema::kEncoding};
  Fields f;
  if (!collect(node, element, names, 0b11111, f)) return false;
  bool bytes = false;
  if (!bytes_encoding(f, kEncoding, element, bytes)) return false;

  if (!hex_id(f, kId, element, names[kId], object.id)) return false;
  if (object.id == 0)
    return fail(f.at[kId], element, names[kId], "id 0 is reserved (it means none)");
  if (!text(f, kName, element, names[kName], bytes, object.name)) return false;
  std::string_view v;
  if (!value(f, kClass, element, names[kClass], v)) return false;
  if (!class_from_name(v, object.object_class)) {
    return fail(f.at[kClass], element, names[kClass], "unknown class " + quoted(v));
  }
  if (!value(f, kColour, element, names[kColour], v)) return false;
  {
    uint8_t rgba[4];
    bool ok = v.size() == 9 && v[0] == '#';
    for (int i = 0; ok && i < 4; ++i) {
      const int hi = hex_digit(v[1 + 2 * i]), lo = hex_digit(v[2 + 2 * i]);
      ok = hi >= 0 && lo >= 0;
      rgba[i] = static_cast<uint8_t>(hi * 16 + lo);
    }
    if (!ok) return fail(f.at[kColour], element, names[kColour], "not #rrggbbaa: " + quoted(v));
    object.colour = {rgba[0], rgba[1], rgba[2], rgba[3]};
  }
  double origin[3];
  if (!numbers(f, kOrigin, element, names[kOrigin], std::span<double>(origin))) return false;
  object.origin_m = {origin[0], origin[1], origin[2]};
  if (f.has(kSource) && !text(f, kSource, element, names[kSource], bytes, object.source))
    return false;
  if (f.has(kPipeline) && !hex_id(f, kPipeline, element, names[kPipeline], object.pipeline_id)) {
    return false;
  }

  return for_each_child(node, element, [&](pugi::xml_node child) {
    const std::string_view name = child.name();
    if (name == "primitive") return read_primitive(child, object.primitives.emplace_back());
    if (name == "attribute") return read_attribute(child, object.attributes.emplace_back());
    if (name == "connection") return read_connection(child, object.connections.emplace_back());
    if (name == "segment") return read_segment(child, object.centreline.emplace_back());
    if (name == "branch") return read_branch(child, object.branches.emplace_back());
    return fail(child.name(), element, {}, "unknown element " + tag(name));
  });
}

bool TreeReader::read_primitive(pugi::xml_node node, Primitive& primitive) {
  // The kind decides which other attributes belong.
  pugi::xml_attribute kind_attribute = node.attribute("kind");
  if (!kind_attribute) return fail(node.name(), "<primitive>", "kind", "missing attribute");
  Fields kind_field;
  kind_field.raw[0] = kind_attribute.value();
  kind_field.at[0] = kind_attribute.name();
  std::string_view kind_text;
  if (!value(kind_field, 0, "<primitive>", "kind", kind_text)) return false;
  PrimitiveKind kind;
  if (!kind_from_name(kind_text, kind)) {
    return fail(kind_attribute.name(), "<primitive>", "kind", "unknown kind " + quoted(kind_text));
  }
  const std::string element = "<primitive kind=\"" + std::string(kind_name(kind)) + "\">";

  const std::vector<std::string_view>& names = primitive_attribute_names(kind);
  Fields f;
  if (!collect(node, element, names, (1u << names.size()) - 1, f)) return false;

  float linear[9], translation[3];
  if (!numbers(f, 1, element, names[1], std::span<float>(linear))) return false;
  if (!numbers(f, 2, element, names[2], std::span<float>(translation))) return false;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) primitive.placement.linear[c][r] = linear[3 * c + r];
  }
  primitive.placement.translation_m = {translation[0], translation[1], translation[2]};

  primitive.shape =
      default_shape(static_cast<size_t>(kind), std::make_index_sequence<kPrimitiveKindCount>());
  return std::visit(
      [&](auto& shape) {
        using S = std::decay_t<decltype(shape)>;
        size_t i = kFirstShapeAttribute;
        if constexpr (std::is_same_v<S, Prism>) {
          std::string_view v;
          if (!value(f, i, element, names[i], v)) return false;
          const auto r = std::from_chars(v.data(), v.data() + v.size(), shape.sides);
          if (r.ec != std::errc() || r.ptr != v.data() + v.size()) {
            return fail(f.at[i], element, names[i],
                        "not a whole number of 0 to 4294967295: " + quoted(v));
          }
          ++i;
        }
        for (const schema::FloatField<S>& field : schema::float_fields<S>()) {
          if (!numbers(f, i, element, names[i], std::span<float>(&(shape.*field.member), 1)))
            return false;
          ++i;
        }
        if constexpr (std::is_same_v<S, FacetGroup>) {
          return read_facet_group(node, element, shape);
        } else {
          return for_each_child(node, element, [&](pugi::xml_node child) {
            return fail(child.name(), element, {},
                        "unexpected element " + tag(child.name()) +
                            " (only facet groups have child elements)");
          });
        }
      },
      primitive.shape);
}

bool TreeReader::read_facet_group(pugi::xml_node node, std::string_view element,
                                  FacetGroup& group) {
  const bool ok = for_each_child(node, element, [&](pugi::xml_node polygon) {
    if (std::string_view(polygon.name()) != "polygon") {
      return fail(polygon.name(), element, {},
                  "unknown element " + tag(polygon.name()) + " (expected <polygon>)");
    }
    Fields none;
    if (!collect(polygon, "<polygon>", {}, 0, none)) return false;
    const bool contours_ok = for_each_child(polygon, "<polygon>", [&](pugi::xml_node contour) {
      if (std::string_view(contour.name()) != "contour") {
        return fail(contour.name(), "<polygon>", {},
                    "unknown element " + tag(contour.name()) + " (expected <contour>)");
      }
      static constexpr std::string_view names[] = {"positions_m", "normals"};
      Fields f;
      if (!collect(contour, "<contour>", names, 0b11, f)) return false;
      for (int list = 0; list < 2; ++list) {
        std::vector<float>& numbers = list == 0 ? positions_ : normals_;
        std::string_view v;
        if (!value(f, list, "<contour>", names[list], v)) return false;
        why_ = parse_float_list(v, numbers);
        if (!why_.empty()) return fail(f.at[list], "<contour>", names[list], why_);
      }
      if (positions_.size() % 3 != 0) {
        return fail(f.at[0], "<contour>", names[0],
                    std::to_string(positions_.size()) + " numbers, not a multiple of 3");
      }
      if (normals_.size() != positions_.size()) {
        return fail(f.at[1], "<contour>", names[1],
                    std::to_string(normals_.size()) + " numbers for " +
                        std::to_string(positions_.size() / 3) + " positions (3 per position)");
      }
      if (group.vertices.size() + positions_.size() / 3 > std::numeric_limits<uint32_t>::max()) {
        return fail(f.at[0], "<contour>", names[0],
                    "more than 2^32 - 1 vertices in one facet group");
      }
      for (size_t i = 0; i < positions_.size(); i += 3) {
        group.vertices.push_back({{positions_[i], positions_[i + 1], positions_[i + 2]},
                                  {normals_[i], normals_[i + 1], normals_[i + 2]}});
      }
      group.contour_ends.push_back(static_cast<uint32_t>(group.vertices.size()));
      return true;
    });
    if (!contours_ok) return false;
    group.polygon_ends.push_back(static_cast<uint32_t>(group.contour_ends.size()));
    return true;
  });
  if (!ok) return false;
  group.triangulate();
  return true;
}

bool TreeReader::read_attribute(pugi::xml_node node, Attribute& attribute) {
  const std::string_view element = "<attribute>";
  static constexpr std::string_view names[] = {"key", "value", schema::kEncoding};
  Fields f;
  bool bytes = false;
  return collect(node, element, names, 0b011, f) && bytes_encoding(f, 2, element, bytes) &&
         text(f, 0, element, names[0], bytes, attribute.key) &&
         text(f, 1, element, names[1], bytes, attribute.value) &&
         for_each_child(node, element, [&](pugi::xml_node child) {
           return fail(child.name(), element, {}, "unexpected element " + tag(child.name()));
         });
}

bool TreeReader::read_connection(pugi::xml_node node, ConnectionPoint& connection) {
  const std::string_view element = "<connection>";
  static constexpr std::string_view names[] = {"position_m", "direction", "diameter_m"};
  Fields f;
  float position[3], direction[3];
  if (!collect(node, element, names, 0b111, f) ||
      !numbers(f, 0, element, names[0], std::span<float>(position)) ||
      !numbers(f, 1, element, names[1], std::span<float>(direction)) ||
      !numbers(f, 2, element, names[2], std::span<float>(&connection.diameter_m, 1))) {
    return false;
  }
  connection.position_m = {position[0], position[1], position[2]};
  connection.direction = {direction[0], direction[1], direction[2]};
  return for_each_child(node, element, [&](pugi::xml_node child) {
    return fail(child.name(), element, {}, "unexpected element " + tag(child.name()));
  });
}

bool TreeReader::read_segment(pugi::xml_node node, CentrelineSegment& segment) {
  const std::string_view element = "<segment>";
  static constexpr std::string_view names[] = {"start_m", "end_m", "diameter_m"};
  Fields f;
  float start[3], end[3];
  if (!collect(node, element, names, 0b111, f) ||
      !numbers(f, 0, element, names[0], std::span<float>(start)) ||
      !numbers(f, 1, element, names[1], std::span<float>(end)) ||
      !numbers(f, 2, element, names[2], std::span<float>(&segment.diameter_m, 1))) {
    return false;
  }
  segment.start_m = {start[0], start[1], start[2]};
  segment.end_m = {end[0], end[1], end[2]};
  return for_each_child(node, element, [&](pugi::xml_node child) {
    return fail(child.name(), element, {}, "unexpected element " + tag(child.name()));
  });
}

bool TreeReader::read_branch(pugi::xml_node node, Branch& branch) {
  const std::string_view element = "<branch>";
  static constexpr std::string_view names[] = {"name", schema::kEncoding};
  Fields f;
  bool bytes = false;
  if (!collect(node, element, names, 0b01, f) || !bytes_encoding(f, 1, element, bytes) ||
      !text(f, 0, element, names[0], bytes, branch.name)) {
    return false;
  }
  return for_each_child(node, element, [&](pugi::xml_node member) {
    if (std::string_view(member.name()) != "member") {
      return fail(member.name(), element, {},
                  "unknown element " + tag(member.name()) + " (expected <member>)");
    }
    static constexpr std::string_view member_names[] = {"id"};
    Fields m;
    uint64_t id = 0;
    if (!collect(member, "<member>", member_names, 1, m) || !hex_id(m, 0, "<member>", "id", id)) {
      return false;
    }
    branch.members.push_back(id);
    return for_each_child(member, "<member>", [&](pugi::xml_node child) {
      return fail(child.name(), "<member>", {}, "unexpected element " + tag(child.name()));
    });
  });
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The top-level scanner.

class XmlReader::Impl {
 public:
  Impl(std::string source, XmlObjectSink sink)
      : source_(std::move(source)), sink_(std::move(sink)) {}

  bool feed(std::string_view bytes, XmlError& error);
  bool finish(XmlError& error);

 private:
  enum class Phase { start, prolog, root, epilog };
  enum class TokenKind { pi, comment, cdata, start_tag, end_tag };
  enum class Scan { token, need_more, failed };
  struct Token {
    TokenKind kind;
    size_t begin, end;      // buffer_ positions: the '<' and one past the '>'
    std::string_view name;  // element name or PI target
    bool self_closing = false;
  };

  bool scan(bool at_end);
  Scan next_token(Token& t);
  bool handle(const Token& t);
  bool open_root(const Token& t);
  bool read_chunk(size_t begin, size_t end);
  bool check_declaration(const Token& t);

  uint64_t line_at(size_t pos) const {
    return consumed_line_ +
           static_cast<uint64_t>(std::count(buffer_.begin() + static_cast<ptrdiff_t>(consumed_),
                                            buffer_.begin() + static_cast<ptrdiff_t>(pos), '\n'));
  }
  void consume_to(size_t pos) {
    consumed_line_ = line_at(pos);
    consumed_ = pos;
  }
  bool fail_at(uint64_t line, std::string what) {
    failed_ = true;
    error_.line = line;
    error_.message = source_ + ":" + std::to_string(line) + ": " + what;
    return false;
  }
  bool fail(size_t pos, std::string what) { return fail_at(line_at(pos), std::move(what)); }

  std::string source_;
  XmlObjectSink sink_;

  std::string buffer_;          // input not yet consumed, and the rest of what has arrived
  size_t consumed_ = 0;         // buffer_ before this is handled and may be dropped
  uint64_t consumed_line_ = 1;  // the line of buffer_[consumed_]
  uint64_t buffer_offset_ = 0;  // file offset of buffer_[0]
  size_t pos_ = 0;              // where the next token starts
  size_t retry_size_ = 0;       // an incomplete token: rescan once buffer_ is this long
  size_t bom_bytes_ = 0;

  Phase phase_ = Phase::start;
  uint64_t root_line_ = 0;
  size_t chunk_start_ = kNone;  // the '<' of the root's child being collected, if any
  uint64_t chunk_line_ = 0;
  uint32_t depth_ = 0;  // open elements inside the chunk

  bool failed_ = false;
  bool finished_ = false;
  XmlError error_;

  std::string scratch_;  // pugixml parses a copy in place, so pointers map to offsets
  pugi::xml_document document_;
  std::unordered_map<uint64_t, uint64_t> id_lines_;  // object id -> line of its <object>
};

bool XmlReader::Impl::feed(std::string_view bytes, XmlError& error) {
  assert(!finished_ && "XmlReader::feed after finish");
  if (failed_) {
    error = error_;
    return false;
  }
  // Drop what is handled; while an object is being collected, consumed_ stays at its start.
  if (consumed_ > 0) {
    buffer_.erase(0, consumed_);
    buffer_offset_ += consumed_;
    pos_ -= consumed_;
    if (chunk_start_ != kNone) chunk_start_ -= consumed_;
    retry_size_ = retry_size_ > consumed_ ? retry_size_ - consumed_ : 0;
    consumed_ = 0;
  }
  buffer_.append(bytes);
  // An incomplete token is scanned again only once the bytes after it have doubled: linear time.
  if (buffer_.size() < retry_size_) return true;
  if (!scan(false)) {
    error = error_;
    return false;
  }
  return true;
}

bool XmlReader::Impl::finish(XmlError& error) {
  assert(!finished_ && "XmlReader::finish called twice");
  finished_ = true;
  if (!failed_ && scan(true)) {
    const size_t end = buffer_.size();
    if (chunk_start_ != kNone) {
      fail(end, "unexpected end of file: <object> (line " + std::to_string(chunk_line_) +
                    ") is not closed");
    } else if (phase_ == Phase::start || phase_ == Phase::prolog) {
      fail(end, "no <" + std::string(xml_schema::kRoot) + "> element");
    } else if (phase_ == Phase::root) {
      fail(end, "unexpected end of file: <" + std::string(xml_schema::kRoot) + "> (line " +
                    std::to_string(root_line_) + ") is not closed");
    }
  }
  if (failed_) {
    error = error_;
    return false;
  }
  return true;
}

bool XmlReader::Impl::scan(bool at_end) {
  retry_size_ = 0;
  if (phase_ == Phase::start) {
    const std::string_view b(buffer_);
    static constexpr std::string_view bom = "\xEF\xBB\xBF";
    if (!at_end && b.size() < bom.size()) return true;  // too few bytes to tell the encoding
    if (b.starts_with(bom)) pos_ = bom_bytes_ = bom.size();
    consume_to(pos_);
    if (b.starts_with("\xFE\xFF") || b.starts_with("\xFF\xFE")) {
      return fail(0, "UTF-16 is not supported: plantview XML is UTF-8");
    }
    phase_ = Phase::prolog;
  }
  while (true) {
    if (chunk_start_ == kNone) {
      // Between top-level markup only white space may stand.
      while (pos_ < buffer_.size() && xml_schema::is_xml_space(buffer_[pos_])) ++pos_;
      consume_to(pos_);
      if (pos_ == buffer_.size()) return true;
      if (buffer_[pos_] != '<') {
        // Quote one byte only: the message must not depend on how the input was cut into pieces.
        const std::string first = quoted(std::string_view(buffer_).substr(pos_, 1));
        return fail(pos_,
                    "unexpected text (starting " + first + ") " +
                        (phase_ == Phase::root ? "between objects" : "outside the root element"));
      }
    } else if (pos_ == buffer_.size()) {
      return true;
    } else if (buffer_[pos_] != '<') {
      // Text inside an object: pugixml sees it and the checker refuses it.
      const size_t lt = buffer_.find('<', pos_);
      pos_ = lt == kNone ? buffer_.size() : lt;
      if (lt == kNone) return true;
    }
    Token t;
    const Scan r = next_token(t);
    if (r == Scan::failed) return false;
    if (r == Scan::need_more) {
      if (at_end) {
        const char c = pos_ + 1 < buffer_.size() ? buffer_[pos_ + 1] : ' ';
        const char* what = c == '!'   ? "comment or CDATA section"
                           : c == '?' ? "processing instruction"
                                      : "tag";
        return fail(buffer_.size(), std::string("unexpected end of file in the ") + what +
                                        " that starts on line " + std::to_string(line_at(pos_)));
      }
      retry_size_ = buffer_.size() + (buffer_.size() - pos_);
      return true;
    }
    if (!handle(t)) return false;
  }
}

XmlReader::Impl::Scan XmlReader::Impl::next_token(Token& t) {
  const std::string_view b(buffer_);
  const size_t p = pos_;
  if (b.size() - p < 2) return Scan::need_more;
  t.begin = p;
  t.self_closing = false;
  const auto name_at = [&](size_t from) {
    const size_t e = b.find_first_of(" \t\r\n/>?", from);
    return b.substr(from, (e == kNone ? b.size() : e) - from);
  };
  const auto until = [&](std::string_view terminator, size_t from, TokenKind kind) {
    const size_t e = b.find(terminator, from);
    if (e == kNone) return Scan::need_more;
    t.kind = kind;
    t.end = e + terminator.size();
    return Scan::token;
  };
  switch (b[p + 1]) {
    case '?':
      t.name = name_at(p + 2);
      return until("?>", p + 2, TokenKind::pi);
    case '!': {
      static constexpr std::string_view comment = "<!--", cdata = "<![CDATA[";
      const std::string_view rest = b.substr(p);
      if (rest.starts_with(comment)) return until("-->", p + comment.size(), TokenKind::comment);
      if (rest.starts_with(cdata)) return until("]]>", p + cdata.size(), TokenKind::cdata);
      if (comment.starts_with(rest) || cdata.starts_with(rest)) return Scan::need_more;
      fail(p, "markup declarations (<!DOCTYPE, <!ENTITY...) are not supported");
      return Scan::failed;
    }
    case '/':
      t.name = name_at(p + 2);
      return until(">", p + 2, TokenKind::end_tag);
    default:
      break;
  }
  // A start tag: '>' inside a quoted attribute value does not end it.
  for (size_t q = p + 1; q < b.size(); ++q) {
    const char c = b[q];
    if (c == '"' || c == '\'') {
      q = b.find(c, q + 1);
      if (q == kNone) return Scan::need_more;
    } else if (c == '>') {
      t.kind = TokenKind::start_tag;
      t.end = q + 1;
      t.self_closing = b[q - 1] == '/';
      t.name = name_at(p + 1);
      return Scan::token;
    }
  }
  return Scan::need_more;
}

bool XmlReader::Impl::handle(const Token& t) {
  const bool in_chunk = chunk_start_ != kNone;
  switch (t.kind) {
    case TokenKind::pi:
      if (t.name.size() == 3 && (t.name[0] | 0x20) == 'x' && (t.name[1] | 0x20) == 'm' &&
          (t.name[2] | 0x20) == 'l' && !check_declaration(t)) {
        return false;
      }
      break;
    case TokenKind::comment:
      break;
    case TokenKind::cdata:
      if (!in_chunk) return fail(t.begin, "unexpected CDATA section outside an object");
      break;
    case TokenKind::start_tag:
      if (in_chunk) {
        if (!t.self_closing && ++depth_ > kMaxDepth) {
          return fail(t.begin, "elements nested more than " + std::to_string(kMaxDepth) + " deep");
        }
      } else if (phase_ == Phase::prolog) {
        if (!open_root(t)) return false;
      } else if (phase_ == Phase::root) {
        if (t.name != "object") {
          return fail(t.begin, "unknown element " + tag(t.name) + " in <" +
                                   std::string(xml_schema::kRoot) + "> (expected <object>)");
        }
        chunk_start_ = t.begin;
        chunk_line_ = line_at(t.begin);
        depth_ = 1;
        if (t.self_closing && !read_chunk(t.begin, t.end)) return false;
      } else {
        return fail(t.begin, "element " + tag(t.name) + " after the end of the root element");
      }
      break;
    case TokenKind::end_tag:
      if (in_chunk) {
        if (--depth_ == 0 && !read_chunk(chunk_start_, t.end)) return false;
      } else if (phase_ == Phase::root) {
        if (t.name != xml_schema::kRoot) {
          return fail(t.begin, "end tag </" + printable(t.name) + "> does not match <" +
                                   std::string(xml_schema::kRoot) + "> (line " +
                                   std::to_string(root_line_) + ")");
        }
        phase_ = Phase::epilog;
      } else {
        return fail(t.begin, "unexpected end tag </" + printable(t.name) + ">");
      }
      break;
  }
  pos_ = t.end;
  if (chunk_start_ == kNone) consume_to(pos_);
  return true;
}

bool XmlReader::Impl::check_declaration(const Token& t) {
  if (buffer_offset_ + t.begin != bom_bytes_) {
    return fail(t.begin, "XML declaration not at the start of the document");
  }
  scratch_.assign(buffer_, t.begin, t.end - t.begin);
  document_.reset();
  const pugi::xml_parse_result r = document_.load_buffer_inplace(
      scratch_.data(), scratch_.size(), pugi::parse_declaration, pugi::encoding_utf8);
  const pugi::xml_node declaration = document_.first_child();
  // pugixml reports a document without an element, which a lone declaration is.
  if ((!r && r.status != pugi::status_no_document_element) ||
      declaration.type() != pugi::node_declaration) {
    return fail(t.begin, "malformed XML declaration");
  }
  const std::string_view encoding = declaration.attribute("encoding").value();
  std::string lower(encoding);
  for (char& c : lower) c = static_cast<char>(c | 0x20);
  if (!encoding.empty() && lower != "utf-8" && lower != "utf8") {
    return fail(t.begin,
                "encoding " + quoted(encoding) + " is not supported: plantview XML is UTF-8");
  }
  return true;
}

bool XmlReader::Impl::open_root(const Token& t) {
  root_line_ = line_at(t.begin);
  if (t.name != xml_schema::kRoot) {
    return fail(t.begin, "root element is " + tag(t.name) + ", expected <" +
                             std::string(xml_schema::kRoot) + ">");
  }
  // Parse the start tag alone, closed.
  const std::string_view tag = std::string_view(buffer_).substr(t.begin, t.end - t.begin);
  if (tag.find('\0') != kNone) return fail(t.begin, "NUL byte (not allowed in XML)");
  scratch_.assign(tag);
  if (!t.self_closing) scratch_.insert(scratch_.size() - 1, "/");
  document_.reset();
  const pugi::xml_parse_result r = document_.load_buffer_inplace(
      scratch_.data(), scratch_.size(), kParseOptions, pugi::encoding_utf8);
  XmlError error;
  TreeReader reader(source_, tag, scratch_.data(), root_line_, error);
  if (!r) {
    return fail_at(reader.line_at_offset(static_cast<size_t>(r.offset)),
                   std::string("malformed XML: ") + r.description());
  }
  if (!reader.read_root(document_.first_child())) {
    failed_ = true;
    error_ = std::move(error);
    return false;
  }
  phase_ = t.self_closing ? Phase::epilog : Phase::root;
  return true;
}

bool XmlReader::Impl::read_chunk(size_t begin, size_t end) {
  const std::string_view text = std::string_view(buffer_).substr(begin, end - begin);
  chunk_start_ = kNone;
  depth_ = 0;
  if (const size_t nul = text.find('\0'); nul != kNone) {
    return fail(begin + nul, "NUL byte (not allowed in XML)");
  }
  document_.reset();
  scratch_.assign(text);
  const pugi::xml_parse_result r = document_.load_buffer_inplace(
      scratch_.data(), scratch_.size(), kParseOptions, pugi::encoding_utf8);
  XmlError error;
  TreeReader reader(source_, text, scratch_.data(), chunk_line_, error);
  if (!r) {
    return fail_at(reader.line_at_offset(static_cast<size_t>(r.offset)),
                   std::string("malformed XML: ") + r.description());
  }
  const pugi::xml_node node = document_.first_child();
  if (node.type() != pugi::node_element || node.next_sibling()) {
    return fail_at(chunk_line_, "malformed XML in the element that starts here");
  }
  Object object;
  if (!reader.read_object(node, object)) {
    failed_ = true;
    error_ = std::move(error);
    return false;
  }
  const auto [it, inserted] = id_lines_.try_emplace(object.id, chunk_line_);
  if (!inserted) {
    char id[20];
    std::snprintf(id, sizeof id, "%016llx", static_cast<unsigned long long>(object.id));
    return fail_at(chunk_line_, "<object>: id: duplicate object id " + std::string(id) +
                                    " (first on line " + std::to_string(it->second) + ")");
  }
  document_.reset();
  sink_(std::move(object));
  return true;
}

// ---------------------------------------------------------------------------------------------

XmlReader::XmlReader(std::string source_name, XmlObjectSink sink)
    : impl_(std::make_unique<Impl>(std::move(source_name), std::move(sink))) {}
XmlReader::~XmlReader() = default;

bool XmlReader::feed(std::string_view bytes, XmlError& error) { return impl_->feed(bytes, error); }
bool XmlReader::finish(XmlError& error) { return impl_->finish(error); }

bool read_xml(std::string_view text, std::string_view source_name, const XmlObjectSink& sink,
              XmlError& error) {
  XmlReader reader(std::string(source_name), sink);
  return reader.feed(text, error) && reader.finish(error);
}

bool read_xml_file(const std::filesystem::path& path, const XmlObjectSink& sink, XmlError& error) {
  const std::string name = path.string();
  std::FILE* file = std::fopen(name.c_str(), "rb");
  if (file == nullptr) {
    error = {name + ": cannot open: " + std::strerror(errno), 0};
    return false;
  }
  XmlReader reader(name, sink);
  std::vector<char> block(kReadBlockBytes);
  bool ok = true;
  while (ok) {
    const size_t n = std::fread(block.data(), 1, block.size(), file);
    if (n > 0) ok = reader.feed(std::string_view(block.data(), n), error);
    if (n < block.size()) {
      if (std::ferror(file)) {
        error = {name + ": cannot read: " + std::strerror(errno), 0};
        ok = false;
      }
      break;
    }
  }
  std::fclose(file);
  return ok && reader.finish(error);
}

}  // namespace plantview
