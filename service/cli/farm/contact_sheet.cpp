#include "cli/farm/contact_sheet.h"

#include <cctype>
#include <cstdio>

namespace plantview::cli::farm {

using nlohmann::json;

namespace {

std::string escape_html(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

// File names are [A-Za-z0-9._-] (the views file's rule), so a relative URL needs no encoding;
// anything else is percent-encoded all the same.
std::string escape_url(const std::string& text) {
  std::string out;
  for (const unsigned char c : text) {
    if (std::isalnum(c) || c == '.' || c == '_' || c == '-' || c == '/') {
      out += char(c);
    } else {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", c);
      out += hex;
    }
  }
  return out;
}

std::string number_text(const json& value, const char* format) {
  if (!value.is_number()) return "-";
  char text[32];
  std::snprintf(text, sizeof text, format, value.get<double>());
  return text;
}

std::string card_html(const json& view) {
  const std::string name = view.value("name", ""), title = view.value("title", ""),
                    status = view.value("status", "missing");
  std::string html = "<figure class=\"view " + escape_html(status) + "\" data-name=\"" +
                     escape_html(name) + "\" data-title=\"" + escape_html(title) + "\">\n";
  if (status == "done") {
    const std::string file = view.value("file", "");
    html += "<a href=\"" + escape_url(file) + "\"><img src=\"" + escape_url(file) +
            "\" loading=\"lazy\" alt=\"" + escape_html(name) + "\"></a>\n";
  } else {
    html += "<div class=\"placeholder\">" + escape_html(status) +
            (view.contains("error") ? ": " + escape_html(view.value("error", "")) : "") + "</div>\n";
  }
  html += "<figcaption><b class=\"name\">" + escape_html(name) + "</b> <span class=\"kind\">" +
          escape_html(view.value("kind", "")) + "</span><br><span class=\"title\">" +
          escape_html(title) + "</span>";
  if (status == "done") {
    const json stats = view.value("stats", json::object());
    const json ms = view.value("ms", json::object());
    html += "<br><span class=\"stats\">" + number_text(stats.value("objects_visible", json()), "%.0f") +
            " objects, " + number_text(stats.value("triangles", json()), "%.0f") + " triangles, " +
            number_text(stats.value("lines", json()), "%.0f") + " lines, " +
            number_text(ms.value("total", json()), "%.0f") + " ms</span>";
  }
  return html + "</figcaption>\n</figure>\n";
}

}  // namespace

std::string contact_sheet_html(const json& manifest) {
  const json summary = manifest.value("summary", json::object());
  std::string html = R"(<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>plantview review images</title>
<style>
body { font-family: sans-serif; margin: 1em; background: #f4f4f4; }
#filter { font-size: 1em; padding: 0.3em; width: 20em; }
#views { display: flex; flex-wrap: wrap; gap: 12px; margin-top: 1em; }
figure.view { margin: 0; width: 320px; background: #fff; border: 1px solid #ccc; padding: 6px; }
figure.view img { width: 320px; display: block; }
figure.view .placeholder { width: 320px; height: 180px; display: flex; align-items: center;
  justify-content: center; background: #ddd; color: #900; text-align: center; }
figcaption { font-size: 0.85em; margin-top: 4px; overflow-wrap: anywhere; }
.kind, .stats { color: #555; }
</style>
</head>
<body>
<h1>Review images</h1>
)";
  html += "<p id=\"summary\">" + std::to_string(summary.value("views", 0)) + " views: " +
          std::to_string(summary.value("done", 0)) + " done, " +
          std::to_string(summary.value("failed", 0)) + " failed, " +
          std::to_string(summary.value("missing", 0)) + " missing.</p>\n";
  html += R"(<label>Filter by name: <input id="filter" type="search" placeholder="P-101"></label>
<span id="shown"></span>
<div id="views">
)";
  for (const json& view : manifest.value("views", json::array())) html += card_html(view);
  html += R"(</div>
<script>
const filter = document.getElementById('filter');
function applyFilter() {
  const text = filter.value.trim().toLowerCase();
  let shown = 0;
  for (const card of document.querySelectorAll('figure.view')) {
    const match = card.dataset.name.toLowerCase().includes(text) ||
                  card.dataset.title.toLowerCase().includes(text);
    card.style.display = match ? '' : 'none';
    if (match) ++shown;
  }
  document.getElementById('shown').textContent = shown + ' shown';
}
filter.addEventListener('input', applyFilter);
applyFilter();
</script>
</body>
</html>
)";
  return html;
}

}  // namespace plantview::cli::farm
