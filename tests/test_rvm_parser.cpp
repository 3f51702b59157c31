// RVM parser (plantview/rvm.h): the Huldra sample, an exact round trip of every chunk and
// primitive kind, every truncation and byte corruption of it, the known exporter variants,
// degenerate primitives and hostile counts.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>

#include "plantview/rvm.h"
#include "support/rvm_writer.h"

namespace plantview::testing {
namespace {

constexpr const char* kSource = "test.rvm";

ParseResult<RvmFile> parse(const RvmWriter& w, RvmParseOptions options = {}) {
  return parse_rvm(w.bytes(), kSource, options);
}

RvmParseOptions warn_mode() {
  RvmParseOptions options;
  options.next_chunk_offsets = RvmNextChunkOffsets::warn;
  return options;
}

bool contains(const std::string& text, std::string_view part) {
  return text.find(part) != std::string::npos;
}

// The basis every test primitive uses: 90 degrees about z.
const glm::mat3 kBasis(glm::vec3(0, 1, 0), glm::vec3(-1, 0, 0), glm::vec3(0, 0, 1));
const glm::vec3 kTranslation(1.5f, -2.25f, 3.0f);
const RvmMatrix kMatrix = rvm_matrix(kBasis, kTranslation);
const std::array<float, 6> kBounds{-50, -100, -150, 50, 100, 150};

void begin_file(RvmWriter& w) {
  w.head(2, "plantview test writer", "", "2024-05-01", "abcd", "UTF-8");
  w.model(1, "PROJ", "/MODEL");
}

// Parameters (file units: mm and radians) of kinds 1..10, in file order.
const std::vector<std::vector<float>> kParameters = {
    {},
    {100, 200, 50, 60, 10, -20, 300},               // 1 pyramid
    {100, 200, 300},                                // 2 box
    {50, 150, 80, 1.5f},                            // 3 rectangular torus
    {300, 50, 3.0f},                                // 4 circular torus
    {500, 250},                                     // 5 elliptical dish
    {400, 100},                                     // 6 spherical dish
    {100, 50, 200, 10, 20, 0.1f, 0.2f, -0.1f, -0.2f},  // 7 snout
    {75, 1000},                                     // 8 cylinder
    {600},                                          // 9 sphere (diameter)
    {-500, 500},                                    // 10 line
};

const std::vector<RvmPolygon> kPolygons = {
    {{{{0, 0, 0}, {0, 0, 1}}, {{1000, 0, 0}, {0, 0, 1}}, {{1000, 1000, 0}, {0, 0, 1}},
      {{0, 1000, 0}, {0, 0, 1}}},
     {{{200, 200, 0}, {0, 0, 1}}, {{400, 200, 0}, {0, 0, 1}}, {{300, 400, 0}, {0, 0, 1}}}},
    {{{{0, 0, 100}, {0, 1, 0}}, {{100, 0, 100}, {0, 1, 0}}, {{0, 100, 100}, {0, 1, 0}}}},
};

// A small file with every chunk and every primitive kind; offsets of interest recorded.
struct EveryChunkFile {
  RvmWriter writer;
  size_t site_offset = 0, zone_offset = 0, empty_offset = 0;
  std::vector<size_t> primitive_offsets;  // kinds 1..11 in the zone
  size_t obstruction_offset = 0, insulation_offset = 0, root_sphere_offset = 0;
  size_t colour_offsets[2] = {};
};

EveryChunkFile every_chunk_file() {
  EveryChunkFile f;
  RvmWriter& w = f.writer;
  begin_file(w);
  f.colour_offsets[0] = w.size();
  w.colour(1, 13, 10, 20, 30);
  f.site_offset = w.size();
  w.begin_group(2, "/SITE", {1000, 2000, 3000}, 3);
  f.zone_offset = w.size();
  w.begin_group(3, "/SITE/ZONE", {0, 0, 0}, 5, 40);
  for (uint32_t kind = 1; kind <= 10; ++kind) {
    f.primitive_offsets.push_back(w.size());
    w.primitive("PRIM", kind, kMatrix, kBounds, kParameters[kind]);
  }
  f.primitive_offsets.push_back(w.size());
  w.facet_group("PRIM", kMatrix, kBounds, kPolygons);
  f.obstruction_offset = w.size();
  w.primitive("OBST", 2, kMatrix, kBounds, kParameters[2], 70);
  f.insulation_offset = w.size();
  w.primitive("INSU", 8, kMatrix, kBounds, kParameters[8], 25);
  w.end_group();
  f.empty_offset = w.size();
  w.begin_group(2, "/SITE/EMPTY", {-1, -2, -3}, 0);
  w.end_group();
  w.end_group();
  f.root_sphere_offset = w.size();
  w.primitive("PRIM", 9, kMatrix, kBounds, kParameters[9]);
  f.colour_offsets[1] = w.size();
  w.colour(1, 14, 200, 100, 50);
  w.end();
  return f;
}

void expect_placement(const RvmPrimitive& p) {
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      EXPECT_NEAR(p.primitive.placement.linear[c][r], kBasis[c][r], 1e-6f) << c << "," << r;
    }
  }
  EXPECT_EQ(p.primitive.placement.translation_m, kTranslation);
  EXPECT_FLOAT_EQ(p.local_bounds_m.min.x, -0.05f);
  EXPECT_FLOAT_EQ(p.local_bounds_m.min.y, -0.1f);
  EXPECT_FLOAT_EQ(p.local_bounds_m.min.z, -0.15f);
  EXPECT_FLOAT_EQ(p.local_bounds_m.max.x, 0.05f);
  EXPECT_FLOAT_EQ(p.local_bounds_m.max.y, 0.1f);
  EXPECT_FLOAT_EQ(p.local_bounds_m.max.z, 0.15f);
}

