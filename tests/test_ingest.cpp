// The ingest pipeline (plantview/ingest.h): files, generated plants and objects in memory into a
// store, its progress reports, cancellation, failures and replacement of a source.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <stop_token>
#include <thread>

#include "plantview/ingest.h"
#include "plantview/xml.h"
#include "support/rvm_writer.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using testing::RvmWriter;
using testing::rvm_matrix;

class Ingest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("plantview-ingest-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::unique_ptr<Store> open(const std::string& name = "store") {
    std::string error;
    auto store = Store::open((dir_ / name).string(), Store::Mode::read_write, error);
    EXPECT_TRUE(store) << error;
    return store;
  }
  fs::path write(const std::string& name, std::string_view bytes) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }
  fs::path write(const std::string& name, std::span<const std::byte> bytes) {
    return write(name, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  }
  fs::path dir_;
};

// ---- inputs

// An RVM with one group per name, each holding one box (and every third one a cylinder too).
std::vector<std::byte> rvm_bytes(const std::vector<std::string>& names) {
  RvmWriter w;
  w.head(2, "plantview test writer", "", "2024-05-01", "abcd", "UTF-8");
  w.model(1, "PROJ", "/MODEL");
  const std::array<float, 6> bounds{-500, -500, -500, 500, 500, 500};
  const std::vector<float> box{100, 200, 300}, cylinder{75, 1000};
  for (size_t i = 0; i < names.size(); ++i) {
    const auto m = rvm_matrix(glm::mat3(1.0f), glm::vec3(float(i) * 2.0f, 0, 0));
    w.begin_group(2, names[i], {0, 0, 0}, 1);
    w.primitive("PRIM", 2, m, bounds, box);
    if (i % 3 == 0) w.primitive("PRIM", 8, m, bounds, cylinder);
    w.end_group();
  }
  w.end();
  return w.bytes();
}

// The attribute file of those groups: every group of the given PDMS type.
std::string attribute_text(const std::vector<std::string>& names, const std::string& type) {
  std::string t = "CADC_Attributes_File v1.0 , start: NEW , end: END , name_end: := , sep: &end&\n";
  for (const std::string& n : names) t += "NEW " + n + "\n  Type:= " + type + " &end& Tag:= '" + n + "'\nEND\n";
  return t;
}

std::vector<std::string> group_names(const std::string& prefix, int count) {
  std::vector<std::string> names;
  for (int i = 0; i < count; ++i) names.push_back(prefix + std::to_string(i));
  return names;
}

Object box_object(const std::string& source, const std::string& name, double x) {
  Object o;
  o.name = name;
  o.source = source;
  o.id = object_id(source, name);
  o.object_class = ObjectClass::equipment;
  o.origin_m = {x, 1, 2};
  o.primitives.push_back(Primitive{Placement{}, Box{1, 2, 3}});
  o.attributes = {{"Type", "EQUI"}};
  return o;
}

std::string xml_text(const std::vector<Object>& objects) {
  std::string out;
  XmlError error;
  EXPECT_TRUE(write_xml(objects, out, error)) << error.message;
  return out;
}

// ---- what a store holds

// Every object with its slot, source and full content (as XML), the statistics and the spatial
// index entries: equal
// snapshots mean the store holds the same model (records, ids, statistics, spatial index).
struct Snapshot {
  std::vector<uint64_t> ids;  // in slot order
  uint64_t content_hash = 0;  // FNV-1a over slot, source and XML of every object
  std::string statistics;
  bool operator==(const Snapshot&) const = default;
};

Snapshot snapshot(const Store& store) {
  std::string error;
  auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  Snapshot s;
  if (!view) return s;
  s.content_hash = 1469598103934665603ull;
  auto mix = [&](std::string_view bytes) {
    for (char c : bytes) s.content_hash = (s.content_hash ^ uint8_t(c)) * 1099511628211ull;
  };
  EXPECT_TRUE(view->for_each_object(
      [&](uint32_t slot, Object&& o) {
        s.ids.push_back(o.id);
        std::string text = std::to_string(slot) + "|" + o.source + "|";
        XmlError xml_error;
        EXPECT_TRUE(append_xml_object(text, o, xml_error)) << xml_error.message;
        mix(text);
        return true;
      },
      true, error))
      << error;
  // The spatial index too: every entry's slot and bounds, in tree order.
  EXPECT_TRUE(view->for_each_spatial_entry(
      [&](const SpatialNode& leaf, const SpatialEntry& e) {
        float mn[3], mx[3];
        entry_bounds(leaf, e, mn, mx);
        mix(std::string_view(reinterpret_cast<const char*>(&e.slot), sizeof e.slot));
        mix(std::string_view(reinterpret_cast<const char*>(mn), sizeof mn));
        mix(std::string_view(reinterpret_cast<const char*>(mx), sizeof mx));
        return true;
      },
      error))
      << error;
  s.statistics = statistics_json(view->info().statistics);
  return s;
}

