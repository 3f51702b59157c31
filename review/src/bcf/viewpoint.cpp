// viewpoint.bcfv (BCF 2.1 visinfo.xsd): camera, clipping planes and components. Elements are
// written in the schema's sequence order (Components, camera, ClippingPlanes).
#include <charconv>
#include <cmath>
#include <pugixml.hpp>
#include <sstream>

#include "bcf_internal.h"

namespace plantview::bcf {

std::string number_text(double value) {
  if (value == 0.0) return "0";  // and not "-0"
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

namespace {

void write_xyz(pugi::xml_node parent, const char* name, const glm::dvec3& v) {
  pugi::xml_node node = parent.append_child(name);
  node.append_child("X").text().set(number_text(v.x).c_str());
  node.append_child("Y").text().set(number_text(v.y).c_str());
  node.append_child("Z").text().set(number_text(v.z).c_str());
}

void write_component(pugi::xml_node parent, const Component& c) {
  pugi::xml_node node = parent.append_child("Component");
  if (!c.ifc_guid.empty()) node.append_attribute("IfcGuid") = c.ifc_guid.c_str();
  if (!c.originating_system.empty())
    node.append_child("OriginatingSystem").text().set(c.originating_system.c_str());
  if (!c.authoring_tool_id.empty())
    node.append_child("AuthoringToolId").text().set(c.authoring_tool_id.c_str());
}

bool read_number(pugi::xml_node node, const char* what, double& out, std::string& error) {
  const std::string text = node.text().as_string();
  const char* begin = text.data();
  while (*begin == ' ' || *begin == '\t' || *begin == '\n' || *begin == '\r') ++begin;
  const char* end = text.data() + text.size();
  while (end > begin && (end[-1] == ' ' || end[-1] == '\t' || end[-1] == '\n' || end[-1] == '\r')) --end;
  const auto result = std::from_chars(begin, end, out);
  if (!node || result.ec != std::errc() || result.ptr != end || !std::isfinite(out)) {
    error = std::string(what) + (node ? " is not a finite number" : " is missing");
    return false;
  }
  return true;
}

bool read_xyz(pugi::xml_node parent, const char* name, glm::dvec3& out, std::string& error) {
  const pugi::xml_node node = parent.child(name);
  const std::string where = std::string(parent.name()) + "/" + name;
  if (!node) {
    error = where + " is missing";
    return false;
  }
  return read_number(node.child("X"), (where + "/X").c_str(), out.x, error) &&
         read_number(node.child("Y"), (where + "/Y").c_str(), out.y, error) &&
         read_number(node.child("Z"), (where + "/Z").c_str(), out.z, error);
}

std::vector<Component> read_components(pugi::xml_node parent) {
  std::vector<Component> out;
  for (pugi::xml_node c : parent.children("Component"))
    out.push_back({c.attribute("IfcGuid").as_string(), c.child("OriginatingSystem").text().as_string(),
                   c.child("AuthoringToolId").text().as_string()});
  return out;
}

}  // namespace

std::string write_viewpoint(const Viewpoint& v) {
  pugi::xml_document doc;
  pugi::xml_node decl = doc.append_child(pugi::node_declaration);
  decl.append_attribute("version") = "1.0";
  decl.append_attribute("encoding") = "UTF-8";
  pugi::xml_node root = doc.append_child("VisualizationInfo");
  root.append_attribute("Guid") = v.guid.c_str();
  pugi::xml_node components = root.append_child("Components");
  if (!v.selection.empty()) {
    pugi::xml_node selection = components.append_child("Selection");
    for (const Component& c : v.selection) write_component(selection, c);
  }
  pugi::xml_node visibility = components.append_child("Visibility");
  visibility.append_attribute("DefaultVisibility") = v.default_visibility ? "true" : "false";
  if (!v.exceptions.empty()) {
    pugi::xml_node exceptions = visibility.append_child("Exceptions");
    for (const Component& c : v.exceptions) write_component(exceptions, c);
  }
  if (!v.colours.empty()) {
    pugi::xml_node coloring = components.append_child("Coloring");
    for (const ColourGroup& g : v.colours) {
      pugi::xml_node colour = coloring.append_child("Color");
      colour.append_attribute("Color") = g.rgb_hex.c_str();
      for (const Component& c : g.components) write_component(colour, c);
    }
  }
  pugi::xml_node camera = root.append_child("PerspectiveCamera");
  write_xyz(camera, "CameraViewPoint", v.eye);
  write_xyz(camera, "CameraDirection", v.direction);
  write_xyz(camera, "CameraUpVector", v.up);
  camera.append_child("FieldOfView").text().set(number_text(v.fov_deg).c_str());
  if (!v.planes.empty()) {
    pugi::xml_node planes = root.append_child("ClippingPlanes");
    for (const ClipPlane& p : v.planes) {
      pugi::xml_node plane = planes.append_child("ClippingPlane");
      write_xyz(plane, "Location", p.point_m);
      write_xyz(plane, "Direction", p.normal);
    }
  }
  std::ostringstream out;
  doc.save(out, "  ", pugi::format_indent, pugi::encoding_utf8);
  return out.str();
}

bool parse_viewpoint(const std::string& xml, Viewpoint& out, std::string& error) {
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_buffer(xml.data(), xml.size());
  if (!parsed) {
    error = std::string("not XML: ") + parsed.description() + " at byte " + std::to_string(parsed.offset);
    return false;
  }
  const pugi::xml_node root = doc.child("VisualizationInfo");
  if (!root) {
    error = "no VisualizationInfo element";
    return false;
  }
  Viewpoint v;
  v.guid = root.attribute("Guid").as_string();
  if (const pugi::xml_node camera = root.child("PerspectiveCamera")) {
    v.camera = Viewpoint::CameraKind::perspective;
    if (!read_xyz(camera, "CameraViewPoint", v.eye, error) ||
        !read_xyz(camera, "CameraDirection", v.direction, error) ||
        !read_xyz(camera, "CameraUpVector", v.up, error) ||
        !read_number(camera.child("FieldOfView"), "PerspectiveCamera/FieldOfView", v.fov_deg, error))
      return false;
  } else if (const pugi::xml_node ortho = root.child("OrthogonalCamera")) {
    v.camera = Viewpoint::CameraKind::orthogonal;
    if (!read_xyz(ortho, "CameraViewPoint", v.eye, error) ||
        !read_xyz(ortho, "CameraDirection", v.direction, error) ||
        !read_xyz(ortho, "CameraUpVector", v.up, error) ||
        !read_number(ortho.child("ViewToWorldScale"), "OrthogonalCamera/ViewToWorldScale", v.view_scale_m,
                     error))
      return false;
  }
  for (pugi::xml_node plane : root.child("ClippingPlanes").children("ClippingPlane")) {
    ClipPlane p;
    if (!read_xyz(plane, "Location", p.point_m, error) || !read_xyz(plane, "Direction", p.normal, error)) {
      error = "ClippingPlane " + std::to_string(v.planes.size() + 1) + ": " + error;
      return false;
    }
    v.planes.push_back(p);
  }
  const pugi::xml_node components = root.child("Components");
  v.selection = read_components(components.child("Selection"));
  const pugi::xml_node visibility = components.child("Visibility");
  v.default_visibility = visibility.attribute("DefaultVisibility").as_bool(true);
  v.exceptions = read_components(visibility.child("Exceptions"));
  for (pugi::xml_node colour : components.child("Coloring").children("Color"))
    v.colours.push_back({colour.attribute("Color").as_string(), read_components(colour)});
  // BCF 2.0 kept selected and hidden components in one list with attributes.
  for (pugi::xml_node c : components.children("Component")) {
    Component component{c.attribute("IfcGuid").as_string(), c.child("OriginatingSystem").text().as_string(),
                        c.child("AuthoringToolId").text().as_string()};
    if (c.attribute("Selected").as_bool(false)) v.selection.push_back(component);
    if (!c.attribute("Visible").as_bool(true)) v.exceptions.push_back(component);
  }
  out = std::move(v);
  return true;
}

}  // namespace plantview::bcf
