// Text for glTF documents (rules in gltf_text.h).
#include "gltf_text.h"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace plantview::detail::gltf {

namespace {

// The length of the valid UTF-8 sequence at bytes[i], or 0.
size_t utf8_sequence(std::string_view bytes, size_t i) {
  const auto b = [&](size_t k) { return static_cast<unsigned char>(bytes[k]); };
  const unsigned char c = b(i);
  if (c < 0x80) return 1;
  size_t n;
  uint32_t cp;
  if ((c & 0xE0) == 0xC0) n = 2, cp = c & 0x1F;
  else if ((c & 0xF0) == 0xE0) n = 3, cp = c & 0x0F;
  else if ((c & 0xF8) == 0xF0) n = 4, cp = c & 0x07;
  else return 0;
  if (i + n > bytes.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    if ((b(i + k) & 0xC0) != 0x80) return 0;
    cp = cp << 6 | (b(i + k) & 0x3F);
  }
  static constexpr uint32_t kMin[5] = {0, 0, 0x80, 0x800, 0x10000};
  if (cp < kMin[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

}  // namespace

std::string utf8_text(std::string_view bytes) {
  std::string out;
  out.reserve(bytes.size());
  for (size_t i = 0; i < bytes.size();) {
    const size_t n = utf8_sequence(bytes, i);
    if (n > 0) {
      out.append(bytes.substr(i, n));
      i += n;
      continue;
    }
    const unsigned char c = static_cast<unsigned char>(bytes[i++]);
    out.push_back(char(0xC0 | (c >> 6)));
    out.push_back(char(0x80 | (c & 0x3F)));
  }
  return out;
}

std::string json_string(std::string_view utf8) {
  std::string out = "\"";
  for (const char ch : utf8) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out.push_back('\\');
      out.push_back(ch);
    } else if (c < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
      out += escaped;
    } else {
      out.push_back(ch);
    }
  }
  return out + "\"";
}

std::string object_extras(const Object& object) {
  char id[17];
  std::snprintf(id, sizeof id, "%016llx", static_cast<unsigned long long>(object.id));
  std::string out = "{\"id\":\"" + std::string(id) + "\",\"class\":\"" +
                    std::string(class_name(object.object_class)) + "\"";
  std::string reserved;  // attributes named "id" or "class"
  for (size_t i = 0; i < object.attributes.size(); ++i) {
    const Attribute& a = object.attributes[i];
    bool repeated = false;
    for (size_t k = 0; k < i && !repeated; ++k) repeated = object.attributes[k].key == a.key;
    if (repeated) continue;
    const std::string pair = json_string(utf8_text(a.key)) + ":" + json_string(utf8_text(a.value));
    if (a.key == "id" || a.key == "class") reserved += (reserved.empty() ? "" : ",") + pair;
    else out += "," + pair;
  }
  if (!reserved.empty()) out += ",\"attributes\":{" + reserved + "}";
  return out + "}";
}

std::string json_number(double value, int decimals) {
  const double scale = std::pow(10.0, decimals);  // exact for the small powers used
  const double rounded = std::round(value * scale) / scale;
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof text, rounded == 0 ? 0.0 : rounded);
  return ec == std::errc() ? std::string(text, end) : "0";
}

std::string json_number(float value) {
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof text, value == 0 ? 0.0f : value);
  return ec == std::errc() ? std::string(text, end) : "0";
}

std::string file_safe(std::string_view name) {
  std::string out;
  for (const char c : name) {
    const bool keep = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                      c == '.' || c == '-';
    if (keep) out.push_back(c);
    else if (out.empty() || out.back() != '_') out.push_back('_');
  }
  while (!out.empty() && (out.front() == '.' || out.front() == '_')) out.erase(out.begin());
  while (!out.empty() && out.back() == '_') out.pop_back();
  return out.empty() ? "group" : out;
}

}  // namespace plantview::detail::gltf
