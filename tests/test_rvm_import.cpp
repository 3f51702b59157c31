// RVM groups to plant objects, on the Huldra sample and on small hand-made trees.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "plantview/rvm_import.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;

const fs::path kHuldra = fs::path(PLANTVIEW_SHARED_DIR) / "data" / "huldra";

struct Huldra {
  RvmFile rvm;
  AttributeFile attributes;
};

const Huldra* huldra() {
  static const Huldra* loaded = [] () -> const Huldra* {
    auto bytes = load_file(kHuldra / "WD1-PSUP.RVM");
    auto text = load_file(kHuldra / "WD1-PSUP.txt");
    if (!bytes || !text) return nullptr;
    auto rvm = parse_rvm(bytes.value(), "WD1-PSUP.RVM");
    const auto& t = text.value();
    auto attributes = parse_attributes(std::string_view(reinterpret_cast<const char*>(t.data()), t.size()),
                                       "WD1-PSUP.txt");
    if (!rvm || !attributes) return nullptr;
    return new Huldra{std::move(rvm).value(), std::move(attributes).value()};
  }();
  return loaded;
}

TEST(RvmImport, HuldraKeepsEveryPrimitiveInExactlyOneObject) {
  if (!fs::exists(kHuldra)) GTEST_SKIP() << "no " << kHuldra;
  ASSERT_TRUE(huldra());
  RvmImportSummary summary;
  const auto objects = rvm_to_objects(huldra()->rvm, &huldra()->attributes, "huldra", summary);
  EXPECT_EQ(summary.groups, 4084u);
  EXPECT_EQ(summary.primitives, 2757u);
  uint64_t primitives = 0;
  std::set<uint64_t> ids;
  for (const Object& o : objects) {
    primitives += o.primitives.size();
    EXPECT_TRUE(ids.insert(o.id).second) << "duplicate id for " << o.name;
  }
  EXPECT_EQ(primitives, 2757u);
  EXPECT_EQ(summary.objects, objects.size());
}

TEST(RvmImport, HuldraObjectsAreStructureWithTheirAttributes) {
  if (!fs::exists(kHuldra)) GTEST_SKIP() << "no " << kHuldra;
  ASSERT_TRUE(huldra());
  RvmImportSummary summary;
  const auto objects = rvm_to_objects(huldra()->rvm, &huldra()->attributes, "huldra", summary);
  EXPECT_GT(summary.groups_with_attributes, 4000u);
  const AttributeIndex index = index_attribute_blocks(huldra()->attributes);
  size_t structure = 0;
  for (const Object& o : objects) {
    if (o.object_class == ObjectClass::structure) ++structure;
    // Every object carries its group's attribute block, found by name, then the names of its
    // enclosing site and zone (the sample's one site holds zones only).
    const auto it = index.find(o.name);
    ASSERT_NE(it, index.end()) << o.name;
    ASSERT_FALSE(o.attributes.empty()) << o.name;
    const auto& block = it->second->attributes;
    ASSERT_EQ(o.attributes.size(), block.size() + 2) << o.name;
    for (size_t i = 0; i < block.size(); ++i) {
      EXPECT_EQ(o.attributes[i].key, block[i].first) << o.name;
      EXPECT_EQ(o.attributes[i].value, block[i].second) << o.name;
    }
    EXPECT_EQ(o.attributes[block.size()], (Attribute{"Site", "/WD1-PSUP"})) << o.name;
    EXPECT_EQ(o.attributes[block.size() + 1].key, "Zone") << o.name;
    const auto zone = index.find(o.attributes[block.size() + 1].value);
    ASSERT_NE(zone, index.end()) << o.name;
    const std::string* zone_type = zone->second->find("Type");
    ASSERT_TRUE(zone_type);
    EXPECT_EQ(*zone_type, "ZONE") << o.name;
  }
  // The sample is a pipe-support model: structure throughout.
  EXPECT_EQ(structure, objects.size());
  // Primitive elements (BOX, CYLI...) are not objects of their own.
  for (const Object& o : objects) {
    const std::string* type = index.at(o.name)->find("Type");
    ASSERT_TRUE(type);
    EXPECT_NE(*type, "BOX");
    EXPECT_NE(*type, "CYLI");
  }
}