// Compares a parsed primitive of kind 1..10 with kParameters (mm -> m, radians kept).
void expect_shape(const Shape& shape, uint32_t rvm_kind) {
  const std::vector<float>& p = kParameters[rvm_kind];
  const auto m = [&](int i) { return p[i] * 0.001f; };
  switch (rvm_kind) {
    case 1: {
      const auto& s = std::get<Pyramid>(shape);
      EXPECT_FLOAT_EQ(s.bottom_x_m, m(0));
      EXPECT_FLOAT_EQ(s.bottom_y_m, m(1));
      EXPECT_FLOAT_EQ(s.top_x_m, m(2));
      EXPECT_FLOAT_EQ(s.top_y_m, m(3));
      EXPECT_FLOAT_EQ(s.offset_x_m, m(4));
      EXPECT_FLOAT_EQ(s.offset_y_m, m(5));
      EXPECT_FLOAT_EQ(s.height_m, m(6));
      break;
    }
    case 2: {
      const auto& s = std::get<Box>(shape);
      EXPECT_FLOAT_EQ(s.size_x_m, m(0));
      EXPECT_FLOAT_EQ(s.size_y_m, m(1));
      EXPECT_FLOAT_EQ(s.size_z_m, m(2));
      break;
    }
    case 3: {
      const auto& s = std::get<RectangularTorus>(shape);
      EXPECT_FLOAT_EQ(s.inner_radius_m, m(0));
      EXPECT_FLOAT_EQ(s.outer_radius_m, m(1));
      EXPECT_FLOAT_EQ(s.height_m, m(2));
      EXPECT_EQ(s.angle_rad, p[3]);
      break;
    }
    case 4: {
      const auto& s = std::get<CircularTorus>(shape);
      EXPECT_FLOAT_EQ(s.bend_radius_m, m(0));
      EXPECT_FLOAT_EQ(s.tube_radius_m, m(1));
      EXPECT_EQ(s.angle_rad, p[2]);
      break;
    }
    case 5: {
      const auto& s = std::get<EllipticalDish>(shape);
      EXPECT_FLOAT_EQ(s.base_radius_m, m(0));
      EXPECT_FLOAT_EQ(s.height_m, m(1));
      break;
    }
    case 6: {
      const auto& s = std::get<SphericalDish>(shape);
      EXPECT_FLOAT_EQ(s.base_radius_m, m(0));
      EXPECT_FLOAT_EQ(s.height_m, m(1));
      break;
    }
    case 7: {
      const auto& s = std::get<Snout>(shape);
      EXPECT_FLOAT_EQ(s.radius_bottom_m, m(0));
      EXPECT_FLOAT_EQ(s.radius_top_m, m(1));
      EXPECT_FLOAT_EQ(s.height_m, m(2));
      EXPECT_FLOAT_EQ(s.offset_x_m, m(3));
      EXPECT_FLOAT_EQ(s.offset_y_m, m(4));
      EXPECT_EQ(s.bottom_shear_x_rad, p[5]);
      EXPECT_EQ(s.bottom_shear_y_rad, p[6]);
      EXPECT_EQ(s.top_shear_x_rad, p[7]);
      EXPECT_EQ(s.top_shear_y_rad, p[8]);
      break;
    }
    case 8: {
      const auto& s = std::get<Cylinder>(shape);
      EXPECT_FLOAT_EQ(s.radius_m, m(0));
      EXPECT_FLOAT_EQ(s.height_m, m(1));
      break;
    }
    case 9: EXPECT_FLOAT_EQ(std::get<Sphere>(shape).radius_m, 0.3f); break;
    case 10: {
      const auto& s = std::get<Line>(shape);
      EXPECT_FLOAT_EQ(s.start_x_m, m(0));
      EXPECT_FLOAT_EQ(s.end_x_m, m(1));
      break;
    }
    default: FAIL() << "kind " << rvm_kind;
  }
}

const PrimitiveKind kKindOf[12] = {
    PrimitiveKind::box,  // unused
    PrimitiveKind::pyramid, PrimitiveKind::box, PrimitiveKind::rectangular_torus,
    PrimitiveKind::circular_torus, PrimitiveKind::elliptical_dish, PrimitiveKind::spherical_dish,
    PrimitiveKind::snout, PrimitiveKind::cylinder, PrimitiveKind::sphere, PrimitiveKind::line,
    PrimitiveKind::facet_group,
};

// Every RvmPrimitive of a file, depth first in file order.
void for_each_primitive(const RvmFile& file, const std::function<void(const RvmPrimitive&)>& fn) {
  std::function<void(const RvmGroup&)> walk = [&](const RvmGroup& g) {
    for (const RvmPrimitive& p : g.primitives) fn(p);
    for (const RvmGroup& c : g.children) walk(c);
  };
  for (const RvmGroup& g : file.roots) walk(g);
  for (const RvmPrimitive& p : file.root_primitives) fn(p);
}

// ---------------------------------------------------------------------------------------------