std::set<std::string> names_of_source(const Store& store, const std::string& source) {
  std::string error;
  auto view = store.read(error);
  std::set<std::string> names;
  EXPECT_TRUE(view->for_each_object(
      [&](uint32_t, Object&& o) {
        if (o.source == source) names.insert(o.name);
        return true;
      },
      false, error));
  return names;
}

ImportPlan plan_of(std::vector<std::string> files) {
  std::string error;
  auto plan = plan_import(files, error);
  EXPECT_TRUE(plan) << error;
  return plan ? *plan : ImportPlan{};
}

std::string source_name(const fs::path& p) { return fs::weakly_canonical(p).string(); }

// ---- files

TEST_F(Ingest, AnRvmIsImportedWithTheAttributeFileBesideIt) {
  const auto names = group_names("/E-", 7);
  const fs::path rvm = write("UNIT.rvm", rvm_bytes(names));
  write("UNIT.txt", attribute_text(names, "EQUI"));
  auto store = open();
  const IngestResult r = ingest_files(*store, plan_of({rvm.string()}));
  ASSERT_TRUE(r) << r.error().message;
  const IngestSummary& s = r.summary();
  ASSERT_EQ(s.files.size(), 1u);
  EXPECT_EQ(s.files[0].path, rvm.string());
  EXPECT_EQ(s.files[0].source, source_name(rvm));
  EXPECT_EQ(s.files[0].attributes_path, (dir_ / "UNIT.txt").string());
  EXPECT_EQ(s.files[0].groups, 7u);
  EXPECT_EQ(s.files[0].primitives, 10u);  // 7 boxes, 3 cylinders
  EXPECT_EQ(s.files[0].objects, 7u);
  EXPECT_EQ(s.added.objects, 7u);
  EXPECT_EQ(s.added.primitives, 10u);
  EXPECT_EQ(s.added.objects_by_class[int(ObjectClass::equipment)], 7u);
  EXPECT_GT(s.added.triangles, 0u);

  std::string error;
  auto view = store->read(error);
  EXPECT_EQ(view->info().statistics.triangles, s.added.triangles);
  size_t seen = 0;
  ASSERT_TRUE(view->for_each_object(
      [&](uint32_t, Object&& o) {
        ++seen;
        EXPECT_EQ(o.source, source_name(rvm));
        EXPECT_EQ(o.object_class, ObjectClass::equipment) << o.name << ": class from the attributes";
        return true;
      },
      true, error));
  EXPECT_EQ(seen, 7u);
}

TEST_F(Ingest, AnAttributeFileGivenAmongTheFilesWinsOverTheOneBesideTheRvm) {
  const auto names = group_names("/S-", 3);
  const fs::path rvm = write("UNIT.RVM", rvm_bytes(names));
  write("UNIT.txt", attribute_text(names, "EQUI"));
  fs::create_directories(dir_ / "other");
  const fs::path given = write("other/UNIT.att", attribute_text(names, "STRU"));
  auto store = open();
  const IngestResult r = ingest_files(*store, plan_of({given.string(), rvm.string()}));
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r.summary().files[0].attributes_path, given.string());
  EXPECT_EQ(r.summary().added.objects_by_class[int(ObjectClass::structure)], 3u);
}

TEST_F(Ingest, AnXmlFileIsImportedObjectForObjectUnderItsOwnSource) {
  std::vector<Object> objects;
  for (int i = 0; i < 5; ++i) objects.push_back(box_object("elsewhere", "/B-" + std::to_string(i), i * 3.0));
  const fs::path xml = write("plant.xml", xml_text(objects));
  auto store = open();
  const IngestResult r = ingest_files(*store, plan_of({xml.string()}));
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r.summary().files[0].xml);
  EXPECT_EQ(r.summary().files[0].objects, 5u);
  EXPECT_EQ(r.summary().files[0].primitives, 5u);
  std::string error;
  auto view = store->read(error);
  for (Object expected : objects) {
    const auto slot = view->slot_of(expected.id);
    ASSERT_TRUE(slot) << expected.name;
    Object o;
    ASSERT_TRUE(view->object(*slot, o, true, error)) << error;
    expected.source = source_name(xml);
    EXPECT_TRUE(o == expected) << expected.name;
  }
}

