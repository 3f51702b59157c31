// The LMDB plant store: lossless records, indexes, replacement by source, transactions,
// snapshots, the spatial hierarchy, and survival of a killed import.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <random>
#include <set>
#include <thread>

#include "plantview/store.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("plantview-store-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::remove_all(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
  static inline int counter_ = 0;
};

// An object with every primitive kind, odd placements, attributes and piping topology.
Object sample_object(const std::string& source, const std::string& name, glm::dvec3 origin) {
  Object o;
  o.name = name;
  o.source = source;
  o.id = object_id(source, name);
  o.object_class = ObjectClass::component;
  o.colour = {10, 200, 30, 128};
  o.origin_m = origin;
  o.pipeline_id = 42;
  float x = 0;
  for (Primitive p : representative_primitives(0.3f)) {
    p.placement.translation_m = {x, 0.5f, -0.25f};
    x += 1.0f;
    o.primitives.push_back(p);
  }
  // A general rotation, a mirrored axis permutation with a scale.
  o.primitives[3].placement.linear = glm::mat3(glm::vec3(0.6f, 0.8f, 0), {-0.8f, 0.6f, 0}, {0, 0, 1});
  o.primitives[4].placement.linear = glm::mat3(glm::vec3(0, 0, -2), {2, 0, 0}, {0, 2, 0});
  o.attributes = {{"Type", "FLAN"}, {"Spec", "A1 \"150#\" & more"}, {"Bytes", std::string("\xff\x00\x80", 3)}};
  o.connections = {{{0, 0, 0}, {-1, 0, 0}, 0.3f}, {{2, 0, 0}, {1, 0, 0}, 0.3f}};
  o.centreline = {{{0, 0, 0}, {2, 0, 0}, 0.3f}};
  o.branches = {{"B1", {1, 2, 3}}};
  return o;
}

std::unique_ptr<Store> open_store(const std::string& dir, Store::Mode mode = Store::Mode::read_write) {
  std::string error;
  auto store = Store::open(dir, mode, error);
  EXPECT_TRUE(store) << error;
  return store;
}

void import_objects(Store& store, const std::vector<Object>& objects, const std::string& source) {
  std::string error;
  auto import = store.begin_import(error);
  ASSERT_TRUE(import) << error;
  ASSERT_TRUE(import->remove_source(source, error)) << error;
  for (const Object& o : objects) ASSERT_TRUE(import->put(o, error)) << error;
  ASSERT_TRUE(import->commit(error)) << error;
}

std::vector<Object> all_objects(const Store& store) {
  std::string error;
  auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  std::vector<Object> out;
  EXPECT_TRUE(view->for_each_object([&](uint32_t, Object&& o) { out.push_back(std::move(o)); return true; },
                                    true, error))
      << error;
  return out;
}

TEST(Store, ObjectsComeBackExactlyAsTheyWentIn) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects;
  for (int i = 0; i < 300; ++i) {  // enough to train a dictionary
    objects.push_back(sample_object("a.rvm", "/OBJ-" + std::to_string(i), {1000.0 * i, -5.5, 12.25}));
  }
  import_objects(*store, objects, "a.rvm");
  const std::vector<Object> back = all_objects(*store);
  ASSERT_EQ(back.size(), objects.size());
  for (size_t i = 0; i < back.size(); ++i) EXPECT_TRUE(back[i] == objects[i]) << "object " << i;
}

TEST(Store, InfoCountsObjectsPrimitivesAndTrianglesAndBounds) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects = {sample_object("a", "/A", {0, 0, 0}), sample_object("a", "/B", {100, 0, 0})};
  objects[1].object_class = ObjectClass::pipe;
  import_objects(*store, objects, "a");
  std::string error;
  const StoreInfo info = store->read(error)->info();
  const ModelStatistics expected = model_statistics(PlantModel{objects});
  EXPECT_EQ(info.format_version, kStoreFormatVersion);
  EXPECT_EQ(info.objects, 2u);
  EXPECT_EQ(info.statistics.objects_by_class[int(ObjectClass::pipe)], 1u);
  EXPECT_EQ(info.statistics.primitives, expected.primitives);
  EXPECT_EQ(info.statistics.triangles, expected.triangles);
  for (int k = 0; k < kPrimitiveKindCount; ++k) {
    EXPECT_EQ(info.statistics.primitives_by_kind[k], 2u) << kind_name(PrimitiveKind(k));
  }
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(info.statistics.bounds.min[a], expected.bounds.min[a], 1e-3);
    EXPECT_NEAR(info.statistics.bounds.max[a], expected.bounds.max[a], 1e-3);
  }
  EXPECT_GT(info.store_bytes, 0u);
}

TEST(Store, FindsObjectsByIdAndByName) {
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, {sample_object("a", "/P-1/FLAN-1", {}), sample_object("a", "/P-1/FLAN-2", {})}, "a");
  std::string error;
  auto view = store->read(error);
  const auto slots = view->slots_named("/P-1/FLAN-2");
  ASSERT_EQ(slots.size(), 1u);
  Object o;
  ASSERT_TRUE(view->object(slots[0], o, true, error)) << error;
  EXPECT_EQ(o.name, "/P-1/FLAN-2");
  EXPECT_EQ(o.attributes.size(), 3u);
  EXPECT_EQ(view->slot_of(object_id("a", "/P-1/FLAN-2")), slots[0]);
  EXPECT_TRUE(view->slots_named("/nothing").empty());
  EXPECT_FALSE(view->slot_of(12345).has_value());
}

