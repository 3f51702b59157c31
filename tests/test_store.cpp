// The LMDB plant store: lossless records, indexes, replacement by source, transactions,
// snapshots, the spatial hierarchy, and survival of a killed import.
#include <gtest/gtest.h>
#include <lmdb.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <latch>
#include <map>
#include <random>
#include <set>
#include <span>
#include <string_view>
#include <thread>

#include "plantview/store.h"
// The store's internal encodings, for the truncation tests below.
#include "chunks.h"
#include "lmdb_guard.h"
#include "record.h"
#include "spatial.h"
#include "store_internal.h"
#include "tables.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

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

// An entry of the spatial hierarchy with its leaf and its bounds (entry_bounds()).
struct FlatEntry {
  SpatialNode leaf;
  SpatialEntry entry;
  std::array<float, 6> box;
};
// Every entry in tree order (for_each_spatial_entry).
std::vector<FlatEntry> flat_entries(const ReadView& view) {
  std::vector<FlatEntry> out;
  std::string error;
  EXPECT_TRUE(view.for_each_spatial_entry(
      [&](const SpatialNode& leaf, const SpatialEntry& entry) {
        FlatEntry f{leaf, entry, {}};
        entry_bounds(leaf, entry, f.box.data(), f.box.data() + 3);
        out.push_back(f);
        return true;
      },
      error))
      << error;
  return out;
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

// A small object: one box at `origin`, a couple of attributes.
Object box_object(const std::string& source, int i, glm::dvec3 origin) {
  Object o;
  o.name = "/BOX-" + std::to_string(i);
  o.source = source;
  o.id = object_id(source, o.name);
  o.origin_m = origin;
  o.colour = {uint8_t(i), uint8_t(i >> 8), 7, 255};
  o.primitives.push_back({{}, Box{1.0f + float(i % 7), 2, 3}});
  o.attributes = {{"Index", std::to_string(i)}, {"Source", source}};
  return o;
}

std::map<uint64_t, Object> objects_by_id(const Store& store) {
  std::map<uint64_t, Object> out;
  for (Object& o : all_objects(store)) out.emplace(o.id, std::move(o));
  return out;
}

// Every object is found by its id and its name (with the other objects of that name), at the
// slot it is read from.
// The store holds exactly `expected` (by id), each object as it went in.
void expect_objects_exactly(const Store& store, const std::map<uint64_t, Object>& expected) {
  const auto back = objects_by_id(store);
  ASSERT_EQ(back.size(), expected.size());
  for (const auto& [id, o] : expected) {
    auto it = back.find(id);
    ASSERT_NE(it, back.end()) << o.name;
    EXPECT_TRUE(it->second == o) << o.name << " of " << o.source;
  }
}

void expect_indexes_agree(const Store& store) {
  std::string error;
  auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  std::map<std::string, std::vector<uint32_t>> slots_by_name;
  size_t count = 0;
  ASSERT_TRUE(view->for_each_object(
      [&](uint32_t slot, Object&& o) {
        ++count;
        EXPECT_EQ(view->slot_of(o.id), slot) << o.name;
        slots_by_name[o.name].push_back(slot);  // in slot order, as slots_named() answers
        return true;
      },
      false, error))
      << error;
  for (const auto& [name, slots] : slots_by_name) EXPECT_EQ(view->slots_named(name), slots) << name;
  EXPECT_EQ(count, view->info().objects);
  EXPECT_EQ(view->spatial_objects(), count);
  EXPECT_EQ(flat_entries(*view).size(), count);
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
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  const StoreInfo info = view->info();
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
  EXPECT_EQ(view->spatial_objects(), 2u);
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

TEST(Store, ASiblingViewReadsItsViewsSnapshotAndNoneIsHadOnceTheStoreMovedOn) {
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, {sample_object("a", "/A1", {})}, "a");
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  auto sibling = view->sibling(error);
  ASSERT_TRUE(sibling) << error;
  // Used on another thread, as a renderer's worker does.
  std::optional<uint32_t> slot;
  Object o;
  std::thread([&] {
    std::string why;
    slot = sibling->slot_of(sample_object("a", "/A1", {}).id);
    if (slot && !sibling->object(*slot, o, false, why)) ADD_FAILURE() << why;
  }).join();
  ASSERT_TRUE(slot);
  EXPECT_EQ(o.name, "/A1");
  EXPECT_EQ(sibling->info().objects, 1u);

  import_objects(*store, {sample_object("b", "/B1", {})}, "b");
  EXPECT_TRUE(sibling->slots_named("/B1").empty()) << "a sibling keeps its snapshot";
  error.clear();
  EXPECT_FALSE(view->sibling(error)) << "the old snapshot cannot be read again";
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
  EXPECT_NE(error.find("committed"), std::string::npos) << error;
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
  ASSERT_TRUE(view) << error;
  ASSERT_EQ(view->spatial_objects(), 500u);
  std::set<uint32_t> seen;
  // Walk from the top's root into every block: every entry is reached once, inside every node
  // above it; a block's root has exactly its top leaf's bounds.
  const auto top = view->spatial_top();
  ASSERT_FALSE(top.empty());
  std::vector<FlatEntry> entries;
  struct Item { uint32_t node; SpatialNode parent; };
  std::vector<Item> top_stack{{0, top[0]}};
  while (!top_stack.empty()) {
    const Item item = top_stack.back();
    top_stack.pop_back();
    const SpatialNode& t = top[item.node];
    for (int a = 0; a < 3; ++a) {
      ASSERT_GE(t.min[a], item.parent.min[a]);
      ASSERT_LE(t.max[a], item.parent.max[a]);
    }
    if (t.count == 0) {
      top_stack.push_back({t.first, t});
      top_stack.push_back({t.first + 1, t});
      continue;
    }
    auto block = view->spatial_block(t.first, error);
    ASSERT_TRUE(block) << error;
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(block->nodes[0].min[a], t.min[a]);
      EXPECT_EQ(block->nodes[0].max[a], t.max[a]);
    }
    std::vector<Item> stack{{0, block->nodes[0]}};
    while (!stack.empty()) {
      const Item in = stack.back();
      stack.pop_back();
      const SpatialNode& n = block->nodes[in.node];
      for (int a = 0; a < 3; ++a) {
        ASSERT_GE(n.min[a], in.parent.min[a]);
        ASSERT_LE(n.max[a], in.parent.max[a]);
      }
      if (n.count == 0) {
        stack.push_back({n.first, n});
        stack.push_back({n.first + 1, n});
        continue;
      }
      for (uint32_t i = n.first; i < n.first + n.count; ++i) {
        EXPECT_TRUE(seen.insert(block->entries[i].slot).second);
        FlatEntry f{n, block->entries[i], {}};
        entry_bounds(n, f.entry, f.box.data(), f.box.data() + 3);
        for (int a = 0; a < 3; ++a) {
          EXPECT_GE(f.box[a], n.min[a]);
          EXPECT_LE(f.box[3 + a], n.max[a]);
        }
        entries.push_back(f);
      }
    }
  }
  EXPECT_EQ(seen.size(), 500u);
  // Entries contain their objects' true bounds (rounded outward), and not by much more: the
  // grid and float rounding, and two of the leaf's 1/65535 steps.
  const glm::dvec3 origin = view->spatial_origin();
  for (const FlatEntry& f : entries) {
    Object o;
    ASSERT_TRUE(view->object(f.entry.slot, o, false, error));
    const DAabb b = object_bounds(o);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(origin[a] + f.box[a], b.min[a]);
      EXPECT_GE(origin[a] + f.box[3 + a], b.max[a]);
      const double slack_m = 0.002 + 2.0 * (f.leaf.max[a] - f.leaf.min[a]) / 65535;
      EXPECT_NEAR(origin[a] + f.box[a], b.min[a], slack_m);
      EXPECT_NEAR(origin[a] + f.box[3 + a], b.max[a], slack_m);
    }
  }
}