TEST_F(Ingest, PlanningRefusesNamesItCannotImport) {
  std::string error;
  const std::vector<std::string> doc{"a.rvm", "notes.doc"}, orphan{"a.rvm", "b.txt"}, none{"a.txt"};
  EXPECT_FALSE(plan_import(doc, error));
  EXPECT_EQ(error, "notes.doc: not an .rvm, .xml, .txt or .att file");
  EXPECT_FALSE(plan_import(orphan, error));
  EXPECT_EQ(error, "b.txt: attribute file without an RVM file of the same name");
  EXPECT_FALSE(plan_import(std::span<const std::string>(), error));
  EXPECT_EQ(error, "no .rvm or .xml file given");
  EXPECT_FALSE(plan_import(none, error));
  const std::vector<std::string> good{"x/A.ATT", "x/A.RVM", "b.Xml"};
  const auto plan = plan_import(good, error);
  ASSERT_TRUE(plan) << error;
  ASSERT_EQ(plan->models.size(), 2u);
  EXPECT_EQ(plan->models[0].attributes, fs::path("x/A.ATT"));
  EXPECT_TRUE(plan->models[1].xml);
}

// ---- generated plants and objects in memory

TEST_F(Ingest, PresetAIsGeneratedUnderItsSourceWithTheGeneratorsCounts) {
  auto store = open();
  GenerateOptions options;
  options.preset = 'a';
  const IngestResult r = ingest_generated(*store, options);
  ASSERT_TRUE(r) << r.error().message;
  const IngestSummary& s = r.summary();
  EXPECT_GT(s.generated.objects, 10000u);
  EXPECT_EQ(s.added.objects, s.generated.objects);
  EXPECT_EQ(s.added.primitives, s.generated.primitives);
  std::string error;
  auto view = store->read(error);
  EXPECT_EQ(view->info().objects, s.generated.objects);
  EXPECT_EQ(view->info().statistics.triangles, s.added.triangles);
  EXPECT_EQ(names_of_source(*store, "gen:a").size(), s.generated.objects);

  // Again: replaced, not doubled, and the same model.
  const Snapshot first = snapshot(*store);
  ASSERT_TRUE(ingest_generated(*store, options));
  EXPECT_EQ(snapshot(*store).ids.size(), first.ids.size());
  EXPECT_EQ(snapshot(*store).statistics, first.statistics);
}

std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// The generator on its own thread, the blocks compressed on a pool, or everything on the calling
// thread: the same store, down to the bytes of its data file when generated afresh, and the same
// content after the plant is replaced (which reads back, erases and rewrites stored blocks). The
// bytes of a replaced store are not compared: pages LMDB reuses within a transaction keep stale
// bytes in their unused gaps (even heap addresses, which differ from run to run of the same
// command), outside any key or value.
TEST_F(Ingest, AGeneratedStoreIsTheSameByteForByteWhateverTheThreadCount) {
  struct Restore {
    ~Restore() {
      set_import_threads(0);
      unsetenv("SOURCE_DATE_EPOCH");
    }
  } restore;
  setenv("SOURCE_DATE_EPOCH", "1765000000", 1);  // the revisions' times (store.h)
  std::vector<std::string> first;
  std::vector<Snapshot> snapshots;
  for (const unsigned threads : {1u, 4u}) {
    set_import_threads(threads);
    const std::string name = "store" + std::to_string(threads);
    auto store = open(name);
    GenerateOptions options;
    options.preset = 'c';
    options.scale = 1;  // about 40 000 objects: more blocks than are ever in flight
    const IngestResult r = ingest_generated(*store, options);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r.summary().added.objects, r.summary().generated.objects);
    first.push_back(file_bytes(dir_ / name / "data.mdb"));
    options.seed = 5;
    ASSERT_TRUE(ingest_generated(*store, options));
    snapshots.push_back(snapshot(*store));
  }
  for (size_t i = 1; i < first.size(); ++i) {
    EXPECT_TRUE(first[i] == first[0]) << "run " << i << " wrote another data file";
    EXPECT_TRUE(snapshots[i] == snapshots[0]);
  }
  EXPECT_GT(first[0].size(), 1000000u);
}

