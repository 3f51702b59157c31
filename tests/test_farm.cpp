// The render farm end to end: `render --views` (named images, manifest, contact sheet,
// resumable), `farm submit` to local shards and to a real single-node Slurm cluster started
// here (munge, slurmctld, slurmd on loopback, configured in a temporary directory), and what bad
// input does. Runs the built plantview binary.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>
#include <utility>

#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using plantview::test::TempDir;
using Clock = std::chrono::steady_clock;

constexpr const char* kSize = "320x180";  // small: the test is about the farm, not the pixels

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

// Runs a shell command line; stdout and stderr captured through files in `scratch`.
Outcome run_shell(const std::string& command, const fs::path& scratch) {
  const fs::path out = scratch / "stdout", err = scratch / "stderr";
  const int raw = std::system((command + " >" + out.string() + " 2>" + err.string()).c_str());
  Outcome r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

Outcome plantview(const std::string& args, const fs::path& scratch) {
  return run_shell(std::string(PLANTVIEW_BIN) + " " + args, scratch);
}

// Image files of a directory by name -> bytes.
std::map<std::string, std::string> images_in(const fs::path& dir) {
  std::map<std::string, std::string> images;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".png" || e.path().extension() == ".jpg")
      images[e.path().filename().string()] = slurp(e.path());
  return images;
}

// name -> finished_unix_ms of every record in DIR/manifest.json that is done.
std::map<std::string, int64_t> done_times(const fs::path& dir) {
  std::map<std::string, int64_t> times;
  const json manifest = json::parse(slurp(dir / "manifest.json"), nullptr, false);
  for (const json& v : manifest.value("views", json::array()))
    if (v.value("status", "") == "done") times[v["name"]] = v["finished_unix_ms"].get<int64_t>();
  return times;
}

// The text of `<object id="ID" ...>...</object>` in a plantview XML document: [begin, end).
std::pair<size_t, size_t> object_span(const std::string& xml, const std::string& id_hex) {
  const size_t begin = xml.find("<object id=\"" + id_hex + "\"");
  if (begin == std::string::npos) return {std::string::npos, std::string::npos};
  return {begin, xml.find("</object>", begin) + std::string("</object>").size()};
}

// Replaces the value of attribute `name` in the first tag of `element`.
std::string with_attribute(std::string element, const std::string& name, const std::string& value) {
  const size_t at = element.find(" " + name + "=\"");
  const size_t first = at + name.size() + 3, last = element.find('"', first);
  return element.replace(first, last - first, value);
}

// `origin_m="x y z"` moved by (dx, dy, dz).
std::string moved(const std::string& element, double dx, double dy, double dz) {
  const size_t at = element.find(" origin_m=\"") + 11;
  std::istringstream in(element.substr(at, element.find('"', at) - at));
  double x = 0, y = 0, z = 0;
  in >> x >> y >> z;
  std::ostringstream out;
  out.precision(17);
  out << x + dx << " " << y + dy << " " << z + dz;
  return with_attribute(element, "origin_m", out.str());
}

std::string id_hex(uint64_t id) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(id));
  return hex;
}

// A store of preset a and a views file of 24 of its equipment items (ids, names and origins
// read back from the store through `export --xml`), each seen from above one corner.
class Farm : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    plant_ = new TempDir;
    fs::create_directories(plant_->path());
    store_ = plant_->path() / "store";
    views_ = plant_->path() / "views.json";
    const Outcome gen = plantview("gen --preset a --seed 2 --store " + store_.string(), plant_->path());
    ASSERT_EQ(gen.status, 0) << gen.err;
    const fs::path xml = plant_->path() / "plant.xml";
    const Outcome exported = plantview("export --store " + store_.string() + " --xml " + xml.string(), plant_->path());
    ASSERT_EQ(exported.status, 0) << exported.err;
    const std::string text = slurp(xml);
    const std::regex equipment(
        R"re(<object id="([0-9a-f]+)" name="/([A-Za-z0-9._-]+)" class="equipment"[^>]*origin_m="([-0-9.e]+) ([-0-9.e]+) ([-0-9.e]+)")re");
    json views = json::array();
    for (auto it = std::sregex_iterator(text.begin(), text.end(), equipment);
         it != std::sregex_iterator() && views.size() < 24; ++it) {
      const auto& m = *it;
      const double x = std::stod(m[3]), y = std::stod(m[4]), z = std::stod(m[5]) + 2;
      views.push_back({{"name", m[2]},
                       {"title", "Equipment " + m[2].str()},
                       {"kind", "equipment"},
                       {"camera",
                        {{"eye", {x + 12, y - 12, z + 9}}, {"target", {x, y, z}}, {"up", {0, 0, 1}}, {"fov_deg", 50}}},
                       {"aspect", 16.0 / 9.0},
                       {"subject", {std::stoull(m[1].str(), nullptr, 16)}},
                       {"attributes", {{"tag", m[2]}, {"type", "equipment"}}}});
      names_.push_back(m[2]);
    }
    ASSERT_EQ(views.size(), 24u);
    std::ofstream(views_) << json{{"version", 1}, {"per", "equipment"}, {"views", views}}.dump(1);
  }
  static void TearDownTestSuite() {
    delete plant_;
    plant_ = nullptr;
  }
  Outcome run(const std::string& args) { return plantview(args, scratch_.path()); }
  void SetUp() override { fs::create_directories(scratch_.path()); }

  // `render --views` of the whole file into `out`, in one process.
  void render_single(const fs::path& out, const std::string& extra = "") {
    const Outcome r = run("render --store " + store_.string() + " --views " + views_.string() + " --out " +
                          out.string() + " --size " + kSize + " " + extra);
    ASSERT_EQ(r.status, 0) << r.err;
  }

  static inline TempDir* plant_ = nullptr;
  static inline fs::path store_, views_;
  static inline std::vector<std::string> names_;
  TempDir scratch_;
};

