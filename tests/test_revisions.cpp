// Revisions (store.h, "Revisions"): what each commit records, the net changes between two
// revisions, previous records, pruning, the format 5 upgrade, two writers at once and a writer
// killed mid-way.
#include <gtest/gtest.h>
#include <lmdb.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "import_runs.h"
#include "plantview/ingest.h"
#include "plantview/store.h"
#include "plantview/xml.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

using test::TempDir;

Object box(int i, double x) {
  Object o;
  o.name = "/BOX-" + std::to_string(i);
  o.source = "plant.rvm";
  o.id = object_id(o.source, o.name);
  o.object_class = i % 2 ? ObjectClass::equipment : ObjectClass::structure;
  o.origin_m = {x, 0, 0};
  o.colour = {200, 100, 50, 255};
  o.primitives.push_back(Primitive{Placement{}, Box{2, 2, 2}});
  o.attributes = {{"Type", "EQUI"}, {"Index", std::to_string(i)}};
  return o;
}

std::vector<Object> boxes(int n) {
  std::vector<Object> out;
  for (int i = 0; i < n; ++i) out.push_back(box(i, i * 3.0));
  return out;
}

std::unique_ptr<Store> open_store(const TempDir& dir) {
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  EXPECT_TRUE(store) << error;
  return store;
}

void ingest(Store& store, const std::vector<Object>& objects, const std::string& note = {},
            uint32_t keep = kDefaultKeepRevisions) {
  IngestControl control;
  control.note = note;
  control.keep_revisions = keep;
  const IngestResult r = ingest_objects(store, objects, control);
  ASSERT_TRUE(r) << r.error().message;
}

std::vector<Revision> revisions_of(Store& store) {
  std::string error;
  auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  std::vector<Revision> out;
  EXPECT_TRUE(view->revisions(out, error)) << error;
  return out;
}

// kind by name, e.g. {"/BOX-1": "modified"}.
std::map<std::string, std::string> changes_of(Store& store, uint32_t from, uint32_t to) {
  std::string error;
  auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  std::vector<ObjectChange> changes;
  EXPECT_TRUE(view->changes(from, to, changes, error)) << error;
  std::map<std::string, std::string> out;
  for (const ObjectChange& c : changes) out[c.name] = std::string(change_kind_name(c.kind));
  return out;
}

TEST(Revisions, EachCommitRecordsItsNumberSourcesNoteAndCounts) {
  TempDir dir;
  auto store = open_store(dir);
  {
    std::string error;
    auto view = store->read(error);
    EXPECT_EQ(view->info().revision, 0u);
  }
  ingest(*store, boxes(6), "first export");
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_EQ(view->info().revision, 1u);
  EXPECT_GT(view->info().revision_time_unix_ms, 1700000000000);
  EXPECT_EQ(view->info().format_version, 6u);
  const std::vector<Revision> all = revisions_of(*store);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].number, 1u);
  EXPECT_EQ(all[0].note, "first export");
  EXPECT_EQ(all[0].sources, std::vector<std::string>{"plant.rvm"});
  EXPECT_EQ(all[0].added, 6u);
  EXPECT_EQ(all[0].removed + all[0].modified, 0u);
  EXPECT_EQ(all[0].objects, 6u);
  EXPECT_TRUE(all[0].changes_kept);
  EXPECT_EQ(all[0].time_unix_ms, view->info().revision_time_unix_ms);
  std::vector<ObjectChange> changes;
  ASSERT_TRUE(view->changes(0, 1, changes, error)) << error;
  ASSERT_EQ(changes.size(), 6u);
  for (size_t i = 1; i < changes.size(); ++i) EXPECT_LT(changes[i - 1].id, changes[i].id);
  for (const ObjectChange& c : changes) {
    EXPECT_EQ(c.kind, ChangeKind::added);
    ASSERT_TRUE(c.slot);
    Object o;
    ASSERT_TRUE(view->object(*c.slot, o, false, error)) << error;
    EXPECT_EQ(o.id, c.id);
    EXPECT_EQ(o.name, c.name);
    EXPECT_EQ(o.object_class, c.object_class);
    uint64_t hash = 0;
    ASSERT_TRUE(view->content_hash(*c.slot, hash, error)) << error;
    EXPECT_EQ(hash, c.hash_after);
    EXPECT_EQ(c.hash_before, 0u);
    EXPECT_EQ(c.revision, 1u);
  }
}

TEST(Revisions, AnUnchangedReimportRecordsARevisionWithNoChanges) {
  TempDir dir;
  auto store = open_store(dir);
  ingest(*store, boxes(6));
  ingest(*store, boxes(6));
  const std::vector<Revision> all = revisions_of(*store);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[1].added + all[1].removed + all[1].modified, 0u);
  EXPECT_EQ(all[1].objects, 6u);
  EXPECT_TRUE(changes_of(*store, 1, 2).empty());
}