TEST_F(Ingest, ObjectsInMemoryReplaceWhatTheirSourcesBroughtBefore) {
  auto store = open();
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("a", "/A1", 0), box_object("a", "/A2", 1),
                                                  box_object("b", "/B1", 2)}));
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("a", "/A3", 0)}));
  EXPECT_EQ(names_of_source(*store, "a"), std::set<std::string>{"/A3"});
  EXPECT_EQ(names_of_source(*store, "b"), std::set<std::string>{"/B1"});
}

// ---- progress

// Checks the order the header promises and returns the stages seen.
std::vector<IngestStage> check_order(const std::vector<IngestProgress>& reports) {
  std::vector<IngestStage> stages;
  EXPECT_FALSE(reports.empty());
  for (size_t i = 0; i < reports.size(); ++i) {
    const IngestProgress& p = reports[i];
    EXPECT_GE(p.total, 1u);
    EXPECT_LE(p.done, p.total);
    if (stages.empty() || stages.back() != p.stage) stages.push_back(p.stage);
    if (i == 0) continue;
    const IngestProgress& q = reports[i - 1];
    EXPECT_GE(p.file_index, q.file_index) << "report " << i;
    if (p.file_index != q.file_index) continue;
    EXPECT_GE(int(p.stage), int(q.stage)) << "report " << i << ": " << stage_name(p.stage) << " after "
                                          << stage_name(q.stage);
    if (p.stage == q.stage) {
      EXPECT_GE(p.done, q.done) << "report " << i << " (" << stage_name(p.stage) << ")";
    }
  }
  if (!reports.empty()) {
    EXPECT_EQ(reports.back().stage, IngestStage::committing);
    EXPECT_EQ(reports.back().done, 1u);
  }
  return stages;
}

TEST_F(Ingest, ProgressOfFilesComesInOrderPerFileAndEndsWithTheCommit) {
  const auto names = group_names("/E-", 20);
  const fs::path rvm = write("UNIT.rvm", rvm_bytes(names));
  write("UNIT.txt", attribute_text(names, "EQUI"));
  std::vector<Object> objects;
  for (int i = 0; i < 4000; ++i) objects.push_back(box_object("x", "/X-" + std::to_string(i), i));
  const fs::path xml = write("plant.xml", xml_text(objects));  // over 1 MB: several blocks
  ASSERT_GT(fs::file_size(xml), 1u << 20);

  std::vector<IngestProgress> reports;
  std::vector<std::string> paths;
  IngestControl control;
  control.progress = [&](const IngestProgress& p) {
    reports.push_back(p);
    paths.emplace_back(p.path);
  };
  auto store = open();
  ASSERT_TRUE(ingest_files(*store, plan_of({rvm.string(), xml.string()}), control));
  const auto stages = check_order(reports);
  EXPECT_EQ(stages, (std::vector<IngestStage>{IngestStage::parsing, IngestStage::classifying,
                                              IngestStage::storing, IngestStage::reading,
                                              IngestStage::committing}));
  for (size_t i = 0; i < reports.size(); ++i) {
    if (reports[i].stage == IngestStage::committing) {
      EXPECT_TRUE(paths[i].empty());
      continue;
    }
    EXPECT_EQ(reports[i].file_count, 2u);
    EXPECT_EQ(paths[i], (reports[i].file_index == 0 ? rvm : xml).string());
  }
  // Each file's last report before the commit says it is complete.
  const auto last_of = [&](IngestStage stage) {
    IngestProgress last;
    for (const auto& p : reports) if (p.stage == stage) last = p;
    return last;
  };
  EXPECT_EQ(last_of(IngestStage::storing).done, 20u);
  EXPECT_EQ(last_of(IngestStage::storing).total, 20u);
  EXPECT_EQ(last_of(IngestStage::reading).done, fs::file_size(xml));
  EXPECT_EQ(last_of(IngestStage::reading).total, fs::file_size(xml));
}

