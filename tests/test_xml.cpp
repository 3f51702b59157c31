// The plantview XML format: lossless round trip, streaming, and errors that name file, line and
// field (docs/xml-format.md, plantview/xml.h).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <pugixml.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "plantview/model.h"
#include "plantview/xml.h"
#include "support/object_bits.h"

namespace plantview {
namespace {

using test::object_difference;

// ---------------------------------------------------------------------------------------------
// A model that exercises every field.

Placement odd_placement(int i) {
  Placement p;
  const float a = 0.37f * static_cast<float>(i + 1);
  const glm::mat3 rotation = {
      {std::cos(a), std::sin(a), 0}, {-std::sin(a), std::cos(a), 0}, {0, 0, 1}};
  const glm::mat3 scale = {{1.0f / 3.0f, 0, 0}, {0, 1e-3f, 0}, {0, 0, 7.25f}};
  p.linear = rotation * scale;
  if (i % 2 == 1) p.linear[1] = -p.linear[1];  // mirrored
  if (i % 5 == 2) p.linear[2] = glm::vec3(-0.0f, std::numeric_limits<float>::denorm_min(), 1e-38f);
  p.translation_m = {123456.789f * static_cast<float>(i), -0.0f, std::numbers::pi_v<float> / 7.0f};
  if (i == 3) p.translation_m.x = std::numeric_limits<float>::max();
  return p;
}

FacetGroup facet_group_with_holes() {
  FacetGroup g;
  auto contour = [&](std::vector<glm::vec3> points, glm::vec3 normal) {
    for (const glm::vec3& p : points) g.vertices.push_back({p, normal});
    g.contour_ends.push_back(static_cast<uint32_t>(g.vertices.size()));
  };
  // A square with two square holes.
  contour({{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}}, {0, 0, 1});
  contour({{1, 1, 0}, {1, 3, 0}, {3, 3, 0}, {3, 1, 0}}, {0, 0, 1});
  contour({{6, 6, 0}, {6, 8.1f, 0}, {8.3f, 8, 0}, {8, 6, 0}}, {-0.0f, 1e-30f, 1});
  g.polygon_ends.push_back(static_cast<uint32_t>(g.contour_ends.size()));
  // A triangle with its own odd normals.
  contour({{0, 0, 1}, {1, 0, 1}, {0, 1, 1.0f / 3.0f}}, {0.577350269f, 0.577350269f, 0.577350269f});
  g.polygon_ends.push_back(static_cast<uint32_t>(g.contour_ends.size()));
  // A polygon without contours, and one whose only contour has no vertices.
  g.polygon_ends.push_back(static_cast<uint32_t>(g.contour_ends.size()));
  contour({}, {0, 0, 1});
  g.polygon_ends.push_back(static_cast<uint32_t>(g.contour_ends.size()));
  g.triangulate();
  return g;
}

std::string all_bytes() {
  std::string s;
  for (int i = 0; i < 256; ++i) s += static_cast<char>(i);
  return s;
}

std::vector<Object> sample_model() {
  const std::string source = "gen:xml test % 100";
  std::vector<Object> objects;

  Object equipment;
  equipment.name = "/EQUIP-1 \"V-101\" & <tank>";
  equipment.id = object_id(source, equipment.name);
  equipment.object_class = ObjectClass::equipment;
  equipment.colour = {1, 2, 254, 128};
  equipment.origin_m = {123456.78901234567, -0.0, std::numeric_limits<double>::denorm_min()};
  equipment.source = source;
  std::vector<Primitive> every_kind = representative_primitives(0.2f);
  for (size_t i = 0; i < every_kind.size(); ++i) {
    Primitive p = every_kind[i];
    p.placement = odd_placement(static_cast<int>(i));
    if (auto* snout = std::get_if<Snout>(&p.shape)) {
      *snout = {0.1f, 0.05f, 0.3f, 0.01f, -0.02f, 0.1f, -0.2f, 0.3f, -0.4f};
    } else if (auto* prism = std::get_if<Prism>(&p.shape)) {
      prism->sides = 7;
    } else if (auto* group = std::get_if<FacetGroup>(&p.shape)) {
      *group = facet_group_with_holes();
    }
    equipment.primitives.push_back(p);
  }
  equipment.primitives.push_back({odd_placement(20), Cylinder{1e-45f, 3.4028235e38f}});
  equipment.primitives.push_back({odd_placement(21), Box{-1.5f, 0.0f, -0.0f}});
  equipment.primitives.push_back({odd_placement(22), Prism{0xFFFFFFFFu, 0.1f, 0.2f}});
  equipment.attributes = {
      {"DESC", "He said \"go\" & 'stop' <now>"},
      {"multi line", "line 1\nline 2\r\nline 3\rend\ttab  two  spaces "},
      {"latin-1",
       "Stra\xDF"
       "e \xE9t\xE9"},
      {"utf-8",
       "Stra\xC3\x9F"
       "e \xF0\x9F\x98\x80 \xE2\x82\xAC"},
      {"percent", "%41 %% 100%"},
      {"controls", std::string("a\0b\x01\x1F\x7F", 6)},
      {"not characters", "\xEF\xBF\xBE \xED\xA0\x80 \xC0\xAF \xE2\x82"},
      {"all bytes", all_bytes()},
      {"", ""},
      {"key \xFF with byte", "plain value"},
  };
  objects.push_back(equipment);

  Object pipeline;
  pipeline.name = "/PIPE-100";
  pipeline.id = object_id(source, pipeline.name);
  pipeline.object_class = ObjectClass::pipeline;
  pipeline.source = source;

  Object pipe;
  pipe.name = "/PIPE-100/B1/TUBE-1";
  pipe.id = object_id(source, pipe.name);
  pipe.object_class = ObjectClass::pipe;
  pipe.colour = {0, 128, 0, 255};
  pipe.origin_m = {1000.5, 2000.25, -3.125};
  pipe.source = source;
  pipe.pipeline_id = pipeline.id;
  pipe.primitives.push_back({odd_placement(30), Cylinder{0.1f, 5.0f}});
  pipe.connections = {{{0, 0, -2.5f}, {0, 0, -1}, 0.2f}, {{0, 0, 2.5f}, {0, 0, 1}, 0.2f}};
  pipe.centreline = {{{0, 0, -2.5f}, {0, 0, 2.5f}, 0.2f}};

  Object component;
  component.name = "/PIPE-100/B1/FLANGE-1";
  component.id = object_id(source, component.name);
  component.object_class = ObjectClass::component;
  component.origin_m = {1000.5, 2000.25, -0.625};
  component.source = source;
  component.pipeline_id = pipeline.id;
  component.primitives.push_back({odd_placement(31), Cylinder{0.15f, 0.05f}});
  component.connections = {{{0, 0, -0.025f}, {0, 0, -1}, 0.2f}, {{0, 0, 0.025f}, {0, 0, 1}, 0.2f}};
  component.attributes = {{"SPEC", "A1A"}};

  pipeline.branches = {{"/PIPE-100/B1", {pipe.id, component.id}},
                       {"", {}},
                       {"branch \xA7 2", {0, 0xFFFFFFFFFFFFFFFFull, pipe.id}}};
  objects.push_back(pipeline);
  objects.push_back(pipe);
  objects.push_back(component);

  Object bare;  // every field at its default, but an id
  bare.id = 1;
  objects.push_back(bare);

  Object odd_name;
  odd_name.id = 0xFFFFFFFFFFFFFFFFull;
  odd_name.name = std::string("\0name\xFF%\n", 8);
  odd_name.source = all_bytes();
  odd_name.object_class = ObjectClass::structure;
  objects.push_back(odd_name);
  return objects;
}

std::vector<Object> read_all(std::string_view text, XmlError& error, bool& ok) {
  std::vector<Object> objects;
  ok = read_xml(
      text, "test.xml", [&](Object&& o) { objects.push_back(std::move(o)); }, error);
  return objects;
}

void expect_same_objects(const std::vector<Object>& expected, const std::vector<Object>& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(object_difference(expected[i], actual[i]), "") << "object " << i;
  }
}

std::string write_or_fail(const std::vector<Object>& objects) {
  std::string text;
  XmlError error;
  EXPECT_TRUE(write_xml(objects, text, error)) << error.message;
  return text;
}

// The fuzzers' seed corpus: written when PLANTVIEW_FUZZ_SEED_DIR names a directory.
void maybe_write_fuzz_seed(const std::string& name, std::string_view text) {
  const char* dir = std::getenv("PLANTVIEW_FUZZ_SEED_DIR");
  if (dir == nullptr || *dir == '\0') return;
  std::ofstream(std::filesystem::path(dir) / name, std::ios::binary) << text;
}

std::filesystem::path temp_path(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("plantview_test_xml_" + std::to_string(::getpid()) + "_" + name);
}

// ---------------------------------------------------------------------------------------------
// Round trip.

TEST(XmlRoundTrip, EveryKindFieldAndStringComesBackBitExact) {
  const std::vector<Object> model = sample_model();
  const std::string text = write_or_fail(model);
  maybe_write_fuzz_seed("xml_every_field.xml", text);
  XmlError error;
  bool ok = false;
  const std::vector<Object> back = read_all(text, error, ok);
  ASSERT_TRUE(ok) << error.message;
  expect_same_objects(model, back);

  // Every kind is there, and writing what was read gives the same text.
  std::vector<bool> kinds(kPrimitiveKindCount);
  for (const Primitive& p : back[0].primitives) kinds[static_cast<size_t>(p.kind())] = true;
  EXPECT_EQ(std::count(kinds.begin(), kinds.end(), true), kPrimitiveKindCount);
  EXPECT_EQ(write_or_fail(back), text);
}

TEST(XmlRoundTrip, FileWriterAndFileReaderAgreeWithTheStringForms) {
  const std::vector<Object> model = sample_model();
  const std::filesystem::path path = temp_path("round_trip.xml");
  XmlWriter writer;
  XmlError error;
  ASSERT_TRUE(writer.open(path, error)) << error.message;
  for (const Object& o : model) EXPECT_TRUE(writer.write_object(o));
  ASSERT_TRUE(writer.close(error)) << error.message;

  std::ifstream file(path, std::ios::binary);
  std::stringstream content;
  content << file.rdbuf();
  EXPECT_EQ(content.str(), write_or_fail(model));

  std::vector<Object> back;
  ASSERT_TRUE(read_xml_file(
      path, [&](Object&& o) { back.push_back(std::move(o)); }, error))
      << error.message;
  expect_same_objects(model, back);
  std::filesystem::remove(path);
}

TEST(XmlRoundTrip, OutputIsUtf8XmlThatAnotherParserReadsTheSame) {
  const std::vector<Object> model = sample_model();
  const std::string text = write_or_fail(model);

  // Only XML characters, as well-formed UTF-8.
  for (size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      ASSERT_TRUE(c >= 0x20 || c == '\n') << "byte " << int(c) << " at " << i;
      ++i;
      continue;
    }
    const int length = c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : 2;
    ASSERT_GE(c, 0xC2) << "at " << i;
    for (int k = 1; k < length; ++k)
      ASSERT_EQ(static_cast<unsigned char>(text[i + k]) & 0xC0, 0x80);
    i += static_cast<size_t>(length);
  }