TEST(RvmParser, EveryChunkAndKindParsesToWhatWasWritten) {
  const EveryChunkFile f = every_chunk_file();
  maybe_write_fuzz_seed("every_chunk.rvm", f.writer.bytes());
  const auto parsed = parse(f.writer);
  ASSERT_TRUE(parsed) << parsed.error().message;
  const RvmFile& file = parsed.value();
  EXPECT_TRUE(file.warnings.empty()) << file.warnings.front().message;

  EXPECT_EQ(file.header.version, 2u);
  EXPECT_EQ(file.header.info, "plantview test writer");
  EXPECT_EQ(file.header.note, "");
  EXPECT_EQ(file.header.date, "2024-05-01");
  EXPECT_EQ(file.header.user, "abcd");
  EXPECT_EQ(file.header.encoding, "UTF-8");
  EXPECT_EQ(file.model.version, 1u);
  EXPECT_EQ(file.model.project, "PROJ");
  EXPECT_EQ(file.model.name, "/MODEL");

  ASSERT_EQ(file.colours.size(), 2u);
  EXPECT_EQ(file.colours[0].kind, 1u);
  EXPECT_EQ(file.colours[0].index, 13u);
  EXPECT_EQ(file.colours[0].r, 10);
  EXPECT_EQ(file.colours[0].g, 20);
  EXPECT_EQ(file.colours[0].b, 30);
  EXPECT_EQ(file.colours[0].file_offset, f.colour_offsets[0]);
  EXPECT_EQ(file.colours[1].index, 14u);
  EXPECT_EQ(file.colours[1].r, 200);
  EXPECT_EQ(file.colours[1].g, 100);
  EXPECT_EQ(file.colours[1].b, 50);
  EXPECT_EQ(file.colours[1].file_offset, f.colour_offsets[1]);

  ASSERT_EQ(file.roots.size(), 1u);
  const RvmGroup& site = file.roots[0];
  EXPECT_EQ(site.name, "/SITE");
  EXPECT_FLOAT_EQ(site.translation_m.x, 1.0f);
  EXPECT_FLOAT_EQ(site.translation_m.y, 2.0f);
  EXPECT_FLOAT_EQ(site.translation_m.z, 3.0f);
  EXPECT_EQ(site.material, 3u);
  EXPECT_EQ(site.transparency_percent, 0);
  EXPECT_FALSE(site.has_own_transparency);
  EXPECT_EQ(site.file_offset, f.site_offset);
  EXPECT_TRUE(site.primitives.empty());
  ASSERT_EQ(site.children.size(), 2u);

  const RvmGroup& zone = site.children[0];
  EXPECT_EQ(zone.name, "/SITE/ZONE");
  EXPECT_EQ(zone.material, 5u);
  EXPECT_EQ(zone.transparency_percent, 40);
  EXPECT_TRUE(zone.has_own_transparency);
  EXPECT_EQ(zone.file_offset, f.zone_offset);
  EXPECT_TRUE(zone.children.empty());
  ASSERT_EQ(zone.primitives.size(), 13u);
  for (uint32_t kind = 1; kind <= 11; ++kind) {
    SCOPED_TRACE("RVM kind " + std::to_string(kind));
    const RvmPrimitive& p = zone.primitives[kind - 1];
    EXPECT_EQ(p.primitive.kind(), kKindOf[kind]);
    EXPECT_EQ(p.role, RvmGeometryRole::primitive);
    EXPECT_EQ(p.transparency_percent, 40) << "inherited from the zone";
    EXPECT_EQ(p.file_offset, f.primitive_offsets[kind - 1]);
    expect_placement(p);
    if (kind <= 10) expect_shape(p.primitive.shape, kind);
  }
  const auto& facets = std::get<FacetGroup>(zone.primitives[10].primitive.shape);
  ASSERT_EQ(facets.vertices.size(), 10u);
  EXPECT_EQ(facets.contour_ends, (std::vector<uint32_t>{4, 7, 10}));
  EXPECT_EQ(facets.polygon_ends, (std::vector<uint32_t>{2, 3}));
  size_t v = 0;
  for (const RvmPolygon& polygon : kPolygons) {
    for (const RvmContour& contour : polygon) {
      for (const RvmFacetVertex& written : contour) {
        for (int i = 0; i < 3; ++i) {
          EXPECT_FLOAT_EQ(facets.vertices[v].position_m[i], written.position_mm[i] * 0.001f);
          EXPECT_EQ(facets.vertices[v].normal[i], written.normal[i]);
        }
        ++v;
      }
    }
  }

  const RvmPrimitive& obstruction = zone.primitives[11];
  EXPECT_EQ(obstruction.role, RvmGeometryRole::obstruction);
  EXPECT_EQ(obstruction.transparency_percent, 70);
  EXPECT_EQ(obstruction.file_offset, f.obstruction_offset);
  expect_shape(obstruction.primitive.shape, 2);
  expect_placement(obstruction);
  const RvmPrimitive& insulation = zone.primitives[12];
  EXPECT_EQ(insulation.role, RvmGeometryRole::insulation);
  EXPECT_EQ(insulation.transparency_percent, 25);
  EXPECT_EQ(insulation.file_offset, f.insulation_offset);
  expect_shape(insulation.primitive.shape, 8);

  const RvmGroup& empty = site.children[1];
  EXPECT_EQ(empty.name, "/SITE/EMPTY");
  EXPECT_FLOAT_EQ(empty.translation_m.x, -0.001f);
  EXPECT_FLOAT_EQ(empty.translation_m.y, -0.002f);
  EXPECT_FLOAT_EQ(empty.translation_m.z, -0.003f);
  EXPECT_EQ(empty.transparency_percent, 0) << "inherited from the site, not the sibling zone";
  EXPECT_EQ(empty.file_offset, f.empty_offset);
  EXPECT_TRUE(empty.primitives.empty() && empty.children.empty());

  ASSERT_EQ(file.root_primitives.size(), 1u);
  EXPECT_EQ(file.root_primitives[0].file_offset, f.root_sphere_offset);
  EXPECT_EQ(file.root_primitives[0].transparency_percent, 0);
  expect_shape(file.root_primitives[0].primitive.shape, 9);

  const RvmStatistics stats = rvm_statistics(file);
  EXPECT_EQ(stats.groups, 3u);
  EXPECT_EQ(stats.primitives, 14u);
  EXPECT_EQ(stats.max_depth, 2u);
  EXPECT_EQ(stats.primitives_by_kind[size_t(PrimitiveKind::box)], 2u);
  EXPECT_EQ(stats.primitives_by_kind[size_t(PrimitiveKind::sphere)], 2u);
  EXPECT_EQ(stats.primitives_by_kind[size_t(PrimitiveKind::facet_group)], 1u);
}