TEST_F(Ingest, ProgressOfAGeneratedPlantCountsThousandthsOfAUnit) {
  std::vector<IngestProgress> reports;
  IngestControl control;
  control.progress = [&](const IngestProgress& p) { reports.push_back(p); };
  auto store = open();
  GenerateOptions options;
  options.preset = 'a';
  options.scale = 2;
  ASSERT_TRUE(ingest_generated(*store, options, control));
  EXPECT_EQ(check_order(reports), (std::vector<IngestStage>{IngestStage::generating, IngestStage::committing}));
  EXPECT_GT(reports.size(), 10u) << "more than a start and an end";
  EXPECT_EQ(reports.front().done, 0u);
  EXPECT_EQ(reports.front().total, 2000u);
  EXPECT_EQ(reports[reports.size() - 3].done, 2000u) << "the generator's last report, before the commit's two";
}

// ---- cancellation and failures

// Runs `ingest` once without stopping to count its reports, then again on `store` with a stop
// requested at report k for several k, and checks each time that the call says "cancelled" and
// the store holds what it held before.
void expect_cancellable(Store& scratch, Store& store,
                        const std::function<IngestResult(Store&, const IngestControl&)>& ingest) {
  size_t count = 0;
  IngestControl counting;
  counting.progress = [&](const IngestProgress&) { ++count; };
  ASSERT_TRUE(ingest(scratch, counting));
  ASSERT_GE(count, 4u);
  const size_t before_commit = count - 2;  // the last two reports are the commit's
  const Snapshot before = snapshot(store);
  std::vector<size_t> points{0, 1, before_commit / 3, before_commit / 2, before_commit - 1};
  for (size_t k : points) {
    std::stop_source source;
    size_t seen = 0;
    IngestControl control;
    control.stop = source.get_token();
    control.progress = [&](const IngestProgress&) {
      if (seen++ == k) source.request_stop();
    };
    const IngestResult r = ingest(store, control);
    ASSERT_FALSE(r) << "a stop at report " << k << " of " << count << " was not noticed";
    EXPECT_EQ(r.error().kind, IngestError::Kind::cancelled);
    EXPECT_EQ(r.error().message, "cancelled");
    EXPECT_LE(seen, k + 2) << "the call went on after the stop";
    EXPECT_TRUE(snapshot(store) == before) << "store changed by a call stopped at report " << k;
  }
  // A stop requested before the call: nothing happens at all.
  std::stop_source early;
  early.request_stop();
  IngestControl control;
  control.stop = early.get_token();
  const IngestResult r = ingest(store, control);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().kind, IngestError::Kind::cancelled);
  EXPECT_TRUE(snapshot(store) == before);
}

TEST_F(Ingest, CancellingAFileImportAtAnyPointLeavesTheStoreAsItWas) {
  const auto names = group_names("/E-", 30);
  const fs::path rvm = write("UNIT.rvm", rvm_bytes(names));
  write("UNIT.txt", attribute_text(names, "EQUI"));
  std::vector<Object> objects;
  for (int i = 0; i < 4000; ++i) objects.push_back(box_object("x", "/X-" + std::to_string(i), i));
  const fs::path xml = write("plant.xml", xml_text(objects));
  const ImportPlan plan = plan_of({rvm.string(), xml.string()});
  auto scratch = open("scratch");
  auto store = open();
  // The store already holds an earlier version of the same RVM, and another source.
  write("UNIT.rvm", rvm_bytes(group_names("/OLD-", 4)));
  ASSERT_TRUE(ingest_files(*store, plan_of({rvm.string()})));
  write("UNIT.rvm", rvm_bytes(names));
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("keep", "/KEEP", 0)}));
  expect_cancellable(*scratch, *store,
                     [&](Store& s, const IngestControl& c) { return ingest_files(s, plan, c); });
}

TEST_F(Ingest, CancellingGenerationAtAnyPointLeavesTheStoreAsItWas) {
  auto scratch = open("scratch");
  auto store = open();
  GenerateOptions options;
  options.preset = 'a';
  options.seed = 7;
  ASSERT_TRUE(ingest_generated(*store, options));  // the preset's earlier plant, to be kept
  options.seed = 8;
  expect_cancellable(*scratch, *store,
                     [&](Store& s, const IngestControl& c) { return ingest_generated(s, options, c); });
}

TEST_F(Ingest, CancellingObjectsInMemoryLeavesTheStoreAsItWas) {
  auto scratch = open("scratch");
  auto store = open();
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("a", "/A-OLD", 0)}));
  std::vector<Object> objects;
  for (int i = 0; i < 100; ++i) objects.push_back(box_object("a", "/A-" + std::to_string(i), i));
  expect_cancellable(*scratch, *store,
                     [&](Store& s, const IngestControl& c) { return ingest_objects(s, objects, c); });
}