  // pugixml with its standard decoding: text-encoded strings read as the original bytes.
  pugi::xml_document document;
  ASSERT_TRUE(document.load_buffer(text.data(), text.size()));
  const pugi::xml_node equipment = document.child("plantview").child("object");
  EXPECT_EQ(std::string(equipment.attribute("name").value()), model[0].name);
  EXPECT_FALSE(equipment.attribute("encoding"));
  int text_attributes = 0, byte_attributes = 0;
  size_t i = 0;
  for (pugi::xml_node a : equipment.children("attribute")) {
    const Attribute& original = model[0].attributes[i++];
    if (a.attribute("encoding")) {
      EXPECT_STREQ(a.attribute("encoding").value(), "bytes");
      ++byte_attributes;
    } else {
      EXPECT_EQ(std::string(a.attribute("key").value()), original.key);
      EXPECT_EQ(std::string(a.attribute("value").value()), original.value);
      ++text_attributes;
    }
  }
  EXPECT_EQ(text_attributes, 5);  // quotes, line breaks, UTF-8, percent, empty key and value
  EXPECT_EQ(byte_attributes, 5);  // Latin-1, controls, non-characters, all bytes, byte in key
}

TEST(XmlRoundTrip, EmptyModelIsAValidDocument) {
  const std::string text = write_or_fail({});
  XmlError error;
  bool ok = false;
  EXPECT_TRUE(read_all(text, error, ok).empty());
  EXPECT_TRUE(ok) << error.message;
}