TEST(RvmParser, EveryTruncationFailsNamingAnOffset) {
  const EveryChunkFile f = every_chunk_file();
  const std::vector<std::byte>& bytes = f.writer.bytes();
  for (RvmParseOptions options : {RvmParseOptions{}, warn_mode()}) {
    for (size_t n = 0; n < bytes.size(); ++n) {
      const auto parsed = parse_rvm(std::span(bytes.data(), n), kSource, options);
      ASSERT_FALSE(parsed) << "prefix of " << n << " bytes parsed";
      const ParseError& e = parsed.error();
      EXPECT_TRUE(e.message.starts_with("test.rvm: offset ")) << e.message;
      EXPECT_LE(e.offset, n) << e.message;
    }
  }
}

TEST(RvmParser, EverySingleByteCorruptionFailsCleanlyOrParses) {
  const EveryChunkFile f = every_chunk_file();
  for (const uint8_t value : {uint8_t{0x00}, uint8_t{0xff}, uint8_t{0x7f}}) {
    for (size_t i = 0; i < f.writer.size(); ++i) {
      std::vector<std::byte> bytes = f.writer.bytes();
      bytes[i] = std::byte{value};
      for (RvmParseOptions options : {RvmParseOptions{}, warn_mode()}) {
        const auto parsed = parse_rvm(bytes, kSource, options);
        if (!parsed) {
          EXPECT_TRUE(contains(parsed.error().message, "offset")) << parsed.error().message;
          EXPECT_LE(parsed.error().offset, bytes.size());
        }
      }
    }
  }
}

TEST(RvmParser, ExtraRootCnteBeforeEndIsAWarning) {
  RvmWriter w;
  begin_file(w);
  w.begin_group(2, "/A", {0, 0, 0}, 1);
  w.primitive("PRIM", 2, kMatrix, kBounds, kParameters[2]);
  w.end_group();
  const size_t extra = w.size();
  w.end_group();  // AVEVA Marine: one CNTE too many
  w.end();
  maybe_write_fuzz_seed("extra_cnte.rvm", w.bytes());
  const auto parsed = parse(w);
  ASSERT_TRUE(parsed) << parsed.error().message;
  ASSERT_EQ(parsed.value().warnings.size(), 1u);
  EXPECT_EQ(parsed.value().warnings[0].offset, extra);
  EXPECT_TRUE(contains(parsed.value().warnings[0].message, "CNTE closes no group"));
  ASSERT_EQ(parsed.value().roots.size(), 1u);
  EXPECT_EQ(parsed.value().roots[0].primitives.size(), 1u);
}

TEST(RvmParser, NextChunkOffsetThatDisagreesIsAnErrorNamingTheChunk) {
  EveryChunkFile f = every_chunk_file();
  const size_t chunk = f.primitive_offsets[3];
  f.writer.patch_u32(chunk + 16, 12345);
  const auto parsed = parse(f.writer);
  ASSERT_FALSE(parsed);
  EXPECT_EQ(parsed.error().offset, chunk + 16);
  EXPECT_TRUE(contains(parsed.error().message, "PRIM chunk at offset " + std::to_string(chunk)))
      << parsed.error().message;
  EXPECT_TRUE(contains(parsed.error().message, "next-chunk offset field is 12345"))
      << parsed.error().message;
}

TEST(RvmParser, NextChunkFieldAsLengthParsesInWarnModeOnly) {
  RvmWriter w;
  w.next_field = RvmWriter::NextField::body_length;
  begin_file(w);
  w.begin_group(2, "/A", {0, 0, 0}, 1);
  for (uint32_t kind = 1; kind <= 10; ++kind) {
    w.primitive("PRIM", kind, kMatrix, kBounds, kParameters[kind]);
  }
  w.facet_group("INSU", kMatrix, kBounds, kPolygons, 10);
  w.end_group();
  w.end();
  maybe_write_fuzz_seed("next_as_length.rvm", w.bytes());
  const auto strict = parse(w);
  ASSERT_FALSE(strict);
  EXPECT_EQ(strict.error().offset, 16u) << "the HEAD chunk's field";

  const auto lenient = parse(w, warn_mode());
  ASSERT_TRUE(lenient) << lenient.error().message;
  const RvmFile& file = lenient.value();
  EXPECT_EQ(file.warnings.size(), 16u) << "HEAD, MODL, CNTB, 11 geometry, CNTE, END:";
  EXPECT_EQ(file.warnings_dropped, 0u);
  EXPECT_TRUE(contains(file.warnings[0].message, "next-chunk offset field"));
  ASSERT_EQ(file.roots.size(), 1u);
  ASSERT_EQ(file.roots[0].primitives.size(), 11u);
  for (uint32_t kind = 1; kind <= 10; ++kind) {
    expect_shape(file.roots[0].primitives[kind - 1].primitive.shape, kind);
  }
  EXPECT_EQ(file.roots[0].primitives[10].transparency_percent, 10);
}

TEST(RvmParser, WarningsAreCappedAndCounted) {
  RvmWriter w;
  w.next_field = RvmWriter::NextField::body_length;
  begin_file(w);
  for (int i = 0; i < 200; ++i) w.colour(1, uint32_t(i), 1, 2, 3);
  w.end();
  const auto parsed = parse(w, warn_mode());
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_EQ(parsed.value().warnings.size(), kMaxRvmWarnings);
  EXPECT_EQ(parsed.value().warnings_dropped, 203u - kMaxRvmWarnings);
  EXPECT_EQ(parsed.value().colours.size(), 200u);
}

