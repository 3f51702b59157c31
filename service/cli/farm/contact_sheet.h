// The contact sheet of a farm's output directory: index.html, one page that opens from disk
// (file://, no server, nothing fetched from elsewhere): per view a thumbnail (the image itself,
// scaled by the browser), its name, title, kind, status and LOD statistics, and a box that
// filters the views by name or title (plain JavaScript, inline).
// Every card is an element with class "view" and data-name="<view name>"; a view that is not
// done shows its status in place of the image.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace plantview::cli::farm {

// The page for a merged manifest (manifest.h: {"summary": ..., "views": [...]}).
std::string contact_sheet_html(const nlohmann::json& manifest);

}  // namespace plantview::cli::farm