TEST(Store, ObjectsOnEitherSideOfChunkAndBlockBoundariesComeBack) {
  TempDir dir;
  auto store = open_store(dir.str());
  // 4100 objects fill object chunks (64 slots) and attribute chunks (256) and spill into the
  // next; imports of odd sizes then append to partly filled ones.
  std::vector<Object> first;
  for (int i = 0; i < 4100; ++i) first.push_back(box_object("a", i, {i * 3.0, 0, 0}));
  import_objects(*store, first, "a");
  std::map<uint64_t, Object> expected;
  for (const Object& o : first) expected.emplace(o.id, o);
  for (int round = 0; round < 3; ++round) {
    const std::string source = "b" + std::to_string(round);
    std::vector<Object> more;
    for (int i = 0; i < 61 + 100 * round; ++i) more.push_back(box_object(source, i, {0, i * 2.0, round}));
    import_objects(*store, more, source);
    for (const Object& o : more) expected.emplace(o.id, o);
  }
  ASSERT_NO_FATAL_FAILURE(expect_objects_exactly(*store, expected));
  // Slots read one by one across the boundaries (the view's chunk cache misses and hits).
  std::string error;
  auto view = store->read(error);
  for (uint32_t slot : {0u, 63u, 64u, 255u, 256u, 2047u, 2048u, 4095u, 4096u, 4099u, 63u, 2048u}) {
    Object o;
    ASSERT_TRUE(view->object(slot, o, true, error)) << error;
    EXPECT_EQ(o.name, "/BOX-" + std::to_string(slot)) << slot;
    EXPECT_EQ(o.attributes[0].value, std::to_string(slot));
  }
  Object none;
  EXPECT_FALSE(view->object(4100 + 1000, none, false, error));
  EXPECT_NE(error.find("slot 5100"), std::string::npos) << error;
  expect_indexes_agree(*store);
}