TEST(RvmImport, WithoutAttributesEveryGroupWithPrimitivesIsAnOtherObject) {
  if (!fs::exists(kHuldra)) GTEST_SKIP() << "no " << kHuldra;
  ASSERT_TRUE(huldra());
  RvmImportSummary summary;
  const auto objects = rvm_to_objects(huldra()->rvm, nullptr, "huldra", summary);
  uint64_t primitives = 0;
  for (const Object& o : objects) {
    EXPECT_EQ(o.object_class, ObjectClass::other);
    primitives += o.primitives.size();
  }
  EXPECT_EQ(primitives, 2757u);
}

// A small pipeline: PIPE > BRAN with two flanges as groups (in flow order, as PDMS writes them)
// and two implied tubes as primitives right under the branch (listed in reverse).
TEST(RvmImport, PipelinesGetBranchesInFlowOrderWithConnectionPoints) {
  auto group = [](std::string name, std::vector<Primitive> prims) {
    RvmGroup g;
    g.name = std::move(name);
    for (Primitive& p : prims) g.primitives.push_back({std::move(p), {}, RvmGeometryRole::primitive, 0, 0});
    return g;
  };
  auto along_x = [](float x0, float length) {  // a cylinder from x0 to x0 + length along +x
    Primitive p{{glm::mat3(glm::vec3(0, 0, -1), {0, 1, 0}, {1, 0, 0}), {x0 + 0.5f * length, 0, 0}},
                Cylinder{0.1f, length}};
    return p;
  };
  RvmFile file;
  RvmGroup pipe = group("/P1", {});
  RvmGroup bran = group("/P1/B1", {});
  bran.primitives.push_back({along_x(2.1f, 3.0f), {}, RvmGeometryRole::primitive, 0, 0});
  bran.primitives.push_back({along_x(0.1f, 1.9f), {}, RvmGeometryRole::primitive, 0, 0});
  bran.children.push_back(group("/P1/B1/FLAN1", {along_x(0.0f, 0.1f)}));
  bran.children.push_back(group("/P1/B1/FLAN2", {along_x(2.0f, 0.1f)}));
  pipe.children.push_back(bran);
  file.roots.push_back(pipe);
  AttributeFile attrs;
  auto block = [](std::string name, std::string type) {
    AttributeBlock b;
    b.name = std::move(name);
    b.attributes.push_back({"Type", std::move(type)});
    return b;
  };
  attrs.blocks.push_back(block("/P1", "PIPE"));
  attrs.blocks[0].children.push_back(block("/P1/B1", "BRAN"));
  for (auto [n, t] : {std::pair{"/P1/B1/FLAN1", "FLAN"}, {"/P1/B1/FLAN2", "FLAN"}}) {
    attrs.blocks[0].children[0].children.push_back(block(n, t));
  }
  RvmImportSummary summary;
  const auto objects = rvm_to_objects(file, &attrs, "test", summary);
  ASSERT_EQ(objects.size(), 5u);
  const Object& pipeline = objects.back();
  EXPECT_EQ(pipeline.object_class, ObjectClass::pipeline);
  ASSERT_EQ(pipeline.branches.size(), 1u);
  std::vector<std::string> order;
  for (uint64_t id : pipeline.branches[0].members) {
    for (const Object& o : objects) {
      if (o.id == id) {
        order.push_back(o.name);
        EXPECT_EQ(o.pipeline_id, pipeline.id);
        EXPECT_EQ(o.connections.size(), 2u);
        EXPECT_EQ(o.centreline.size(), 1u);
      }
    }
  }
  EXPECT_EQ(order, (std::vector<std::string>{"/P1/B1/FLAN1", "/P1/B1/TUBE 2", "/P1/B1/FLAN2",
                                             "/P1/B1/TUBE 1"}));
  for (const Object& o : objects) {
    if (o.name == "/P1/B1/FLAN1") {
      EXPECT_EQ(o.object_class, ObjectClass::component);
    }
    if (o.name == "/P1/B1/TUBE 2") {
      EXPECT_EQ(o.object_class, ObjectClass::pipe);
      EXPECT_NEAR(o.connections[0].diameter_m, 0.2f, 1e-6f);
    }
  }
}

}  // namespace
}  // namespace plantview
