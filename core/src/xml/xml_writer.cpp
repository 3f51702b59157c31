// plantview XML writer: objects to text (docs/xml-format.md).
//
// One element per line, two spaces of indent per level, so that a reader's line numbers point at
// one primitive. Numbers are std::to_chars shortest form, which from_chars reads back to the same
// bits. A string is written as text when it is UTF-8 made only of XML characters; otherwise the
// element is marked encoding="bytes" and the bytes that cannot be text (and '%') become %XX.
#include <cassert>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <system_error>
#include <type_traits>
#include <variant>

#include "plantview/xml.h"
#include "xml/xml_schema.h"

namespace plantview {

namespace {

namespace schema = xml_schema;

constexpr size_t kFlushBytes = size_t(1) << 20;

// True if `s` can be written as XML text as it is: UTF-8 made of XML characters only.
bool is_xml_text(std::string_view s) {
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x80) {
      ++i;
      continue;
    }
    const schema::Utf8Char u = schema::decode_utf8(s.substr(i));
    if (u.length == 0 || !schema::is_xml_char(u.code_point)) return false;
    i += u.length;
  }
  return true;
}

void append_hex_byte(std::string& out, unsigned char c) {
  static constexpr char digits[] = "0123456789ABCDEF";
  out += '%';
  out += digits[c >> 4];
  out += digits[c & 15];
}

// The reference for a character that cannot stand literally in a double-quoted attribute value,
// or nullptr. Tab and line breaks are among them: XML reads them back as spaces.
const char* reference_for(unsigned char c) {
  switch (c) {
    case '&': return "&amp;";
    case '<': return "&lt;";
    case '>': return "&gt;";
    case '"': return "&quot;";
    case '\t': return "&#9;";
    case '\n': return "&#10;";
    case '\r': return "&#13;";
    default: return nullptr;
  }
}

// Appends `s` as the inside of a double-quoted attribute value. With `bytes`, '%' and every byte
// that is not part of an XML character become %XX.
void append_escaped(std::string& out, std::string_view s, bool bytes) {
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (const char* reference = reference_for(c)) {
      out += reference;
      ++i;
      continue;
    }
    if (c == '%' && bytes) {
      append_hex_byte(out, c);
      ++i;
    } else if (c >= 0x20 && c < 0x80) {
      out += static_cast<char>(c);
      ++i;
    } else {
      const schema::Utf8Char u = schema::decode_utf8(s.substr(i));
      if (u.length != 0 && schema::is_xml_char(u.code_point)) {
        out.append(s.substr(i, u.length));
        i += u.length;
      } else {
        // Only reached with `bytes`: callers check is_xml_text first.
        append_hex_byte(out, c);
        ++i;
      }
    }
  }
}

void append_hex_id(std::string& out, uint64_t id) {
  char text[16];
  for (int i = 15; i >= 0; --i, id >>= 4) text[i] = "0123456789abcdef"[id & 15];
  out.append(text, 16);
}

// Builds one object's text; the first refusal is kept and the caller drops the text.
class ObjectText {
 public:
  ObjectText(std::string& out, const Object& object) : out_(out), object_(object) {}

  bool write(XmlError& error);

 private:
  void refuse(std::string what) {
    if (!refused_) {
      refused_ = true;
      reason_ = std::move(what);
    }
  }
  // Names the element that a refusal is about: "primitive 3 (cylinder)".
  void set_context(std::string_view element, size_t index, std::string_view kind) {
    if (refused_) return;
    context_.clear();
    if (element.empty()) return;
    context_ = std::string(element) + " " + std::to_string(index);
    if (!kind.empty()) context_ += " (" + std::string(kind) + ")";
  }
  void open_attribute(std::string_view name) {
    out_ += ' ';
    out_ += name;
    out_ += "=\"";
  }
  void append_number(float v, std::string_view field) {
    if (!std::isfinite(v)) refuse(std::string(field) + " is not finite");
    char text[32];
    const auto r = std::to_chars(text, text + sizeof text, v);
    out_.append(text, r.ptr);
  }
  void append_number(double v, std::string_view field) {
    if (!std::isfinite(v)) refuse(std::string(field) + " is not finite");
    char text[32];
    const auto r = std::to_chars(text, text + sizeof text, v);
    out_.append(text, r.ptr);
  }
  template <class T>
  void number_attribute(std::string_view name, T v) {
    open_attribute(name);
    append_number(v, name);
    out_ += '"';
  }
  template <class V>
  void vector_attribute(std::string_view name, const V& v) {
    open_attribute(name);
    for (int i = 0; i < V::length(); ++i) {
      if (i) out_ += ' ';
      append_number(v[i], name);
    }
    out_ += '"';
  }
  void string_attribute(std::string_view name, std::string_view value, bool bytes) {
    open_attribute(name);
    append_escaped(out_, value, bytes);
    out_ += '"';
  }
  void id_attribute(std::string_view name, uint64_t id) {
    open_attribute(name);
    append_hex_id(out_, id);
    out_ += '"';
  }

