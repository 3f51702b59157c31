// The views file: what `plantview views` writes and `render --views` reads, and what a view's
// caption says (plantview/review.h).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "plantview/review.h"

namespace plantview {

namespace {

using Json = nlohmann::ordered_json;  // keeps the views' and attributes' order as written

constexpr int kViewsFileVersion = 1;
constexpr size_t kMaxViewNameChars = 200;

Json vec3(const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); }

// A list of 3 finite numbers at `key` of `object` into `out`; `name` names it in errors.
template <typename Fail>
bool read_vec3(const Json& object, const char* key, const std::string& name, glm::dvec3& out,
               const Fail& fail) {
  if (!object.contains(key)) return fail("'" + name + "' is missing");
  const Json& a = object[key];
  if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() ||
      !a[2].is_number())
    return fail("'" + name + "' must be a list of 3 numbers");
  out = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
  if (!std::isfinite(out.x + out.y + out.z)) return fail("'" + name + "' must be finite");
  return true;
}

template <typename Fail>
bool check_keys(const Json& object, const std::string& name,
                std::initializer_list<std::string_view> allowed, const Fail& fail) {
  if (!object.is_object()) return fail("'" + name + "' must be an object");
  for (const auto& [key, value] : object.items()) {
    (void)value;
    bool known = false;
    std::string list;
    for (const std::string_view a : allowed) {
      known = known || key == a;
      list += (list.empty() ? "" : ", ") + std::string(a);
    }
    if (!known) return fail("unknown key '" + name + "." + key + "' (" + list + ")");
  }
  return true;
}

template <typename Fail>
bool parse_section(const Json& json, Section& out, const Fail& fail) {
  if (!check_keys(json, "section", {"planes", "box", "capped"}, fail)) return false;
  Section section;
  if (json.contains("planes")) {
    const Json& planes = json["planes"];
    if (!planes.is_array()) return fail("'section.planes' must be a list of planes");
    if (planes.size() > kMaxClipPlanes)
      return fail("'section.planes' holds " + std::to_string(planes.size()) +
                  " planes; at most " + std::to_string(kMaxClipPlanes));
    for (size_t i = 0; i < planes.size(); ++i) {
      const std::string name = "section.planes[" + std::to_string(i) + "]";
      if (!check_keys(planes[i], name, {"point", "normal"}, fail)) return false;
      ClipPlane plane;
      if (!read_vec3(planes[i], "point", name + ".point", plane.point_m, fail) ||
          !read_vec3(planes[i], "normal", name + ".normal", plane.normal, fail))
        return false;
      const double length = glm::length(plane.normal);
      if (!(length > 1e-12)) return fail("'" + name + ".normal' has no direction (zero length)");
      // (A unit normal is kept bit for bit, so that a file reads back as it was written.)
      if (std::abs(length - 1.0) > 1e-12) plane.normal /= length;
      section.planes.push_back(plane);
    }
  }
  if (json.contains("box")) {
    if (!check_keys(json["box"], "section.box", {"min", "max"}, fail) ||
        !read_vec3(json["box"], "min", "section.box.min", section.box.min, fail) ||
        !read_vec3(json["box"], "max", "section.box.max", section.box.max, fail))
      return false;
    if (section.box.empty()) return fail("'section.box' has min above max on an axis");
    section.has_box = true;
  }
  if (json.contains("capped")) {
    if (!json["capped"].is_boolean()) return fail("'section.capped' must be true or false");
    section.capped = json["capped"].get<bool>();
  }
  out = std::move(section);
  return true;
}

template <typename Fail>
bool parse_style(const Json& json, ObjectStyle& out, const Fail& fail) {
  if (!check_keys(json, "style", {"colour_by", "hide", "only"}, fail)) return false;
  ObjectStyle style;
  if (json.contains("colour_by")) {
    if (!json["colour_by"].is_string()) return fail("'style.colour_by' must be a string");
    style.colour_by = json["colour_by"].get<std::string>();
  }
  for (const char* key : {"hide", "only"}) {
    if (!json.contains(key)) continue;
    const Json& list = json[key];
    const std::string name = std::string("style.") + key;
    if (!list.is_array()) return fail("'" + name + "' must be a list of strings");
    auto& words = std::string_view(key) == "hide" ? style.hide : style.only;
    for (size_t i = 0; i < list.size(); ++i) {
      if (!list[i].is_string() || list[i].get<std::string>().empty())
        return fail("'" + name + "[" + std::to_string(i) + "]' must be a non-empty string");
      words.push_back(list[i].get<std::string>());
    }
  }
  out = std::move(style);
  return true;
}