TEST(Revisions, AddRemoveMoveRecolourAndAttributeEditsAreFoundByContent) {
  TempDir dir;
  auto store = open_store(dir);
  std::vector<Object> objects = boxes(6);
  ingest(*store, objects);
  objects[1].origin_m.x += 0.5;                  // moved
  objects[2].colour = {0, 255, 0, 255};          // recoloured
  objects[3].attributes[0].value = "PUMP";       // attribute edited
  objects.erase(objects.begin() + 4);            // removed
  objects.push_back(box(6, 30));                 // added
  ingest(*store, objects);
  const std::map<std::string, std::string> expected = {
      {"/BOX-1", "modified"}, {"/BOX-2", "modified"}, {"/BOX-3", "modified"},
      {"/BOX-4", "removed"},  {"/BOX-6", "added"}};
  EXPECT_EQ(changes_of(*store, 1, 2), expected);
  const Revision r = revisions_of(*store).back();
  EXPECT_EQ(r.added, 1u);
  EXPECT_EQ(r.removed, 1u);
  EXPECT_EQ(r.modified, 3u);
  EXPECT_EQ(r.objects, 6u);

  std::string error;
  auto view = store->read(error);
  std::vector<ObjectChange> changes;
  ASSERT_TRUE(view->changes(1, 2, changes, error)) << error;
  for (const ObjectChange& c : changes) {
    EXPECT_EQ(c.slot.has_value(), c.kind != ChangeKind::removed) << c.name;
    EXPECT_EQ(c.hash_before != 0, c.kind != ChangeKind::added) << c.name;
    EXPECT_EQ(c.hash_after != 0, c.kind != ChangeKind::removed) << c.name;
    if (c.name == "/BOX-4") {
      EXPECT_EQ(c.object_class, ObjectClass::structure);
    }
  }
  // The previous records: as they were at revision 1.
  const std::vector<Object> first = boxes(6);
  for (int i : {1, 2, 3, 4, 5}) {
    Object o;
    bool found = false;
    ASSERT_TRUE(view->object_at(1, first[size_t(i)].id, o, found, true, error)) << error;
    ASSERT_TRUE(found) << i;
    EXPECT_TRUE(o == first[size_t(i)]) << i;
  }
  Object o;
  bool found = true;
  ASSERT_TRUE(view->object_at(1, box(6, 30).id, o, found, false, error)) << error;
  EXPECT_FALSE(found);  // added later
  ASSERT_TRUE(view->object_at(2, first[4].id, o, found, false, error)) << error;
  EXPECT_FALSE(found);  // removed by revision 2
}

TEST(Revisions, ChangesAcrossSeveralRevisionsAreNet) {
  TempDir dir;
  auto store = open_store(dir);
  std::vector<Object> objects = boxes(4);
  ingest(*store, objects);                       // 1
  objects[0].origin_m.y = 1;
  objects.push_back(box(7, 40));
  ingest(*store, objects);                       // 2: 0 modified, 7 added
  objects[0].origin_m.y = 2;
  objects.pop_back();
  ingest(*store, objects);                       // 3: 0 modified again, 7 removed
  objects[1].origin_m.z = 1;
  ingest(*store, objects);                       // 4: 1 modified
  objects[1].origin_m.z = 0;
  ingest(*store, objects);                       // 5: 1 back as it was
  EXPECT_EQ(changes_of(*store, 1, 3), (std::map<std::string, std::string>{{"/BOX-0", "modified"}}));
  EXPECT_EQ(changes_of(*store, 1, 5), (std::map<std::string, std::string>{{"/BOX-0", "modified"}}));
  EXPECT_EQ(changes_of(*store, 3, 4), (std::map<std::string, std::string>{{"/BOX-1", "modified"}}));
  EXPECT_TRUE(changes_of(*store, 4, 5).size() == 1u);
  std::string error;
  auto view = store->read(error);
  std::vector<ObjectChange> changes;
  ASSERT_TRUE(view->changes(1, 3, changes, error)) << error;
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].revision, 3u);
  // hash_before is revision 1's, after revision 3's.
  Object at1;
  bool found;
  ASSERT_TRUE(view->object_at(1, changes[0].id, at1, found, true, error)) << error;
  ASSERT_TRUE(found);
  EXPECT_EQ(at1.origin_m.y, 0.0);
  Object at2;
  ASSERT_TRUE(view->object_at(2, changes[0].id, at2, found, true, error)) << error;
  EXPECT_EQ(at2.origin_m.y, 1.0);
  uint64_t now_hash;
  ASSERT_TRUE(view->content_hash(*changes[0].slot, now_hash, error));
  EXPECT_EQ(changes[0].hash_after, now_hash);
  EXPECT_NE(changes[0].hash_before, now_hash);
}

