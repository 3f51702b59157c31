// markup.bcf (BCF 2.1 markup.xsd): one topic with its viewpoints and documents. Elements are
// written in the schema's sequence order; reading is lenient about what plantview does not use.
#include <pugixml.hpp>
#include <sstream>

#include "bcf_internal.h"

namespace plantview::bcf {

namespace {

void text_child(pugi::xml_node parent, const char* name, const std::string& value) {
  parent.append_child(name).text().set(value.c_str());
}

std::string child_text(pugi::xml_node node, const char* name) { return node.child(name).text().as_string(); }

}  // namespace

std::string write_markup(const Markup& m) {
  pugi::xml_document doc;
  pugi::xml_node decl = doc.append_child(pugi::node_declaration);
  decl.append_attribute("version") = "1.0";
  decl.append_attribute("encoding") = "UTF-8";
  pugi::xml_node root = doc.append_child("Markup");
  pugi::xml_node topic = root.append_child("Topic");
  topic.append_attribute("Guid") = m.guid.c_str();
  if (!m.topic_type.empty()) topic.append_attribute("TopicType") = m.topic_type.c_str();
  // Sequence: Title, CreationDate, CreationAuthor, Description, DocumentReference.
  text_child(topic, "Title", m.title);
  text_child(topic, "CreationDate", m.date);
  text_child(topic, "CreationAuthor", m.author);
  if (!m.description.empty()) text_child(topic, "Description", m.description);
  for (const DocumentRef& d : m.documents) {
    pugi::xml_node ref = topic.append_child("DocumentReference");
    ref.append_attribute("isExternal") = "false";
    text_child(ref, "ReferencedDocument", d.file);
    if (!d.description.empty()) text_child(ref, "Description", d.description);
  }
  for (const ViewpointRef& v : m.viewpoints) {
    pugi::xml_node vp = root.append_child("Viewpoints");
    vp.append_attribute("Guid") = v.guid.c_str();
    if (!v.viewpoint.empty()) text_child(vp, "Viewpoint", v.viewpoint);
    if (!v.snapshot.empty()) text_child(vp, "Snapshot", v.snapshot);
  }
  std::ostringstream out;
  doc.save(out, "  ", pugi::format_indent, pugi::encoding_utf8);
  return out.str();
}

bool parse_markup(const std::string& xml, Markup& out, std::string& error) {
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_buffer(xml.data(), xml.size());
  if (!parsed) {
    error = std::string("not XML: ") + parsed.description() + " at byte " + std::to_string(parsed.offset);
    return false;
  }
  const pugi::xml_node root = doc.child("Markup");
  const pugi::xml_node topic = root.child("Topic");
  if (!root || !topic) {
    error = "no Markup/Topic element";
    return false;
  }
  Markup m;
  m.guid = topic.attribute("Guid").as_string();
  m.topic_type = topic.attribute("TopicType").as_string();
  m.title = child_text(topic, "Title");
  m.date = child_text(topic, "CreationDate");
  m.author = child_text(topic, "CreationAuthor");
  m.description = child_text(topic, "Description");
  for (pugi::xml_node d : topic.children("DocumentReference")) {
    if (d.attribute("isExternal").as_bool(false)) continue;
    m.documents.push_back({child_text(d, "ReferencedDocument"), child_text(d, "Description")});
  }
  for (pugi::xml_node v : root.children("Viewpoints"))
    m.viewpoints.push_back(
        {v.attribute("Guid").as_string(), child_text(v, "Viewpoint"), child_text(v, "Snapshot")});
  out = std::move(m);
  return true;
}

}  // namespace plantview::bcf