TEST_F(Farm, RenderViewsWritesNamedImagesManifestStatsAndContactSheet) {
  const fs::path out = scratch_.path() / "out";
  render_single(out);
  const auto images = images_in(out);
  ASSERT_EQ(images.size(), 24u);
  for (const std::string& name : names_) EXPECT_TRUE(images.count(name + ".png")) << name;
  const json manifest = json::parse(slurp(out / "manifest.json"));
  EXPECT_EQ(manifest["summary"]["done"], 24);
  EXPECT_EQ(manifest["summary"]["complete"], true);
  ASSERT_EQ(manifest["views"].size(), 24u);
  for (size_t i = 0; i < 24; ++i) {
    const json& v = manifest["views"][i];
    EXPECT_EQ(v["name"], names_[i]) << "in the views file's order";
    EXPECT_EQ(v["status"], "done");
    EXPECT_EQ(v["file"], names_[i] + ".png");
    EXPECT_EQ(v["settings_hash"].get<std::string>().size(), 16u);
    EXPECT_EQ(v["subject"].size(), 1u);
    EXPECT_EQ(v["camera"]["eye"].size(), 3u);
    EXPECT_GT(v["stats"]["objects_visible"].get<int>(), 0) << names_[i];
    EXPECT_GT(v["ms"]["total"].get<double>(), 0);
  }
  std::ifstream stats(out / "stats.jsonl");
  int lines = 0;
  for (std::string line; std::getline(stats, line); ++lines)
    EXPECT_TRUE(json::parse(line, nullptr, false).contains("triangles")) << line;
  EXPECT_EQ(lines, 24);
  const std::string sheet = slurp(out / "index.html");
  for (const std::string& name : names_) {
    EXPECT_NE(sheet.find("data-name=\"" + name + "\""), std::string::npos) << name;
    EXPECT_NE(sheet.find("src=\"" + name + ".png\""), std::string::npos) << name;
  }
  EXPECT_NE(sheet.find("id=\"filter\""), std::string::npos);
  for (const auto& e : fs::directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().rfind(".tmp-", 0), std::string::npos) << "no temporary left";
}

TEST_F(Farm, ARenderAgainSkipsWhatIsDoneAndForceRendersAgain) {
  const fs::path out = scratch_.path() / "out";
  render_single(out, "--shard 0/4");
  const auto before = done_times(out);
  ASSERT_EQ(before.size(), 6u);
  Outcome again = run("render --store " + store_.string() + " --views " + views_.string() + " --out " +
                      out.string() + " --size " + kSize + " --shard 0/4");
  ASSERT_EQ(again.status, 0) << again.err;
  json summary = json::parse(again.out);
  EXPECT_EQ(summary["rendered"], 0);
  EXPECT_EQ(summary["skipped"], 6);
  EXPECT_EQ(done_times(out), before);
  // Other settings are another image: nothing is skipped.
  again = run("render --store " + store_.string() + " --views " + views_.string() + " --out " + out.string() +
              " --size 160x90 --shard 0/6");
  ASSERT_EQ(again.status, 0) << again.err;
  EXPECT_EQ(json::parse(again.out)["rendered"], 4);
  // --force renders again what is done with the same settings.
  again = run("render --store " + store_.string() + " --views " + views_.string() + " --out " + out.string() +
              " --size 160x90 --shard 0/6 --force");
  ASSERT_EQ(again.status, 0) << again.err;
  summary = json::parse(again.out);
  EXPECT_EQ(summary["rendered"], 4);
  EXPECT_EQ(summary["skipped"], 0);
}