TEST(Revisions, AnObjectPutTwiceInOneImportIsOneChangeOfItsLastVersion) {
  TempDir dir;
  auto store = open_store(dir);
  ingest(*store, boxes(2));
  std::string error;
  auto import = store->begin_import(error);
  ASSERT_TRUE(import) << error;
  Object a = box(0, 0), b = box(5, 50);
  a.origin_m.x = 7;
  ASSERT_TRUE(import->put(a, error)) << error;
  a.origin_m.x = 0;  // back as it was: no change
  ASSERT_TRUE(import->put(a, error)) << error;
  ASSERT_TRUE(import->put(b, error)) << error;
  b.colour.r = 1;
  ASSERT_TRUE(import->put(b, error)) << error;
  import->set_note("twice");
  ASSERT_TRUE(import->commit(error)) << error;
  EXPECT_EQ(changes_of(*store, 1, 2), (std::map<std::string, std::string>{{"/BOX-5", "added"}}));
  auto view = store->read(error);
  std::vector<ObjectChange> changes;
  ASSERT_TRUE(view->changes(1, 2, changes, error));
  uint64_t hash;
  ASSERT_TRUE(view->content_hash(*changes[0].slot, hash, error));
  EXPECT_EQ(changes[0].hash_after, hash);
  Object o;
  ASSERT_TRUE(view->object(*changes[0].slot, o, false, error));
  EXPECT_EQ(o.colour.r, 1);
  EXPECT_EQ(revisions_of(*store).back().note, "twice");
}

// Re-imports keep unchanged objects in place (store.h, "Revisions"): an object put again with
// the content it has keeps its slot, and nothing of it is written.
std::map<uint64_t, uint32_t> slots_of(Store& store, const std::vector<Object>& objects) {
  std::string error;
  auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  std::map<uint64_t, uint32_t> out;
  for (const Object& o : objects) {
    if (const std::optional<uint32_t> slot = view->slot_of(o.id)) out[o.id] = *slot;
  }
  return out;
}

TEST(KeepSlots, AnUnchangedReimportKeepsEverySlotAndWritesNothing) {
  TempDir dir;
  auto store = open_store(dir);
  const std::vector<Object> objects = boxes(300);
  ingest(*store, objects);
  const std::map<uint64_t, uint32_t> before = slots_of(*store, objects);
  ASSERT_EQ(before.size(), 300u);
  std::string error;
  ingest(*store, objects);
  ingest(*store, objects);
  EXPECT_EQ(slots_of(*store, objects), before);
  const std::vector<Revision> all = revisions_of(*store);
  ASSERT_EQ(all.size(), 3u);
  for (size_t r = 1; r < 3; ++r) {
    EXPECT_EQ(all[r].added + all[r].removed + all[r].modified, 0u);
    EXPECT_EQ(all[r].objects, 300u);
  }
  EXPECT_TRUE(changes_of(*store, 1, 3).empty());
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  // No slot was used: one object more goes to slot 300.
  std::vector<Object> more = objects;
  more.push_back(box(300, 900));
  ingest(*store, more);
  EXPECT_EQ(slots_of(*store, {more.back()}).begin()->second, 300u);
  // Revision 2's state of an object is its slot's (no previous record was kept for it).
  Object o;
  bool found = true;
  ASSERT_TRUE(view->object_at(2, objects[5].id, o, found, false, error)) << error;
  EXPECT_TRUE(found);
  EXPECT_EQ(o.name, objects[5].name);
}

TEST(KeepSlots, AMovedObjectGetsANewSlotTheOthersKeepTheirsARemovedOneIsGone) {
  TempDir dir;
  auto store = open_store(dir);
  std::vector<Object> objects = boxes(200);
  ingest(*store, objects);
  const std::map<uint64_t, uint32_t> before = slots_of(*store, objects);
  std::string error;
  auto old_view = store->read(error);  // holds the first commit's snapshot throughout
  ASSERT_TRUE(old_view) << error;
  const Object removed = objects[7];
  objects[3].origin_m.y = 5;                                          // moved
  objects.erase(objects.begin() + 7);                                 // removed
  ingest(*store, objects);
  const std::map<uint64_t, uint32_t> after = slots_of(*store, objects);
  ASSERT_EQ(after.size(), 199u);
  for (const auto& [id, slot] : after) {
    if (id == objects[3].id) {
      EXPECT_EQ(slot, 200u);  // the first new slot
    } else {
      EXPECT_EQ(slot, before.at(id));
    }
  }
  EXPECT_TRUE(slots_of(*store, {removed}).empty());
  EXPECT_EQ(changes_of(*store, 1, 2), (std::map<std::string, std::string>{
                                          {objects[3].name, "modified"}, {removed.name, "removed"}}));
  const Revision last = revisions_of(*store).back();
  EXPECT_EQ(last.modified, 1u);
  EXPECT_EQ(last.removed, 1u);
  EXPECT_EQ(last.added, 0u);
  {
    auto view = store->read(error);
    ASSERT_TRUE(view) << error;
    std::vector<uint32_t> slots;
    ASSERT_TRUE(view->slots_named(removed.name, slots, error)) << error;
    EXPECT_TRUE(slots.empty());
    Object o;
    EXPECT_FALSE(view->object(before.at(removed.id), o, false, error));
    EXPECT_FALSE(view->object(before.at(objects[3].id), o, false, error));
    ASSERT_TRUE(view->object(200, o, false, error)) << error;
    EXPECT_EQ(o.origin_m.y, 5);
  }
  // The reader of the first commit still reads every object where it was (copy-on-write).
  for (const Object& o : boxes(200)) {
    Object read;
    ASSERT_TRUE(old_view->object(before.at(o.id), read, true, error)) << error;
    EXPECT_EQ(read.name, o.name);
    EXPECT_EQ(read.origin_m, o.origin_m);
    EXPECT_EQ(read.attributes, o.attributes);
  }
  EXPECT_EQ(old_view->info().statistics.objects, 200u);
}