TEST(RvmParser, UnknownChunkIsSkippedOnlyWhenItsNextOffsetIsTrustedAndSane) {
  const auto build = [](uint32_t next_override) {
    RvmWriter w;
    begin_file(w);
    w.begin_group(2, "/A", {0, 0, 0}, 1);
    const size_t unknown = w.begin_chunk("XTRA");
    w.u32(7);
    w.u32(8);
    w.end_chunk();
    if (next_override != 0) w.patch_u32(unknown + 16, next_override);
    w.primitive("PRIM", 8, kMatrix, kBounds, kParameters[8]);
    w.end_group();
    w.end();
    return std::make_pair(w, unknown);
  };
  const auto [good, unknown] = build(0);
  maybe_write_fuzz_seed("unknown_chunk.rvm", good.bytes());
  const auto skipped = parse(good);
  ASSERT_TRUE(skipped) << skipped.error().message;
  ASSERT_EQ(skipped.value().warnings.size(), 1u);
  EXPECT_EQ(skipped.value().warnings[0].offset, unknown);
  EXPECT_TRUE(contains(skipped.value().warnings[0].message, "XTRA chunk at offset"));
  EXPECT_EQ(skipped.value().roots.at(0).primitives.size(), 1u);

  const auto untrusted = parse(good, warn_mode());
  ASSERT_FALSE(untrusted);
  EXPECT_EQ(untrusted.error().offset, unknown);
  EXPECT_TRUE(contains(untrusted.error().message, "XTRA chunk at offset " +
                                                      std::to_string(unknown) + " (0x"));
  EXPECT_TRUE(contains(untrusted.error().message, "unknown chunk id"));

  for (uint32_t bad_next : {uint32_t(unknown + 8), 0xfffffff0u}) {
    const auto insane = parse(build(bad_next).first);
    ASSERT_FALSE(insane) << bad_next;
    EXPECT_TRUE(contains(insane.error().message, "unknown chunk id")) << insane.error().message;
  }
}

TEST(RvmParser, MalformedChunkIdIsAnError) {
  RvmWriter w;
  begin_file(w);
  const size_t at = w.size();
  w.colour(1, 2, 3, 4, 5);
  w.end();
  std::vector<std::byte> bytes = w.bytes();
  bytes[at + 4] = std::byte{0x01};  // the 'O' of COLR gets a high byte
  const auto parsed = parse_rvm(bytes, kSource);
  ASSERT_FALSE(parsed);
  EXPECT_EQ(parsed.error().offset, at + 4);
  EXPECT_TRUE(contains(parsed.error().message, "malformed chunk id")) << parsed.error().message;
}

TEST(RvmParser, StructuralErrorsNameWhatAndWhere) {
  {  // END: with a group open
    RvmWriter w;
    begin_file(w);
    const size_t group = w.size();
    w.begin_group(2, "/OPEN", {0, 0, 0}, 1);
    const size_t end = w.size();
    w.end();
    const auto parsed = parse(w);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().offset, end);
    EXPECT_TRUE(contains(parsed.error().message, "\"/OPEN\", began at offset " +
                                                     std::to_string(group)))
        << parsed.error().message;
  }
  {  // no END: at all
    RvmWriter w;
    begin_file(w);
    w.begin_group(2, "/A", {0, 0, 0}, 1);
    w.end_group();
    const auto parsed = parse(w);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().offset, w.size());
    EXPECT_TRUE(contains(parsed.error().message, "without an END: chunk"));
  }
  {  // not an RVM file
    const std::string text = "CADC_Attributes_File v1.0 , start: NEW , end: END";
    const auto parsed = parse_rvm(std::as_bytes(std::span(text)), kSource);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().offset, 0u);
    EXPECT_TRUE(contains(parsed.error().message, "malformed chunk id")) << parsed.error().message;
  }
  {  // MODL missing; a second MODL
    RvmWriter w;
    w.head(2, "i", "n", "d", "u", "e");
    w.end();
    EXPECT_TRUE(contains(parse(w).error().message, "expected a MODL chunk after HEAD"));
    RvmWriter w2;
    begin_file(w2);
    w2.model(1, "P", "N");
    w2.end();
    EXPECT_TRUE(contains(parse(w2).error().message, "MODL chunk at offset"));
    EXPECT_TRUE(contains(parse(w2).error().message, "out of place"));
  }
  {  // HEAD version 1 has no encoding
    RvmWriter w;
    w.head(1, "info", "note", "date", "user", "ignored");
    w.model(1, "P", "N");
    w.end();
    const auto parsed = parse(w);
    ASSERT_TRUE(parsed) << parsed.error().message;
    EXPECT_EQ(parsed.value().header.user, "user");
    EXPECT_EQ(parsed.value().header.encoding, "");
  }
  {  // bytes after END: are ignored
    RvmWriter w;
    begin_file(w);
    w.end();
    for (int i = 0; i < 64; ++i) w.u32(i == 3 ? 0xdeadbeef : 0);
    EXPECT_TRUE(parse(w));
  }
}

TEST(RvmParser, UnknownPrimitiveKindIsAnErrorNamingTheKind) {
  for (uint32_t kind : {0u, 12u, 0xffffffffu}) {
    RvmWriter w;
    begin_file(w);
    w.begin_group(2, "/A", {0, 0, 0}, 1);
    const size_t at = w.size();
    w.primitive("PRIM", kind, kMatrix, kBounds, kParameters[2]);
    w.end_group();
    w.end();
    const auto parsed = parse(w);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().offset, at + 28) << "the kind field";
    EXPECT_TRUE(contains(parsed.error().message, "unknown primitive kind " + std::to_string(kind)))
        << parsed.error().message;
  }
}

