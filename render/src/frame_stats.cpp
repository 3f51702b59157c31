// Frame statistics: stage times and the JSON form of FrameStats (render.h).
#include <cstdio>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "frame_stats.h"
#include "plantview/render.h"

namespace plantview {

std::string FrameStats::to_json() const {
  std::string levels;
  for (size_t l = 0; l < triangles_by_level.size(); ++l)
    levels += (l ? "," : "") + std::to_string(triangles_by_level[l]);
  char times[480];
  std::snprintf(times, sizeof times,
                "{\"cull\":%.3f,\"occlusion\":%.3f,\"depth_reduction\":%.3f,\"choose\":%.3f,"
                "\"stream\":%.3f,\"arena_growth\":%.3f,\"cpu\":%.3f,\"draw\":%.3f,"
                "\"ahead\":%.3f,\"read_back\":%.3f,\"encode\":%.3f,\"total\":%.3f}",
                ms.cull, ms.occlusion, ms.depth_reduction, ms.choose, ms.stream, ms.arena_growth,
                ms.cpu, ms.draw, ms.ahead, ms.read_back, ms.encode, ms.total);
  return "{\"objects_visible\":" + std::to_string(objects_visible) +
         ",\"objects_culled\":" + std::to_string(objects_culled) +
         ",\"objects_occluded\":" + std::to_string(objects_occluded) +
         ",\"objects_clipped\":" + std::to_string(objects_clipped) +
         ",\"nodes_occluded\":" + std::to_string(nodes_occluded) +
         ",\"occluders\":" + std::to_string(occluders) +
         ",\"triangles\":" + std::to_string(triangles) + ",\"lines\":" + std::to_string(lines) +
         ",\"triangles_by_level\":[" + levels + "]" +
         ",\"centreline_pipes\":" + std::to_string(centreline_pipes) +
         ",\"hlod_merges\":" + std::to_string(hlod_merges) +
         ",\"hlod_members\":" + std::to_string(hlod_members) +
         ",\"budget_proxies\":" + std::to_string(budget_proxies) +
         ",\"budget_coarsened\":" + std::to_string(budget_coarsened) +
         ",\"objects_refined\":" + std::to_string(objects_refined) +
         ",\"objects_deferred\":" + std::to_string(objects_deferred) +
         ",\"objects_subpixel\":" + std::to_string(objects_subpixel) +
         ",\"node_proxies\":" + std::to_string(node_proxies) +
         ",\"node_proxy_pixels\":" + std::to_string(node_proxy_pixels) +
         ",\"objects_in_node_proxies\":" + std::to_string(objects_in_node_proxies) +
         ",\"spatial_blocks_walked\":" + std::to_string(spatial_blocks_walked) +
         ",\"spatial_blocks_held\":" + std::to_string(spatial_blocks_held) +
         ",\"draw_commands\":" + std::to_string(draw_commands) +
         ",\"arena_bytes_budget\":" + std::to_string(arena_bytes_budget) +
         ",\"arena_bytes_resident\":" + std::to_string(arena_bytes_resident) +
         ",\"arena_bytes_uploaded\":" + std::to_string(arena_bytes_uploaded) +
         ",\"arena_bytes_evicted\":" + std::to_string(arena_bytes_evicted) +
         ",\"objects_resident\":" + std::to_string(objects_resident) +
         ",\"objects_tessellated\":" + std::to_string(objects_tessellated) +
         ",\"objects_evicted\":" + std::to_string(objects_evicted) +
         ",\"objects_hidden\":" + std::to_string(objects_hidden) +
         (legend.key.empty() ? std::string() : ",\"legend\":" + legend.to_json()) +
         (!changes.shown ? std::string()
                         : ",\"changes\":{\"from\":" + std::to_string(changes.from) +
                               ",\"to\":" + std::to_string(changes.to) +
                               ",\"added\":" + std::to_string(changes.added) +
                               ",\"modified\":" + std::to_string(changes.modified) +
                               ",\"removed\":" + std::to_string(changes.removed) + "}") +
         ",\"ms\":" + times + "}";
}

namespace {

// A JSON string of `bytes`: quotes, backslashes and control characters escaped, each invalid
// UTF-8 sequence written as U+FFFD (attribute values are bytes as the model gave them).
std::string json_text(std::string_view bytes) {
  std::string out = "\"";
  for (size_t i = 0; i < bytes.size();) {
    const unsigned char c = static_cast<unsigned char>(bytes[i]);
    if (c < 0x80) {
      if (c == '"' || c == '\\') {
        out += '\\';
        out += char(c);
      } else if (c < 0x20) {
        char u[8];
        std::snprintf(u, sizeof u, "\\u%04x", c);
        out += u;
      } else {
        out += char(c);
      }
      ++i;
      continue;
    }
    const size_t n = c >= 0xF0 && c < 0xF5 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 && c < 0xE0 ? 2 : 0;
    bool valid = n > 0 && i + n <= bytes.size();
    for (size_t k = 1; valid && k < n; ++k)
      valid = (static_cast<unsigned char>(bytes[i + k]) & 0xC0) == 0x80;
    if (valid) {
      out.append(bytes.substr(i, n));
      i += n;
    } else {
      out += "\xEF\xBF\xBD";
      ++i;
    }
  }
  return out + "\"";
}

std::string hex(Colour c) {
  char s[8];
  std::snprintf(s, sizeof s, "#%02x%02x%02x", c.r, c.g, c.b);
  return std::string("\"") + s + "\"";
}

std::string number(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.10g", v);
  return s;
}

}  // namespace

std::string FrameLegend::to_json() const {
  std::string out = "{\"key\":" + json_text(key);
  if (kind == Kind::ramp) {
    out += ",\"kind\":\"ramp\",\"unit\":" + json_text(unit) + ",\"min\":" + number(min) +
           ",\"max\":" + number(max) + ",\"colours\":[";
    for (size_t i = 0; i < colours.size(); ++i) out += (i ? "," : "") + hex(colours[i]);
    out += "],\"objects\":" + std::to_string(objects);
  } else {
    out += ",\"kind\":\"categories\",\"entries\":[";
    for (size_t i = 0; i < entries.size(); ++i)
      out += std::string(i ? "," : "") + "{\"value\":" + json_text(entries[i].value) +
             ",\"colour\":" + hex(entries[i].colour) +
             ",\"objects\":" + std::to_string(entries[i].objects) + "}";
    out += "],\"other_objects\":" + std::to_string(other_objects);
  }
  return out + ",\"missing_objects\":" + std::to_string(missing_objects) + "}";
}

namespace {

bool colour_from_hex(const nlohmann::json& j, Colour& out) {
  if (!j.is_string()) return false;
  const std::string text = j.get<std::string>();
  unsigned r = 0, g = 0, b = 0;
  if (text.size() != 7 || text[0] != '#' || std::sscanf(text.c_str() + 1, "%2x%2x%2x", &r, &g, &b) != 3)
    return false;
  out = {uint8_t(r), uint8_t(g), uint8_t(b), 255};
  return true;
}

}  // namespace

bool FrameLegend::from_json(std::string_view json, FrameLegend& out, std::string& error) {
  const nlohmann::json j = nlohmann::json::parse(json, nullptr, false);
  const auto fail = [&](const std::string& what) {
    error = "legend: " + what;
    return false;
  };
  if (!j.is_object()) return fail("not a JSON object");
  FrameLegend legend;
  if (!j.contains("key") || !j["key"].is_string()) return fail("'key' must be a string");
  legend.key = j["key"].get<std::string>();
  const std::string kind = j.value("kind", std::string());
  if (kind == "ramp") {
    legend.kind = Kind::ramp;
    if (!j.contains("min") || !j["min"].is_number() || !j.contains("max") || !j["max"].is_number())
      return fail("a ramp needs numbers 'min' and 'max'");
    legend.min = j["min"].get<double>();
    legend.max = j["max"].get<double>();
    if (j.contains("unit") && j["unit"].is_string()) legend.unit = j["unit"].get<std::string>();
    if (j.contains("colours") && j["colours"].is_array())
      for (const auto& c : j["colours"]) {
        Colour colour;
        if (!colour_from_hex(c, colour)) return fail("'colours' must be \"#rrggbb\" strings");
        legend.colours.push_back(colour);
      }
  } else if (kind == "categories") {
    if (!j.contains("entries") || !j["entries"].is_array()) return fail("'entries' must be a list");
    for (const auto& e : j["entries"]) {
      Entry entry;
      if (!e.is_object() || !e.contains("value") || !e["value"].is_string() || !e.contains("colour") ||
          !colour_from_hex(e["colour"], entry.colour))
        return fail("each entry needs a string 'value' and a \"#rrggbb\" 'colour'");
      entry.value = e["value"].get<std::string>();
      if (e.contains("objects") && e["objects"].is_number_unsigned()) entry.objects = e["objects"].get<uint64_t>();
      legend.entries.push_back(std::move(entry));
    }
    if (j.contains("other_objects") && j["other_objects"].is_number_unsigned())
      legend.other_objects = j["other_objects"].get<uint64_t>();
  } else {
    return fail("'kind' must be categories or ramp");
  }
  if (j.contains("missing_objects") && j["missing_objects"].is_number_unsigned())
    legend.missing_objects = j["missing_objects"].get<uint64_t>();
  out = std::move(legend);
  return true;
}

namespace detail {

void report_times(const StageTimes& stages, double total_ms, FrameStats::Times& ms) {
  ms.cull = stages.cull;
  ms.occlusion = stages.occlusion;
  ms.depth_reduction = stages.depth_reduction;
  ms.choose = stages.choose + stages.index_lists;
  ms.stream = stages.stream + stages.decode;
  ms.arena_growth = stages.arena_growth;
  ms.cpu = ms.cull + ms.occlusion + ms.choose + ms.stream;
  ms.draw = stages.draw;
  ms.ahead = stages.ahead;
  ms.read_back = stages.read_back;
  ms.total = total_ms;
}

}  // namespace detail

}  // namespace plantview