TEST(KeepSlots, PutTwiceTheLaterWinsWhetherKeptOrChanged) {
  TempDir dir;
  auto store = open_store(dir);
  ingest(*store, boxes(4));
  const std::map<uint64_t, uint32_t> before = slots_of(*store, boxes(4));
  std::string error;
  auto import = store->begin_import(error);
  ASSERT_TRUE(import) << error;
  ASSERT_TRUE(import->remove_source("plant.rvm", error)) << error;
  Object a = box(0, 0), b = box(1, 3), c = box(2, 6), d = box(3, 9);
  // a: unchanged, then changed: modified, at a new slot.
  ASSERT_TRUE(import->put(a, error)) << error;
  a.colour.g = 7;
  ASSERT_TRUE(import->put(a, error)) << error;
  // b: changed, then as committed: no change (its slot moved).
  Object b2 = b;
  b2.colour.g = 7;
  ASSERT_TRUE(import->put(b2, error)) << error;
  ASSERT_TRUE(import->put(b, error)) << error;
  // c: unchanged twice: kept.
  ASSERT_TRUE(import->put(c, error)) << error;
  ASSERT_TRUE(import->put(c, error)) << error;
  (void)d;  // d: not put again: removed
  ASSERT_TRUE(import->commit(error)) << error;
  EXPECT_EQ(changes_of(*store, 1, 2), (std::map<std::string, std::string>{
                                          {a.name, "modified"}, {d.name, "removed"}}));
  const std::map<uint64_t, uint32_t> after = slots_of(*store, boxes(4));
  ASSERT_EQ(after.size(), 3u);
  EXPECT_EQ(after.at(c.id), before.at(c.id));
  EXPECT_GE(after.at(a.id), 4u);
  EXPECT_GE(after.at(b.id), 4u);
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  Object o;
  ASSERT_TRUE(view->object(after.at(a.id), o, false, error)) << error;
  EXPECT_EQ(o.colour.g, 7);
  ASSERT_TRUE(view->object(after.at(b.id), o, false, error)) << error;
  EXPECT_EQ(o.colour.g, 100);
  EXPECT_EQ(view->info().statistics.objects, 3u);
}