// ---------------------------------------------------------------------------------------------
// Streaming.

TEST(XmlReader, PiecesOfAnySizeGiveTheSameObjects) {
  const std::vector<Object> model = sample_model();
  const std::string text = write_or_fail(model);
  std::mt19937 rng(7);
  for (size_t max_piece : {size_t(1), size_t(2), size_t(7), size_t(64), size_t(4096)}) {
    std::vector<Object> back;
    XmlReader reader("pieces.xml", [&](Object&& o) { back.push_back(std::move(o)); });
    XmlError error;
    bool ok = true;
    for (size_t at = 0; ok && at < text.size();) {
      const size_t n = std::min(text.size() - at, 1 + rng() % max_piece);
      ok = reader.feed(std::string_view(text).substr(at, n), error);
      at += n;
    }
    ASSERT_TRUE(ok && reader.finish(error)) << max_piece << ": " << error.message;
    expect_same_objects(model, back);
  }
}

TEST(XmlReader, ObjectsArriveBeforeTheDocumentEnds) {
  const std::vector<Object> model = sample_model();
  const std::string text = write_or_fail(model);
  size_t received = 0;
  XmlReader reader("early.xml", [&](Object&&) { ++received; });
  XmlError error;
  const size_t second_object = text.find("<object", text.find("<object") + 1);
  ASSERT_TRUE(reader.feed(std::string_view(text).substr(0, second_object), error)) << error.message;
  EXPECT_EQ(received, 1u);
}

