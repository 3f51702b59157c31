// Object styling (view_filters.h: ObjectStyle) in the renderer, on preset c's overview: hide and
// only leave objects out of the id buffer and count them; colour by an attribute gives objects
// of one value one colour (categories) or a ramp over the values drawn; an unknown key is an
// error that lists the keys found; a style changed through set_options is evaluated again. And
// the rules of values and colours (object_style.h) without GL.
#include <gtest/gtest.h>

#include <fnmatch.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <nlohmann/json.hpp>
#include <set>

#include "object_style.h"
#include "plantview/camera.h"
#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/render.h"
#include "plantview/store.h"
#include "support/gl_context.h"
#include "support/stores.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

constexpr uint32_t kWidth = 480, kHeight = 270;

class Style : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    store_ = test::generated_store(*dir_, 'c').release();
    ASSERT_TRUE(store_);
  }
  static void TearDownTestSuite() {
    delete store_;
    delete dir_;
  }

  // Plain colours: no antialiasing, ambient occlusion or ground, so a pixel is its object's
  // colour, lit.
  static RenderOptions plain(const ObjectStyle& style = {}) {
    RenderOptions o;
    o.antialias = false;
    o.ambient_occlusion = false;
    o.ground = false;
    o.style = style;
    return o;
  }
  static std::unique_ptr<Renderer> renderer(const RenderOptions& options) {
    test::gl_context();
    std::string error;
    auto r = Renderer::create(*store_, options, error);
    EXPECT_TRUE(r) << error;
    return r;
  }
  static Camera overview(const Renderer& r) {
    return default_camera(overview_boxes(r.read_view()), double(kWidth) / kHeight);
  }
  // The objects of the id buffer, each read with its attributes.
  static std::map<uint64_t, Object> objects_drawn(const Renderer& r, const Image& image) {
    std::map<uint64_t, Object> out;
    for (const uint64_t id : image.object_ids) {
      if (id == 0 || out.count(id)) continue;
      std::string error;
      const auto slot = r.read_view().slot_of(id);
      EXPECT_TRUE(slot) << id;
      if (!slot) continue;
      EXPECT_TRUE(r.read_view().object(*slot, out[id], true, error)) << error;
    }
    return out;
  }
  static const std::string* attribute(const Object& o, const std::string& key) {
    for (const Attribute& a : o.attributes)
      if (a.key == key) return &a.value;
    return nullptr;
  }

  static inline test::TempDir* dir_ = nullptr;
  static inline Store* store_ = nullptr;
};

TEST_F(Style, HideLeavesClassOut) {
  ObjectStyle style;
  style.hide = {"structure"};
  auto r = renderer(plain(style));
  Image image;
  FrameStats stats;
  std::string error;
  ASSERT_TRUE(r->render(overview(*r), kWidth, kHeight, true, image, stats, error)) << error;
  EXPECT_GT(stats.objects_hidden, 0u);
  const auto drawn = objects_drawn(*r, image);
  ASSERT_GT(drawn.size(), 100u);
  for (const auto& [id, o] : drawn) EXPECT_NE(o.object_class, ObjectClass::structure) << o.name;
  EXPECT_NE(stats.to_json().find("\"objects_hidden\":" + std::to_string(stats.objects_hidden)),
            std::string::npos);

  // The same renderer without the style: structure is back, nothing hidden.
  r->set_options(plain());
  ASSERT_TRUE(r->render(overview(*r), kWidth, kHeight, true, image, stats, error)) << error;
  EXPECT_EQ(stats.objects_hidden, 0u);
  size_t structure = 0;
  for (const auto& [id, o] : objects_drawn(*r, image))
    structure += o.object_class == ObjectClass::structure;
  EXPECT_GT(structure, 0u);
}

TEST_F(Style, OnlyGlobShowsMatchesAlone) {
  ObjectStyle style;
  style.only = {"P-*"};
  auto r = renderer(plain());
  Image image;
  FrameStats stats;
  std::string error;
  ASSERT_TRUE(r->render(overview(*r), kWidth, kHeight, true, image, stats, error)) << error;
  // Changed on a renderer that knows the objects already: each is evaluated again.
  r->set_options(plain(style));
  ASSERT_TRUE(r->render(overview(*r), kWidth, kHeight, true, image, stats, error)) << error;
  EXPECT_GT(stats.objects_hidden, 0u);
  const auto drawn = objects_drawn(*r, image);
  ASSERT_FALSE(drawn.empty());
  for (const auto& [id, o] : drawn) {
    const std::string* tag = attribute(o, "Tag");
    EXPECT_TRUE(fnmatch("P-*", o.name.c_str(), 0) == 0 ||
                (tag && fnmatch("P-*", tag->c_str(), 0) == 0))
        << o.name;
  }
}