TEST(KeepSlots, StatisticsEqualAFreshImportsAndTheSameImportsGiveTheSameCommit) {
  std::vector<Object> first = boxes(150), second = boxes(160);
  second[10].origin_m.z = 4;
  second.erase(second.begin() + 20);
  second[30].attributes.push_back({"Note", "edited"});
  const auto run = [&](const TempDir& dir) {
    auto store = open_store(dir);
    ingest(*store, first);
    ingest(*store, second);
    ingest(*store, first);
    ingest(*store, second);
    std::string error;
    auto view = store->read(error);
    return std::pair(statistics_json(view->info().statistics), view->info().commit_id);
  };
  TempDir a, b, fresh;
  const auto [stats_a, id_a] = run(a);
  const auto [stats_b, id_b] = run(b);
  EXPECT_EQ(stats_a, stats_b);
  EXPECT_EQ(id_a, id_b);
  auto fresh_store = open_store(fresh);
  ingest(*fresh_store, second);
  std::string error;
  auto view = fresh_store->read(error);
  EXPECT_EQ(stats_a, statistics_json(view->info().statistics));
  const auto bytes = [](const TempDir& dir) {
    std::ifstream in(dir.str() + "/data.mdb", std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string bytes_a = bytes(a), bytes_b = bytes(b);
  EXPECT_FALSE(bytes_a.empty());
  // Revision times differ between the runs (their JSON, not its length): the same file size.
  EXPECT_EQ(bytes_a.size(), bytes_b.size());
}

// Change lists are kept in blocks of 256 objects: lookups across many blocks.
TEST(Revisions, ManyChangesAcrossBlocksAreAllFound) {
  TempDir dir;
  auto store = open_store(dir);
  std::vector<Object> objects = boxes(1500);
  ingest(*store, objects);
  std::map<std::string, std::string> expected;
  for (size_t i = 0; i < objects.size(); i += 3) {
    objects[i].origin_m.y = 5;
    expected[objects[i].name] = "modified";
  }
  for (int i = 0; i < 400; ++i) {
    objects.push_back(box(2000 + i, 0));
    expected[objects.back().name] = "added";
  }
  for (size_t i = 1; i < 1500; i += 50) expected[objects[i].name] = "removed";
  std::vector<Object> kept;
  for (const Object& o : objects) {
    auto it = expected.find(o.name);
    if (it == expected.end() || it->second != "removed") kept.push_back(o);
  }
  ingest(*store, kept);
  EXPECT_EQ(changes_of(*store, 1, 2), expected);
  std::string error;
  auto view = store->read(error);
  const std::vector<Object> first = boxes(1500);
  for (size_t i = 0; i < first.size(); i += 7) {
    Object o;
    bool found = false;
    ASSERT_TRUE(view->object_at(1, first[i].id, o, found, true, error)) << error;
    ASSERT_TRUE(found) << i;
    EXPECT_TRUE(o == first[i]) << i;
  }
  for (int i = 0; i < 400; i += 13) {
    Object o;
    bool found = true;
    ASSERT_TRUE(view->object_at(1, box(2000 + i, 0).id, o, found, false, error)) << error;
    EXPECT_FALSE(found) << i;
  }
}

std::string g_store_dir, g_run_files_seen;  // for a stage hook (a plain function)

// The change items spill to run files, and the names past the name log's 1 MB buffer to its
// file: the same changes.
TEST(Revisions, SpilledChangeItemsAndNamesGiveTheSameChanges) {
  detail::set_import_run_bytes(4096);
  struct Restore {
    ~Restore() { detail::set_import_run_bytes(size_t(64) << 20); }
  } restore;
  TempDir dir;
  g_store_dir = dir.str();
  detail::set_import_stage_hook([](const char* stage) {
    if (std::strcmp(stage, "ids merged") != 0) return;
    for (const auto& entry : std::filesystem::directory_iterator(g_store_dir))
      g_run_files_seen += entry.path().filename().string() + " ";
  });
  auto store = open_store(dir);
  std::vector<Object> objects;
  const std::string padding(900, 'x');
  for (int i = 0; i < 1500; ++i) {
    Object o = box(i, i * 3.0);
    o.name += "/" + padding;
    o.id = object_id(o.source, o.name);
    objects.push_back(o);
  }
  ingest(*store, objects);
  std::map<std::string, std::string> expected;
  for (size_t i = 0; i < objects.size(); i += 11) {
    objects[i].colour.g = 7;
    expected[objects[i].name] = "modified";
  }
  ingest(*store, objects);
  EXPECT_EQ(changes_of(*store, 1, 2), expected);
  EXPECT_EQ(changes_of(*store, 0, 1).size(), 1500u);
  EXPECT_NE(g_run_files_seen.find("-puts-"), std::string::npos) << g_run_files_seen;
  EXPECT_NE(g_run_files_seen.find("-removals-"), std::string::npos) << g_run_files_seen;
  EXPECT_NE(g_run_files_seen.find("-changenames.run"), std::string::npos) << g_run_files_seen;
  detail::set_import_stage_hook(nullptr);
  for (const auto& entry : std::filesystem::directory_iterator(dir.path()))
    EXPECT_NE(entry.path().extension(), ".run") << "left behind: " << entry.path();
}

TEST(Revisions, OldChangeListsArePrunedAndABadRangeIsNamed) {
  TempDir dir;
  auto store = open_store(dir);
  std::vector<Object> objects = boxes(3);
  for (int r = 1; r <= 4; ++r) {
    objects[0].origin_m.z = r;
    ingest(*store, objects, {}, 2);
  }
  const std::vector<Revision> all = revisions_of(*store);
  ASSERT_EQ(all.size(), 4u);
  EXPECT_FALSE(all[0].changes_kept);
  EXPECT_FALSE(all[1].changes_kept);
  EXPECT_TRUE(all[2].changes_kept);
  EXPECT_TRUE(all[3].changes_kept);
  std::string error;
  auto view = store->read(error);
  std::vector<ObjectChange> changes;
  EXPECT_TRUE(view->changes(2, 4, changes, error)) << error;
  EXPECT_FALSE(view->changes(1, 4, changes, error));
  EXPECT_NE(error.find("revision 2's changes were pruned: the store keeps the last 2 "
                       "(--keep-revisions)"), std::string::npos) << error;
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
  EXPECT_FALSE(view->changes(4, 5, changes, error));
  EXPECT_NE(error.find("no revision 5 (the newest is 4)"), std::string::npos) << error;
  Object o;
  bool found;
  EXPECT_FALSE(view->object_at(1, objects[0].id, o, found, false, error));
  EXPECT_NE(error.find("pruned"), std::string::npos) << error;
  ASSERT_TRUE(view->object_at(2, objects[0].id, o, found, false, error)) << error;
  EXPECT_EQ(o.origin_m.z, 2.0);
  // The pruned revisions left nothing behind: a database scan by hand.
  MDB_env* env = nullptr;
  ASSERT_EQ(mdb_env_create(&env), 0);
  mdb_env_set_maxdbs(env, 12);
  view.reset();
  store.reset();
  ASSERT_EQ(mdb_env_open(env, dir.str().c_str(), MDB_RDONLY, 0644), 0);
  MDB_txn* txn;
  ASSERT_EQ(mdb_txn_begin(env, nullptr, MDB_RDONLY, &txn), 0);
  for (const char* name : {"changes", "history"}) {
    MDB_dbi dbi;
    ASSERT_EQ(mdb_dbi_open(txn, name, 0, &dbi), 0);
    MDB_cursor* cursor;
    ASSERT_EQ(mdb_cursor_open(txn, dbi, &cursor), 0);
    MDB_val k, v;
    ASSERT_EQ(mdb_cursor_get(cursor, &k, &v, MDB_FIRST), 0);
    const auto* b = static_cast<const unsigned char*>(k.mv_data);
    EXPECT_EQ(b[3], 3) << name;  // the oldest kept revision
    mdb_cursor_close(cursor);
  }
  mdb_txn_abort(txn);
  mdb_env_close(env);
}

// A format 5 store: the same less the revision databases and meta/"format" 5.
void make_format_5(const std::string& dir) {
  MDB_env* env = nullptr;
  ASSERT_EQ(mdb_env_create(&env), 0);
  mdb_env_set_maxdbs(env, 12);
  mdb_env_set_mapsize(env, size_t(1) << 40);
  ASSERT_EQ(mdb_env_open(env, dir.c_str(), 0, 0644), 0);
  MDB_txn* txn;
  ASSERT_EQ(mdb_txn_begin(env, nullptr, 0, &txn), 0);
  for (const char* name : {"revisions", "changes", "history"}) {
    MDB_dbi dbi;
    ASSERT_EQ(mdb_dbi_open(txn, name, 0, &dbi), 0);
    ASSERT_EQ(mdb_drop(txn, dbi, 1), 0);
  }
  MDB_dbi meta;
  ASSERT_EQ(mdb_dbi_open(txn, "meta", 0, &meta), 0);
  const uint32_t five = 5;
  MDB_val k{6, const_cast<char*>("format")}, v{4, const_cast<uint32_t*>(&five)};
  ASSERT_EQ(mdb_put(txn, meta, &k, &v, 0), 0);
  ASSERT_EQ(mdb_txn_commit(txn), 0);
  mdb_env_close(env);
}

TEST(Revisions, AFormat5StoreIsUpgradedInPlaceReadWriteAndRefusedReadOnly) {
  TempDir dir;
  std::vector<Object> objects = boxes(4);
  {
    auto store = open_store(dir);
    ingest(*store, objects);
  }
  make_format_5(dir.str());
  std::string error;
  EXPECT_FALSE(Store::open(dir.str(), Store::Mode::read_only, error));
  EXPECT_EQ(error, "store " + dir.str() + ": format 5, run `plantview upgrade --store " +
                       dir.str() + "` (or any import) to upgrade it in place");
  auto store = open_store(dir);
  ASSERT_TRUE(store);
  {
    auto view = store->read(error);
    EXPECT_EQ(view->info().format_version, 6u);
    EXPECT_EQ(view->info().revision, 1u);
    EXPECT_EQ(view->info().objects, 4u);
  }
  std::vector<Revision> all = revisions_of(*store);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].note, "upgraded from format 5");
  EXPECT_EQ(all[0].objects, 4u);
  objects[2].origin_m.z = 3;
  ingest(*store, objects);
  EXPECT_EQ(changes_of(*store, 1, 2), (std::map<std::string, std::string>{{"/BOX-2", "modified"}}));
  auto view = store->read(error);
  std::vector<ObjectChange> changes;
  EXPECT_FALSE(view->changes(0, 2, changes, error));
  EXPECT_NE(error.find("revision 1's changes are not known: it upgraded a format 5 store"),
            std::string::npos) << error;
  Object o;
  bool found;
  ASSERT_TRUE(view->object_at(1, objects[2].id, o, found, false, error)) << error;
  EXPECT_EQ(o.origin_m.z, 0.0);
  view.reset();
  store.reset();
  // Read-only now works.
  EXPECT_TRUE(Store::open(dir.str(), Store::Mode::read_only, error)) << error;
}

