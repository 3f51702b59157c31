// The service follows imports (issue 42, item 1): a served store written by another process (the
// built plantview binary's import and gen), the answers that follow, a frame in flight during a
// commit, and an import killed mid-way. Runs the built plantview binary.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "plantview/ingest.h"
#include "plantview/store.h"
#include "plantview/xml.h"
#include "support/box_row.h"
#include "support/http_client.h"
#include "support/serve_process.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using Response = test_support::HttpResponse;
using Client = test_support::HttpClient;

nlohmann::json json_of(const Response& r) { return nlohmann::json::parse(r.body, nullptr, false); }

// A store of the six boxes (box_row.h) in `dir`.
void make_box_store(const fs::path& dir) {
  std::string error;
  auto store = Store::open(dir.string(), Store::Mode::read_write, error);
  ASSERT_TRUE(store) << error;
  const IngestResult result = ingest_objects(*store, test::box_row_objects());
  ASSERT_TRUE(result) << result.error().message;
}

// An XML file of `count` boxes named /NEW-0.. beyond the row (x from 30 m).
void write_new_boxes(const fs::path& file, int count) {
  std::vector<Object> objects;
  for (int i = 0; i < count; ++i) {
    Object o;
    o.name = "/NEW-" + std::to_string(i);
    o.source = file.string();
    o.id = object_id(o.source, o.name);
    o.object_class = ObjectClass::equipment;
    o.origin_m = {30.0 + 3 * i, 0, 0};
    o.colour = {200, 40, 40, 255};
    o.primitives.push_back(Primitive{Placement{}, Box{2, 2, 2}});
    objects.push_back(std::move(o));
  }
  std::string xml;
  XmlError error;
  ASSERT_TRUE(write_xml(objects, xml, error)) << error.message;
  std::ofstream(file) << xml;
}