// ---------------------------------------------------------------------------------------------
// Truncation.

// A small document; the cases below name its lines (line 1 is the declaration, 5 the cylinder,
// 8 the contour, 11 the attribute, 13 the second object, 18 the root's end tag).
const char* const kSmallDocument = R"xml(<?xml version="1.0" encoding="UTF-8"?>
<!-- a comment -->
<plantview format_version="1">
  <object id="00000000000000a1" name="/V-1" class="equipment" colour="#a0a0a0ff" origin_m="1 2 3" source="s">
    <primitive kind="cylinder" radius_m="0.5" height_m="2" linear="1 0 0 0 1 0 0 0 1" translation_m="0 0 0"/>
    <primitive kind="facet_group" linear="1 0 0 0 1 0 0 0 1" translation_m="0 0 1">
      <polygon>
        <contour positions_m="0 0 0 1 0 0 0 1 0" normals="0 0 1 0 0 1 0 0 1"/>
      </polygon>
    </primitive>
    <attribute key="DESC" value="a &amp; b"/>
  </object>
  <object id="00000000000000b2" name="/P-1" class="pipeline" colour="#000000ff" origin_m="0 0 0" source="s">
    <branch name="B1">
      <member id="00000000000000a1"/>
    </branch>
  </object>
</plantview>
)xml";

TEST(XmlReader, SmallDocumentReads) {
  maybe_write_fuzz_seed("xml_small.xml", kSmallDocument);
  XmlError error;
  bool ok = false;
  const std::vector<Object> objects = read_all(kSmallDocument, error, ok);
  ASSERT_TRUE(ok) << error.message;
  ASSERT_EQ(objects.size(), 2u);
  EXPECT_EQ(objects[0].primitives.size(), 2u);
  EXPECT_EQ(objects[0].attributes[0].value, "a & b");
  EXPECT_EQ(objects[1].branches[0].members, std::vector<uint64_t>{0xa1});
}