std::string read_all(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Two writers: the second fails naming the first (no wait) or waits, saying for whom.
TEST(Revisions, ASecondWriterNamesTheFirstAndWaitsOrFails) {
  TempDir dir;
  { auto store = open_store(dir); ingest(*store, boxes(2)); }
  int go[2], ready[2];
  ASSERT_EQ(pipe(go), 0);
  ASSERT_EQ(pipe(ready), 0);
  const pid_t holder = fork();
  ASSERT_GE(holder, 0);
  if (holder == 0) {
    set_import_threads(1);
    std::string error;
    auto store = Store::open(dir.str(), Store::Mode::read_write, error);
    auto import = store ? store->begin_import(error) : nullptr;
    char c = import ? 'y' : 'n';
    if (write(ready[1], &c, 1) != 1) _exit(3);
    if (!import || read(go[0], &c, 1) != 1) _exit(2);
    import->put(box(9, 90), error);
    _exit(import->commit(error) ? 0 : 1);
  }
  char c = 0;
  ASSERT_EQ(read(ready[0], &c, 1), 1);
  ASSERT_EQ(c, 'y');
  const std::string who = "the import by pid " + std::to_string(holder) + " (";
  EXPECT_NE(read_all(dir.str() + "/import.writer").find(std::to_string(holder)), std::string::npos);
  // No wait: a clean failure naming the other writer, from open() (which needs the lock to
  // create databases) and from begin_import().
  set_import_lock_wait(false);
  std::string error;
  EXPECT_FALSE(Store::open(dir.str(), Store::Mode::read_write, error));
  EXPECT_NE(error.find("store " + dir.str() + ": busy: " + who), std::string::npos) << error;
  EXPECT_NE(error.find("plantview_revisions_tests"), std::string::npos) << error;
  set_import_lock_wait(true);
  // A waiting writer, in a process of its own, says for whom on stderr.
  const std::string log = dir.str() + ".stderr";
  const pid_t waiter = fork();
  ASSERT_GE(waiter, 0);
  if (waiter == 0) {
    set_import_threads(1);
    if (!freopen(log.c_str(), "w", stderr)) _exit(3);
    std::string e;
    auto store = Store::open(dir.str(), Store::Mode::read_write, e);
    auto import = store ? store->begin_import(e) : nullptr;
    if (!import) _exit(2);
    import->put(box(10, 100), e);
    _exit(import->commit(e) ? 0 : 1);
  }
  for (int i = 0; i < 200 && read_all(log).empty(); ++i) usleep(10000);
  EXPECT_NE(read_all(log).find("store " + dir.str() + ": waiting for " + who), std::string::npos)
      << read_all(log);
  c = 'g';
  ASSERT_EQ(write(go[1], &c, 1), 1);
  int status = 0;
  ASSERT_EQ(waitpid(holder, &status, 0), holder);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ASSERT_EQ(waitpid(waiter, &status, 0), waiter);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  std::filesystem::remove(log);
  auto store = open_store(dir);
  EXPECT_EQ(revisions_of(*store).size(), 3u);
  EXPECT_FALSE(std::filesystem::exists(dir.str() + "/import.writer"));
  for (int fd : {go[0], go[1], ready[0], ready[1]}) close(fd);
}

// A writer killed mid-commit: a reader that was reading goes on, and the store keeps the last
// commit (revision, counts); the next import goes on from there.
TEST(Revisions, AnImportKilledMidwayLeavesTheLastCommit) {
  TempDir dir;
  auto store = open_store(dir);
  ingest(*store, boxes(50));
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    set_import_threads(1);
    detail::set_import_stage_hook([](const char* stage) {
      if (std::strcmp(stage, "blocks written") == 0) raise(SIGKILL);
    });
    std::string e;
    auto other = Store::open(dir.str(), Store::Mode::read_write, e);
    if (!other) _exit(2);
    std::vector<Object> changed = boxes(80);
    changed[3].origin_m.z = 9;
    IngestControl control;
    ingest_objects(*other, changed, control);
    _exit(1);  // not reached
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
  Object o;
  ASSERT_TRUE(view->object(0, o, false, error)) << error;
  auto after = store->read(error);
  ASSERT_TRUE(after) << error;
  EXPECT_EQ(after->info().revision, 1u);
  EXPECT_EQ(after->info().objects, 50u);
  EXPECT_EQ(revisions_of(*store).size(), 1u);
  // The dead writer's file names a process that is gone: ignored, and the next import proceeds.
  EXPECT_TRUE(std::filesystem::exists(dir.str() + "/import.writer"));
  view.reset();
  after.reset();
  std::vector<Object> changed = boxes(51);
  ingest(*store, changed);
  EXPECT_EQ(changes_of(*store, 1, 2), (std::map<std::string, std::string>{{"/BOX-50", "added"}}));
}

// ---- the commands (the built plantview binary)

struct Outcome {
  int status = -1;
  std::string out, err;
};

Outcome run(const TempDir& scratch, const std::string& args) {
  const std::string out = scratch.str() + "/stdout", err = scratch.str() + "/stderr";
  std::filesystem::create_directories(scratch.path());
  const std::string cmd = std::string(PLANTVIEW_BIN) + " " + args + " >" + out + " 2>" + err;
  const int raw = std::system(cmd.c_str());
  Outcome r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = read_all(out);
  r.err = read_all(err);
  return r;
}

std::string write_plant(const TempDir& scratch, const std::string& name,
                        const std::vector<Object>& objects) {
  std::string text;
  XmlError error;
  EXPECT_TRUE(write_xml(objects, text, error)) << error.message;
  std::filesystem::create_directories(scratch.path());
  const std::string path = scratch.str() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(RevisionsCli, ImportRevisionsChangesAndInfo) {
  TempDir scratch, store;
  std::vector<Object> objects = boxes(5);
  for (Object& o : objects) o.source = "plant.xml";
  for (Object& o : objects) o.id = object_id(o.source, o.name);
  const std::string s = " --store " + store.str();
  const std::string first = write_plant(scratch, "plant.xml", objects);
  EXPECT_EQ(run(scratch, "import " + first + s + " --keep-revisions 0").status, 2);
  Outcome r = run(scratch, "import " + first + s + " --note 'first export' --keep-revisions 2");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("(revision 1: 5 added, 0 removed, 0 modified)"), std::string::npos) << r.err;
  objects[1].origin_m.z = 4;
  objects.pop_back();
  write_plant(scratch, "plant.xml", objects);
  r = run(scratch, "import " + first + s + " --keep-revisions 2");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("(revision 2: 0 added, 1 removed, 1 modified)"), std::string::npos) << r.err;

  r = run(scratch, "revisions --json" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto revisions = nlohmann::json::parse(r.out);
  ASSERT_EQ(revisions.size(), 2u);
  EXPECT_EQ(revisions[0]["revision"], 1);
  EXPECT_EQ(revisions[0]["note"], "first export");
  EXPECT_EQ(revisions[0]["added"], 5);
  EXPECT_EQ(revisions[1]["modified"], 1);
  ASSERT_EQ(revisions[1]["sources"].size(), 1u);  // the file's canonical path
  EXPECT_EQ(revisions[1]["sources"][0], std::filesystem::canonical(first).string());
  r = run(scratch, "revisions" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("first export; " + std::filesystem::canonical(first).string()),
            std::string::npos) << r.out;

  r = run(scratch, "changes --from 1 --json" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto changes = nlohmann::json::parse(r.out);
  EXPECT_EQ(changes["from"], 1);
  EXPECT_EQ(changes["to"], 2);
  ASSERT_EQ(changes["changes"].size(), 2u);
  for (const auto& c : changes["changes"]) {
    EXPECT_TRUE((c["tag"] == "/BOX-1" && c["kind"] == "modified" && c["class"] == "equipment") ||
                (c["tag"] == "/BOX-4" && c["kind"] == "removed" && c["class"] == "structure"))
        << c.dump();
    EXPECT_EQ(c["revision"], 2);
    EXPECT_TRUE(c["id"].is_string());
  }
  r = run(scratch, "changes --from 0 --to 1" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("5 added, 0 removed, 0 modified"), std::string::npos) << r.out;
  r = run(scratch, "changes --from 2" + s);  // nothing since the newest
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("0 added, 0 removed, 0 modified"), std::string::npos) << r.out;

  // Bad arguments: 2; a revision that does not exist or was pruned: 1, naming it.
  EXPECT_EQ(run(scratch, "changes" + s).status, 2);
  EXPECT_EQ(run(scratch, "changes --from x" + s).status, 2);
  EXPECT_EQ(run(scratch, "changes --from -1" + s).status, 2);
  EXPECT_EQ(run(scratch, "changes --from 2 --to 1" + s).status, 2);
  r = run(scratch, "changes --from 1 --to 7" + s);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("no revision 7 (the newest is 2)"), std::string::npos) << r.err;
  r = run(scratch, "changes --from 5" + s);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("no revision 5 (the newest is 2)"), std::string::npos) << r.err;
  r = run(scratch, "import " + first + s + " --keep-revisions 2");  // 3: prunes 1
  ASSERT_EQ(r.status, 0) << r.err;
  r = run(scratch, "changes --from 0" + s);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("revision 1's changes were pruned: the store keeps the last 2"),
            std::string::npos) << r.err;

  r = run(scratch, "info --json" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto info = nlohmann::json::parse(r.out);
  EXPECT_EQ(info["revision"], 3);
  EXPECT_EQ(info["format_version"], 6);
  EXPECT_EQ(info["revision_time"].get<std::string>().size(), 20u);
  r = run(scratch, "info" + s);
  EXPECT_NE(r.out.find("revision 3, committed "), std::string::npos) << r.out;
}