// Runs `plantview args...` to its end (another process); its exit status.
int run_plantview(const std::vector<std::string>& args) {
  std::string command = PLANTVIEW_BIN;
  for (const std::string& a : args) command += " '" + a + "'";
  command += " >/dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Starts `plantview args...` in the background; its pid.
pid_t start_plantview(const std::vector<std::string>& args) {
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<std::string> all = {PLANTVIEW_BIN};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int null = ::open("/dev/null", O_WRONLY);
    dup2(null, 1);
    dup2(null, 2);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

int revision_of(const Response& r) {
  const auto it = r.headers.find("x-plantview-revision");
  return it == r.headers.end() ? -1 : std::atoi(it->second.c_str());
}

const std::string kWholeView = "eye=20,-60,20&target=20,0,0&up=0,0,1&fov=60&w=96&h=64";

TEST(Follow, AnImportFromAnotherProcessIsServedWithinASecond) {
  const test::TempDir dir;
  make_box_store(dir.path());
  test::ServeProcess server(PLANTVIEW_BIN, dir.str());
  Client c(server.port());
  ASSERT_TRUE(c.connected());
  const Response before = c.request("/api/model");
  ASSERT_EQ(before.status, 200);
  EXPECT_EQ(json_of(before)["objects"], 6);
  const int first = revision_of(before);
  ASSERT_GE(first, 0) << "no X-Plantview-Revision";
  EXPECT_EQ(json_of(before)["revision"], first);
  const Response frame = c.request("/api/frame?" + kWholeView);
  ASSERT_EQ(frame.status, 200);
  EXPECT_EQ(revision_of(frame), first);
  EXPECT_EQ(c.request("/api/objects/NEW-0").status, 404);

  const fs::path xml = dir.path() / "new.xml";
  write_new_boxes(xml, 2);
  ASSERT_EQ(run_plantview({"import", xml.string(), "--store", dir.str()}), 0);
  const auto committed = Clock::now();

  // Each of the model, a look-up and a frame shows the import within a second.
  bool model_seen = false, object_seen = false, frame_seen = false;
  while (Clock::now() - committed < 1s && !(model_seen && object_seen && frame_seen)) {
    if (!model_seen) {
      const Response m = c.request("/api/model");
      ASSERT_EQ(m.status, 200);
      model_seen = json_of(m)["objects"] == 8;
      if (model_seen) {
        const auto described = json_of(m);
        EXPECT_EQ(described["bounds"]["max"][0], 34.0);
        // What the revision changed, and when (ISO 8601, UTC).
        EXPECT_EQ(described["changes"]["added"], 2);
        EXPECT_EQ(described["changes"]["removed"], 0);
        EXPECT_EQ(described["changes"]["modified"], 0);
        EXPECT_EQ(described["sources"].size(), 1u);
        ASSERT_TRUE(described["revision_time"].is_string());
        const std::string time = described["revision_time"];
        EXPECT_EQ(time.size(), 24u) << time;  // 2026-12-06T09:30:00.123Z
        EXPECT_EQ(time.back(), 'Z') << time;
        if (first > 0) { EXPECT_EQ(revision_of(m), first + 1); }
      }
    }
    if (!object_seen) {
      const Response o = c.request("/api/objects/NEW-1");
      ASSERT_TRUE(o.status == 200 || o.status == 404) << o.status << " " << o.body;
      object_seen = o.status == 200;
      if (object_seen && first > 0) { EXPECT_EQ(revision_of(o), first + 1); }
    }
    if (!frame_seen) {
      const Response f = c.request("/api/stats?" + kWholeView);
      ASSERT_EQ(f.status, 200) << f.body;
      frame_seen = json_of(f)["objects_visible"] == 8;
      if (frame_seen && first > 0) { EXPECT_EQ(revision_of(f), first + 1); }
    }
  }
  EXPECT_TRUE(model_seen) << "/api/model still has the old count after 1 s";
  EXPECT_TRUE(object_seen) << "/api/objects/NEW-1 not found after 1 s";
  EXPECT_TRUE(frame_seen) << "the renderer still draws the old commit after 1 s";
}

// Stats answers while imports commit: each answer's count is its revision's, whichever that is
// (a frame reads one snapshot), and none fails.
TEST(Follow, FramesInFlightDuringCommitsReadOneSnapshot) {
  const test::TempDir dir;
  make_box_store(dir.path());
  test::ServeProcess server(PLANTVIEW_BIN, dir.str());
  std::atomic<bool> done{false};
  std::map<int, std::set<int>> counts_by_revision;  // revision -> objects_visible seen
  std::map<int, std::set<int>> picks_by_revision;   // revision -> whether the pick found NEW-0
  int failures = 0, answers = 0;
  std::thread client([&] {
    Client c(server.port());
    while (!done) {
      const Response s = c.request("/api/stats?" + kWholeView);
      ++answers;
      if (s.status != 200) {
        ++failures;
        continue;
      }
      counts_by_revision[revision_of(s)].insert(json_of(s)["objects_visible"].get<int>());
      // NEW-0's centre, at x = 30 m, seen down the y axis.
      const Response p = c.request("/api/pick?eye=30,-10,0&target=30,0,0&w=40&h=40&x=20&y=20");
      if (p.status != 200) {
        ++failures;
        continue;
      }
      picks_by_revision[revision_of(p)].insert(json_of(p)["object"].is_object() ? 1 : 0);
    }
  });
  // Three imports: 6 boxes, then 8, 10, 12 (each file adds its own two).
  for (int i = 0; i < 3; ++i) {
    std::this_thread::sleep_for(300ms);
    const fs::path xml = dir.path() / ("new" + std::to_string(i) + ".xml");
    write_new_boxes(xml, 2);
    // Each file's boxes are named alike but come from another source: other ids, same places.
    ASSERT_EQ(run_plantview({"import", xml.string(), "--store", dir.str()}), 0);
  }
  std::this_thread::sleep_for(500ms);
  done = true;
  client.join();
  EXPECT_EQ(failures, 0) << "of " << answers;
  ASSERT_FALSE(counts_by_revision.empty());
  EXPECT_GE(counts_by_revision.begin()->first, 0) << "an answer without X-Plantview-Revision";
  if (counts_by_revision.rbegin()->first == 0)
    GTEST_SKIP() << "the store records no revisions (StoreInfo::revision is 0): cannot tell snapshots apart";
  for (const auto& [revision, counts] : counts_by_revision)
    EXPECT_EQ(counts.size(), 1u) << "revision " << revision << " drew different counts";
  for (const auto& [revision, seen] : picks_by_revision)
    EXPECT_EQ(seen.size(), 1u) << "revision " << revision << " picked and missed NEW-0";
  EXPECT_GE(counts_by_revision.size(), 2u) << "no later revision was served";
  EXPECT_EQ(*counts_by_revision.rbegin()->second.begin(), 12);
}

// An import killed mid-way (SIGKILL): the service goes on serving the last commit, answering
// every request, and a later import commits and is served.
TEST(Follow, AnImportKilledMidwayLeavesTheServiceOnTheLastCommit) {
  const test::TempDir dir;
  make_box_store(dir.path());
  test::ServeProcess server(PLANTVIEW_BIN, dir.str());
  Client c(server.port());
  const Response before = c.request("/api/model");
  ASSERT_EQ(before.status, 200);
  const int first = revision_of(before);

  const pid_t gen = start_plantview({"gen", "--preset", "c", "--scale", "4", "--store", dir.str()});
  ASSERT_GT(gen, 0);
  int failures = 0;
  const auto until = Clock::now() + 1500ms;
  while (Clock::now() < until) {
    const Response s = c.request("/api/stats?" + kWholeView);
    const Response m = c.request("/api/model");
    if (s.status != 200 || m.status != 200) ++failures;
    EXPECT_EQ(json_of(m)["objects"], 6);
    EXPECT_EQ(revision_of(m), first);
  }
  int status = 0;
  if (waitpid(gen, &status, WNOHANG) == gen) GTEST_SKIP() << "the generate finished before it was killed";
  ASSERT_EQ(kill(gen, SIGKILL), 0);
  ASSERT_EQ(waitpid(gen, &status, 0), gen);
  for (int i = 0; i < 10; ++i) {
    const Response s = c.request("/api/stats?" + kWholeView);
    const Response m = c.request("/api/model");
    if (s.status != 200 || m.status != 200) ++failures;
    EXPECT_EQ(json_of(s)["objects_visible"], 6);
    EXPECT_EQ(json_of(m)["objects"], 6);
    EXPECT_EQ(revision_of(m), first);
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(failures, 0);

  // The killed writer's lock and pages are taken over by the next import.
  const fs::path xml = dir.path() / "new.xml";
  write_new_boxes(xml, 1);
  ASSERT_EQ(run_plantview({"import", xml.string(), "--store", dir.str()}), 0);
  bool seen = false;
  for (const auto start = Clock::now(); !seen && Clock::now() - start < 1s;)
    seen = c.request("/api/objects/NEW-0").status == 200;
  EXPECT_TRUE(seen);
}

}  // namespace
}  // namespace plantview
