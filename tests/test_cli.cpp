// The plantview program end to end: gen, import, info, export, and what bad input (or a missing
// image module) does.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

namespace {

namespace fs = std::filesystem;

const fs::path kHuldra = fs::path(PLANTVIEW_SHARED_DIR) / "data" / "huldra";

struct Outcome {
  int status = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("plantview-cli-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // `environment`: NAME=VALUE settings for this run only, as the shell reads them.
  Outcome run(const std::string& args, const std::string& environment = "") {
    const fs::path out = dir_ / "stdout", err = dir_ / "stderr";
    const std::string cmd = environment + " " + std::string(PLANTVIEW_BIN) + " " + args + " >" +
                            out.string() + " 2>" + err.string();
    const int raw = std::system(cmd.c_str());
    Outcome r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }
  nlohmann::json info(const fs::path& store) {
    const Outcome r = run("info --json --store " + store.string());
    EXPECT_EQ(r.status, 0) << r.err;
    return nlohmann::json::parse(r.out, nullptr, false);
  }
  fs::path dir_;
};

TEST_F(Cli, UsageErrorsExitTwoAndHelpExitsZero) {
  EXPECT_EQ(run("--help").status, 0);
  EXPECT_EQ(run("--version").status, 0);
  EXPECT_EQ(run("").status, 2);
  EXPECT_EQ(run("frobnicate").status, 2);
  EXPECT_EQ(run("gen --preset z --store " + (dir_ / "s").string()).status, 2);
  EXPECT_EQ(run("gen --preset a --scale 0 --store " + (dir_ / "s").string()).status, 2);
  EXPECT_EQ(run("import --store " + (dir_ / "s").string() + " notes.doc").status, 2);
}

TEST_F(Cli, GenWritesAStoreThatInfoDescribes) {
  const fs::path store = dir_ / "store";
  const Outcome gen = run("gen --preset a --seed 3 --store " + store.string());
  ASSERT_EQ(gen.status, 0) << gen.err;
  EXPECT_TRUE(gen.out.empty()) << "machine-readable stdout stays empty";
  const auto j = info(store);
  EXPECT_GT(j["objects"].get<int>(), 10000);
  EXPECT_GT(j["triangles_full_resolution"].get<long>(), 1000000);
  EXPECT_GT(j["objects_by_class"]["pipe"].get<int>(), 1000);
  EXPECT_GT(j["store_bytes"].get<long>(), 0);
  // Generating the same preset again replaces it rather than doubling it.
  ASSERT_EQ(run("gen --preset a --seed 3 --store " + store.string()).status, 0);
  EXPECT_EQ(info(store)["objects"], j["objects"]);
}

TEST_F(Cli, ImportOfHuldraCountsItsPrimitivesAndReimportReplaces) {
  if (!fs::exists(kHuldra)) GTEST_SKIP() << "no " << kHuldra;
  const fs::path store = dir_ / "store";
  const std::string rvm = (kHuldra / "WD1-PSUP.RVM").string();
  Outcome r = run("import " + rvm + " --store " + store.string());
  ASSERT_EQ(r.status, 0) << r.err;
  auto j = info(store);
  EXPECT_EQ(j["primitives"], 2757);
  EXPECT_EQ(j["primitives_by_kind"]["box"], 936);
  EXPECT_EQ(j["primitives_by_kind"]["cylinder"], 624);
  EXPECT_EQ(j["primitives_by_kind"]["pyramid"], 472);
  EXPECT_EQ(j["primitives_by_kind"]["facet_group"], 334);
  EXPECT_EQ(j["primitives_by_kind"]["rectangular_torus"], 262);
  EXPECT_EQ(j["primitives_by_kind"]["line"], 129);
  EXPECT_GT(j["objects_by_class"]["structure"].get<int>(), 0) << "attributes found beside the RVM";
  r = run("import " + rvm + " --store " + store.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(info(store)["primitives"], 2757);
}

TEST_F(Cli, ATruncatedRvmFailsNamingTheOffsetAndLeavesTheStoreAsItWas) {
  if (!fs::exists(kHuldra)) GTEST_SKIP() << "no " << kHuldra;
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  const auto before = info(store);
  const std::string bytes = slurp(kHuldra / "WD1-PSUP.RVM");
  const fs::path cut = dir_ / "CUT.RVM";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  const Outcome r = run("import " + cut.string() + " --store " + store.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("CUT.RVM"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("offset"), std::string::npos) << r.err;
  EXPECT_EQ(info(store), before);
}

TEST_F(Cli, ExportedXmlImportsToTheSameModel) {
  const fs::path store = dir_ / "store", copy = dir_ / "copy", xml = dir_ / "plant.xml";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  Outcome r = run("export --store " + store.string() + " --xml " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("import " + xml.string() + " --store " + copy.string());
  ASSERT_EQ(r.status, 0) << r.err;
  auto a = info(store), b = info(copy);
  a.erase("store");
  b.erase("store");
  a.erase("store_bytes");
  b.erase("store_bytes");
  // The same model, imported another way: another commit (each commit id digests its import).
  EXPECT_NE(a["commit_id"], b["commit_id"]);
  a.erase("commit_id");
  b.erase("commit_id");
  a.erase("revision_time");  // each commit's own (both are revision 1)
  b.erase("revision_time");
  EXPECT_EQ(a, b);
}

// A damaged store: `info` and `render` exit 1 (not a signal) with the reason on stderr, and
// data.mdb keeps its bytes.
class DamagedStore : public Cli {
 protected:
  void expect_refused(const fs::path& store, const std::string& reason) {
    const std::string before = slurp(store / "data.mdb");
    const std::string commands[] = {
        "info --store " + store.string(),
        "info --json --store " + store.string(),
        "render --store " + store.string() + " --out " + (dir_ / "frame.png").string(),
    };
    for (const std::string& command : commands) {
      SCOPED_TRACE(command);
      const Outcome r = run(command);
      EXPECT_EQ(r.status, 1) << "a status over 128 is a signal: " << r.err;
      EXPECT_NE(r.err.find(reason), std::string::npos) << r.err;
      EXPECT_NE(r.err.find(store.string()), std::string::npos) << r.err;
    }
    EXPECT_TRUE(slurp(store / "data.mdb") == before) << "data.mdb changed";
  }
};

TEST_F(DamagedStore, ATruncatedDataFileFailsInfoAndRenderWithAMessage) {
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  fs::resize_file(store / "data.mdb", fs::file_size(store / "data.mdb") / 2);
  expect_refused(store, "data.mdb is truncated");
}

TEST_F(DamagedStore, AnEmptyDataFileFailsInfoAndRenderWithAMessage) {
  const fs::path store = dir_ / "store";
  fs::create_directories(store);
  std::ofstream(store / "data.mdb").close();
  expect_refused(store, "data.mdb is empty: not a plantview store");
  EXPECT_EQ(run("import " + (kHuldra / "WD1-PSUP.RVM").string() + " --store " + store.string()).status, 1);
  EXPECT_EQ(fs::file_size(store / "data.mdb"), 0u) << "an import must not take it for a new store";
}

TEST_F(DamagedStore, StatisticsOfTheWrongShapeFailInfoAndRenderNamingTheKey) {
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  // meta/"statistics" starts with {"bounds_m":{"max":[x,y,z] (keys in order): make that array a
  // string of the same length, so that the JSON stays JSON but has the wrong shape. Every copy
  // (a page an earlier commit left behind may hold one too).
  std::string bytes = slurp(store / "data.mdb");
  const std::string key = R"({"bounds_m":{"max":[)";
  int copies = 0;
  for (size_t at = bytes.find(key); at != std::string::npos; at = bytes.find(key, at + 1)) {
    bytes[at + key.size() - 1] = '"';
    const size_t close = bytes.find(']', at);
    ASSERT_NE(close, std::string::npos);
    bytes[close] = '"';
    ++copies;
  }
  ASSERT_GE(copies, 1);
  std::ofstream(store / "data.mdb", std::ios::binary | std::ios::trunc) << bytes;
  expect_refused(store, "meta/\"statistics\" is damaged: \"bounds_m.max\"");
}

TEST_F(Cli, ADirectoryGivenAsAnRvmOrAttributeFileFailsNamingIt) {
  if (!fs::exists(kHuldra)) GTEST_SKIP() << "no " << kHuldra;
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  const auto before = info(store);
  const fs::path rvm_dir = dir_ / "MODEL.RVM", att_dir = dir_ / "WD1-PSUP.txt";
  fs::create_directories(rvm_dir);
  fs::create_directories(att_dir);
  Outcome r = run("import " + rvm_dir.string() + " --store " + store.string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find(rvm_dir.string() + ": is a directory"), std::string::npos) << r.err;
  r = run("import " + (kHuldra / "WD1-PSUP.RVM").string() + " " + att_dir.string() + " --store " +
          store.string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find(att_dir.string() + ": is a directory"), std::string::npos) << r.err;
  EXPECT_EQ(info(store), before);
}

TEST_F(Cli, CompareWithoutTheImageModuleFailsNamingWhereItLooked) {
  const std::string a = (dir_ / "a.png").string(), b = (dir_ / "b.png").string();
  const Outcome r = run("compare " + a + " " + b, "PLANTVIEW_IMAGE_MODULE=" + (dir_ / "none.so").string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find("cannot load the image module"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("PLANTVIEW_IMAGE_MODULE=" + (dir_ / "none.so").string()), std::string::npos) << r.err;
}

TEST_F(Cli, AGenKilledPartWayLeavesTheStoreAsItWas) {
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  const auto before = info(store);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string s = store.string();
    execl(PLANTVIEW_BIN, PLANTVIEW_BIN, "gen", "--preset", "c", "--scale", "20", "--store", s.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "gen finished before it was killed";
  EXPECT_EQ(info(store), before);
}

// Usage errors of render and path exit 2 with a message naming what is wrong, before the store
// is opened (the store here does not exist: a usage error must be found first).
TEST_F(Cli, RenderAndPathUsageErrorsExitTwoNamingTheOption) {
  const std::string store = (dir_ / "no-store").string();
  const fs::path file = dir_ / "a-file";
  std::ofstream(file) << "x";
  const fs::path camera_path = dir_ / "path.json";
  std::ofstream(camera_path) << R"([{"eye": [1, 2, 3], "target": [0, 0, 0]}])";
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"render --store " + store + " --size 100 --out x.png", "--size"},
      {"render --store " + store + " --out x.gif", "x.gif"},
      {"render --store " + store + " --camera eye=1,2,3 --out x.png", "--camera"},
      {"render --store " + store + " --format gif --path " + camera_path.string() + " --out d", "--format"},
      {"render --store " + store + " --shard 4/4 --path " + camera_path.string() + " --out d", "--shard"},
      {"render --store " + store + " --lod-policy fast --out x.png", "--lod-policy"},
      {"render --store " + store + " --occlusion-test fast --out x.png", "--occlusion-test"},
      {"render --store " + store + " --path " + camera_path.string() + " --camera eye=1,2,3,target=0,0,0 --out d",
       "one of --camera, --path"},
      {"render --store " + store + " --path " + camera_path.string() + " --out " + (dir_ / "walk.png").string(),
       "walk.png names an image file"},
      {"render --store " + store + " --path " + camera_path.string() + " --out " + file.string(), "is a file"},
      {"path --store " + store + " --kind spiral --out p.json", "spiral"},
      {"path --store " + store + " --frames 0 --out p.json", "--frames"},
  };
  for (const Case& c : cases) {
    const Outcome r = run(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ / "walk.png")) << "no directory named like an image";
}

// Each occlusion test renders (the renderer's tests compare their images with occlusion off).
TEST_F(Cli, RenderTakesEachOcclusionTest) {
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  for (const char* test : {"automatic", "coarse", "exact"}) {
    const fs::path image = dir_ / (std::string(test) + ".png");
    const Outcome r = run("render --store " + store.string() + " --size 320x180 --occlusion-test " +
                          test + " --out " + image.string());
    EXPECT_EQ(r.status, 0) << test << ": " << r.err;
    EXPECT_GT(fs::exists(image) ? fs::file_size(image) : 0, 0u) << test;
  }
}

// --highlight takes ids and tags; one that matches no object is a usage error naming it, found
// before any file is written; the same subject by tag and by id gives the same image.
TEST_F(Cli, RenderHighlightTakesIdsAndTagsAndRefusesOneThatMatchesNothing) {
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  const Outcome views = run("views --store " + store.string() + " --per equipment --out " +
                            (dir_ / "v.json").string());
  ASSERT_EQ(views.status, 0) << views.err;
  const auto file = nlohmann::json::parse(slurp(dir_ / "v.json"));
  const std::string tag = file["views"][0]["attributes"]["tag"];
  const std::string id = std::to_string(file["views"][0]["subject"][0].get<uint64_t>());
  const std::string render = "render --store " + store.string() + " --size 160x90 ";
  for (const std::string& word : {std::string("12345"), std::string("NO-SUCH-TAG")}) {
    const fs::path image = dir_ / "none.png";
    const Outcome r = run(render + "--highlight " + tag + "," + word + " --out " + image.string());
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("--highlight: no object has the id or the tag '" + word + "'"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(image));
  }
  ASSERT_EQ(run(render + "--highlight " + tag + " --out " + (dir_ / "by-tag.png").string()).status, 0);
  ASSERT_EQ(run(render + "--highlight " + id + " --out " + (dir_ / "by-id.png").string()).status, 0);
  ASSERT_EQ(run(render + "--out " + (dir_ / "plain.png").string()).status, 0);
  EXPECT_EQ(slurp(dir_ / "by-tag.png"), slurp(dir_ / "by-id.png"));
  EXPECT_NE(slurp(dir_ / "by-tag.png"), slurp(dir_ / "plain.png"));
}

// An image into a directory that does not exist fails before anything is rendered.
TEST_F(Cli, RenderIntoAMissingDirectoryFailsBeforeRendering) {
  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  Outcome r = run("render --store " + store.string() + " --out " + (dir_ / "missing" / "y.png").string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("missing"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("rendering on"), std::string::npos) << "no GPU context was made: " << r.err;
  r = run("path --store " + store.string() + " --frames 3 --out " + (dir_ / "missing" / "p.json").string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
}

// An operator picks --device from `devices`: the default it names is the device `render` uses
// without --device, each usable index renders on that device, and one past the list is refused.
TEST_F(Cli, DevicesNamesTheDeviceRenderUsesAndTheIndicesItTakes) {
  const Outcome listed = run("devices --json");
  ASSERT_EQ(listed.status, 0) << listed.err;
  const auto j = nlohmann::json::parse(listed.out, nullptr, false);
  ASSERT_TRUE(j.is_object() && j["devices"].is_array()) << listed.out;
  const auto& devices = j["devices"];
  std::string default_description;
  if (j["default"].is_number()) {
    const int chosen = j["default"].get<int>();
    ASSERT_GE(chosen, 0);
    ASSERT_LT(size_t(chosen), devices.size());
    EXPECT_TRUE(devices[size_t(chosen)]["usable"].get<bool>());
    default_description = devices[size_t(chosen)]["description"].get<std::string>();
  } else {
    default_description = j.value("surfaceless", "");
  }
  ASSERT_FALSE(default_description.empty()) << listed.out;
  for (size_t i = 0; i < devices.size(); ++i) EXPECT_EQ(devices[i]["index"].get<size_t>(), i);

  const fs::path store = dir_ / "store";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  const std::string render = "render --store " + store.string() + " --size 64x36 --out ";
  Outcome r = run(render + (dir_ / "default.png").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("rendering on " + default_description + "\n"), std::string::npos)
      << "devices said " << default_description << "; render said " << r.err;
  for (const auto& d : devices) {
    if (!d["usable"].get<bool>()) continue;
    const std::string index = std::to_string(d["index"].get<int>());
    r = run(render + (dir_ / ("device" + index + ".png")).string() + " --device " + index);
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("rendering on " + d["description"].get<std::string>() + "\n"), std::string::npos)
        << r.err;
  }
  r = run(render + (dir_ / "none.png").string() + " --device " + std::to_string(devices.size()));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("no device " + std::to_string(devices.size())), std::string::npos) << r.err;

  const Outcome text = run("devices");
  EXPECT_EQ(text.status, 0) << text.err;
  EXPECT_NE(text.out.find(default_description), std::string::npos) << text.out;
}

}  // namespace

namespace {

// render --path writes its images on other threads while the next view renders: every image
// and its stats line still come out, the lines in view order; an image it cannot write stops
// the run with its name, after the views before it.
TEST_F(Cli, RenderPathWritesEveryImageAndItsStatsInViewOrderAndStopsAtOneItCannotWrite) {
  const fs::path store = dir_ / "store", camera_path = dir_ / "walk.json";
  ASSERT_EQ(run("gen --preset a --store " + store.string()).status, 0);
  ASSERT_EQ(run("path --store " + store.string() + " --kind orbit --frames 5 --out " + camera_path.string()).status, 0);
  const std::string render = "render --store " + store.string() + " --size 96x64 --path " + camera_path.string();
  const fs::path out = dir_ / "out";
  Outcome r = run(render + " --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream stats(out / "stats.jsonl");
  size_t view = 0;
  for (std::string line; std::getline(stats, line); ++view) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["view"], view);
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.png", view);
    EXPECT_EQ(j["file"], (out / name).string());
    EXPECT_GT(fs::file_size(out / name), 0u) << name;
    EXPECT_GT(j["ms"]["encode"].get<double>(), 0.0);
  }
  EXPECT_EQ(view, 5u);

  // A directory where view 2's image goes: it cannot be written.
  const fs::path blocked = dir_ / "blocked";
  fs::create_directories(blocked / "000002.png" / "inside");
  r = run(render + " --out " + blocked.string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find("000002.png"), std::string::npos) << r.err;
  for (const char* before : {"000000.png", "000001.png"})
    EXPECT_TRUE(fs::is_regular_file(blocked / before)) << before;
  std::ifstream blocked_stats(blocked / "stats.jsonl");
  size_t lines = 0;
  for (std::string line; std::getline(blocked_stats, line);) EXPECT_EQ(nlohmann::json::parse(line)["view"], lines++);
  EXPECT_EQ(lines, 2u) << "the views before the one that failed";
}

// Colour by, hide, only (view_filters.h) on the command line: the legend in the stats line and a
// legend strip on the image; an unknown key fails naming the keys found; empty word lists are
// usage errors; `views --colour-by` writes the style into every view.
TEST_F(Cli, RenderColourByHideOnly) {
  const std::string store = (dir_ / "s").string();
  ASSERT_EQ(run("gen --preset a --store " + store).status, 0);
  const std::string image = (dir_ / "coloured.png").string();
  Outcome r = run("render --store " + store + " --size 320x180 --colour-by Material --hide structure --out " + image);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json stats = nlohmann::json::parse(r.out);
  EXPECT_EQ(stats["legend"]["key"], "Material");
  EXPECT_EQ(stats["legend"]["kind"], "categories");
  EXPECT_GT(stats["objects_hidden"].get<int>(), 0);
  EXPECT_TRUE(fs::exists(image));
  r = run("render --store " + store + " --size 320x180 --colour-by Nonesuch --out " + image);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("'Nonesuch'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Material"), std::string::npos) << r.err;
  EXPECT_EQ(run("render --store " + store + " --only , --out " + image).status, 2);
  const std::string views = (dir_ / "views.json").string();
  ASSERT_EQ(run("views --store " + store + " --per overview --colour-by Material --only 'P-*' --out " + views).status, 0);
  const nlohmann::json file = nlohmann::json::parse(slurp(views));
  EXPECT_EQ(file["views"][0]["style"]["colour_by"], "Material");
  EXPECT_EQ(file["views"][0]["style"]["only"][0], "P-*");
}

}  // namespace