TEST_F(Farm, ARenderAgainAfterAnImportThatKeptEveryCountRendersWhatItReaches) {
  // A copy of the plant's store, rendered; then every object imported again with one
  // recoloured: the same counts and bounds, other images where it was drawn.
  const fs::path store = scratch_.path() / "store", out = scratch_.path() / "out";
  fs::copy(store_, store, fs::copy_options::recursive);
  const std::string render = "render --store " + store.string() + " --views " + views_.string() +
                             " --out " + out.string() + " --size " + kSize + " --shard 0/4";
  Outcome first = run(render);
  ASSERT_EQ(first.status, 0) << first.err;
  ASSERT_EQ(json::parse(first.out)["rendered"], 6);
  const Outcome info_before = run("info --json --store " + store.string());
  ASSERT_EQ(info_before.status, 0) << info_before.err;

  std::string xml = slurp(plant_->path() / "plant.xml");
  const size_t colour = xml.find("colour=\"#");
  ASSERT_NE(colour, std::string::npos);
  xml.replace(colour, std::string("colour=\"#123456ff\"").size(), "colour=\"#123456ff\"");
  const fs::path recoloured = scratch_.path() / "recoloured.xml";
  std::ofstream(recoloured) << xml;
  const Outcome imported = run("import --store " + store.string() + " " + recoloured.string());
  ASSERT_EQ(imported.status, 0) << imported.err;

  const Outcome info_after = run("info --json --store " + store.string());
  ASSERT_EQ(info_after.status, 0) << info_after.err;
  json before = json::parse(info_before.out), after = json::parse(info_after.out);
  EXPECT_NE(before["commit_id"], after["commit_id"]);
  for (json* j : {&before, &after}) {
    j->erase("commit_id");
    j->erase("store_bytes");
    j->erase("revision");       // each import makes one (store.h, "Revisions")
    j->erase("revision_time");
  }
  EXPECT_EQ(before, after) << "the statistics alone cannot tell the two stores apart";

  // The views that drew the recoloured object are rendered again, the others kept: every image
  // is what a render of the new state into an empty directory writes.
  const Outcome status = run("farm status --json " + out.string() + " --store " + store.string());
  ASSERT_EQ(status.status, 0) << status.err;
  const Outcome again = run(render);
  ASSERT_EQ(again.status, 0) << again.err;
  const json summary = json::parse(again.out);
  EXPECT_EQ(summary["rendered"], json::parse(status.out)["stale"]["stale"]) << status.out;
  EXPECT_EQ(summary["rendered"].get<int>() + summary["skipped"].get<int>(), 6);
  const fs::path fresh = scratch_.path() / "fresh";
  const Outcome whole = run("render --store " + store.string() + " --views " + views_.string() + " --out " +
                            fresh.string() + " --size " + kSize + " --shard 0/4");
  ASSERT_EQ(whole.status, 0) << whole.err;
  EXPECT_EQ(images_in(out), images_in(fresh));
}

// A revision of the plant as an import would bring it (every object put again, so every slot
// changes): view `changed`'s subject recoloured, and a copy of view `added`'s subject (a new id)
// 3 m above it. Returns the ids of the two objects.
std::pair<uint64_t, uint64_t> write_revision(const fs::path& xml_path, const json& views, size_t changed,
                                             size_t added) {
  std::string xml = slurp(xml_path);
  const uint64_t changed_id = views["views"][changed]["subject"][0].get<uint64_t>();
  const uint64_t copied_id = views["views"][added]["subject"][0].get<uint64_t>();
  const uint64_t new_id = 0x00f0f0f0f0f0f0f0ull;
  auto [begin, end] = object_span(xml, id_hex(changed_id));
  EXPECT_NE(begin, std::string::npos);
  xml.replace(begin, end - begin, with_attribute(xml.substr(begin, end - begin), "colour", "#ff00ffff"));
  std::tie(begin, end) = object_span(xml, id_hex(copied_id));
  EXPECT_NE(begin, std::string::npos);
  std::string copy = moved(xml.substr(begin, end - begin), 0, 0, 3);
  copy = with_attribute(with_attribute(copy, "id", id_hex(new_id)), "name", "/ADDED-1");
  xml.insert(xml.rfind("</plantview>"), copy + "\n");
  std::ofstream(xml_path) << xml;
  return {changed_id, new_id};
}