Json section_json(const Section& section) {
  Json json = Json::object();
  if (!section.planes.empty()) {
    Json planes = Json::array();
    for (const ClipPlane& p : section.planes)
      planes.push_back(Json{{"point", vec3(p.point_m)}, {"normal", vec3(p.normal)}});
    json["planes"] = planes;
  }
  if (section.has_box)
    json["box"] = Json{{"min", vec3(section.box.min)}, {"max", vec3(section.box.max)}};
  if (!section.capped) json["capped"] = false;
  return json;
}

Json style_json(const ObjectStyle& style) {
  Json json = Json::object();
  if (!style.colour_by.empty()) json["colour_by"] = style.colour_by;
  if (!style.hide.empty()) json["hide"] = style.hide;
  if (!style.only.empty()) json["only"] = style.only;
  return json;
}

// Reads one view; `where` names it in errors ("views file: view 3 ('P-101A')").
bool parse_view(const Json& item, const std::string& where, ReviewView& v, std::string& error) {
  const auto fail = [&](const std::string& what) {
    error = where + ": " + what;
    return false;
  };
  for (const auto& [key, value] : item.items()) {
    (void)value;
    if (key != "name" && key != "title" && key != "kind" && key != "camera" && key != "aspect" &&
        key != "subject" && key != "attributes" && key != "section" && key != "style" &&
        key != "changes" && key != "colours")
      return fail("unknown key '" + key +
                  "' (name, title, kind, camera, aspect, subject, attributes, section, style, "
                  "changes, colours)");
  }
  const auto text = [&](const char* key, std::string& out) {
    if (!item.contains(key)) return fail(std::string("'") + key + "' is missing");
    if (!item[key].is_string()) return fail(std::string("'") + key + "' must be a string");
    out = item[key].get<std::string>();
    return true;
  };
  if (!text("name", v.name) || !text("title", v.title) || !text("kind", v.kind)) return false;
  if (!is_safe_view_name(v.name))
    return fail("'name' must be 1 to 200 of A-Z a-z 0-9 . _ - and not start with '.'");
  if (!is_review_kind(v.kind))
    return fail("'kind' is '" + v.kind + "' (overview, equipment, pipeline, area, change, clash)");

  if (!item.contains("camera")) return fail("'camera' is missing");
  const Json& cam = item["camera"];
  if (!cam.is_object()) return fail("'camera' must be an object");
  for (const auto& [key, value] : cam.items()) {
    (void)value;
    if (key != "eye" && key != "target" && key != "up" && key != "fov_deg")
      return fail("unknown key 'camera." + key + "' (eye, target, up, fov_deg)");
  }
  const auto point = [&](const char* key, glm::dvec3& out, bool required) {
    if (!cam.contains(key)) return required ? fail(std::string("'camera.") + key + "' is missing") : true;
    const Json& a = cam[key];
    if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() ||
        !a[2].is_number())
      return fail(std::string("'camera.") + key + "' must be a list of 3 numbers");
    out = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
    return true;
  };
  if (!point("eye", v.camera.eye_m, true) || !point("target", v.camera.target_m, true))
    return false;
  v.camera.up = default_up(v.camera.target_m - v.camera.eye_m);
  if (!point("up", v.camera.up, false)) return false;
  if (cam.contains("fov_deg")) {
    if (!cam["fov_deg"].is_number()) return fail("'camera.fov_deg' must be a number");
    v.camera.fov_deg = cam["fov_deg"].get<double>();
  }
  std::string why;
  if (!validate_camera(v.camera, why)) return fail(why);

  if (!item.contains("aspect")) return fail("'aspect' is missing");
  if (!item["aspect"].is_number() || !(item["aspect"].get<double>() > 0.0) ||
      !std::isfinite(item["aspect"].get<double>()))
    return fail("'aspect' must be a positive number (width / height)");
  v.aspect = item["aspect"].get<double>();

  if (!item.contains("subject")) return fail("'subject' is missing");
  const Json& subject = item["subject"];
  if (!subject.is_array()) return fail("'subject' must be a list of object ids");
  v.subject.reserve(subject.size());
  for (size_t i = 0; i < subject.size(); ++i) {
    if (!subject[i].is_number_unsigned())
      return fail("'subject[" + std::to_string(i) + "]' must be an object id (an integer >= 0)");
    v.subject.push_back(subject[i].get<uint64_t>());
  }

  if (item.contains("attributes")) {
    const Json& attributes = item["attributes"];
    if (!attributes.is_object()) return fail("'attributes' must be an object of strings");
    for (const auto& [key, value] : attributes.items()) {
      if (!value.is_string()) return fail("'attributes." + key + "' must be a string");
      v.attributes.emplace_back(key, value.get<std::string>());
    }
  }
  if (item.contains("section") && !parse_section(item["section"], v.section, fail)) return false;
  if (item.contains("style") && !parse_style(item["style"], v.style, fail)) return false;
  if (item.contains("changes")) {
    if (!item["changes"].is_string()) return fail("'changes' must be a string (R1 or R1..R2)");
    ChangeRange range;
    if (!parse_change_range(item["changes"].get<std::string>(), range, why))
      return fail("'changes': " + why);
    v.changes = range;
  }
  if (item.contains("colours")) {
    const Json& colours = item["colours"];
    if (!colours.is_array()) return fail("'colours' must be a list of {id, colour, label, see_through}");
    for (size_t i = 0; i < colours.size(); ++i) {
      const std::string name = "colours[" + std::to_string(i) + "]";
      const Json& c = colours[i];
      if (!c.is_object()) return fail("'" + name + "' must be an object {id, colour, label, see_through}");
      if (!check_keys(c, name, {"id", "colour", "label", "see_through"}, fail)) return false;
      SubjectColour sc;
      if (!c.contains("id") || !c["id"].is_number_unsigned())
        return fail("'" + name + ".id' must be an object id (an integer >= 0)");
      sc.id = c["id"].get<uint64_t>();
      if (std::find(v.subject.begin(), v.subject.end(), sc.id) == v.subject.end())
        return fail("'" + name + ".id' " + std::to_string(sc.id) + " is not in 'subject'");
      for (const SubjectColour& earlier : v.colours)
        if (earlier.id == sc.id)
          return fail("'" + name + ".id' " + std::to_string(sc.id) + " is coloured twice");
      unsigned r = 0, g = 0, b = 0;
      const std::string hex_text = c.contains("colour") && c["colour"].is_string() ? c["colour"].get<std::string>() : "";
      if (hex_text.size() != 7 || hex_text[0] != '#' ||
          hex_text.find_first_not_of("0123456789abcdefABCDEF", 1) != std::string::npos ||
          std::sscanf(hex_text.c_str() + 1, "%2x%2x%2x", &r, &g, &b) != 3)
        return fail("'" + name + ".colour' must be \"#rrggbb\"");
      sc.colour = Colour{uint8_t(r), uint8_t(g), uint8_t(b), 255};
      if (c.contains("label")) {
        if (!c["label"].is_string()) return fail("'" + name + ".label' must be a string");
        sc.label = c["label"].get<std::string>();
      }
      if (c.contains("see_through")) {
        if (!c["see_through"].is_boolean()) return fail("'" + name + ".see_through' must be true or false");
        sc.see_through = c["see_through"].get<bool>();
      }
      v.colours.push_back(std::move(sc));
    }
  }
  return true;
}

}  // namespace