TEST(XmlReader, EveryTruncationFailsWithALineUnlessOnlyTrailingSpaceIsCut) {
  const std::string text = kSmallDocument;
  const size_t root_end = text.rfind("</plantview>") + std::string("</plantview>").size();
  for (size_t n = 0; n < text.size(); ++n) {
    const std::string_view prefix = std::string_view(text).substr(0, n);
    XmlError error;
    bool ok = false;
    const std::vector<Object> objects = read_all(prefix, error, ok);
    if (n >= root_end) {
      EXPECT_TRUE(ok) << n << ": " << error.message;
      continue;
    }
    ASSERT_FALSE(ok) << "a prefix of " << n << " bytes was accepted";
    const uint64_t lines =
        1 + static_cast<uint64_t>(std::count(prefix.begin(), prefix.end(), '\n'));
    EXPECT_GE(error.line, 1u) << n;
    EXPECT_LE(error.line, lines) << n << ": " << error.message;
    EXPECT_EQ(error.message.rfind("test.xml:" + std::to_string(error.line) + ": ", 0), 0u)
        << error.message;
    // Only whole objects reach the sink.
    EXPECT_LE(objects.size(), 2u);
    if (n < text.find("</object>") + 9) {
      EXPECT_TRUE(objects.empty()) << n;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Wrong fields.

struct BadCase {
  const char* label;
  const char* from;  // replaced in kSmallDocument (first occurrence)
  const char* to;
  const char* expected;  // the whole message must contain this
};

std::string replaced(const char* from, const char* to) {
  std::string text = kSmallDocument;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, std::strlen(from), to);
  return text;
}

TEST(XmlReader, WrongFieldsNameTheLineElementAndField) {
  const BadCase cases[] = {
      {"non-numeric radius", "radius_m=\"0.5\"", "radius_m=\"abc\"",
       "test.xml:5: <primitive kind=\"cylinder\">: radius_m: not a number: \"abc\""},
      {"nan radius", "radius_m=\"0.5\"", "radius_m=\"nan\"",
       "test.xml:5: <primitive kind=\"cylinder\">: radius_m: not finite: \"nan\""},
      {"infinite height", "height_m=\"2\"", "height_m=\"-inf\"",
       "test.xml:5: <primitive kind=\"cylinder\">: height_m: not finite"},
      {"out of range", "height_m=\"2\"", "height_m=\"1e39\"",
       "test.xml:5: <primitive kind=\"cylinder\">: height_m: out of range: \"1e39\""},
      {"trailing garbage", "height_m=\"2\"", "height_m=\"2m\"", "height_m: not a number: \"2m\""},
      {"empty number", "height_m=\"2\"", "height_m=\"\"", "height_m: expected 1 number, found 0"},
      {"two numbers in a scalar", "height_m=\"2\"", "height_m=\"2 3\"",
       "height_m: expected 1 number, found 2"},
      {"unknown kind", "kind=\"cylinder\"", "kind=\"cone\"",
       "test.xml:5: <primitive>: kind: unknown kind \"cone\""},
      {"8 numbers in linear", "linear=\"1 0 0 0 1 0 0 0 1\" translation_m=\"0 0 0\"",
       "linear=\"1 0 0 0 1 0 0 0\" translation_m=\"0 0 0\"",
       "test.xml:5: <primitive kind=\"cylinder\">: linear: expected 9 numbers, found 8"},
      {"10 numbers in linear", "linear=\"1 0 0 0 1 0 0 0 1\" translation_m=\"0 0 0\"",
       "linear=\"1 0 0 0 1 0 0 0 1 0\" translation_m=\"0 0 0\"",
       "linear: expected 9 numbers, found 10"},
      {"missing field", "radius_m=\"0.5\" ", "",
       "test.xml:5: <primitive kind=\"cylinder\">: radius_m: missing attribute"},
      {"field of another kind", "radius_m=\"0.5\"", "radius_m=\"0.5\" size_x_m=\"1\"",
       "test.xml:5: <primitive kind=\"cylinder\">: unknown attribute \"size_x_m\""},
      {"field given twice", "radius_m=\"0.5\"", "radius_m=\"0.5\" radius_m=\"0.5\"",
       "test.xml:5: <primitive kind=\"cylinder\">: radius_m: attribute given twice"},
      {"unknown class", "class=\"equipment\"", "class=\"vessel\"",
       "test.xml:4: <object>: class: unknown class \"vessel\""},
      {"bad hex id", "id=\"00000000000000a1\" name", "id=\"0x1\" name",
       "test.xml:4: <object>: id: not an id of 1 to 16 hexadecimal digits: \"0x1\""},
      {"17-digit id", "id=\"00000000000000a1\" name", "id=\"100000000000000a1\" name",
       "<object>: id: not an id"},
      {"id 0", "id=\"00000000000000a1\" name", "id=\"0\" name",
       "test.xml:4: <object>: id: id 0 is reserved"},
      {"duplicate id", "id=\"00000000000000b2\"", "id=\"00000000000000A1\"",
       "test.xml:13: <object>: id: duplicate object id 00000000000000a1 (first on line 4)"},
      {"bad member id", "<member id=\"00000000000000a1\"", "<member id=\"g\"",
       "test.xml:15: <member>: id: not an id"},
      {"bad colour", "#a0a0a0ff", "#a0a0a0",
       "test.xml:4: <object>: colour: not #rrggbbaa: \"#a0a0a0\""},
      {"origin with two numbers", "origin_m=\"1 2 3\"", "origin_m=\"1 2\"",
       "test.xml:4: <object>: origin_m: expected 3 numbers, found 2"},
      {"unknown element", "<attribute key", "<attrib key",
       "test.xml:11: <object>: unknown element <attrib>"},
      {"unknown root child", "<object id=\"00000000000000b2\"", "<thing id=\"00000000000000b2\"",
       "test.xml:13: unknown element <thing> in <plantview>"},
      {"text in an object", "    <attribute key", "    text<attribute key",
       "test.xml:10: <object>: unexpected text \""},
      {"child of a cylinder", "translation_m=\"0 0 0\"/>",
       "translation_m=\"0 0 0\"><polygon/></primitive>",
       "test.xml:5: <primitive kind=\"cylinder\">: unexpected element <polygon>"},
      {"contour of 8 numbers", "positions_m=\"0 0 0 1 0 0 0 1 0\"",
       "positions_m=\"0 0 0 1 0 0 0 1\"",
       "test.xml:8: <contour>: positions_m: 8 numbers, not a multiple of 3"},
      {"normals too few", "normals=\"0 0 1 0 0 1 0 0 1\"", "normals=\"0 0 1\"",
       "test.xml:8: <contour>: normals: 3 numbers for 3 positions"},
      {"contour outside polygon", "      <polygon>\n",
       "      <contour positions_m=\"\" normals=\"\"/><polygon>\n",
       "test.xml:7: <primitive kind=\"facet_group\">: unknown element <contour> (expected "
       "<polygon>)"},
      {"bad entity", "a &amp; b", "a &nbsp; b",
       "test.xml:11: <attribute>: value: unknown entity or bad character reference"},
      {"bad character reference", "a &amp; b", "a &#1; b",
       "<attribute>: value: unknown entity or bad character reference \"&#1; b\""},
      {"raw non-UTF-8", "a &amp; b", "a \xE9 b",
       "test.xml:11: <attribute>: value: byte 0xE9 is not UTF-8 text"},
      {"bad percent escape", "value=\"a &amp; b\"", "value=\"a %4 b\" encoding=\"bytes\"",
       "test.xml:11: <attribute>: value: '%' not followed by two hexadecimal digits"},
      {"unknown encoding", "value=\"a &amp; b\"", "value=\"a\" encoding=\"latin1\"",
       "test.xml:11: <attribute>: encoding: unknown encoding \"latin1\""},
      {"'<' in a value", "a &amp; b", "a < b",
       "test.xml:11: <attribute>: value: '<' is not allowed"},
      {"format version", "format_version=\"1\"", "format_version=\"2\"",
       "test.xml:3: <plantview>: format_version: version \"2\" is not supported"},
      {"no format version", " format_version=\"1\"", "",
       "test.xml:3: <plantview>: format_version: missing attribute"},
      {"wrong root", "<plantview format_version=\"1\">", "<plant format_version=\"1\">",
       "test.xml:3: root element is <plant>, expected <plantview>"},
      {"mismatched end tag", "    </branch>", "    </member>", "test.xml:16: malformed XML"},
      {"wrong root end tag", "</plantview>", "</plant>",
       "test.xml:18: end tag </plant> does not match <plantview> (line 3)"},
      {"content after the root", "</plantview>\n", "</plantview>\n<object/>\n",
       "test.xml:19: element <object> after the end of the root element"},
      {"text after the root", "</plantview>\n", "</plantview>\nx\n",
       "test.xml:19: unexpected text (starting \"x\") outside the root element"},
      {"text between objects", "  </object>\n  <object", "  </object>\n x <object",
       "test.xml:13: unexpected text (starting \"x\") between objects"},
      {"doctype", "<!-- a comment -->", "<!DOCTYPE plantview>", "test.xml:2: markup declarations"},
      {"declaration not first", "<!-- a comment -->", "<?xml version=\"1.0\"?>",
       "test.xml:2: XML declaration not at the start"},
      {"latin-1 declaration", "encoding=\"UTF-8\"", "encoding=\"ISO-8859-1\"",
       "test.xml:1: encoding \"ISO-8859-1\" is not supported"},
      {"NUL byte", "a &amp; b", "a ", "test.xml:11: NUL byte"},
      {"sides not a whole number", "kind=\"cylinder\" radius_m=\"0.5\" height_m=\"2\"",
       "kind=\"prism\" sides=\"-6\" radius_m=\"0.5\" height_m=\"2\"",
       "test.xml:5: <primitive kind=\"prism\">: sides: not a whole number"},
  };
  for (const BadCase& c : cases) {
    std::string text = replaced(c.from, c.to);
    if (std::string_view(c.label) == "NUL byte") {  // c_str() above stops at the NUL
      text = replaced("a &amp; b", "a ");
      text.insert(text.find("value=\"a ") + 9, std::string("\0 b", 3));
    }
    XmlError error;
    bool ok = true;
    read_all(text, error, ok);
    EXPECT_FALSE(ok) << c.label;
    EXPECT_NE(error.message.find(c.expected), std::string::npos)
        << c.label << "\n  expected: " << c.expected << "\n  got:      " << error.message;
    EXPECT_EQ(error.message.rfind("test.xml:" + std::to_string(error.line) + ": ", 0), 0u)
        << c.label << ": " << error.message;
  }
}

TEST(XmlReader, RefusesUtf16AndEmptyInput) {
  XmlError error;
  bool ok = true;
  read_all("\xFF\xFE<\0p\0", error, ok);
  EXPECT_FALSE(ok);
  EXPECT_NE(error.message.find("UTF-16 is not supported"), std::string::npos) << error.message;
  read_all("", error, ok);
  EXPECT_FALSE(ok);
  EXPECT_EQ(error.message, "test.xml:1: no <plantview> element");
  read_all("<!-- only -->\n", error, ok);
  EXPECT_FALSE(ok);
  EXPECT_EQ(error.message, "test.xml:2: no <plantview> element");
}

TEST(XmlReader, AcceptsWhatXmlAllows) {
  // A byte-order mark, CR LF line ends, single quotes, comments and processing instructions
  // anywhere, attributes over several lines, references in numbers, an empty element written
  // with an end tag, and a literal line break inside a value (read as a space, as XML requires).
  const std::string text =
      "\xEF\xBB\xBF<?xml version='1.0'?>\r\n"
      "<?app data?><plantview format_version='1'><!-- c -->\r\n"
      "<object\r\n id='a1'\tname='x\r\ny' class='other' colour='#00000000' origin_m=' 1  &#50;\t3 "
      "'\r\n"
      " source=''><?pi inside?><!-- c -->\r\n"
      "<primitive kind='sphere' radius_m='&#x31;' linear='1 0 0 0 1 0 0 0 1' translation_m='0 0 0'>"
      "</primitive>\r\n"
      "<attribute key='k' value='&lt;&gt;&apos;&quot;&#9;'/>\r\n"
      "</object></plantview><!-- end -->\r\n<?done?>\r\n";
  maybe_write_fuzz_seed("xml_syntax_variants.xml", text);
  XmlError error;
  bool ok = false;
  const std::vector<Object> objects = read_all(text, error, ok);
  ASSERT_TRUE(ok) << error.message;
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0].id, 0xa1u);
  EXPECT_EQ(objects[0].name, "x y");
  EXPECT_EQ(objects[0].origin_m, glm::dvec3(1, 2, 3));
  EXPECT_EQ(std::get<Sphere>(objects[0].primitives[0].shape).radius_m, 1.0f);
  EXPECT_EQ(objects[0].attributes[0].value, "<>'\"\t");
  EXPECT_EQ(objects[0].colour, (Colour{0, 0, 0, 0}));
}