TEST(RevisionsCli, UpgradeAndNoWait) {
  TempDir scratch, store;
  {
    auto opened = open_store(store);
    ingest(*opened, boxes(3));
  }
  make_format_5(store.str());
  const std::string s = " --store " + store.str();
  Outcome r = run(scratch, "info" + s);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("format 5, run `plantview upgrade --store"), std::string::npos) << r.err;
  r = run(scratch, "upgrade" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  r = run(scratch, "revisions --json" + s);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)[0]["note"], "upgraded from format 5");

  // An import while another holds the store: --no-wait fails at once, naming it.
  int go[2], ready[2];
  ASSERT_EQ(pipe(go), 0);
  ASSERT_EQ(pipe(ready), 0);
  const pid_t holder = fork();
  ASSERT_GE(holder, 0);
  if (holder == 0) {
    set_import_threads(1);
    std::string error;
    auto opened = Store::open(store.str(), Store::Mode::read_write, error);
    auto import = opened ? opened->begin_import(error) : nullptr;
    char c = import ? 'y' : 'n';
    if (write(ready[1], &c, 1) != 1 || read(go[0], &c, 1) != 1) _exit(2);
    _exit(0);  // abandoned
  }
  char c = 0;
  ASSERT_EQ(read(ready[0], &c, 1), 1);
  ASSERT_EQ(c, 'y');
  const std::string file = write_plant(scratch, "more.xml", {box(20, 60)});
  r = run(scratch, "import " + file + s + " --no-wait");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("busy: the import by pid " + std::to_string(holder)), std::string::npos)
      << r.err;
  ASSERT_EQ(write(go[1], &c, 1), 1);
  int status;
  ASSERT_EQ(waitpid(holder, &status, 0), holder);
  r = run(scratch, "import " + file + s + " --no-wait");
  EXPECT_EQ(r.status, 0) << r.err;
  for (int fd : {go[0], go[1], ready[0], ready[1]}) close(fd);
}

}  // namespace
}  // namespace plantview