bool is_review_kind(std::string_view kind) {
  return kind == "overview" || kind == "equipment" || kind == "pipeline" || kind == "area" ||
         kind == "change" || kind == "clash";
}

bool is_safe_view_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxViewNameChars || name.front() == '.') return false;
  for (const char c : name) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

std::string review_views_json(const std::vector<ReviewView>& views, std::string_view per) {
  Json list = Json::array();
  for (const ReviewView& v : views) {
    Json attributes = Json::object();
    for (const auto& [key, value] : v.attributes) attributes[key] = value;
    list.push_back(Json{{"name", v.name},
                        {"title", v.title},
                        {"kind", v.kind},
                        {"camera", Json{{"eye", vec3(v.camera.eye_m)},
                                        {"target", vec3(v.camera.target_m)},
                                        {"up", vec3(v.camera.up)},
                                        {"fov_deg", v.camera.fov_deg}}},
                        {"aspect", v.aspect},
                        {"subject", v.subject},
                        {"attributes", attributes}});
    if (!v.section.empty()) list.back()["section"] = section_json(v.section);
    if (!v.style.empty()) list.back()["style"] = style_json(v.style);
    if (v.changes) list.back()["changes"] = change_range_text(*v.changes);
    if (!v.colours.empty()) {
      Json colours = Json::array();
      for (const SubjectColour& c : v.colours) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "#%02x%02x%02x", c.colour.r, c.colour.g, c.colour.b);
        colours.push_back(Json{{"id", c.id}, {"colour", hex}, {"label", c.label}});
        if (c.see_through) colours.back()["see_through"] = true;
      }
      list.back()["colours"] = colours;
    }
  }
  Json file = Json::object();  // (keys sorted as written: the list moved in, not copied)
  file["version"] = kViewsFileVersion;
  file["per"] = std::string(per);
  file["views"] = std::move(list);
  // Attribute values are bytes as the model gave them, not always UTF-8: invalid sequences
  // become U+FFFD rather than failing the file.
  return file.dump(1, ' ', false, Json::error_handler_t::replace) + "\n";
}