  void write_primitive(const Primitive& primitive);
  void write_facet_group(const FacetGroup& group);

  std::string& out_;
  const Object& object_;
  std::string context_;  // "primitive 3 (cylinder)": where a refusal happened
  bool refused_ = false;
  std::string reason_;
};

bool ObjectText::write(XmlError& error) {
  const size_t start = out_.size();
  if (object_.id == 0) refuse("id is 0, which means \"none\"");
  if (static_cast<int>(object_.object_class) >= kObjectClassCount) {
    refuse("class " + std::to_string(static_cast<int>(object_.object_class)) +
           " is not an ObjectClass");
  }

  const bool bytes = !is_xml_text(object_.name) || !is_xml_text(object_.source);
  out_ += "  <object";
  id_attribute("id", object_.id);
  string_attribute("name", object_.name, bytes);
  open_attribute("class");
  out_ += class_name(object_.object_class);
  out_ += '"';
  open_attribute("colour");
  out_ += '#';
  for (uint8_t c : {object_.colour.r, object_.colour.g, object_.colour.b, object_.colour.a}) {
    out_ += "0123456789abcdef"[c >> 4];
    out_ += "0123456789abcdef"[c & 15];
  }
  out_ += '"';
  vector_attribute("origin_m", object_.origin_m);
  string_attribute("source", object_.source, bytes);
  if (object_.pipeline_id != 0) id_attribute("pipeline_id", object_.pipeline_id);
  if (bytes) string_attribute(schema::kEncoding, schema::kBytes, false);

  const bool empty = object_.primitives.empty() && object_.attributes.empty() &&
                     object_.connections.empty() && object_.centreline.empty() &&
                     object_.branches.empty();
  if (empty) {
    out_ += "/>\n";
  } else {
    out_ += ">\n";
    for (size_t i = 0; i < object_.primitives.size(); ++i) {
      const Primitive& p = object_.primitives[i];
      set_context("primitive", i, kind_name(p.kind()));
      write_primitive(p);
    }
    set_context({}, 0, {});
    for (const Attribute& a : object_.attributes) {
      const bool a_bytes = !is_xml_text(a.key) || !is_xml_text(a.value);
      out_ += "    <attribute";
      string_attribute("key", a.key, a_bytes);
      string_attribute("value", a.value, a_bytes);
      if (a_bytes) string_attribute(schema::kEncoding, schema::kBytes, false);
      out_ += "/>\n";
    }
    for (size_t i = 0; i < object_.connections.size(); ++i) {
      const ConnectionPoint& c = object_.connections[i];
      set_context("connection", i, {});
      out_ += "    <connection";
      vector_attribute("position_m", c.position_m);
      vector_attribute("direction", c.direction);
      number_attribute("diameter_m", c.diameter_m);
      out_ += "/>\n";
    }
    for (size_t i = 0; i < object_.centreline.size(); ++i) {
      const CentrelineSegment& s = object_.centreline[i];
      set_context("segment", i, {});
      out_ += "    <segment";
      vector_attribute("start_m", s.start_m);
      vector_attribute("end_m", s.end_m);
      number_attribute("diameter_m", s.diameter_m);
      out_ += "/>\n";
    }
    for (const Branch& b : object_.branches) {
      const bool b_bytes = !is_xml_text(b.name);
      out_ += "    <branch";
      string_attribute("name", b.name, b_bytes);
      if (b_bytes) string_attribute(schema::kEncoding, schema::kBytes, false);
      if (b.members.empty()) {
        out_ += "/>\n";
        continue;
      }
      out_ += ">\n";
      for (uint64_t m : b.members) {
        out_ += "      <member";
        id_attribute("id", m);
        out_ += "/>\n";
      }
      out_ += "    </branch>\n";
    }
    out_ += "  </object>\n";
  }

  if (refused_) {
    out_.resize(start);
    error.line = 0;
    std::string id_text;
    append_hex_id(id_text, object_.id);
    error.message = "object " + id_text + " \"" + object_.name +
                    "\": " + (context_.empty() ? "" : context_ + ": ") + reason_ +
                    "; the object is not written";
    return false;
  }
  return true;
}

void ObjectText::write_primitive(const Primitive& primitive) {
  out_ += "    <primitive kind=\"";
  out_ += kind_name(primitive.kind());
  out_ += '"';
  std::visit(
      [&](const auto& shape) {
        using S = std::decay_t<decltype(shape)>;
        if constexpr (std::is_same_v<S, Prism>) {
          open_attribute("sides");
          char text[16];
          const auto r = std::to_chars(text, text + sizeof text, shape.sides);
          out_.append(text, r.ptr);
          out_ += '"';
        }
        for (const schema::FloatField<S>& f : schema::float_fields<S>()) {
          number_attribute(f.name, shape.*f.member);
        }
      },
      primitive.shape);
  open_attribute("linear");
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      if (c || r) out_ += ' ';
      append_number(primitive.placement.linear[c][r], "linear");
    }
  }
  out_ += '"';
  vector_attribute("translation_m", primitive.placement.translation_m);
  const FacetGroup* group = std::get_if<FacetGroup>(&primitive.shape);
  if (group == nullptr || group->polygon_ends.empty()) {
    if (group != nullptr) write_facet_group(*group);  // checks that nothing is left out
    out_ += "/>\n";
    return;
  }
  out_ += ">\n";
  write_facet_group(*group);
  out_ += "    </primitive>\n";
}