TEST(XmlReader, OptionalAttributesTakeTheirDefaults) {
  const std::string text =
      "<plantview format_version=\"1\"><object id=\"5\" name=\"\" class=\"pipe\" "
      "colour=\"#01020304\" "
      "origin_m=\"0 0 0\"/></plantview>";
  XmlError error;
  bool ok = false;
  const std::vector<Object> objects = read_all(text, error, ok);
  ASSERT_TRUE(ok) << error.message;
  EXPECT_EQ(objects[0].pipeline_id, 0u);
  EXPECT_EQ(objects[0].source, "");
}

TEST(XmlReader, MissingFileIsAnErrorNamingThePath) {
  XmlError error;
  EXPECT_FALSE(read_xml_file(
      "/nonexistent-dir/plant.xml", [](Object&&) {}, error));
  EXPECT_EQ(error.message.rfind("/nonexistent-dir/plant.xml: cannot open", 0), 0u) << error.message;
  EXPECT_EQ(error.line, 0u);
}

TEST(XmlReader, TheSchemaDocumentsExampleReads) {
  // docs/xml-format.md: the first ```xml block is a whole document.
  const std::filesystem::path doc =
      std::filesystem::path(__FILE__).parent_path().parent_path() / "docs" / "xml-format.md";
  std::ifstream file(doc);
  if (!file) GTEST_SKIP() << doc << " not found";
  std::stringstream content;
  content << file.rdbuf();
  const std::string md = content.str();
  const size_t begin = md.find("```xml\n");
  ASSERT_NE(begin, std::string::npos);
  const size_t end = md.find("```", begin + 7);
  XmlError error;
  bool ok = false;
  const std::vector<Object> objects = read_all(md.substr(begin + 7, end - begin - 7), error, ok);
  EXPECT_TRUE(ok) << error.message;
  EXPECT_GE(objects.size(), 3u);
}