TEST_F(Ingest, AStopFromAnotherThreadEndsAGenerationEarly) {
  auto store = open();
  const Snapshot before = snapshot(*store);
  std::stop_source source;
  std::atomic<bool> started{false};
  IngestControl control;
  control.stop = source.get_token();
  control.progress = [&](const IngestProgress&) { started = true; };
  std::thread stopper([&] {
    while (!started) std::this_thread::yield();
    source.request_stop();
  });
  GenerateOptions options;
  options.preset = 'c';
  options.scale = 20;  // seconds of work if it were not stopped
  const auto start = std::chrono::steady_clock::now();
  const IngestResult r = ingest_generated(*store, options, control);
  stopper.join();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().kind, IngestError::Kind::cancelled);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_TRUE(snapshot(*store) == before);
}

TEST_F(Ingest, ATruncatedRvmFailsNamingTheFileAndOffsetAndLeavesTheStoreAsItWas) {
  const auto names = group_names("/E-", 10);
  const fs::path good = write("GOOD.rvm", rvm_bytes(names));
  const auto bytes = rvm_bytes(group_names("/C-", 10));
  const fs::path cut = write("CUT.rvm", std::span(bytes).first(bytes.size() / 2));
  auto store = open();
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("keep", "/KEEP", 0)}));
  const Snapshot before = snapshot(*store);
  const IngestResult r = ingest_files(*store, plan_of({good.string(), cut.string()}));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().kind, IngestError::Kind::input);
  EXPECT_EQ(r.error().path, cut.string());
  EXPECT_NE(r.error().message.find(cut.string()), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("offset"), std::string::npos) << r.error().message;
  EXPECT_TRUE(snapshot(*store) == before);
}

TEST_F(Ingest, BadXmlAndBadAttributesFailNamingTheFileAndLine) {
  auto store = open();
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("keep", "/KEEP", 0)}));
  const Snapshot before = snapshot(*store);

  const std::string text = xml_text({box_object("x", "/X", 0), box_object("x", "/Y", 1)});
  const fs::path xml = write("cut.xml", text.substr(0, text.size() - 40));
  IngestResult r = ingest_files(*store, plan_of({xml.string()}));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().path, xml.string());
  EXPECT_EQ(r.error().message.rfind(xml.string() + ":", 0), 0u) << r.error().message;
  EXPECT_TRUE(snapshot(*store) == before);

  const auto names = group_names("/E-", 3);
  const fs::path rvm = write("UNIT.rvm", rvm_bytes(names));
  const fs::path att = write("UNIT.att", attribute_text(names, "EQUI") + "END\n");
  r = ingest_files(*store, plan_of({rvm.string()}));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().path, att.string());
  EXPECT_EQ(r.error().message.rfind(att.string() + ":", 0), 0u) << r.error().message;
  EXPECT_TRUE(snapshot(*store) == before);

  r = ingest_files(*store, plan_of({(dir_ / "missing.rvm").string()}));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().path, (dir_ / "missing.rvm").string());
  EXPECT_TRUE(snapshot(*store) == before);
}

TEST_F(Ingest, ReimportingAFileReplacesWhatItBroughtAndKeepsOtherSources) {
  const fs::path rvm = write("UNIT.rvm", rvm_bytes(group_names("/E-", 6)));
  auto store = open();
  ASSERT_TRUE(ingest_objects(*store, std::vector{box_object("keep", "/KEEP", 0)}));
  ASSERT_TRUE(ingest_files(*store, plan_of({rvm.string()})));
  EXPECT_EQ(names_of_source(*store, source_name(rvm)).size(), 6u);
  write("UNIT.rvm", rvm_bytes(group_names("/F-", 2)));
  ASSERT_TRUE(ingest_files(*store, plan_of({rvm.string()})));
  EXPECT_EQ(names_of_source(*store, source_name(rvm)), (std::set<std::string>{"/F-0", "/F-1"}));
  EXPECT_EQ(names_of_source(*store, "keep"), std::set<std::string>{"/KEEP"});
  // The same file named another way is the same source.
  ASSERT_TRUE(ingest_files(*store, plan_of({(dir_ / "." / "UNIT.rvm").string()})));
  std::string error;
  EXPECT_EQ(store->read(error)->info().objects, 3u);
}

}  // namespace
}  // namespace plantview