TEST_F(Farm, AfterARevisionOnlyTheViewsItCanChangeAreRenderedAgainByteIdenticalToAFullRender) {
  // The plant imported from its XML; 24 views rendered by 2 local shards.
  const fs::path store = scratch_.path() / "store", out = scratch_.path() / "out", full = scratch_.path() / "full";
  const fs::path xml = scratch_.path() / "plant.xml";
  fs::copy_file(plant_->path() / "plant.xml", xml);
  Outcome r = run("import --store " + store.string() + " " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string submit = "farm submit --scheduler local --tasks 2 --views " + views_.string() + " --store " +
                             store.string() + " --size " + kSize + " --out ";
  r = run(submit + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(json::parse(r.out)["done"], 24);
  const json first = json::parse(slurp(out / "manifest.json"));
  for (const json& v : first["views"]) {
    EXPECT_GT(v["drawn"]["objects"].get<int>(), 0) << v["name"];
    EXPECT_TRUE(fs::exists(out / v["drawn"]["file"].get<std::string>())) << v["name"];
  }
  // Nothing changed: nothing is stale.
  r = run("farm status --json " + out.string() + " --store " + store.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["stale"]["stale"], 0) << r.out;

  // The revision: view 0's subject recoloured, an object added above view 12's subject.
  const json views = json::parse(slurp(views_));
  const auto [changed_id, added_id] = write_revision(xml, views, 0, 12);
  r = run("import --store " + store.string() + " " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;

  // farm status says which views are stale and why.
  r = run("farm status --json " + out.string() + " --store " + store.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const json stale = json::parse(r.out)["stale"];
  std::map<std::string, std::string> stale_reasons;
  for (const json& v : stale["views"]) stale_reasons[v["name"]] = v["reason"];
  ASSERT_TRUE(stale_reasons.count(names_[0])) << r.out;
  EXPECT_EQ(stale_reasons[names_[0]], "changed object") << r.out;
  ASSERT_TRUE(stale_reasons.count(names_[12])) << r.out;
  EXPECT_EQ(stale_reasons[names_[12]], "added object in view") << r.out;
  EXPECT_LT(stale_reasons.size(), 24u / 2) << "a revision of two objects leaves most views as they are: " << r.out;
  for (const auto& [name, reason] : stale_reasons)
    EXPECT_TRUE(reason == "changed object" || reason == "added object in view") << name << ": " << reason;
  const Outcome text = run("farm status " + out.string() + " --store " + store.string());
  ASSERT_EQ(text.status, 0) << text.err;
  EXPECT_NE(text.out.find(std::to_string(stale_reasons.size()) + " of 24 done views stale"), std::string::npos)
      << text.out;

  // Submitted again: exactly the stale views are rendered, the rest kept.
  const auto before = done_times(out);
  r = run(submit + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto after = done_times(out);
  ASSERT_EQ(after.size(), 24u);
  std::set<std::string> rendered;
  for (const auto& [name, time] : after)
    if (time != before.at(name)) rendered.insert(name);
  std::set<std::string> expected;
  for (const auto& [name, reason] : stale_reasons) expected.insert(name);
  EXPECT_EQ(rendered, expected);
  const json second = json::parse(slurp(out / "manifest.json"));
  for (const json& v : second["views"])
    if (expected.count(v["name"])) {
      EXPECT_TRUE(v.contains("rendered_because")) << v["name"];
    }

  // Every image, kept or rendered again, is byte for byte what a full render of this revision
  // writes.
  r = run(submit + full.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto incremental = images_in(out), whole = images_in(full);
  ASSERT_EQ(incremental.size(), 24u);
  for (const auto& [name, bytes] : whole)
    EXPECT_TRUE(incremental.count(name) && incremental.at(name) == bytes) << name << " differs from a full render";

  // And a third run renders nothing.
  r = run(submit + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(done_times(out), after);
  (void)changed_id;
  (void)added_id;
}

TEST_F(Farm, LocalShardsWriteTheSameBytesAsOneProcess) {
  const fs::path single = scratch_.path() / "single", sharded = scratch_.path() / "sharded";
  render_single(single);
  const Outcome r = run("farm submit --scheduler local --tasks 3 --views " + views_.string() + " --store " +
                        store_.string() + " --out " + sharded.string() + " --size " + kSize);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["done"], 24);
  EXPECT_EQ(images_in(sharded), images_in(single));
  for (int i = 0; i < 3; ++i)
    EXPECT_TRUE(fs::exists(sharded / ("manifest." + std::to_string(i) + "-of-3.json")));
  const Outcome status = run("farm status --json " + sharded.string());
  ASSERT_EQ(status.status, 0) << status.err;
  EXPECT_EQ(json::parse(status.out)["complete"], true);
}

TEST_F(Farm, BadInputIsRefusedBeforeAnyImage) {
  const fs::path out = scratch_.path() / "out";
  // A subject id that is not in the store.
  json views = json::parse(slurp(views_));
  views["views"][5]["subject"].push_back(123456789);
  const fs::path bad_views = scratch_.path() / "bad_views.json";
  std::ofstream(bad_views) << views.dump();
  Outcome r = run("render --store " + store_.string() + " --views " + bad_views.string() + " --out " + out.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("id 123456789"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(names_[5]), std::string::npos) << r.err;
  EXPECT_TRUE(!fs::exists(out) || images_in(out).empty());
  r = run("farm submit --scheduler local --tasks 2 --views " + bad_views.string() + " --store " +
          store_.string() + " --out " + out.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("id 123456789"), std::string::npos) << r.err;
  EXPECT_TRUE(!fs::exists(out) || images_in(out).empty());
  // A render option every shard would refuse: a usage error naming it, before anything is
  // written.
  for (const std::string& option : {std::string("--lod-policy fast"), std::string("--samples 99"),
                                    std::string("--occlusion-test best"), std::string("--size 0x0")}) {
    const fs::path fresh = scratch_.path() / "out-options";
    r = run("farm submit --scheduler local --tasks 2 --views " + views_.string() + " --store " +
            store_.string() + " --out " + fresh.string() + " " + option);
    EXPECT_EQ(r.status, 2) << option << "\n" << r.err;
    EXPECT_NE(r.err.find(option.substr(0, option.find(' '))), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(fresh)) << option;
  }
  // A store that does not open.
  r = run("render --store " + (scratch_.path() / "nowhere").string() + " --views " + views_.string() +
          " --out " + out.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("nowhere"), std::string::npos) << r.err;
  // An output directory that cannot be made (its parent is a file).
  const fs::path file = scratch_.path() / "a-file";
  std::ofstream(file) << "x";
  r = run("render --store " + store_.string() + " --views " + views_.string() + " --out " +
          (file / "out").string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("a-file"), std::string::npos) << r.err;
  // A views file that is not one.
  r = run("render --store " + store_.string() + " --views " + file.string() + " --out " + out.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("a-file"), std::string::npos) << r.err;
  // A scheduler that refuses the job: its message, exit status 1.
  const fs::path sbatch = scratch_.path() / "sbatch";
  std::ofstream(sbatch) << "#!/bin/sh\necho 'sbatch: error: Batch job submission failed: Invalid account' >&2\nexit 1\n";
  const auto listing = [](const fs::path& dir) {
    std::vector<std::string> names;
    std::error_code ec;
    if (fs::exists(dir, ec))
      for (const auto& e : fs::recursive_directory_iterator(dir)) names.push_back(e.path().string());
    std::sort(names.begin(), names.end());
    return names;
  };
  const std::vector<std::string> before = listing(out);
  fs::permissions(sbatch, fs::perms::owner_all);
  r = run_shell("PLANTVIEW_SBATCH=" + sbatch.string() + " " + PLANTVIEW_BIN +
                    " farm submit --tasks 4 --views " + views_.string() + " --store " + store_.string() +
                    " --out " + out.string(),
                scratch_.path());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("Invalid account"), std::string::npos) << r.err;
  EXPECT_TRUE(images_in(out).empty());
  // ... and leaves no script, views copy or logs behind: the directory is as it was.
  EXPECT_EQ(listing(out), before) << "a refused submit changed " << out;
  // Usage errors exit 2.
  EXPECT_EQ(run("farm submit --scheduler pbs --tasks 2 --views " + views_.string() + " --store " +
                store_.string() + " --out " + out.string()).status, 2);
  EXPECT_EQ(run("farm submit --tasks 0 --views " + views_.string() + " --store " + store_.string() +
                " --out " + out.string()).status, 2);
  EXPECT_EQ(run("render --store " + store_.string() + " --views " + views_.string() + " --out " +
                (scratch_.path() / "x.png").string()).status, 2);
}

TEST_F(Farm, DryRunPrintsAnArrayScriptWithOneShardPerTask) {
  const Outcome r = run("farm submit --dry-run --tasks 4 --partition debug --time 10:00 --views " +
                        views_.string() + " --store " + store_.string() + " --out " +
                        (scratch_.path() / "out").string() +
                        " --size 640x360 --format jpeg --antialias supersampling --no-ground");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("#SBATCH --array=0-3\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("#SBATCH --partition=debug\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("#SBATCH --time=10:00\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"${SLURM_ARRAY_TASK_ID}/4\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("'--size' '640x360'"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("'--format' 'jpeg'"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("'--antialias' 'supersampling'"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("'--no-ground'"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(scratch_.path() / "out")) << "a dry run writes nothing";
}

// ---------------------------------------------------------------------------------------------
// A single-node Slurm cluster in a temporary directory, run as root: munged, slurmctld and
// slurmd on free loopback ports; stopped by process id.
class SlurmCluster {
 public:
  // Empty when running, else why it could not start (the test skips with it).
  std::string start(const fs::path& dir) {
    if (::geteuid() != 0) return "not root: slurmctld and slurmd run as root here";
    for (const char* tool : {"munged", "slurmctld", "slurmd", "sbatch", "squeue", "scancel", "sinfo"})
      if (std::system(("command -v " + std::string(tool) + " >/dev/null 2>&1").c_str()) != 0)
        return std::string(tool) + " is not installed (Debian: slurm-wlm, munge)";
    dir_ = dir;
    fs::create_directories(dir / "munge");
    fs::permissions(dir / "munge", fs::perms::owner_all);
    fs::create_directories(dir / "state");
    fs::create_directories(dir / "spool");
    {
      std::ofstream key(dir / "munge" / "munge.key", std::ios::binary);
      std::random_device random;
      for (int i = 0; i < 1024; ++i) key.put(char(random() & 0xff));
    }
    fs::permissions(dir / "munge" / "munge.key", fs::perms::owner_read | fs::perms::owner_write);
    const std::string m = (dir / "munge").string();
    spawn({"munged", "-F", "-f", "-S", m + "/munge.sock", "--key-file=" + m + "/munge.key",
           "--log-file=" + m + "/munged.log", "--pid-file=" + m + "/munged.pid",
           "--seed-file=" + m + "/munged.seed"},
          dir / "munged.out");
    for (int i = 0; i < 100 && !fs::exists(dir / "munge" / "munge.sock"); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!fs::exists(dir / "munge" / "munge.sock")) return "munged did not start: " + slurp(dir / "munged.out");

    const std::string d = dir.string();
    std::ofstream(dir / "slurm.conf")
        << "ClusterName=plantviewtest\nSlurmctldHost=localhost\n"
        << "SlurmctldPort=" << free_port() << "\nSlurmdPort=" << free_port() << "\n"
        << "SlurmUser=root\nSlurmdUser=root\nAuthType=auth/munge\nCredType=cred/munge\n"
        << "AuthInfo=socket=" << m << "/munge.sock\n"
        << "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n"
        << "SelectType=select/cons_tres\nSelectTypeParameters=CR_CPU\n"
        << "JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n"
        << "MpiDefault=none\nReturnToService=2\nSchedulerType=sched/backfill\n"
        << "StateSaveLocation=" << d << "/state\nSlurmdSpoolDir=" << d << "/spool\n"
        << "SlurmctldPidFile=" << d << "/slurmctld.pid\nSlurmdPidFile=" << d << "/slurmd.pid\n"
        << "SlurmctldLogFile=" << d << "/slurmctld.log\nSlurmdLogFile=" << d << "/slurmd.log\n"
        << "NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN\n"
        << "PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP\n";
    ::setenv("SLURM_CONF", (dir / "slurm.conf").c_str(), 1);
    spawn({"slurmctld", "-D", "-i", "-f", d + "/slurm.conf"}, dir / "slurmctld.out");
    spawn({"slurmd", "-D", "-N", "localhost", "-f", d + "/slurm.conf"}, dir / "slurmd.out");
    const auto deadline = Clock::now() + std::chrono::seconds(30);
    while (Clock::now() < deadline) {
      const Outcome r = run_shell("sinfo -h -o %t", dir);
      if (r.status == 0 && r.out.rfind("idle", 0) == 0) return "";
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    return "the node did not become idle in 30 s: " + slurp(dir / "slurmctld.log").substr(0, 2000) +
           slurp(dir / "slurmd.log").substr(0, 2000);
  }

  // Stops the daemons (slurmd, slurmctld, munged: the reverse of their start).
  void stop() {
    for (auto it = pids_.rbegin(); it != pids_.rend(); ++it) {
      ::kill(*it, SIGTERM);
      int status = 0;
      const auto deadline = Clock::now() + std::chrono::seconds(10);
      while (::waitpid(*it, &status, WNOHANG) == 0) {
        if (Clock::now() > deadline) {
          ::kill(*it, SIGKILL);
          ::waitpid(*it, &status, 0);
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    pids_.clear();
    ::unsetenv("SLURM_CONF");
  }
  ~SlurmCluster() { stop(); }

  // Waits until job `id` has left the queue (finished, failed or cancelled).
  bool wait_for_job(const std::string& id, std::chrono::seconds limit) {
    const auto deadline = Clock::now() + limit;
    while (Clock::now() < deadline) {
      const Outcome r = run_shell("squeue -h -j " + id, dir_);
      if (r.status == 0 && r.out.empty()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    return false;
  }

 private:
  static int free_port() {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
    socklen_t length = sizeof addr;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &length);
    ::close(fd);
    return ntohs(addr.sin_port);
  }
  void spawn(const std::vector<std::string>& argv, const fs::path& log) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      ::execvp(args[0], args.data());
      ::_exit(127);
    }
    if (pid > 0) pids_.push_back(pid);
  }
  std::vector<pid_t> pids_;
  fs::path dir_;
};

TEST_F(Farm, SlurmArrayRendersTheSameImagesResumesAndCompletesACancelledTask) {
  TempDir cluster_dir;
  SlurmCluster cluster;
  if (const std::string why = cluster.start(cluster_dir.path()); !why.empty()) GTEST_SKIP() << why;

  // 24 views as a 4-task array; the same bytes as one process.
  const fs::path out = scratch_.path() / "slurm", single = scratch_.path() / "single";
  const std::string submit = "farm submit --scheduler slurm --tasks 4 --views " + views_.string() +
                             " --store " + store_.string() + " --out ";
  Outcome r = run(submit + out.string() + " --size " + kSize);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string job = r.out.substr(0, r.out.find('\n'));
  ASSERT_FALSE(job.empty());
  render_single(single);
  ASSERT_TRUE(cluster.wait_for_job(job, std::chrono::seconds(90))) << "job " << job << " still queued";
  r = run("farm status --json " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["done"], 24) << r.out << slurp(out / "logs" / ("slurm-" + job + "_0.log"));
  EXPECT_EQ(images_in(out), images_in(single));
  const json manifest = json::parse(slurp(out / "manifest.json"));
  EXPECT_EQ(manifest["summary"]["complete"], true);
  std::set<std::string> shards;
  for (const json& v : manifest["views"]) shards.insert(v["shard"].get<std::string>());
  EXPECT_EQ(shards, (std::set<std::string>{"0/4", "1/4", "2/4", "3/4"}));

  // Submitted again: every task finds its views done and renders nothing.
  const auto times = done_times(out);
  r = run(submit + out.string() + " --size " + kSize);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string again = r.out.substr(0, r.out.find('\n'));
  ASSERT_TRUE(cluster.wait_for_job(again, std::chrono::seconds(60)));
  EXPECT_EQ(done_times(out), times);
  for (int task = 0; task < 4; ++task) {
    const std::string log = slurp(out / "logs" / ("slurm-" + again + "_" + std::to_string(task) + ".log"));
    EXPECT_NE(log.find("\"rendered\":0"), std::string::npos) << log;
  }

  // One task cancelled after its first view: submitting again completes exactly what is missing.
  const fs::path cut = scratch_.path() / "cancelled";
  r = run(submit + cut.string() + " --size 640x360");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string cancelled = r.out.substr(0, r.out.find('\n'));
  const fs::path part = cut / "manifest.0-of-4.json";
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (Clock::now() < deadline && !fs::exists(part))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(run_shell("scancel " + cancelled + "_0", scratch_.path()).status, 0);
  ASSERT_TRUE(cluster.wait_for_job(cancelled, std::chrono::seconds(90)));
  r = run("farm status --json " + cut.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const json after_cancel = json::parse(r.out);
  EXPECT_GE(after_cancel["missing"].get<int>(), 1) << "task 0 was cancelled after its first view";
  EXPECT_LT(after_cancel["missing"].get<int>(), 6) << "it finished a view before";
  const auto kept = done_times(cut);
  r = run(submit + cut.string() + " --size 640x360");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string completion = r.out.substr(0, r.out.find('\n'));
  ASSERT_TRUE(cluster.wait_for_job(completion, std::chrono::seconds(90)));
  r = run("farm status --json " + cut.string());
  EXPECT_EQ(json::parse(r.out)["complete"], true) << r.out;
  const auto completed = done_times(cut);
  EXPECT_EQ(completed.size(), 24u);
  for (const auto& [name, time] : kept) EXPECT_EQ(completed.at(name), time) << name << " rendered twice";

  // After a revision, a Slurm run renders again only the views it can change, and every image
  // is what a full render of the revision writes.
  const fs::path store = scratch_.path() / "revised-store", xml = scratch_.path() / "revised.xml";
  const fs::path incremental = scratch_.path() / "incremental", full = scratch_.path() / "full";
  fs::copy_file(plant_->path() / "plant.xml", xml);
  r = run("import --store " + store.string() + " " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string revised_submit = " --views " + views_.string() + " --store " + store.string() +
                                     " --size " + kSize + " --out ";
  r = run("farm submit --scheduler slurm --tasks 2" + revised_submit + incremental.string());
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(cluster.wait_for_job(r.out.substr(0, r.out.find('\n')), std::chrono::seconds(90)));
  write_revision(xml, json::parse(slurp(views_)), 0, 12);
  r = run("import --store " + store.string() + " " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("farm status --json " + incremental.string() + " --store " + store.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const json status = json::parse(r.out);
  std::set<std::string> stale;
  for (const json& v : status["stale"]["views"]) stale.insert(v["name"].get<std::string>());
  EXPECT_TRUE(stale.count(names_[0]) && stale.count(names_[12])) << r.out;
  EXPECT_LT(stale.size(), 12u) << r.out;
  const auto before = done_times(incremental);
  ASSERT_EQ(before.size(), 24u);
  r = run("farm submit --scheduler slurm --tasks 2" + revised_submit + incremental.string());
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(cluster.wait_for_job(r.out.substr(0, r.out.find('\n')), std::chrono::seconds(90)));
  r = run("farm status --json " + incremental.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto after = done_times(incremental);
  std::set<std::string> rendered;
  for (const auto& [name, time] : after)
    if (!before.count(name) || time != before.at(name)) rendered.insert(name);
  EXPECT_EQ(rendered, stale);
  r = run("farm submit --scheduler local --tasks 2" + revised_submit + full.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(images_in(incremental), images_in(full));

  // A clash job (farm submit --clash) as a 4-task array: the clashes.json of one process.
  const fs::path clash_out = scratch_.path() / "clash-slurm", single_clashes = scratch_.path() / "single-clashes.json";
  r = run("farm submit --clash --scheduler slurm --tasks 4 --store " + store_.string() + " --out " + clash_out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string clash_job = r.out.substr(0, r.out.find('\n'));
  r = run("clash --store " + store_.string() + " --out " + single_clashes.string());
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(cluster.wait_for_job(clash_job, std::chrono::seconds(90))) << "job " << clash_job << " still queued";
  r = run("farm status --json " + clash_out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["complete"], true) << r.out << slurp(clash_out / "logs" / ("slurm-" + clash_job + "_0.log"));
  EXPECT_EQ(json::parse(r.out)["shards_done"], 4) << r.out;
  EXPECT_EQ(slurp(clash_out / "clashes.json"), slurp(single_clashes));
  // Again, --since the job's own clashes.json: the array's merging task reads the copy submit
  // left in the directory, and every clash is active.
  r = run("farm submit --clash --scheduler slurm --tasks 4 --store " + store_.string() + " --out " +
          clash_out.string() + " --since " + (clash_out / "clashes.json").string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string since_job = r.out.substr(0, r.out.find('\n'));
  ASSERT_TRUE(cluster.wait_for_job(since_job, std::chrono::seconds(90))) << "job " << since_job << " still queued";
  r = run("farm status --json " + clash_out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const json since_status = json::parse(r.out);
  EXPECT_EQ(since_status["complete"], true) << r.out;
  EXPECT_EQ(since_status["new"], 0) << r.out;
  EXPECT_EQ(since_status["resolved"], 0) << r.out;
  EXPECT_EQ(since_status["active"], json::parse(slurp(single_clashes))["clashes"].size()) << r.out;
}

TEST_F(Farm, LocalClashShardsWriteTheSameClashesAsOneProcess) {
  const fs::path out = scratch_.path() / "clash-local", single = scratch_.path() / "single-clashes.json";
  Outcome r = run("farm submit --clash --scheduler local --tasks 4 --store " + store_.string() + " --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const json summary = json::parse(r.out);
  EXPECT_EQ(summary["complete"], true) << r.out;
  EXPECT_EQ(summary["shards_done"], 4) << r.out;
  r = run("clash --store " + store_.string() + " --out " + single.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string merged = slurp(out / "clashes.json");
  EXPECT_FALSE(merged.empty());
  EXPECT_EQ(merged, slurp(single));
  EXPECT_EQ(json::parse(merged)["clashes"].size(), summary["clashes"].get<size_t>());
  r = run("farm status " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("4 of 4 shards done"), std::string::npos) << r.out;
  // A render option is refused for a clash job, before anything is written.
  r = run("farm submit --clash --scheduler local --tasks 2 --size 64x36 --store " + store_.string() + " --out " +
          (scratch_.path() / "never").string());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_FALSE(fs::exists(scratch_.path() / "never"));
}

TEST_F(Farm, LocalClashJobSinceARevisionWritesWhatOneProcessDoes) {
  // Preset a imported from its XML, its clashes, then a revision (an item recoloured, a copy of
  // another 3 m above it): `farm submit --clash --since` merges 3 shards into one process's
  // `clash --since` file, byte for byte, statuses and changed objects included.
  const fs::path store = scratch_.path() / "store", xml = scratch_.path() / "plant.xml";
  const fs::path first = scratch_.path() / "first.json", single = scratch_.path() / "single.json",
                 out = scratch_.path() / "clash-since";
  fs::copy_file(plant_->path() / "plant.xml", xml);
  Outcome r = run("import --store " + store.string() + " " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("clash --store " + store.string() + " --out " + first.string());
  ASSERT_EQ(r.status, 0) << r.err;
  write_revision(xml, json::parse(slurp(views_)), 0, 12);
  r = run("import --store " + store.string() + " " + xml.string());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("clash --store " + store.string() + " --since " + first.string() + " --out " + single.string());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("farm submit --clash --scheduler local --tasks 3 --store " + store.string() + " --since " +
          first.string() + " --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const json summary = json::parse(r.out);
  const std::string merged = slurp(out / "clashes.json");
  EXPECT_EQ(merged, slurp(single));
  const json clashes = json::parse(merged)["clashes"];
  std::map<std::string, int> by_status;
  for (const json& c : clashes) ++by_status[c["status"].get<std::string>()];
  EXPECT_GT(by_status["active"], 0) << "the clashes the revision left";
  EXPECT_GT(by_status["new"], 0) << "the copy 3 m above an item meets what is there";
  for (const json& c : clashes)
    if (c["status"] == "new") {
      EXPECT_EQ(c.value("changed_tag", ""), "/ADDED-1") << c.dump();
    }
  for (const char* status : {"new", "active", "resolved"}) EXPECT_EQ(summary[status], by_status[status]) << r.out;
  r = run("farm status --json " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out), summary);
}

}  // namespace