// ---------------------------------------------------------------------------------------------
// Writer refusals.

TEST(XmlWriter, RefusesWhatTheReaderWouldRejectAndNamesTheField) {
  std::vector<Object> model = sample_model();
  std::string text;
  XmlError error;

  Object nan_radius = model[2];
  std::get<Cylinder>(nan_radius.primitives[0].shape).radius_m = std::nanf("");
  text = "unchanged";
  EXPECT_FALSE(append_xml_object(text, nan_radius, error));
  EXPECT_EQ(text, "unchanged");
  EXPECT_NE(error.message.find("primitive 0 (cylinder): radius_m is not finite"), std::string::npos)
      << error.message;

  Object infinite_origin = model[3];
  infinite_origin.origin_m.y = INFINITY;
  EXPECT_FALSE(append_xml_object(text, infinite_origin, error));
  EXPECT_NE(error.message.find(": origin_m is not finite"), std::string::npos) << error.message;

  Object bad_connection = model[2];
  bad_connection.connections[1].direction.z = -INFINITY;
  EXPECT_FALSE(append_xml_object(text, bad_connection, error));
  EXPECT_NE(error.message.find("connection 1: direction is not finite"), std::string::npos)
      << error.message;

  Object zero_id = model[4];
  zero_id.id = 0;
  EXPECT_FALSE(append_xml_object(text, zero_id, error));
  EXPECT_NE(error.message.find("id is 0"), std::string::npos) << error.message;

  Object bad_class = model[4];
  bad_class.object_class = static_cast<ObjectClass>(kObjectClassCount);
  EXPECT_FALSE(append_xml_object(text, bad_class, error));
  EXPECT_NE(error.message.find("class 6 is not an ObjectClass"), std::string::npos)
      << error.message;

  Object loose_vertices = model[0];
  std::get<FacetGroup>(loose_vertices.primitives[13].shape).vertices.push_back({});
  EXPECT_FALSE(append_xml_object(text, loose_vertices, error));
  EXPECT_NE(error.message.find("primitive 13 (facet_group): vertices after the last contour end"),
            std::string::npos)
      << error.message;

  Object bad_ends = model[0];
  std::get<FacetGroup>(bad_ends.primitives[13].shape).polygon_ends[0] = 99;
  EXPECT_FALSE(append_xml_object(text, bad_ends, error));
  EXPECT_NE(error.message.find("polygon_ends"), std::string::npos) << error.message;
}