TEST(Store, ImportingASourceAgainReplacesWhatItBroughtAndKeepsOthers) {
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, {sample_object("a", "/A1", {}), sample_object("a", "/A2", {})}, "a");
  import_objects(*store, {sample_object("b", "/B1", {})}, "b");
  import_objects(*store, {sample_object("a", "/A3", {})}, "a");
  std::set<std::string> names;
  for (const Object& o : all_objects(*store)) names.insert(o.name);
  EXPECT_EQ(names, (std::set<std::string>{"/A3", "/B1"}));
  std::string error;
  auto view = store->read(error);
  EXPECT_EQ(view->info().objects, 2u);
  EXPECT_TRUE(view->slots_named("/A1").empty());
  EXPECT_EQ(view->spatial_entries().size(), 2u);
}

TEST(Store, AnAbandonedImportLeavesTheStoreAsItWas) {
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, {sample_object("a", "/A1", {})}, "a");
  {
    std::string error;
    auto import = store->begin_import(error);
    ASSERT_TRUE(import->remove_source("a", error));
    ASSERT_TRUE(import->put(sample_object("a", "/A2", {}), error));
    // Destroyed without commit: an error part-way through an import.
  }
  const auto objects = all_objects(*store);
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0].name, "/A1");
}

TEST(Store, AReadViewIsASnapshotWhileAnImportCommits) {
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, {sample_object("a", "/A1", {})}, "a");
  std::string error;
  auto before = store->read(error);
  import_objects(*store, {sample_object("b", "/B1", {})}, "b");
  EXPECT_EQ(before->info().objects, 1u);
  EXPECT_TRUE(before->slots_named("/B1").empty());
  EXPECT_EQ(store->read(error)->info().objects, 2u);
}

TEST(Store, TheSpatialHierarchyHoldsEveryObjectInsideItsNodes) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> at(-3000, 3000);
  std::vector<Object> objects;
  for (int i = 0; i < 500; ++i) {
    Object o;
    o.name = "/O" + std::to_string(i);
    o.source = "s";
    o.id = object_id("s", o.name);
    o.origin_m = {at(rng), at(rng), at(rng) / 100};
    o.primitives.push_back({{}, Box{1, 2, 3}});
    objects.push_back(o);
  }
  import_objects(*store, objects, "s");
  std::string error;
  auto view = store->read(error);
  const auto nodes = view->spatial_nodes();
  const auto entries = view->spatial_entries();
  ASSERT_EQ(entries.size(), 500u);
  std::set<uint32_t> seen;
  // Walk from the root: every entry is reached once, inside every node above it.
  struct Item { uint32_t node; SpatialNode parent; };
  std::vector<Item> stack{{0, nodes[0]}};
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    const SpatialNode& n = nodes[item.node];
    for (int a = 0; a < 3; ++a) {
      ASSERT_GE(n.min[a], item.parent.min[a]);
      ASSERT_LE(n.max[a], item.parent.max[a]);
    }
    if (n.count == 0) {
      stack.push_back({n.first, n});
      stack.push_back({n.first + 1, n});
      continue;
    }
    for (uint32_t i = n.first; i < n.first + n.count; ++i) {
      EXPECT_TRUE(seen.insert(entries[i].slot).second);
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(entries[i].min[a], n.min[a]);
        EXPECT_LE(entries[i].max[a], n.max[a]);
      }
    }
  }
  EXPECT_EQ(seen.size(), 500u);
  // Entries contain their objects' true bounds (rounded outward).
  const glm::dvec3 origin = view->spatial_origin();
  for (const SpatialEntry& e : entries) {
    Object o;
    ASSERT_TRUE(view->object(e.slot, o, false, error));
    const DAabb b = object_bounds(o);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(origin[a] + e.min[a], b.min[a]);
      EXPECT_GE(origin[a] + e.max[a], b.max[a]);
    }
  }
}

TEST(Store, ReadOnlyOpeningOfAMissingStoreFailsWithItsPath) {
  TempDir dir;
  std::string error;
  EXPECT_FALSE(Store::open(dir.str(), Store::Mode::read_only, error));
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
}

TEST(Store, AnImportKilledPartWayLeavesExactlyTheEarlierContents) {
  TempDir dir;
  {
    auto store = open_store(dir.str());
    import_objects(*store, {sample_object("a", "/KEEP", {})}, "a");
  }
  for (int attempt = 0; attempt < 3; ++attempt) {
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      // Replaces source "a" with an endless stream of objects, never committing.
      std::string error;
      auto store = Store::open(dir.str(), Store::Mode::read_write, error);
      if (!store) _exit(3);
      auto import = store->begin_import(error);
      if (!import || !import->remove_source("a", error)) _exit(4);
      for (int i = 0;; ++i) {
        if (!import->put(sample_object("a", "/NEW-" + std::to_string(i), {}), error)) _exit(5);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(150 + 100 * attempt));
    ASSERT_EQ(kill(child, SIGKILL), 0);
    int status = 0;
    waitpid(child, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the child stopped by itself: " << WEXITSTATUS(status);
    auto store = open_store(dir.str());
    std::set<std::string> names;
    for (const Object& o : all_objects(*store)) names.insert(o.name);
    std::set<std::string> expected{"/KEEP"};
    for (int earlier = 0; earlier < attempt; ++earlier) expected.insert("/B" + std::to_string(earlier));
    EXPECT_EQ(names, expected);
    // And the store still takes imports.
    const std::string source = "b" + std::to_string(attempt);
    import_objects(*store, {sample_object(source, "/B" + std::to_string(attempt), {})}, source);
  }
}

}  // namespace
}  // namespace plantview