bool parse_review_views(std::string_view json, std::vector<ReviewView>& out, std::string& error) {
  const Json file = Json::parse(json, nullptr, false);
  if (file.is_discarded()) {
    error = "views file: not valid JSON";
    return false;
  }
  if (!file.is_object()) {
    error = "views file: not a JSON object";
    return false;
  }
  for (const auto& [key, value] : file.items()) {
    (void)value;
    if (key != "version" && key != "per" && key != "views") {
      error = "views file: unknown key '" + key + "' (version, per, views)";
      return false;
    }
  }
  if (!file.contains("version") || !file["version"].is_number_integer() ||
      file["version"].get<int64_t>() != kViewsFileVersion) {
    error = "views file: 'version' must be " + std::to_string(kViewsFileVersion);
    return false;
  }
  if (!file.contains("per") || !file["per"].is_string() ||
      !is_review_kind(file["per"].get<std::string>())) {
    error = "views file: 'per' must be one of overview, equipment, pipeline, area, change, clash";
    return false;
  }
  if (!file.contains("views") || !file["views"].is_array()) {
    error = "views file: 'views' must be a list of views";
    return false;
  }
  const Json& list = file["views"];
  if (list.empty()) {
    error = "views file: the list of views is empty";
    return false;
  }
  std::vector<ReviewView> views;
  views.reserve(list.size());
  std::set<std::string, std::less<>> names;
  for (size_t i = 0; i < list.size(); ++i) {
    const Json& item = list[i];
    std::string where = "views file: view " + std::to_string(i);
    if (!item.is_object()) {
      error = where + " is not an object";
      return false;
    }
    if (item.contains("name") && item["name"].is_string())
      where += " ('" + item["name"].get<std::string>() + "')";
    ReviewView v;
    if (!parse_view(item, where, v, error)) return false;
    if (!names.insert(v.name).second) {
      error = where + ": the name is used by an earlier view";
      return false;
    }
    views.push_back(std::move(v));
  }
  out = std::move(views);
  return true;
}

std::vector<std::string> caption_lines(const ReviewView& view) {
  std::vector<std::string> lines;
  for (const auto& [key, value] : view.attributes) {
    if (value.empty()) continue;
    std::string label = key;
    if (!label.empty()) label[0] = char(std::toupper(static_cast<unsigned char>(label[0])));
    lines.push_back(label + " " + value);
  }
  return lines;
}

}  // namespace plantview