// The legend colour nearest a lit pixel's chromaticity.
size_t nearest_colour(const uint8_t* p, const std::vector<Colour>& colours) {
  const auto chroma = [](double r, double g, double b) {
    const double s = std::max(r + g + b, 1.0);
    return std::array<double, 2>{r / s, g / s};
  };
  const auto c = chroma(p[0], p[1], p[2]);
  size_t best = 0;
  double best_d = INFINITY;
  for (size_t i = 0; i < colours.size(); ++i) {
    const auto k = chroma(colours[i].r, colours[i].g, colours[i].b);
    const double d = std::hypot(c[0] - k[0], c[1] - k[1]);
    if (d < best_d) best_d = d, best = i;
  }
  return best;
}

TEST_F(Style, ColourByCategoriesSharesColoursByValue) {
  ObjectStyle style;
  style.colour_by = "Material";
  auto r = renderer(plain(style));
  Image image;
  FrameStats stats;
  std::string error;
  ASSERT_TRUE(r->render(overview(*r), kWidth, kHeight, true, image, stats, error)) << error;
  const FrameLegend& legend = stats.legend;
  ASSERT_EQ(legend.key, "Material");
  ASSERT_EQ(legend.kind, FrameLegend::Kind::categories);
  ASSERT_GE(legend.entries.size(), 3u);
  // Distinct colours for distinct values, values in text order.
  std::map<std::string, Colour> colour_of;
  std::vector<Colour> colours;
  for (size_t i = 0; i < legend.entries.size(); ++i) {
    const auto& e = legend.entries[i];
    if (i) {
      EXPECT_LT(legend.entries[i - 1].value, e.value);
    }
    for (const Colour& c : colours) {
      EXPECT_FALSE(c == e.colour) << e.value;
    }
    colours.push_back(e.colour);
    colour_of[e.value] = e.colour;
    EXPECT_GT(e.objects, 0u);
  }
  colours.push_back(FrameLegend::kMissingColour);
  // Each object's pixels are mostly nearest its value's colour (by chromaticity: lighting
  // changes brightness, and similar palette entries are told apart by the most of its pixels).
  const auto drawn = objects_drawn(*r, image);
  std::map<uint64_t, std::vector<size_t>> votes;  // per object, per colour
  for (size_t i = 0; i < image.object_ids.size(); ++i) {
    if (!drawn.count(image.object_ids[i])) continue;
    auto& v = votes[image.object_ids[i]];
    v.resize(colours.size());
    ++v[nearest_colour(&image.rgba[i * 4], colours)];
  }
  size_t agree = 0, total = 0;
  for (const auto& [id, v] : votes) {
    const size_t pixels = std::accumulate(v.begin(), v.end(), size_t(0));
    // Too few pixels to tell shading from colour; or a pipe, far pipes being drawn as lines
    // of partial coverage over what lies behind.
    // (Pipelines stand for merged runs of their members, coloured by their deciding member.)
    if (pixels < 30 || drawn.at(id).object_class == ObjectClass::pipe ||
        drawn.at(id).object_class == ObjectClass::pipeline)
      continue;
    const std::string* value = attribute(drawn.at(id), "Material");
    size_t want = colours.size() - 1;
    if (value) {
      const auto c = colour_of.find(*value);
      if (c == colour_of.end()) continue;  // beyond the palette
      want = size_t(std::find(colours.begin(), colours.end(), c->second) - colours.begin());
    }
    ++total;
    const size_t got = size_t(std::max_element(v.begin(), v.end()) - v.begin());
    agree += got == want;
    if (got != want && std::getenv("STYLE_DEBUG"))
      std::fprintf(stderr, "%s [%s] want %zu got %zu (%zu px)\n", drawn.at(id).name.c_str(),
                   value ? value->c_str() : "-", want, got, pixels);
  }
  if (const char* dump = std::getenv("STYLE_DUMP")) {
    EXPECT_TRUE(write_image(dump, image, 90, error));
  }
  ASSERT_GT(total, 20u);
  EXPECT_GT(double(agree) / double(total), 0.9) << agree << " of " << total;
  // The JSON form (the service's X-Plantview-Legend).
  const nlohmann::json j = nlohmann::json::parse(stats.to_json());
  ASSERT_TRUE(j.contains("legend"));
  EXPECT_EQ(j["legend"]["key"], "Material");
  EXPECT_EQ(j["legend"]["kind"], "categories");
  EXPECT_EQ(j["legend"]["entries"].size(), legend.entries.size());
  EXPECT_EQ(j["legend"]["entries"][0]["colour"].get<std::string>().size(), 7u);
  EXPECT_TRUE(j["legend"].contains("missing_objects"));
  EXPECT_TRUE(j["legend"].contains("other_objects"));
}