TEST(Store, ReplacingAnObjectInTheMiddleOfAChunkKeepsItsNeighbours) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects;
  for (int i = 0; i < 200; ++i) objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  import_objects(*store, objects, "a");
  std::string error;
  const uint32_t old_slot = store->read(error)->slot_of(objects[100].id).value();
  // Same id, new content, without removing the source: the object is replaced where it is.
  Object changed = objects[100];
  changed.colour = {1, 2, 3, 4};
  changed.origin_m = {-50, 10, 10};
  {
    auto import = store->begin_import(error);
    ASSERT_TRUE(import->put(changed, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  auto view = store->read(error);
  EXPECT_EQ(view->info().objects, 200u);
  const auto slot = view->slot_of(changed.id);
  ASSERT_TRUE(slot.has_value());
  EXPECT_NE(*slot, old_slot);
  EXPECT_EQ(view->slots_named(changed.name), std::vector<uint32_t>{*slot});
  Object o;
  EXPECT_FALSE(view->object(old_slot, o, false, error));
  ASSERT_TRUE(view->object(*slot, o, true, error)) << error;
  EXPECT_TRUE(o == changed);
  for (int neighbour : {99, 101, 0, 63, 64, 199}) {
    const auto s = view->slot_of(objects[neighbour].id);
    ASSERT_TRUE(s.has_value());
    ASSERT_TRUE(view->object(*s, o, true, error)) << error;
    EXPECT_TRUE(o == objects[neighbour]) << neighbour;
  }
  // The replacement's bounds are in the spatial index, the old ones are not.
  size_t entries_for_slot = 0;
  for (const FlatEntry& f : flat_entries(*view)) {
    EXPECT_NE(f.entry.slot, old_slot);
    if (f.entry.slot == *slot) {
      ++entries_for_slot;
      EXPECT_LE(view->spatial_origin().x + f.box[0], -50.0);
    }
  }
  EXPECT_EQ(entries_for_slot, 1u);
  expect_indexes_agree(*store);
}

TEST(Store, EveryImportChangesTheCommitIdAndTheSameImportsGiveTheSameId) {
  TempDir a, b;
  auto first = open_store(a.str()), second = open_store(b.str());
  std::string error;
  EXPECT_EQ(first->read(error)->info().commit_id, 0u) << "nothing committed yet";
  std::vector<Object> objects;
  for (int i = 0; i < 100; ++i) objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  import_objects(*first, objects, "a");
  import_objects(*second, objects, "a");
  const uint64_t imported = first->read(error)->info().commit_id;
  EXPECT_NE(imported, 0u);
  EXPECT_EQ(second->read(error)->info().commit_id, imported) << "the same imports, the same id";

  // Recoloured: every count and the bounds stay, the commit id does not.
  Object recoloured = objects[40];
  recoloured.colour = {1, 2, 3, 255};
  const auto put = [&](Store& store, const Object& o) {
    auto import = store.begin_import(error);
    ASSERT_TRUE(import->put(o, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  };
  put(*first, recoloured);
  const StoreInfo after = first->read(error)->info();
  EXPECT_EQ(statistics_json(after.statistics),
            statistics_json(second->read(error)->info().statistics));
  EXPECT_NE(after.commit_id, imported);
  // Put back as it was: the content equals the second store's, but the history does not, so
  // the id differs from both earlier ones (it never comes back).
  put(*first, objects[40]);
  const uint64_t restored = first->read(error)->info().commit_id;
  EXPECT_NE(restored, imported);
  EXPECT_NE(restored, after.commit_id);
  // An import that fails leaves the id as it was; the id survives reopening.
  {
    auto import = first->begin_import(error);
    Object no_id = objects[0];
    no_id.id = 0;
    EXPECT_FALSE(import->put(no_id, error));
  }
  EXPECT_EQ(first->read(error)->info().commit_id, restored);
  first.reset();
  EXPECT_EQ(open_store(a.str())->read(error)->info().commit_id, restored);
}

TEST(Store, ReplacingASourceKeepsAnotherSourcesObjectsInTheSameChunks) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> a, b;
  {
    // Interleaved: every chunk holds objects of both sources.
    std::string error;
    auto import = store->begin_import(error);
    for (int i = 0; i < 300; ++i) {
      a.push_back(box_object("a", i, {i * 1.0, 0, 0}));
      b.push_back(box_object("b", i, {i * 1.0, 5, 0}));
      ASSERT_TRUE(import->put(a.back(), error)) << error;
      ASSERT_TRUE(import->put(b.back(), error)) << error;
    }
    ASSERT_TRUE(import->commit(error)) << error;
  }
  std::vector<Object> a2;
  for (int i = 0; i < 50; ++i) a2.push_back(box_object("a", 1000 + i, {i * 1.0, -5, 0}));
  import_objects(*store, a2, "a");

  std::map<uint64_t, Object> expected;
  for (const Object& o : b) expected.emplace(o.id, o);
  for (const Object& o : a2) expected.emplace(o.id, o);
  ASSERT_NO_FATAL_FAILURE(expect_objects_exactly(*store, expected));
  std::string error;
  auto view = store->read(error);
  EXPECT_EQ(view->info().objects, 350u);
  EXPECT_EQ(view->info().statistics.primitives, 350u);
  EXPECT_FALSE(view->slot_of(a[0].id).has_value());
  EXPECT_TRUE(view->slots_named("/BOX-1001").size() == 1);
  // "/BOX-5" now names only b's object.
  const auto named = view->slots_named("/BOX-5");
  ASSERT_EQ(named.size(), 1u);
  EXPECT_EQ(view->slot_of(b[5].id), named[0]);
  expect_indexes_agree(*store);

  // Removing b altogether leaves a's new objects.
  import_objects(*store, {}, "b");
  EXPECT_EQ(objects_by_id(*store).size(), 50u);
  expect_indexes_agree(*store);
}

TEST(Store, AnImportTouchingMoreBlocksThanItHoldsInMemoryReplacesASource) {
  TempDir dir;
  auto store = open_store(dir.str());
  // 70000 objects span 1094 object chunks, more than an import keeps decoded at once.
  std::vector<Object> objects;
  for (int i = 0; i < 70000; ++i) {
    Object o = box_object("big", i, {i % 400, i / 400, 0});
    o.attributes.clear();
    objects.push_back(std::move(o));
  }
  import_objects(*store, objects, "big");
  import_objects(*store, {box_object("other", 0, {})}, "other");
  std::vector<Object> again(objects.begin() + 1000, objects.begin() + 1100);
  import_objects(*store, again, "big");
  std::string error;
  auto view = store->read(error);
  EXPECT_EQ(view->info().objects, 101u);
  EXPECT_FALSE(view->slot_of(objects[0].id).has_value());
  EXPECT_FALSE(view->slot_of(objects[69999].id).has_value());
  const auto slot = view->slot_of(objects[1050].id);
  ASSERT_TRUE(slot.has_value());
  Object o;
  ASSERT_TRUE(view->object(*slot, o, true, error)) << error;
  EXPECT_TRUE(o == objects[1050]);
  expect_indexes_agree(*store);
}

// Lookups are built per committed state, on first use: after objects are replaced and removed,
// a new view finds them where they are now, and a view from before (whose tables are built only
// after the import) still finds them where they were.
TEST(Store, LookupsFollowReplacementsAndRemovalsAndOldViewsKeepTheirState) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> a, b;
  for (int i = 0; i < 150; ++i) a.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  for (int i = 0; i < 150; ++i) b.push_back(box_object("b", i, {i * 1.0, 9, 0}));
  import_objects(*store, a, "a");
  import_objects(*store, b, "b");
  std::string error;
  auto early = store->read(error);  // builds its id lookup now, its name lookup only later
  ASSERT_TRUE(early) << error;
  const uint32_t a7 = early->slot_of(a[7].id).value();
  const uint32_t b7 = early->slot_of(b[7].id).value();

  // Source a again with one object fewer and one changed; b's object 7 replaced in place.
  std::vector<Object> a2(a.begin(), a.end() - 1);
  a2[7].colour = {9, 9, 9, 9};
  import_objects(*store, a2, "a");
  Object b7_changed = b[7];
  b7_changed.origin_m = {-20, -20, 0};
  {
    auto import = store->begin_import(error);
    ASSERT_TRUE(import->put(b7_changed, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }

  auto now = store->read(error);
  ASSERT_TRUE(now) << error;
  EXPECT_FALSE(now->slot_of(a.back().id).has_value());
  EXPECT_TRUE(now->slots_named(a.back().name).size() == 1);  // b's object of that name is left
  const auto a7_now = now->slot_of(a[7].id);
  const auto b7_now = now->slot_of(b[7].id);
  ASSERT_TRUE(a7_now && b7_now);
  EXPECT_NE(*a7_now, a7);
  EXPECT_NE(*b7_now, b7);
  EXPECT_EQ(now->slots_named("/BOX-7"), (std::vector<uint32_t>{std::min(*a7_now, *b7_now),
                                                               std::max(*a7_now, *b7_now)}));
  Object o;
  ASSERT_TRUE(now->object(*b7_now, o, true, error)) << error;
  EXPECT_TRUE(o == b7_changed);
  EXPECT_FALSE(now->object(b7, o, false, error));
  expect_indexes_agree(*store);

  // The early view: its own state, with the name lookup built from it after the imports.
  EXPECT_EQ(early->slot_of(a[7].id), a7);
  EXPECT_EQ(early->slot_of(a.back().id), early->slots_named(a.back().name).front());
  EXPECT_EQ(early->slots_named("/BOX-7"), (std::vector<uint32_t>{a7, b7}));
  ASSERT_TRUE(early->object(b7, o, true, error)) << error;
  EXPECT_TRUE(o == b[7]);
  std::optional<uint32_t> slot;
  ASSERT_TRUE(early->slot_of(a[7].id, slot, error)) << error;
  EXPECT_EQ(slot, a7);
  ASSERT_TRUE(now->slot_of(12345, slot, error)) << error;
  EXPECT_FALSE(slot.has_value());
}

TEST(Store, ForEachObjectVisitsLiveSlotsInOrderAndSkipsEmptiedOnes) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> a, b;
  for (int i = 0; i < 100; ++i) a.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  for (int i = 0; i < 100; ++i) b.push_back(box_object("b", i, {i * 1.0, 5, 0}));
  import_objects(*store, a, "a");  // slots 0-99
  import_objects(*store, b, "b");  // slots 100-199
  // Replace a's object 3 (slot 3 empties, the object moves to slot 200), then remove b: the
  // highest slot in use is 200, with 100-199 empty below it.
  {
    std::string error;
    auto import = store->begin_import(error);
    Object changed = a[3];
    changed.colour = {1, 1, 1, 1};
    ASSERT_TRUE(import->put(changed, error)) << error;
    ASSERT_TRUE(import->remove_source("b", error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  std::vector<uint32_t> slots;
  std::vector<std::string> names;
  ASSERT_TRUE(view->for_each_object(
      [&](uint32_t slot, Object&& o) {
        slots.push_back(slot);
        names.push_back(o.name);
        return true;
      },
      false, error))
      << error;
  std::vector<uint32_t> expected;
  for (uint32_t s = 0; s < 100; ++s) {
    if (s != 3) expected.push_back(s);
  }
  expected.push_back(200);
  EXPECT_EQ(slots, expected);
  EXPECT_EQ(names.back(), "/BOX-3");
  for (uint32_t empty : {3u, 100u, 199u, 201u, 5000u}) {
    Object o;
    EXPECT_FALSE(view->object(empty, o, false, error)) << empty;
    EXPECT_NE(error.find("no object in slot " + std::to_string(empty)), std::string::npos) << error;
  }
  // It stops when asked to.
  size_t visited = 0;
  ASSERT_TRUE(view->for_each_object([&](uint32_t, Object&&) { return ++visited < 5; }, false, error));
  EXPECT_EQ(visited, 5u);
  expect_indexes_agree(*store);
}

// An object's key (id and pipeline id) read from its record's first bytes is the decoded
// object's, for every live slot; an empty slot gives object()'s error; and a record cut short
// anywhere before the pipeline id is refused with a message, never misread.
TEST(Store, AnObjectsKeyIsItsRecordsIdAndPipelineAndAnEmptySlotHasNone) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects;
  for (int i = 0; i < 70; ++i) {  // two chunks of 64 slots
    objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
    objects.back().pipeline_id = i % 3 ? 1000u + uint64_t(i / 10) : 0u;
  }
  import_objects(*store, objects, "a");
  {
    std::string error;
    auto import = store->begin_import(error);
    Object changed = objects[3];  // slot 3 empties, the object moves to slot 70
    changed.colour = {1, 1, 1, 1};
    ASSERT_TRUE(import->put(changed, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  for (uint32_t slot = 0; slot <= 70; ++slot) {
    uint64_t id = 0, pipeline_id = 0;
    if (slot == 3) {
      EXPECT_FALSE(view->object_key(slot, id, pipeline_id, error));
      EXPECT_NE(error.find("no object in slot 3"), std::string::npos) << error;
      continue;
    }
    Object o;
    ASSERT_TRUE(view->object(slot, o, false, error)) << error;
    ASSERT_TRUE(view->object_key(slot, id, pipeline_id, error)) << error;
    EXPECT_EQ(id, o.id) << slot;
    EXPECT_EQ(pipeline_id, o.pipeline_id) << slot;
  }

  using namespace detail;
  Object o = objects[1];
  o.name = "/a name of some length";
  o.source = "a source";
  std::vector<uint8_t> record;
  encode_object(o, record);
  // version, class, colour, id, origin, name, source, pipeline id
  const size_t key_bytes = 1 + 1 + 4 + 8 + 24 + 4 + o.name.size() + 4 + o.source.size() + 8;
  for (size_t n = 0; n <= record.size(); ++n) {
    uint64_t id = 0, pipeline_id = 0;
    error.clear();
    const bool read = decode_object_key(record.data(), n, id, pipeline_id, error);
    EXPECT_EQ(read, n >= key_bytes) << n;
    if (read) {
      EXPECT_EQ(id, o.id);
      EXPECT_EQ(pipeline_id, o.pipeline_id);
    } else {
      EXPECT_NE(error.find("truncated"), std::string::npos) << n << ": " << error;
    }
  }
  record[0] += 1;  // another layout
  uint64_t id = 0, pipeline_id = 0;
  EXPECT_FALSE(decode_object_key(record.data(), record.size(), id, pipeline_id, error));
  EXPECT_NE(error.find("record layout"), std::string::npos) << error;
}

// A pass over one class yields exactly that class's objects, in slot order, as they are
// (removed ones skipped), and their attributes when asked; the other records are not decoded.
TEST(Store, APassOverOneClassYieldsExactlyItsObjectsInSlotOrder) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects;
  for (int i = 0; i < 300; ++i) {
    Object o = box_object("a", i, {i * 1.0, 0, 0});
    o.object_class = ObjectClass(i % kObjectClassCount);
    objects.push_back(std::move(o));
  }
  import_objects(*store, objects, "a");
  // Replacing some equipment leaves their old slots empty.
  std::vector<Object> again;
  for (int i = 0; i < 30; i += kObjectClassCount) again.push_back(objects[size_t(i)]);
  for (Object& o : again) o.colour.r = 200;
  {
    std::string error;
    auto import = store->begin_import(error);
    ASSERT_TRUE(import) << error;
    for (const Object& o : again) ASSERT_TRUE(import->put(o, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_EQ(view->slot_count(), 300u + again.size());
  for (int c = 0; c < kObjectClassCount; ++c) {
    std::vector<std::pair<uint32_t, Object>> all, of_class;
    ASSERT_TRUE(view->for_each_object(
        [&](uint32_t slot, Object&& o) {
          if (o.object_class == ObjectClass(c)) all.emplace_back(slot, std::move(o));
          return true;
        },
        true, error)) << error;
    ASSERT_TRUE(view->for_each_object_of_class(
        ObjectClass(c),
        [&](uint32_t slot, Object&& o) {
          of_class.emplace_back(slot, std::move(o));
          return true;
        },
        true, error)) << error;
    ASSERT_EQ(of_class.size(), 50u) << c;
    ASSERT_EQ(of_class.size(), all.size());
    for (size_t k = 0; k < all.size(); ++k) {
      EXPECT_EQ(of_class[k].first, all[k].first);
      EXPECT_EQ(of_class[k].second.id, all[k].second.id);
      EXPECT_EQ(of_class[k].second.object_class, ObjectClass(c));
      EXPECT_EQ(of_class[k].second.colour.r, all[k].second.colour.r);
      EXPECT_EQ(of_class[k].second.attributes, all[k].second.attributes);
      if (k > 0) {
        EXPECT_LT(of_class[k - 1].first, of_class[k].first);
      }
    }
  }
  // The replaced equipment comes once, from its new slot.
  size_t recoloured = 0;
  ASSERT_TRUE(view->for_each_object_of_class(
      ObjectClass::equipment,
      [&](uint32_t slot, Object&& o) {
        if (o.colour.r == 200) {
          ++recoloured;
          EXPECT_GE(slot, 300u);
        }
        return true;
      },
      false, error)) << error;
  EXPECT_EQ(recoloured, again.size());
  // It stops when asked to.
  size_t visited = 0;
  ASSERT_TRUE(view->for_each_object_of_class(
      ObjectClass::pipe, [&](uint32_t, Object&&) { return ++visited < 3; }, false, error));
  EXPECT_EQ(visited, 3u);
}

// Views of one committed state share its lookups, which the first caller builds: two threads
// asking at once both get every answer right (run under the sanitizers too).
TEST(Store, TwoThreadsLookUpSlotsOnViewsOfTheSameStateAtOnce) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects;
  for (int i = 0; i < 5000; ++i) objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  import_objects(*store, objects, "a");
  std::map<uint64_t, uint32_t> expected;
  {
    std::string error;
    auto view = store->read(error);
    ASSERT_TRUE(view->for_each_object(
        [&](uint32_t slot, Object&& o) {
          expected[o.id] = slot;
          return true;
        },
        false, error))
        << error;
  }
  // Objects were read before any lookup: the lookups of this state are not built yet.
  std::latch start(2);
  auto look_up = [&](size_t& wrong) {
    std::string error;
    auto view = store->read(error);  // each thread a view of its own
    start.arrive_and_wait();
    if (!view) {
      ++wrong;
      return;
    }
    for (int i = 0; i < 5000; i += 7) {
      const Object& o = objects[i];
      if (view->slot_of(o.id) != expected[o.id]) ++wrong;
      if (view->slots_named(o.name) != std::vector<uint32_t>{expected[o.id]}) ++wrong;
    }
  };
  size_t wrong_a = 0, wrong_b = 0;
  std::thread a(look_up, std::ref(wrong_a)), b(look_up, std::ref(wrong_b));
  a.join();
  b.join();
  EXPECT_EQ(wrong_a, 0u);
  EXPECT_EQ(wrong_b, 0u);
}

// The stored spatial blocks' grid boxes by slot (no Store open on `dir`).
std::map<uint32_t, std::array<int32_t, 6>> stored_grid_boxes(const std::string& dir) {
  std::map<uint32_t, std::array<int32_t, 6>> out;
  MDB_env* env = nullptr;
  EXPECT_EQ(mdb_env_create(&env), MDB_SUCCESS);
  mdb_env_set_maxdbs(env, 12);
  EXPECT_EQ(mdb_env_open(env, dir.c_str(), MDB_RDONLY, 0644), MDB_SUCCESS);
  MDB_txn* txn = nullptr;
  MDB_dbi meta, blocks;
  EXPECT_EQ(mdb_txn_begin(env, nullptr, MDB_RDONLY, &txn), MDB_SUCCESS);
  EXPECT_EQ(mdb_dbi_open(txn, "meta", 0, &meta), MDB_SUCCESS);
  MDB_val k{11, const_cast<char*>("spatial_top")}, v;
  EXPECT_EQ(mdb_get(txn, meta, &k, &v), MDB_SUCCESS);
  std::vector<uint8_t> raw;
  std::string error;
  detail::ZstdDCtx dctx(ZSTD_createDCtx());
  EXPECT_TRUE(detail::inflate_frame(dctx.get(), {static_cast<const uint8_t*>(v.mv_data), v.mv_size}, raw, error));
  detail::DecodedTop top;
  EXPECT_TRUE(detail::decode_top(raw.data(), raw.size(), top, error)) << error;
  EXPECT_EQ(mdb_dbi_open(txn, top.database == 0 ? "spatial_a" : "spatial_b", 0, &blocks), MDB_SUCCESS);
  for (uint32_t b = 0; b < top.block_entries.size(); ++b) {
    const detail::Key32 key(b);
    MDB_val bk = key.val(), bv;
    EXPECT_EQ(mdb_get(txn, blocks, &bk, &bv), MDB_SUCCESS);
    EXPECT_TRUE(detail::inflate_frame(dctx.get(), {static_cast<const uint8_t*>(bv.mv_data), bv.mv_size}, raw, error));
    std::vector<detail::BlockEntry> entries;
    EXPECT_TRUE(detail::decode_block(raw.data(), raw.size(), entries, error)) << error;
    for (const auto& e : entries) {
      out[e.grid.slot] = {e.grid.min[0], e.grid.min[1], e.grid.min[2], e.grid.max[0], e.grid.max[1], e.grid.max[2]};
    }
  }
  mdb_txn_abort(txn);
  mdb_env_close(env);
  return out;
}

// What is stored does not move when the index is rebuilt (readers' boxes are quantised within
// their leaf, whose members may change, but always contain the stored ones).
TEST(Store, SpatialBoundsDoNotDriftWhenOtherSourcesAreReimported) {
  TempDir dir;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> at(-300, 300);
  std::vector<Object> objects;
  for (int i = 0; i < 100; ++i) objects.push_back(box_object("a", i, {at(rng), at(rng), at(rng)}));
  import_objects(*open_store(dir.str()), objects, "a");
  const auto before = stored_grid_boxes(dir.str());
  ASSERT_EQ(before.size(), 100u);
  {
    auto store = open_store(dir.str());
    for (int round = 0; round < 5; ++round) {
      import_objects(*store, {box_object("b", round, {at(rng), at(rng), at(rng)})}, "b");
    }
  }
  auto after = stored_grid_boxes(dir.str());
  for (const auto& [slot, bounds] : before) EXPECT_EQ(after[slot], bounds) << "slot " << slot;
}

TEST(Store, AnObjectBeyondTheSpatialGridIsRefusedNamingItsSlot) {
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, {box_object("a", 0, {})}, "a");
  std::string error;
  auto import = store->begin_import(error);
  EXPECT_FALSE(import->put(box_object("far", 1, {1e10, 0, 0}), error));
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
  EXPECT_NE(error.find("slot 1"), std::string::npos) << error;
  import.reset();
  EXPECT_EQ(objects_by_id(*store).size(), 1u);
}

// Replaces every occurrence of `from` in the file with `to` (same length); returns how many.
int patch_file(const fs::path& path, const std::string& from, const std::string& to) {
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  int count = 0;
  for (size_t at = bytes.find(from); at != std::string::npos; at = bytes.find(from, at + 1)) {
    bytes.replace(at, to.size(), to);
    ++count;
  }
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  return count;
}

TEST(Store, AStoreOfAnotherFormatVersionIsRefusedNotMisread) {
  TempDir dir;
  {
    auto store = open_store(dir.str());
    import_objects(*store, {sample_object("a", "/A", {})}, "a");
  }
  // meta/"format" holds the version right after its key; make it version 1.
  std::string current("format\0\0\0\0", 10), old("format\x01\0\0\0", 10);
  const uint32_t version = kStoreFormatVersion;
  std::memcpy(current.data() + 6, &version, 4);
  ASSERT_GE(patch_file(fs::path(dir.str()) / "data.mdb", current, old), 1);
  for (auto mode : {Store::Mode::read_only, Store::Mode::read_write}) {
    std::string error;
    EXPECT_FALSE(Store::open(dir.str(), mode, error));
    EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
    EXPECT_NE(error.find("has format 1; this build reads format " +
                         std::to_string(kStoreFormatVersion)), std::string::npos) << error;
  }
}

// Format 5 keeps each chunk of records in an LMDB value of its own, keyed by its first slot and
// cut by compressed bytes: every value but the last of its span fills the two pages it takes to
// within a few percent (so that LMDB's rounding to whole pages costs little), and the chunks
// cover every slot once, in order, without crossing a span.
TEST(Store, EachChunkOfRecordsFillsTwoPagesAndTheChunksCoverEverySlotOnce) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 20000; ++i) objects.push_back(box_object("a", i, {i * 3.0, 0, 0}));
  {
    auto store = open_store(dir.str());
    import_objects(*store, objects, "a");
  }
  MDB_env* env = nullptr;
  ASSERT_EQ(mdb_env_create(&env), MDB_SUCCESS);
  mdb_env_set_maxdbs(env, 12);
  ASSERT_EQ(mdb_env_open(env, dir.str().c_str(), MDB_RDONLY, 0644), MDB_SUCCESS);
  MDB_txn* txn = nullptr;
  ASSERT_EQ(mdb_txn_begin(env, nullptr, MDB_RDONLY, &txn), MDB_SUCCESS);
  MDB_stat stat;
  ASSERT_EQ(mdb_env_stat(env, &stat), MDB_SUCCESS);
  const size_t budget = detail::chunk_frame_budget(stat.ms_psize, 2) + 4;  // the whole value
  for (const auto& [database, shape] :
       {std::pair<const char*, detail::ColumnShape>{"objects", detail::kObjectShape},
        {"attributes", detail::kAttributeShape}}) {
    MDB_dbi dbi;
    ASSERT_EQ(mdb_dbi_open(txn, database, 0, &dbi), MDB_SUCCESS);
    MDB_cursor* cursor = nullptr;
    ASSERT_EQ(mdb_cursor_open(txn, dbi, &cursor), MDB_SUCCESS);
    MDB_val k, v;
    uint64_t next = 0;  // the first slot no chunk so far holds
    size_t values = 0, full = 0;
    for (int rc = mdb_cursor_get(cursor, &k, &v, MDB_FIRST); rc == MDB_SUCCESS;
         rc = mdb_cursor_get(cursor, &k, &v, MDB_NEXT)) {
      ASSERT_EQ(k.mv_size, 4u);
      const uint32_t first = detail::read_be32(k.mv_data);
      uint32_t count = 0;
      std::span<const uint8_t> frame;
      std::string error;
      ASSERT_TRUE(detail::split_chunk_value(static_cast<const uint8_t*>(v.mv_data), v.mv_size,
                                            count, frame, error)) << error;
      EXPECT_EQ(first, next) << database;  // every slot holds an object: no gaps
      EXPECT_EQ(first / shape.span_slots, (first + count - 1) / shape.span_slots) << database;
      next = uint64_t(first) + count;
      EXPECT_LE(v.mv_size, budget) << database << " chunk at " << first;
      ++values;
      if (v.mv_size + budget / 16 >= budget) ++full;
    }
    mdb_cursor_close(cursor);
    EXPECT_EQ(next, objects.size()) << database;
    // Every value fills its pages but the last of each span (20000 slots: 5 object spans, 2
    // attribute spans).
    const size_t spans = (objects.size() + shape.span_slots - 1) / shape.span_slots;
    EXPECT_GE(full + spans, values) << database;
    EXPECT_GT(values, spans) << database;
  }
  mdb_txn_abort(txn);
  mdb_env_close(env);
}

// Records of every size cut into chunks: a record bigger than the budget is a chunk of its own;
// a chunk whose frame is exactly the budget is kept whole, one byte less splits it; empty slots
// lead no chunk; and the chunks give back every record.
TEST(StoreChunks, ChunksAreCutAtTheBudgetAndGiveBackEveryRecord) {
  using namespace detail;
  const ZstdCCtx cctx = make_compressor();
  const ZstdDCtx dctx{ZSTD_createDCtx()};
  std::mt19937 random(7);
  // Records of 0 (none) to 300 bytes of half-random text, and now and then one of 20 KB of noise.
  std::vector<std::vector<uint8_t>> records(3000);
  for (size_t i = 0; i < records.size(); ++i) {
    if (i % 13 == 5 || i < 3) continue;  // empty slots, the first three among them
    const size_t n = i % 397 == 100 ? 20000 : 20 + random() % 280;
    for (size_t b = 0; b < n; ++b)
      records[i].push_back(uint8_t(n > 10000 || b % 3 == 0 ? random() : 'a' + b % 7));
  }
  const auto flat = [](const std::vector<std::vector<uint8_t>>& rs, size_t begin, size_t end,
                       std::vector<uint32_t>& sizes, std::vector<uint8_t>& bytes) {
    sizes.clear();
    bytes.clear();
    for (size_t i = begin; i < end; ++i) {
      sizes.push_back(uint32_t(rs[i].size()));
      bytes.insert(bytes.end(), rs[i].begin(), rs[i].end());
    }
  };
  std::vector<uint32_t> sizes;
  std::vector<uint8_t> bytes;
  flat(records, 0, records.size(), sizes, bytes);
  const size_t budget = chunk_frame_budget(4096, 2);
  std::vector<ChunkValue> chunks;
  std::string error;
  ASSERT_TRUE(cut_chunks(cctx.get(), 1000, sizes, bytes, budget, chunks, error)) << error;
  ASSERT_GT(chunks.size(), 5u);
  std::vector<std::vector<uint8_t>> back(records.size());
  uint64_t next = 0;
  for (const ChunkValue& c : chunks) {
    uint32_t count = 0;
    std::span<const uint8_t> frame;
    ASSERT_TRUE(split_chunk_value(c.value.data(), c.value.size(), count, frame, error)) << error;
    ASSERT_GE(c.first_slot, 1000 + next);
    const uint32_t at = c.first_slot - 1000;
    for (uint64_t s = next; s < at; ++s) EXPECT_TRUE(records[s].empty()) << s;
    EXPECT_FALSE(records[at].empty()) << "a chunk leads with an empty slot " << at;
    std::vector<uint8_t> layout;
    std::vector<uint32_t> ends;
    ASSERT_TRUE(inflate_frame(dctx.get(), frame, layout, error)) << error;
    ASSERT_TRUE(check_chunk(layout, count, ends, error)) << error;
    for (uint32_t i = 0; i < count; ++i) {
      const auto r = chunk_record(layout, ends, i);
      back[at + i].assign(r.begin(), r.end());
    }
    if (frame.size() > budget) {
      EXPECT_EQ(count, 1u) << "only a record alone may be over the budget, at " << at;
      EXPECT_GT(records[at].size(), budget);
    }
    next = uint64_t(at) + count;
  }
  EXPECT_EQ(back, records);

  // A chunk exactly full: the first 40 records' frame is the budget; they are one chunk, and
  // with one byte less of budget they are not.
  flat(records, 3, 43, sizes, bytes);
  std::vector<uint8_t> layout, frame;
  pack_chunk(sizes, bytes, layout);
  ASSERT_TRUE(compress_frame(cctx.get(), layout, frame, error)) << error;
  for (size_t exact : {frame.size(), frame.size() - 1}) {
    chunks.clear();
    ASSERT_TRUE(cut_chunks(cctx.get(), 0, sizes, bytes, exact, chunks, error)) << error;
    uint32_t count = 0;
    std::span<const uint8_t> first_frame;
    ASSERT_TRUE(split_chunk_value(chunks[0].value.data(), chunks[0].value.size(), count,
                                  first_frame, error)) << error;
    if (exact == frame.size()) {
      EXPECT_EQ(chunks.size(), 1u);
      EXPECT_EQ(count, 40u);
      EXPECT_EQ(first_frame.size(), exact);
    } else {
      EXPECT_GE(chunks.size(), 2u);
      EXPECT_LT(count, 40u);
      EXPECT_LE(first_frame.size(), exact);
    }
  }
  // Nothing but empty slots: no chunk.
  chunks.clear();
  const std::vector<uint32_t> empty(50, 0);
  ASSERT_TRUE(cut_chunks(cctx.get(), 0, empty, {}, budget, chunks, error)) << error;
  EXPECT_TRUE(chunks.empty());
}

// Records bigger than a page and imports that add and remove sources in turn, over span and
// chunk boundaries: every slot reads back as the last import left it.
TEST(Store, EverySlotReadsBackAfterImportsThatAddAndRemoveSources) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::map<uint64_t, Object> expected;
  std::mt19937 random(11);
  const auto make = [&](const std::string& source, int count) {
    std::vector<Object> objects;
    for (int i = 0; i < count; ++i) {
      Object o = box_object(source, i, {i * 2.0, double(source.size()), 0});
      // Now and then a name bigger than a page, which makes its record a chunk of its own.
      if (random() % 500 == 0) {
        o.name += "-";
        for (int c = 0; c < 9000; ++c) o.name += char('a' + random() % 26);
      }
      objects.push_back(std::move(o));
    }
    return objects;
  };
  const std::vector<std::pair<std::string, int>> rounds = {
      {"a", 5000}, {"b", 3000}, {"a", 1000}, {"c", 4500}, {"b", 0}, {"d", 200}, {"c", 4600}};
  std::map<std::string, std::vector<Object>> by_source;
  for (const auto& [source, count] : rounds) {
    by_source[source] = make(source, count);
    import_objects(*store, by_source[source], source);
    expected.clear();
    for (const auto& [s, objects] : by_source) {
      for (const Object& o : objects) expected.emplace(o.id, o);
    }
    ASSERT_NO_FATAL_FAILURE(expect_objects_exactly(*store, expected)) << source;
  }
  expect_indexes_agree(*store);
  // Slot by slot, backwards (every lookup a miss of the view's cache), against a pass in order.
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  std::map<uint32_t, uint64_t> in_order;
  ASSERT_TRUE(view->for_each_object([&](uint32_t slot, Object&& o) {
    in_order[slot] = o.id;
    return true;
  }, false, error)) << error;
  EXPECT_EQ(in_order.size(), expected.size());
  for (uint32_t slot = view->slot_count(); slot-- > 0;) {
    Object o;
    const bool found = view->object(slot, o, true, error);
    const auto it = in_order.find(slot);
    ASSERT_EQ(found, it != in_order.end()) << slot << ": " << error;
    if (found) {
      EXPECT_EQ(o.id, it->second) << slot;
      EXPECT_TRUE(o == expected.at(o.id)) << slot;
    }
  }
}

// A store of an earlier format (3: 32 chunks a value; 4: a chunk every 64 slots) is refused with
// what to do about it.
TEST(Store, AnEarlierFormatsStoreIsRefusedWithAnInstructionToImportAgain) {
  for (const char old_version : {'\x03', '\x04'}) {
    TempDir dir;
    {
      auto store = open_store(dir.str());
      import_objects(*store, {sample_object("a", "/A", {})}, "a");
    }
    std::string current("format\0\0\0\0", 10), old("format\0\0\0\0", 10);
    old[6] = old_version;
    const uint32_t version = kStoreFormatVersion;
    std::memcpy(current.data() + 6, &version, 4);
    ASSERT_GE(patch_file(fs::path(dir.str()) / "data.mdb", current, old), 1);
    for (auto mode : {Store::Mode::read_only, Store::Mode::read_write}) {
      std::string error;
      EXPECT_FALSE(Store::open(dir.str(), mode, error));
      EXPECT_NE(error.find("store " + dir.str() + " has format " + std::to_string(old_version) +
                           "; this build reads format 6: import or generate it again"),
                std::string::npos) << error;
    }
  }
}

void put_raw(const std::string& dir, const char* database, std::string_view key,
             std::span<const uint8_t> bytes);

TEST(Store, ACorruptChunkGivesAnErrorNamingTheStoreAndTheSlot) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 3000; ++i) objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  {
    auto store = open_store(dir.str());
    import_objects(*store, objects, "a");
  }
  // The object chunk at slot 0 says it holds slots 0-63, in a frame that is not zstd (chunks.h:
  // u32 slot count, frame).
  const char key[4] = {0, 0, 0, 0};
  const uint8_t value[8] = {64, 0, 0, 0, 'X', 'X', 'X', 'X'};
  ASSERT_NO_FATAL_FAILURE(put_raw(dir.str(), "objects", std::string_view(key, 4), value));

  auto store = open_store(dir.str(), Store::Mode::read_only);
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  Object o;
  EXPECT_FALSE(view->object(5, o, false, error));
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
  EXPECT_NE(error.find("object slot 5"), std::string::npos) << error;
  // Other chunks still read; listing everything stops at the corrupt one with the same message.
  ASSERT_TRUE(view->object(2999, o, true, error)) << error;
  EXPECT_TRUE(o == objects[2999]);
  error.clear();
  EXPECT_FALSE(view->for_each_object([](uint32_t, Object&&) { return true; }, false, error));
  EXPECT_NE(error.find("object slot 0"), std::string::npos) << error;
}

// Overwrites <database>/<key> with `bytes`, as a damaged disk might (no Store open on `dir`).
void put_raw(const std::string& dir, const char* database, std::string_view key,
             std::span<const uint8_t> bytes) {
  MDB_env* env = nullptr;
  ASSERT_EQ(mdb_env_create(&env), MDB_SUCCESS);
  mdb_env_set_maxdbs(env, 12);
  ASSERT_EQ(mdb_env_open(env, dir.c_str(), 0, 0644), MDB_SUCCESS);
  MDB_txn* txn = nullptr;
  MDB_dbi dbi;
  ASSERT_EQ(mdb_txn_begin(env, nullptr, 0, &txn), MDB_SUCCESS);
  ASSERT_EQ(mdb_dbi_open(txn, database, 0, &dbi), MDB_SUCCESS);
  MDB_val k{key.size(), const_cast<char*>(key.data())};
  MDB_val v{bytes.size(), const_cast<uint8_t*>(bytes.data())};
  ASSERT_EQ(mdb_put(txn, dbi, &k, &v, 0), MDB_SUCCESS);
  ASSERT_EQ(mdb_txn_commit(txn), MDB_SUCCESS);
  mdb_env_close(env);
}

// Every decoder of the store's own bytes refuses each truncation of a valid input, and survives
// (refuses or accepts, without reading out of bounds) every single corrupted byte.
TEST(StoreEncodings, DecodersRefuseEveryTruncationAndSurviveCorruptBytes) {
  using namespace detail;
  std::vector<KeySlot> table;
  for (uint32_t i = 0; i < 40; ++i) table.push_back({uint64_t(i) * 0x9e3779b97f4a7c15ull % 1000003, i * 3});
  std::sort(table.begin(), table.end());
  std::vector<uint8_t> keys;
  encode_key_slots(table, keys);
  std::vector<uint8_t> runs;
  encode_slot_runs({1, 2, 3, 7, 8, 100, 4000}, runs);
  std::vector<BlockEntry> grid;
  for (uint32_t i = 0; i < 40; ++i) {
    grid.push_back({{{int32_t(i * 10), -int32_t(i), 5}, {int32_t(i * 10 + 4), 3, 9 + int32_t(i)}, 1000 - i},
                    0x01020304u * i});
  }
  std::vector<uint8_t> spatial;
  encode_block(grid.data(), uint32_t(grid.size()), spatial);
  std::vector<BlockSummary> summaries(3);
  for (auto& summary : summaries) summarise_block(grid.data(), uint32_t(grid.size()), summary);
  std::vector<uint8_t> top;
  encode_top({1, 2, 3}, 1, summaries, top);

  std::vector<KeySlot> keys_back;
  std::vector<uint32_t> runs_back;
  std::vector<BlockEntry> grid_back;
  DecodedTop top_back;
  std::string error;
  ASSERT_TRUE(decode_key_slots(keys.data(), keys.size(), keys_back, error)) << error;
  EXPECT_EQ(keys_back.size(), table.size());
  ASSERT_TRUE(decode_slot_runs(runs.data(), runs.size(), 5000, runs_back, error)) << error;
  EXPECT_EQ(runs_back, (std::vector<uint32_t>{1, 2, 3, 7, 8, 100, 4000}));
  EXPECT_FALSE(decode_slot_runs(runs.data(), runs.size(), 4000, runs_back, error));
  ASSERT_TRUE(decode_block(spatial.data(), spatial.size(), grid_back, error)) << error;
  ASSERT_EQ(grid_back.size(), grid.size());
  for (size_t i = 0; i < grid.size(); ++i) {
    EXPECT_EQ(std::memcmp(&grid_back[i], &grid[i], sizeof(BlockEntry)), 0) << i;
  }
  ASSERT_TRUE(decode_top(top.data(), top.size(), top_back, error)) << error;
  EXPECT_EQ(top_back.entries, 120u);
  EXPECT_EQ(top_back.database, 1);
  EXPECT_EQ(top_back.origin, glm::dvec3(1, 2, 3));
  // The readers' form: entries in the same order, their grid boxes inside the float ones, each
  // leaf's entries inside it.
  SpatialBlock expanded;
  expand_block(grid_back, expanded);
  ASSERT_EQ(expanded.entries.size(), grid.size());
  for (const SpatialNode& node : expanded.nodes) {
    for (uint32_t k = node.first; node.count > 0 && k < node.first + node.count; ++k) {
      EXPECT_EQ(expanded.entries[k].slot, grid[k].grid.slot) << k;
      float lo[3], hi[3];
      entry_bounds(node, expanded.entries[k], lo, hi);
      for (int a = 0; a < 3; ++a) {
        EXPECT_LE(double(lo[a]), grid[k].grid.min[a] * kSpatialCellM) << k;
        EXPECT_GE(double(hi[a]), grid[k].grid.max[a] * kSpatialCellM) << k;
        EXPECT_LE(node.min[a], lo[a]);
        EXPECT_GE(node.max[a], hi[a]);
      }
    }
  }

  for (size_t n = 0; n < keys.size(); ++n) {
    EXPECT_FALSE(decode_key_slots(keys.data(), n, keys_back, error)) << n;
  }
  for (size_t n = 0; n < runs.size(); ++n) {
    EXPECT_FALSE(decode_slot_runs(runs.data(), n, 5000, runs_back, error)) << n;
  }
  for (size_t n = 0; n < spatial.size(); ++n) {
    EXPECT_FALSE(decode_block(spatial.data(), n, grid_back, error)) << n;
  }
  for (size_t n = 0; n < top.size(); ++n) {
    EXPECT_FALSE(decode_top(top.data(), n, top_back, error)) << n;
  }
  for (uint8_t value : {uint8_t(0x00), uint8_t(0x7f), uint8_t(0xff)}) {
    for (auto* bytes : {&keys, &runs, &spatial, &top}) {
      for (size_t i = 0; i < bytes->size(); ++i) {
        std::vector<uint8_t> bad = *bytes;
        bad[i] = value;
        decode_key_slots(bad.data(), bad.size(), keys_back, error);
        decode_slot_runs(bad.data(), bad.size(), 5000, runs_back, error);
        decode_block(bad.data(), bad.size(), grid_back, error);
        decode_top(bad.data(), bad.size(), top_back, error);
      }
    }
  }

  // Blocks and chunks.
  std::vector<std::vector<uint8_t>> records = {{1, 2, 3}, {}, {4}, {5, 6}};
  std::vector<uint8_t> chunk;
  pack_chunk(records, chunk);
  std::vector<uint32_t> ends;
  ASSERT_TRUE(check_chunk(chunk, 4, ends, error)) << error;
  for (uint32_t i = 0; i < 4; ++i) {
    const auto r = chunk_record(chunk, ends, i);
    EXPECT_EQ(std::vector<uint8_t>(r.begin(), r.end()), records[i]) << i;
  }
  for (size_t n = 0; n < chunk.size(); ++n) {
    std::vector<uint8_t> cut(chunk.begin(), chunk.begin() + n);
    EXPECT_FALSE(check_chunk(cut, 4, ends, error)) << n;
  }
  std::vector<uint8_t> value;
  const std::vector<uint8_t> frame_bytes = {9, 9, 8};
  join_chunk_value(3, frame_bytes, value);
  uint32_t count = 0;
  std::span<const uint8_t> frame;
  ASSERT_TRUE(split_chunk_value(value.data(), value.size(), count, frame, error)) << error;
  EXPECT_EQ(count, 3u);
  EXPECT_EQ(std::vector<uint8_t>(frame.begin(), frame.end()), frame_bytes);
  for (size_t n = 0; n <= 4; ++n) {
    EXPECT_FALSE(split_chunk_value(value.data(), n, count, frame, error)) << n;
  }
  value[0] = 0;
  EXPECT_FALSE(split_chunk_value(value.data(), value.size(), count, frame, error));
}

TEST(Store, ReadOnlyOpeningOfAMissingStoreFailsWithItsPath) {
  TempDir dir;
  std::string error;
  EXPECT_FALSE(Store::open(dir.str(), Store::Mode::read_only, error));
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
}

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Opening fails in both modes with a message holding every one of `expected`, and data.mdb keeps
// its bytes.
void expect_refused_untouched(const std::string& dir, const std::vector<std::string>& expected) {
  const fs::path data = fs::path(dir) / "data.mdb";
  const std::string before = file_bytes(data);
  for (auto mode : {Store::Mode::read_only, Store::Mode::read_write}) {
    std::string error;
    EXPECT_FALSE(Store::open(dir, mode, error));
    for (const std::string& part : expected) {
      EXPECT_NE(error.find(part), std::string::npos) << "missing \"" << part << "\" in: " << error;
    }
  }
  EXPECT_TRUE(file_bytes(data) == before) << "data.mdb changed";
}

TEST(Store, ATruncatedDataFileIsRefusedNamingItsSizeInsteadOfFaulting) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 3000; ++i) objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  {
    auto store = open_store(dir.str());
    import_objects(*store, objects, "a");
  }
  const fs::path data = fs::path(dir.str()) / "data.mdb";
  const uintmax_t size = fs::file_size(data);
  ASSERT_GT(size, 16u * 4096u);
  // A partial copy: half the file, then only the two meta pages and a bit.
  for (uintmax_t cut : {size / 2, uintmax_t(2 * 4096 + 100)}) {
    fs::resize_file(data, cut);
    expect_refused_untouched(dir.str(), {dir.str(), "data.mdb is truncated",
                                         std::to_string(cut) + " bytes", std::to_string(size)});
  }
  // Shorter than LMDB's meta pages.
  fs::resize_file(data, 100);
  expect_refused_untouched(dir.str(), {dir.str(), "100 bytes", "truncated copy"});
}

TEST(Store, ADataFileCutShortWhileOpenFailsTheNextViewInsteadOfFaulting) {
  TempDir dir;
  std::vector<Object> objects;
  for (int i = 0; i < 3000; ++i) objects.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  {
    auto store = open_store(dir.str());
    import_objects(*store, objects, "a");
  }
  auto store = open_store(dir.str(), Store::Mode::read_only);
  const fs::path data = fs::path(dir.str()) / "data.mdb";
  fs::resize_file(data, fs::file_size(data) / 2);
  std::string error;
  EXPECT_FALSE(store->read(error));
  EXPECT_NE(error.find("data.mdb is truncated"), std::string::npos) << error;
}

TEST(Store, AnEmptyDataFileIsRefusedAsNotAStoreAndStaysEmpty) {
  TempDir dir;
  fs::create_directories(dir.str());
  std::ofstream(fs::path(dir.str()) / "data.mdb").close();
  expect_refused_untouched(dir.str(), {(fs::path(dir.str()) / "data.mdb").string() +
                                       " is empty: not a plantview store"});
  EXPECT_EQ(fs::file_size(fs::path(dir.str()) / "data.mdb"), 0u);
}

// Overwrites meta/"statistics" with `value` (no Store open on `dir`).
void put_statistics(const std::string& dir, const std::string& value) {
  put_raw(dir, "meta", "statistics",
          std::span(reinterpret_cast<const uint8_t*>(value.data()), value.size()));
}

TEST(Store, StatisticsOfTheWrongShapeAreRefusedNamingTheKey) {
  TempDir dir;
  {
    auto store = open_store(dir.str());
    import_objects(*store, {sample_object("a", "/A", {})}, "a");
  }
  const std::pair<std::string, std::string> cases[] = {
      {R"({"objects":"many"})", "\"objects\" is a JSON string"},
      {R"([1,2,3])", "a JSON array, not an object"},
      {R"({"objects_by_class":5})", "\"objects_by_class\" is a JSON number"},
      {R"({"primitives_by_kind":{"box":-1}})", "\"primitives_by_kind.box\""},
      {R"({"triangles_by_class":{"pipe":1.5}})", "\"triangles_by_class.pipe\""},
      {R"({"bounds_m":{"min":[0,0]}})", "\"bounds_m.min\""},
      {R"({"bounds_m":{"min":[0,0,0]}})", "\"bounds_m.max\""},
      {"{\"objects\": 3", "not JSON"},
  };
  for (const auto& [value, why] : cases) {
    SCOPED_TRACE(value);
    put_statistics(dir.str(), value);
    expect_refused_untouched(dir.str(), {dir.str(), "meta/\"statistics\" is damaged", why});
  }
  // The form the store writes reads back.
  ModelStatistics s;
  s.objects = 7;
  s.objects_by_class[0] = 7;
  s.bounds.extend(glm::dvec3(1, 2, 3));
  put_statistics(dir.str(), statistics_json(s));
  auto store = open_store(dir.str(), Store::Mode::read_only);
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_EQ(view->info().objects, 7u);
  EXPECT_EQ(view->info().statistics.bounds.max, glm::dvec3(1, 2, 3));
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

uint32_t index_key_bits_of(const std::string& dir) {
  MDB_env* env = nullptr;
  EXPECT_EQ(mdb_env_create(&env), MDB_SUCCESS);
  mdb_env_set_maxdbs(env, 12);
  EXPECT_EQ(mdb_env_open(env, dir.c_str(), MDB_RDONLY, 0644), MDB_SUCCESS);
  MDB_txn* txn = nullptr;
  MDB_dbi dbi;
  uint32_t bits = 0;
  if (mdb_txn_begin(env, nullptr, MDB_RDONLY, &txn) == MDB_SUCCESS) {
    MDB_val k{14, const_cast<char*>("index_key_bits")}, v;
    if (mdb_dbi_open(txn, "meta", 0, &dbi) == MDB_SUCCESS &&
        mdb_get(txn, dbi, &k, &v) == MDB_SUCCESS && v.mv_size == 4) {
      std::memcpy(&bits, v.mv_data, 4);
    }
    mdb_txn_abort(txn);
  }
  mdb_env_close(env);
  return bits;
}

// meta/"index_key_bits" of the store in `dir` (0 when absent). LMDB must not have an environment
// open twice in one process: `store` is closed meanwhile and opened again.
uint32_t index_key_bits_of(const std::string& dir, std::unique_ptr<Store>& store) {
  store.reset();
  const uint32_t bits = index_key_bits_of(dir);
  store = open_store(dir);
  return bits;
}
TEST(StoreIndexes, TheKeyWidthFollowsTheObjectCountAndChangesOnlyWhenItDoublesOrHalves) {
  using detail::index_key_bits;
  // Empty indexes take the width of about 32 entries a key (preset c, its x100 and x1000).
  EXPECT_EQ(index_key_bits(0, 0), 8u);
  EXPECT_EQ(index_key_bits(40746, 0), 10u);
  EXPECT_EQ(index_key_bits(4074822, 0), 17u);
  EXPECT_EQ(index_key_bits(40746000, 0), 20u);
  EXPECT_EQ(index_key_bits(uint64_t(1) << 40, 0), detail::kMaxIndexKeyBits);
  // A width is kept while its keys hold 16 to 64 entries on average.
  EXPECT_EQ(index_key_bits(16 * 1024, 10), 10u);
  EXPECT_EQ(index_key_bits(16 * 1024 - 1, 10), 9u);
  EXPECT_EQ(index_key_bits(64 * 1024 - 1, 10), 10u);
  EXPECT_EQ(index_key_bits(64 * 1024, 10), 11u);
  EXPECT_EQ(index_key_bits(300 * 1024, 10), 13u);
  // At the bounds whatever the count.
  EXPECT_EQ(index_key_bits(1, 8), 8u);
  EXPECT_EQ(index_key_bits(uint64_t(1) << 40, 24), 24u);
}

// The ids and names are written again with another key width when an import doubles the store
// or takes most of it away; every lookup answers as before, in the same import as a replacement
// (looked up with the old width) and afterwards.
TEST(StoreIndexes, TheIndexesAreReKeyedAsTheStoreGrowsAndShrinksAndEveryLookupFollows) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::map<uint64_t, Object> expected;
  std::vector<Object> a, b;
  for (int i = 0; i < 1000; ++i) a.push_back(box_object("a", i, {i * 1.0, 0, 0}));
  for (int i = 0; i < 20000; ++i) b.push_back(box_object("b", i, {i * 1.0, 5, 0}));
  // (Box names are "/BOX-<i>" in every source: a's 1,000 names are also b's first 1,000.)
  import_objects(*store, a, "a");
  EXPECT_EQ(index_key_bits_of(dir.str(), store), 8u);
  for (const Object& o : a) expected.emplace(o.id, o);
  expect_indexes_agree(*store);

  // 21,000 objects: 82 a key at 8 bits, so 9 (41 a key). One of a's objects is replaced in the
  // same import.
  {
    std::string error;
    auto import = store->begin_import(error);
    ASSERT_TRUE(import) << error;
    for (const Object& o : b) ASSERT_TRUE(import->put(o, error)) << error;
    Object again = a[500];
    again.colour = {1, 2, 3, 4};
    ASSERT_TRUE(import->put(again, error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
    for (const Object& o : b) expected.emplace(o.id, o);
    expected[again.id] = again;
  }
  EXPECT_EQ(index_key_bits_of(dir.str(), store), 9u);
  ASSERT_NO_FATAL_FAILURE(expect_objects_exactly(*store, expected));
  expect_indexes_agree(*store);

  // Within the width's band nothing is written again: 19,000 objects are 37 a key.
  import_objects(*store, std::vector<Object>(b.begin(), b.begin() + 18000), "b");
  for (size_t i = 18000; i < b.size(); ++i) expected.erase(b[i].id);
  EXPECT_EQ(index_key_bits_of(dir.str(), store), 9u);
  expect_indexes_agree(*store);

  // Back to 1,000: 2 a key at 9 bits, so 8 again.
  import_objects(*store, {}, "b");
  for (size_t i = 0; i < 18000; ++i) expected.erase(b[i].id);
  EXPECT_EQ(index_key_bits_of(dir.str(), store), 8u);
  ASSERT_NO_FATAL_FAILURE(expect_objects_exactly(*store, expected));
  expect_indexes_agree(*store);
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_FALSE(view->slot_of(b[0].id));
  EXPECT_EQ(view->slots_named(b[5000].name).size(), 0u);
  EXPECT_EQ(view->slots_named(a[1].name).size(), 1u);
}

TEST(StoreIndexes, ADamagedKeyWidthIsRefusedNamingTheKey) {
  TempDir dir;
  {
    auto store = open_store(dir.str());
    import_objects(*store, {sample_object("a", "/A", {})}, "a");
  }
  const uint32_t too_wide = 25;
  const uint8_t three_bytes[3] = {8, 0, 0};
  put_raw(dir.str(), "meta", "index_key_bits",
          std::span(reinterpret_cast<const uint8_t*>(&too_wide), 4));
  expect_refused_untouched(dir.str(), {dir.str(), "meta/\"index_key_bits\" is damaged"});
  put_raw(dir.str(), "meta", "index_key_bits", three_bytes);
  expect_refused_untouched(dir.str(), {dir.str(), "meta/\"index_key_bits\" is damaged"});
}

}  // namespace
}  // namespace plantview