void ObjectText::write_facet_group(const FacetGroup& group) {
  // The lists must partition: every vertex in one contour, every contour in one polygon.
  const size_t vertex_count = group.vertices.size();
  const size_t contour_count = group.contour_ends.size();
  uint32_t previous = 0;
  for (uint32_t end : group.contour_ends) {
    if (end < previous || end > vertex_count) {
      refuse("contour_ends is not a non-decreasing list of vertex counts");
      return;
    }
    previous = end;
  }
  if (previous != vertex_count) refuse("vertices after the last contour end");
  previous = 0;
  for (uint32_t end : group.polygon_ends) {
    if (end < previous || end > contour_count) {
      refuse("polygon_ends is not a non-decreasing list of contour counts");
      return;
    }
    previous = end;
  }
  if (previous != contour_count) refuse("contours after the last polygon end");
  if (refused_) return;

  uint32_t contour = 0;
  for (uint32_t polygon_end : group.polygon_ends) {
    if (contour == polygon_end) {
      out_ += "      <polygon/>\n";
      continue;
    }
    out_ += "      <polygon>\n";
    for (; contour < polygon_end; ++contour) {
      const uint32_t first = contour == 0 ? 0 : group.contour_ends[contour - 1];
      const uint32_t last = group.contour_ends[contour];
      out_ += "        <contour";
      open_attribute("positions_m");
      for (uint32_t v = first; v < last; ++v) {
        for (int i = 0; i < 3; ++i) {
          if (v != first || i) out_ += ' ';
          append_number(group.vertices[v].position_m[i], "positions_m");
        }
      }
      out_ += '"';
      open_attribute("normals");
      for (uint32_t v = first; v < last; ++v) {
        for (int i = 0; i < 3; ++i) {
          if (v != first || i) out_ += ' ';
          append_number(group.vertices[v].normal[i], "normals");
        }
      }
      out_ += "\"/>\n";
    }
    out_ += "      </polygon>\n";
  }
}

}  // namespace

void append_xml_header(std::string& out) {
  out += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<";
  out += schema::kRoot;
  out += ' ';
  out += schema::kFormatVersion;
  out += "=\"";
  out += std::to_string(kXmlFormatVersion);
  out += "\">\n";
}

bool append_xml_object(std::string& out, const Object& object, XmlError& error) {
  return ObjectText(out, object).write(error);
}

void append_xml_footer(std::string& out) {
  out += "</";
  out += schema::kRoot;
  out += ">\n";
}

bool write_xml(std::span<const Object> objects, std::string& out, XmlError& error) {
  out.clear();
  append_xml_header(out);
  for (const Object& object : objects) {
    if (!append_xml_object(out, object, error)) {
      out.clear();
      return false;
    }
  }
  append_xml_footer(out);
  return true;
}

// ---------------------------------------------------------------------------------------------
// XmlWriter

XmlWriter::~XmlWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

bool XmlWriter::open(const std::filesystem::path& path, XmlError& error) {
  assert(file_ == nullptr && "XmlWriter::open on an open writer");
  path_ = path.string();
  buffer_.clear();
  failed_ = false;
  failure_ = {};
  file_ = std::fopen(path_.c_str(), "wb");
  if (file_ == nullptr) {
    error = {path_ + ": cannot create: " + std::strerror(errno), 0};
    return false;
  }
  append_xml_header(buffer_);
  return true;
}

bool XmlWriter::flush() {
  if (buffer_.empty()) return true;
  if (std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size()) {
    failed_ = true;
    failure_ = {path_ + ": cannot write: " + std::strerror(errno), 0};
    return false;
  }
  buffer_.clear();
  return true;
}

bool XmlWriter::write_object(const Object& object) {
  assert(file_ != nullptr && "XmlWriter::write_object on a writer that is not open");
  if (failed_) return false;
  XmlError refusal;
  if (!append_xml_object(buffer_, object, refusal)) {
    // The objects before it are written, so the file does not depend on the buffer size.
    if (flush()) {
      failed_ = true;
      failure_ = {path_ + ": " + refusal.message, 0};
    }
    return false;
  }
  return buffer_.size() < kFlushBytes || flush();
}

bool XmlWriter::close(XmlError& error) {
  assert(file_ != nullptr && "XmlWriter::close on a writer that is not open");
  if (!failed_) {
    append_xml_footer(buffer_);
    flush();
  }
  if (std::fclose(file_) != 0 && !failed_) {
    failed_ = true;
    failure_ = {path_ + ": cannot write: " + std::strerror(errno), 0};
  }
  file_ = nullptr;
  if (failed_) {
    error = failure_;
    return false;
  }
  return true;
}

}  // namespace plantview