TEST_F(Style, ColourByNumbersIsARampOverTheValuesDrawn) {
  ObjectStyle style;
  style.colour_by = "Design temperature";
  auto r = renderer(plain(style));
  Image image;
  FrameStats stats;
  std::string error;
  ASSERT_TRUE(r->render(overview(*r), kWidth, kHeight, true, image, stats, error)) << error;
  const FrameLegend& legend = stats.legend;
  ASSERT_EQ(legend.kind, FrameLegend::Kind::ramp);
  EXPECT_EQ(legend.unit, "degC");
  EXPECT_LT(legend.min, legend.max);
  ASSERT_EQ(legend.colours.size(), 5u);
  EXPECT_EQ(legend.colours.front(), (Colour{68, 1, 84, 255}));
  EXPECT_EQ(legend.colours.back(), (Colour{253, 231, 37, 255}));
  EXPECT_GT(legend.objects, 0u);
  EXPECT_GT(legend.missing_objects, 0u);  // structure and pipes have no design temperature
  // The range is the drawn values': those of the objects in the id buffer lie within it, and
  // the ends are met (by objects drawn, if not necessarily seen).
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& [id, o] : objects_drawn(*r, image)) {
    const std::string* v = attribute(o, "Design temperature");
    // (A pipeline's id marks a merged run of its members, which take their own values.)
    if (!v || o.object_class == ObjectClass::pipeline) continue;
    const double t = std::stod(*v);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  EXPECT_LE(legend.min, lo);
  EXPECT_GE(legend.max, hi);
  const nlohmann::json j = nlohmann::json::parse(stats.to_json());
  EXPECT_EQ(j["legend"]["kind"], "ramp");
  EXPECT_EQ(j["legend"]["colours"][0], "#440154");
  EXPECT_EQ(j["legend"]["colours"][4], "#fde725");
}

TEST_F(Style, UnknownKeyListsTheKeysFound) {
  ObjectStyle style;
  style.colour_by = "Colour of the sky";
  auto r = renderer(plain(style));
  Image image;
  FrameStats stats;
  std::string error;
  EXPECT_FALSE(r->render(overview(*r), kWidth, kHeight, false, image, stats, error));
  EXPECT_NE(error.find("'Colour of the sky'"), std::string::npos) << error;
  EXPECT_NE(error.find("Material"), std::string::npos) << error;
  EXPECT_NE(error.find("Tag"), std::string::npos) << error;
  // A known key on the same renderer works again.
  style.colour_by = "Material";
  r->set_options(plain(style));
  EXPECT_TRUE(r->render(overview(*r), kWidth, kHeight, false, image, stats, error)) << error;
}

TEST(StyleRules, NumericValues) {
  double v = 0;
  std::string unit;
  EXPECT_TRUE(detail::parse_numeric_value("260 degC", v, unit));
  EXPECT_EQ(v, 260);
  EXPECT_EQ(unit, "degC");
  EXPECT_TRUE(detail::parse_numeric_value("12.5 barg", v, unit));
  EXPECT_EQ(unit, "barg");
  EXPECT_TRUE(detail::parse_numeric_value("-3", v, unit));
  EXPECT_EQ(unit, "");
  EXPECT_TRUE(detail::parse_numeric_value("150mm", v, unit));
  EXPECT_EQ(unit, "mm");
  EXPECT_FALSE(detail::parse_numeric_value("DN150", v, unit));
  EXPECT_FALSE(detail::parse_numeric_value("Hot, 50 mm", v, unit));
  EXPECT_FALSE(detail::parse_numeric_value("DN150 (6\")", v, unit));
  EXPECT_FALSE(detail::parse_numeric_value("1/2 in", v, unit));
  EXPECT_FALSE(detail::parse_numeric_value("", v, unit));
  EXPECT_EQ(detail::ramp_colour(0), (Colour{68, 1, 84, 255}));
  EXPECT_EQ(detail::ramp_colour(1), (Colour{253, 231, 37, 255}));
  EXPECT_EQ(detail::ramp_colour(0.5), (Colour{33, 145, 140, 255}));
  EXPECT_GE(detail::kCategoryCount, 12u);
}

TEST(StyleRules, HideAndOnlyWords) {
  ObjectStyle style;
  style.only = {"equipment", "P-*"};
  style.hide = {"*B"};
  const detail::CompiledStyle s(style);
  EXPECT_TRUE(s.needs_record());
  Object o;
  o.object_class = ObjectClass::equipment;
  o.name = "/E-101";
  EXPECT_FALSE(s.hides(o));
  o.name = "/E-101B";
  EXPECT_TRUE(s.hides(o));  // hide after only
  o.object_class = ObjectClass::pipe;
  o.name = "/PIPE-1";
  EXPECT_TRUE(s.hides(o));
  o.attributes.push_back({"Tag", "P-7"});
  EXPECT_FALSE(s.hides(o));  // its Tag matches
  ObjectStyle classes;
  classes.hide = {"structure"};
  EXPECT_FALSE(detail::CompiledStyle(classes).needs_record());
  EXPECT_TRUE(detail::CompiledStyle(classes).hides_class(ObjectClass::structure));
}

}  // namespace
}  // namespace plantview