TEST(RvmParser, NonFiniteFloatsAreErrorsNamingTheirOffset) {
  const float nan = std::nanf(""), inf = INFINITY;
  struct Case {
    const char* name;
    std::function<size_t(RvmWriter&)> write;  // returns the offset of the bad float
    const char* field;
  };
  const std::vector<Case> cases = {
      {"matrix", [&](RvmWriter& w) {
         RvmMatrix m = kMatrix;
         m[10] = nan;
         const size_t at = w.size();
         w.primitive("PRIM", 2, m, kBounds, kParameters[2]);
         return at + 32 + 40;
       }, "matrix (float 11 of 12)"},
      {"bounds", [&](RvmWriter& w) {
         std::array<float, 6> b = kBounds;
         b[0] = -inf;
         const size_t at = w.size();
         w.primitive("PRIM", 2, kMatrix, b, kParameters[2]);
         return at + 32 + 48;
       }, "bounding box (float 1 of 6)"},
      {"parameter", [&](RvmWriter& w) {
         const float p[] = {75, inf};
         const size_t at = w.size();
         w.primitive("OBST", 8, kMatrix, kBounds, p, 5);
         return at + 32 + 48 + 24 + 4 + 4;
       }, "primitive parameters (float 2 of 2)"},
      {"facet vertex", [&](RvmWriter& w) {
         std::vector<RvmPolygon> polygons = kPolygons;
         polygons[1][0][2].normal.y = nan;  // the last vertex of the file's facets
         w.facet_group("PRIM", kMatrix, kBounds, polygons);
         return w.size() - 8;
       }, "facet group vertex (float 5 of 6)"},
      {"overflow", [&](RvmWriter& w) {
         RvmMatrix m = kMatrix;
         m[4] = 1e38f;
         const size_t at = w.size();
         w.primitive("PRIM", 2, m, kBounds, kParameters[2]);
         return at + 32 + 16;
       }, "matrix value overflows"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    RvmWriter w;
    begin_file(w);
    w.begin_group(2, "/A", {0, 0, 0}, 1);
    const size_t at = c.write(w);
    w.end_group();
    w.end();
    const auto parsed = parse(w);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().offset, at) << parsed.error().message;
    EXPECT_TRUE(contains(parsed.error().message, c.field)) << parsed.error().message;
  }
  RvmWriter w;  // a group's translation
  begin_file(w);
  const size_t group = w.size();
  w.begin_group(2, "/ABC", {0, nan, 0}, 1);
  w.end_group();
  w.end();
  const auto parsed = parse(w);
  ASSERT_FALSE(parsed);
  EXPECT_EQ(parsed.error().offset, group + 24 + 4 + 8 + 4);
  EXPECT_TRUE(contains(parsed.error().message, "CNTB translation (float 2 of 3)"))
      << parsed.error().message;
}

TEST(RvmParser, DegeneratePrimitivesParseAsWrittenAndFinite) {
  RvmWriter w;
  begin_file(w);
  w.begin_group(2, "/DEGENERATE", {0, 0, 0}, 1);
  const std::vector<std::pair<uint32_t, std::vector<float>>> shapes = {
      {8, {0, 1000}},                       // zero radius
      {8, {100, 0}},                        // zero height
      {1, {0, 0, 0, 0, 0, 0, 100}},         // zero-size sides
      {1, {100, 0, 100, 0, 0, 0, 100}},     // zero-width wedge
      {2, {-100, 200, 0}},                  // negative and zero sides
      {4, {0, 0, 0}},                       // empty torus
      {3, {200, 100, 50, 0}},               // inner > outer, zero sweep
      {7, {0, 0, 0, 0, 0, 1.5707963f, 0, 0, 0}},
      {9, {0}},
      {5, {0, 100}},
      {6, {100, 0}},
      {10, {0, 0}},
  };
  for (const auto& [kind, p] : shapes) w.primitive("PRIM", kind, kMatrix, kBounds, p);
  // A facet group of empty contours, a polygon without contours, and lone points and segments.
  const RvmFacetVertex a{{0, 0, 0}, {0, 0, 0}}, b{{1, 0, 0}, {0, 0, 1}};
  w.facet_group("PRIM", kMatrix, kBounds, {{{}, {}}, {}, {{a}}, {{a, b}}, {{a, a, a}}});
  w.facet_group("PRIM", kMatrix, kBounds, {});
  // A zero matrix: every local point lands on the translation.
  w.primitive("PRIM", 2, RvmMatrix{}, kBounds, kParameters[2]);
  w.end_group();
  w.end();
  maybe_write_fuzz_seed("degenerate.rvm", w.bytes());
  const auto parsed = parse(w);
  ASSERT_TRUE(parsed) << parsed.error().message;
  const auto& primitives = parsed.value().roots.at(0).primitives;
  ASSERT_EQ(primitives.size(), shapes.size() + 3);
  EXPECT_FLOAT_EQ(std::get<Box>(primitives[4].primitive.shape).size_x_m, -0.1f) << "kept as is";
  EXPECT_EQ(std::get<Sphere>(primitives[8].primitive.shape).radius_m, 0.0f);
  const auto& facets = std::get<FacetGroup>(primitives[shapes.size()].primitive.shape);
  EXPECT_EQ(facets.polygon_ends, (std::vector<uint32_t>{2, 2, 3, 4, 5}));
  EXPECT_EQ(facets.contour_ends, (std::vector<uint32_t>{0, 0, 1, 3, 6}));
  EXPECT_EQ(facets.vertices.size(), 6u);
  const auto& no_facets = std::get<FacetGroup>(primitives[shapes.size() + 1].primitive.shape);
  EXPECT_TRUE(no_facets.vertices.empty() && no_facets.polygon_ends.empty());
  EXPECT_EQ(primitives.back().primitive.placement.linear, glm::mat3(0.0f));

  for_each_primitive(parsed.value(), [](const RvmPrimitive& p) {
    const Placement& pl = p.primitive.placement;
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) ASSERT_TRUE(std::isfinite(pl.linear[c][r]));
      ASSERT_TRUE(std::isfinite(pl.translation_m[c]));
    }
  });
}