TEST(XmlWriter, AFailedFileIsLeftWithoutItsClosingTag) {
  std::vector<Object> model = sample_model();
  std::get<Cylinder>(model[2].primitives[0].shape).height_m = NAN;
  const std::filesystem::path path = temp_path("refused.xml");
  XmlWriter writer;
  XmlError error;
  ASSERT_TRUE(writer.open(path, error)) << error.message;
  EXPECT_TRUE(writer.write_object(model[0]));
  EXPECT_TRUE(writer.write_object(model[1]));
  EXPECT_FALSE(writer.write_object(model[2]));
  EXPECT_FALSE(writer.write_object(model[3]));  // failed stays failed
  EXPECT_FALSE(writer.close(error));
  EXPECT_EQ(error.message.rfind(path.string() + ": object ", 0), 0u) << error.message;
  EXPECT_NE(error.message.find("height_m is not finite"), std::string::npos) << error.message;
  EXPECT_FALSE(read_xml_file(
      path, [](Object&&) {}, error));
  EXPECT_NE(error.message.find("is not closed"), std::string::npos) << error.message;
  std::filesystem::remove(path);
}

TEST(XmlWriter, OpenFailureNamesThePath) {
  XmlWriter writer;
  XmlError error;
  EXPECT_FALSE(writer.open("/nonexistent-dir/out.xml", error));
  EXPECT_EQ(error.message.rfind("/nonexistent-dir/out.xml: cannot create", 0), 0u) << error.message;
  EXPECT_FALSE(writer.is_open());
}

// ---------------------------------------------------------------------------------------------
// Speed: a preset-sized model (70,000 primitives) is written and read well under a second.

TEST(XmlPerformance, SeventyThousandPrimitivesWriteAndReadQuickly) {
  std::vector<Object> model;
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  const std::vector<Primitive> kinds = representative_primitives(0.3f);
  size_t primitives = 0;
  for (int i = 0; primitives < 70000; ++i) {
    Object o;
    o.name = "/SITE/ZONE-" + std::to_string(i / 100) + "/OBJ-" + std::to_string(i);
    o.id = object_id("gen:bench", o.name);
    o.object_class = ObjectClass(i % kObjectClassCount);
    o.origin_m = {1000.0 * unit(rng), 1000.0 * unit(rng), 50.0 * unit(rng)};
    o.source = "gen:bench";
    o.attributes = {{"TYPE", "EQUI"}, {"DESC", "object " + std::to_string(i)}};
    for (int k = 0; k < 7; ++k, ++primitives) {
      Primitive p =
          kinds[static_cast<size_t>(rng() % (kPrimitiveKindCount - 1))];  // no facet groups
      const glm::vec3 axis = glm::normalize(glm::vec3(unit(rng), unit(rng), unit(rng)) + 1e-3f);
      const glm::vec3 side = glm::normalize(glm::cross(axis, glm::vec3(0.3f, 0.5f, 0.7f)));
      p.placement.linear = glm::mat3(side, glm::cross(axis, side), axis);
      p.placement.translation_m = {10 * unit(rng), 10 * unit(rng), 10 * unit(rng)};
      o.primitives.push_back(p);
    }
    model.push_back(std::move(o));
  }

  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  std::string text;
  XmlError error;
  ASSERT_TRUE(write_xml(model, text, error)) << error.message;
  const auto t1 = clock::now();
  std::vector<Object> back;
  back.reserve(model.size());
  bool ok = false;
  ok = read_xml(
      text, "bench.xml", [&](Object&& o) { back.push_back(std::move(o)); }, error);
  const auto t2 = clock::now();
  ASSERT_TRUE(ok) << error.message;
  expect_same_objects(model, back);

  const double write_s = std::chrono::duration<double>(t1 - t0).count();
  const double read_s = std::chrono::duration<double>(t2 - t1).count();
  std::printf("[ figures  ] %zu objects, %zu primitives, %.1f MB: write %.3f s, read %.3f s\n",
              model.size(), primitives, static_cast<double>(text.size()) / 1e6, write_s, read_s);
  // Generous bounds: sanitizer builds are several times slower than release ones.
  EXPECT_LT(write_s, 10.0);
  EXPECT_LT(read_s, 10.0);
}

}  // namespace
}  // namespace plantview