TEST(RvmParser, TransparencyIsInheritedAndClamped) {
  RvmWriter w;
  begin_file(w);
  w.begin_group(3, "/T60", {0, 0, 0}, 1, 60);
  w.begin_group(2, "/T60/INHERITS", {0, 0, 0}, 1);
  w.primitive("PRIM", 2, kMatrix, kBounds, kParameters[2]);
  w.primitive("INSU", 2, kMatrix, kBounds, kParameters[2], 0);
  w.begin_group(3, "/T60/INHERITS/OWN0", {0, 0, 0}, 1, 0);
  w.primitive("PRIM", 2, kMatrix, kBounds, kParameters[2]);
  w.end_group();
  w.end_group();
  w.end_group();
  const size_t too_much = w.size();
  w.begin_group(3, "/T200", {0, 0, 0}, 1, 200);
  w.end_group();
  w.end();
  const auto parsed = parse(w);
  ASSERT_TRUE(parsed) << parsed.error().message;
  const RvmGroup& inherits = parsed.value().roots.at(0).children.at(0);
  EXPECT_EQ(inherits.transparency_percent, 60);
  EXPECT_FALSE(inherits.has_own_transparency);
  EXPECT_EQ(inherits.primitives.at(0).transparency_percent, 60);
  EXPECT_EQ(inherits.primitives.at(1).transparency_percent, 0) << "INSU's own 0 wins";
  EXPECT_EQ(inherits.children.at(0).primitives.at(0).transparency_percent, 0);
  EXPECT_EQ(parsed.value().roots.at(1).transparency_percent, 100);
  ASSERT_EQ(parsed.value().warnings.size(), 1u);
  EXPECT_EQ(parsed.value().warnings[0].offset, too_much + 24 + 4 + 12 + 12 + 4);
  EXPECT_TRUE(contains(parsed.value().warnings[0].message, "transparency 200"));
}

TEST(RvmParser, HostileCountsFailWithoutAllocating) {
  struct Case {
    const char* name;
    std::function<size_t(RvmWriter&)> write;  // writes the chunk, returns the count's offset
    const char* expected;
  };
  const auto facet_header = [](RvmWriter& w) {
    w.begin_chunk("PRIM");
    w.u32(1);
    w.u32(11);
    for (float f : kMatrix) w.f32(f);
    for (float f : kBounds) w.f32(f);
  };
  const std::vector<Case> cases = {
      {"polygons", [&](RvmWriter& w) {
         facet_header(w);
         const size_t at = w.size();
         w.u32(0x80000000u);
         w.end_chunk();
         return at;
       }, "facet group polygon count 2147483648"},
      {"contours", [&](RvmWriter& w) {
         facet_header(w);
         w.u32(1);
         const size_t at = w.size();
         w.u32(0xffffffffu);
         w.end_chunk();
         return at;
       }, "facet group contour count 4294967295"},
      {"vertices", [&](RvmWriter& w) {
         facet_header(w);
         w.u32(1);
         w.u32(1);
         const size_t at = w.size();
         w.u32(0x7fffffffu);
         for (int i = 0; i < 12; ++i) w.f32(1);
         w.end_chunk();
         return at;
       }, "facet group vertex count 2147483647"},
      {"string", [&](RvmWriter& w) {
         w.begin_chunk("CNTB");
         w.u32(2);
         const size_t at = w.size();
         w.u32(0xffffffffu);
         w.end_chunk();
         return at;
       }, "CNTB name: string of 4294967295 words"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    RvmWriter w;
    begin_file(w);
    w.begin_group(2, "/A", {0, 0, 0}, 1);
    const size_t at = c.write(w);
    w.end_group();
    w.end();
    maybe_write_fuzz_seed(std::string("hostile_") + c.name + ".rvm", w.bytes());
    const auto parsed = parse(w);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().offset, at) << parsed.error().message;
    EXPECT_TRUE(contains(parsed.error().message, c.expected)) << parsed.error().message;
  }
}

TEST(RvmParser, NestingIsLimited) {
  for (const uint32_t depth : {kMaxRvmGroupDepth, kMaxRvmGroupDepth + 1}) {
    RvmWriter w;
    begin_file(w);
    for (uint32_t i = 0; i < depth; ++i) w.begin_group(2, "/G", {0, 0, 0}, 1);
    for (uint32_t i = 0; i < depth; ++i) w.end_group();
    w.end();
    const auto parsed = parse(w);
    if (depth == kMaxRvmGroupDepth) {
      ASSERT_TRUE(parsed) << parsed.error().message;
      EXPECT_EQ(rvm_statistics(parsed.value()).max_depth, depth);
    } else {
      ASSERT_FALSE(parsed);
      EXPECT_TRUE(contains(parsed.error().message, "groups nest deeper than"));
    }
  }
}

// ---------------------------------------------------------------------------------------------
// load_file.

TEST(LoadFile, ADirectoryIsRefusedNamingItNotReadAsAHugeFile) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("plantview-load-file-" + std::to_string(::getpid()) + ".rvm");
  std::filesystem::create_directories(dir);
  const auto bytes = load_file(dir);
  std::filesystem::remove_all(dir);
  ASSERT_FALSE(bytes);
  EXPECT_EQ(bytes.error().message, dir.string() + ": is a directory, not a file");
}

TEST(LoadFile, AMissingFileIsRefusedWithTheSystemsReason) {
  const auto bytes = load_file("/nonexistent/plantview/test.rvm");
  ASSERT_FALSE(bytes);
  EXPECT_TRUE(contains(bytes.error().message, "/nonexistent/plantview/test.rvm: cannot open"))
      << bytes.error().message;
}

TEST(LoadFile, AFileComesBackWhole) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("plantview-load-file-" + std::to_string(::getpid()) + ".txt");
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fputs("abc\n", f);
    std::fclose(f);
  }
  const auto bytes = load_file(path);
  std::filesystem::remove(path);
  ASSERT_TRUE(bytes) << bytes.error().message;
  ASSERT_EQ(bytes.value().size(), 4u);
  EXPECT_EQ(char(bytes.value()[0]), 'a');
}

// ---------------------------------------------------------------------------------------------
// The Huldra sample (../shared/data/huldra): real exporter output.

std::filesystem::path huldra_rvm() {
  return std::filesystem::path(PLANTVIEW_SHARED_DIR) / "data/huldra/WD1-PSUP.RVM";
}

TEST(RvmParserHuldra, SampleParsesWithItsKnownCounts) {
  if (!std::filesystem::exists(huldra_rvm())) GTEST_SKIP() << "no sample at " << huldra_rvm();
  const auto bytes = load_file(huldra_rvm());
  ASSERT_TRUE(bytes) << bytes.error().message;
  RvmParseOptions options;
  options.triangulate_facet_groups = false;  // counts only; triangulation has its own tests
  const auto parsed = parse_rvm(bytes.value(), "WD1-PSUP.RVM", options);
  ASSERT_TRUE(parsed) << parsed.error().message;
  const RvmFile& file = parsed.value();
  EXPECT_TRUE(file.warnings.empty()) << file.warnings.front().message;

  EXPECT_EQ(file.header.version, 2u);
  EXPECT_TRUE(file.header.info.starts_with("AVEVA Everything3D Design")) << file.header.info;
  EXPECT_EQ(file.header.note, "Level 1 to 6");
  EXPECT_EQ(file.header.user, "f_pdmsbatch@WS3208");
  EXPECT_EQ(file.header.encoding, "Unicode UTF-8");
  EXPECT_EQ(file.model.project, "HDA");
  EXPECT_EQ(file.model.name, "/HDA");
  ASSERT_EQ(file.roots.size(), 1u);
  EXPECT_EQ(file.roots[0].name, "/WD1-PSUP");
  EXPECT_TRUE(file.root_primitives.empty());

  const RvmStatistics stats = rvm_statistics(file);
  EXPECT_EQ(stats.groups, 4084u);
  EXPECT_EQ(stats.max_depth, 6u);
  EXPECT_EQ(stats.primitives, 2757u);
  const auto count = [&](PrimitiveKind k) { return stats.primitives_by_kind[size_t(k)]; };
  EXPECT_EQ(count(PrimitiveKind::box), 936u);
  EXPECT_EQ(count(PrimitiveKind::cylinder), 624u);
  EXPECT_EQ(count(PrimitiveKind::pyramid), 472u);
  EXPECT_EQ(count(PrimitiveKind::facet_group), 334u);
  EXPECT_EQ(count(PrimitiveKind::rectangular_torus), 262u);
  EXPECT_EQ(count(PrimitiveKind::line), 129u);

  // Facet groups (counted independently from the file); every placement scales metres to metres.
  size_t polygons = 0, contours = 0, vertices = 0;
  const RvmPrimitive* first_line = nullptr;
  for_each_primitive(file, [&](const RvmPrimitive& p) {
    if (const auto* f = std::get_if<FacetGroup>(&p.primitive.shape)) {
      polygons += f->polygon_ends.size();
      contours += f->contour_ends.size();
      vertices += f->vertices.size();
    }
    if (p.primitive.kind() == PrimitiveKind::line && first_line == nullptr) first_line = &p;
    for (int c = 0; c < 3; ++c) {
      ASSERT_NEAR(glm::length(p.primitive.placement.linear[c]), 1.0f, 1e-4f) << p.file_offset;
    }
  });
  EXPECT_EQ(polygons, 3209u);
  EXPECT_EQ(contours, 3227u);
  EXPECT_EQ(vertices, 15246u);

  // The first primitive of the file, a line at offset 524.
  ASSERT_NE(first_line, nullptr);
  EXPECT_EQ(first_line->file_offset, 524u);
  const Line& line = std::get<Line>(first_line->primitive.shape);
  EXPECT_FLOAT_EQ(line.start_x_m, 0.005f);
  EXPECT_FLOAT_EQ(line.end_x_m, 0.0f);
  const Placement& pl = first_line->primitive.placement;
  EXPECT_NEAR(pl.translation_m.x, 106.565f, 1e-4f);
  EXPECT_NEAR(pl.translation_m.y, 310.3f, 1e-4f);
  EXPECT_NEAR(pl.translation_m.z, 35.45f, 1e-4f);
  EXPECT_NEAR(pl.linear[0].y, 1.0f, 1e-6f);
  EXPECT_NEAR(pl.linear[1].z, -1.0f, 1e-6f);
  EXPECT_NEAR(pl.linear[2].x, -1.0f, 1e-6f);
  EXPECT_FLOAT_EQ(first_line->local_bounds_m.max.z, 0.1445f);
}

TEST(RvmParserHuldra, SampleParsesInAFewMilliseconds) {
  if (!std::filesystem::exists(huldra_rvm())) GTEST_SKIP() << "no sample at " << huldra_rvm();
  const auto bytes = load_file(huldra_rvm());
  ASSERT_TRUE(bytes) << bytes.error().message;
  for (const bool triangulate : {false, true}) {
    RvmParseOptions options;
    options.triangulate_facet_groups = triangulate;
    double best_ms = 1e9;
    size_t warnings = 0;
    for (int run = 0; run < 10; ++run) {
      const auto start = std::chrono::steady_clock::now();
      const auto parsed = parse_rvm(bytes.value(), "WD1-PSUP.RVM", options);
      const auto stop = std::chrono::steady_clock::now();
      ASSERT_TRUE(parsed) << parsed.error().message;
      warnings = parsed.value().warnings.size() + parsed.value().warnings_dropped;
      best_ms = std::min(best_ms, std::chrono::duration<double, std::milli>(stop - start).count());
    }
    std::printf("WD1-PSUP.RVM (%zu bytes), facet groups %s: parsed in %.2f ms (best of 10), "
                "%zu warnings\n",
                bytes.value().size(), triangulate ? "triangulated" : "not triangulated", best_ms,
                warnings);
    RecordProperty(triangulate ? "parse_and_triangulate_ms" : "parse_ms", std::to_string(best_ms));
  }
}

}  // namespace
}  // namespace plantview::testing
