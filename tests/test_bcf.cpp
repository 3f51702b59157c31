// BCF files (plantview/bcf.h) through the plantview program, on a generated plant (preset a):
// views with sections and styles rendered with `render --views --bcf`, then
//   - imported back (`bcf import`): cameras, section planes and box, selections, styles;
//   - read by an independent reader (@parametricos/bcf-js under node, tests/bcf/read_bcf.js;
//     skipped when node or the package is missing): topics, cameras, clipping planes,
//     components and snapshots against the views and their images;
//   - checked against the BCF 2.1 schemas (tests/data/bcf, xmllint; skipped without xmllint);
//   - another tool's BCF (IFC GUIDs, an orthogonal camera, a topic without viewpoint), made with
//     python3's zipfile, imports with a report;
//   - bad files (truncated, not a zip, a '../' entry, a viewpoint without camera, a missing
//     snapshot) fail with exit 1, a message naming what and where, and nothing written.
#include <algorithm>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "plantview/bcf.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kSource = PLANTVIEW_SOURCE_DIR;
const fs::path kModules = kSource / ".tools/npm/node_modules";

struct Outcome {
  int status = -1;
  std::string out, err;
};

// Runs a shell command; stdout and stderr apart.
Outcome run(const std::string& command, const fs::path& dir) {
  Outcome r;
  const fs::path err = dir / "stderr.txt";
  FILE* p = ::popen((command + " 2>" + err.string()).c_str(), "r");
  if (!p) return r;
  char buffer[4096];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, p)) > 0) r.out.append(buffer, n);
  const int raw = ::pclose(p);
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::ifstream e(err);
  std::stringstream s;
  s << e.rdbuf();
  r.err = s.str();
  return r;
}

bool have(const std::string& program) {
  return std::system(("command -v " + program + " >/dev/null 2>&1").c_str()) == 0;
}

std::string plantview(const std::string& args) { return std::string(PLANTVIEW_BIN) + " " + args; }

json read_json(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

// Python 3 with its zipfile module writes the hand-made archives.
void python(const std::string& script, const fs::path& dir) {
  const fs::path file = dir / "make.py";
  std::ofstream(file) << script;
  const Outcome r = run("python3 " + file.string(), dir);
  ASSERT_EQ(r.status, 0) << r.err;
}

// One plant, four views with sections and styles, rendered with --bcf: shared by the tests.
class Bcf : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new plantview::test::TempDir();
    fs::create_directories(dir_->path());
    const fs::path d = dir_->path();
    Outcome r = run(plantview("gen --preset a --threads 2 --store " + (d / "store").string()), d);
    ASSERT_EQ(r.status, 0) << r.err;
    r = run(
        plantview("views --store " + (d / "store").string() + " --per equipment --select 'P-01-00[12]*' " +
                  "--size 320x180 --out " + (d / "views.json").string()),
        d);
    ASSERT_EQ(r.status, 0) << r.err;
    json views = read_json(d / "views.json");
    ASSERT_EQ(views["views"].size(), 4u);
    // A box and a plan cut, hidden structure; only the pumps, coloured by material; a wide
    // field of view (outside BCF 2.1's 45..60: written as it is).
    views["views"][0]["section"] = {{"planes", {{{"point", {1.5, 2, 3}}, {"normal", {0, 0, 1}}}}},
                                    {"box", {{"min", {0, 0, 0}}, {"max", {50, 40, 30}}}}};
    views["views"][0]["style"] = {{"hide", {"structure"}}};
    // A subject colour drawn see-through (a clash view's container): an ARGB Coloring.
    views["views"][0]["colours"] = {{{"id", views["views"][0]["subject"][0]},
                                     {"colour", "#14afeb"},
                                     {"label", "second: P-01-001 (see-through)"},
                                     {"see_through", true}}};
    views["views"][1]["style"] = {{"only", {"P-01-*"}}, {"colour_by", "Material"}};
    views["views"][2]["section"] = {{"planes", {{{"point", {10, 0, 0}}, {"normal", {0.6, 0.8, 0}}}}},
                                    {"capped", false}};
    views["views"][3]["camera"]["fov_deg"] = 70.0;
    std::ofstream(d / "views.json") << views.dump();
    r = run(
        plantview("render --store " + (d / "store").string() + " --views " + (d / "views.json").string() +
                  " --out " + (d / "images").string() + " --size 160x90 --bcf " + (d / "out.bcf").string()),
        d);
    ASSERT_EQ(r.status, 0) << r.err;
    ASSERT_EQ(json::parse(r.out).value("bcf", ""), "written") << r.out;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static fs::path dir() { return dir_->path(); }
  static std::string store() { return (dir() / "store").string(); }
  static json views() { return read_json(dir() / "views.json")["views"]; }

  static inline plantview::test::TempDir* dir_ = nullptr;
};

void expect_vec_near(const json& a, const json& b, double tolerance, const std::string& what) {
  ASSERT_EQ(a.size(), 3u) << what;
  ASSERT_EQ(b.size(), 3u) << what;
  for (size_t i = 0; i < 3; ++i)
    EXPECT_NEAR(a[i].get<double>(), b[i].get<double>(), tolerance) << what << "[" << i << "]";
}

TEST_F(Bcf, RoundTripKeepsCamerasSectionsSelectionsAndStyles) {
  const fs::path back = dir() / "back.json";
  const Outcome r = run(plantview("bcf import " + (dir() / "out.bcf").string() + " --store " + store() +
                                  " --json --out " + back.string()),
                        dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const json report = json::parse(r.out);
  EXPECT_EQ(report["topics"], 4);
  EXPECT_EQ(report["imported"], 4);
  EXPECT_EQ(report["components_unknown"], 0);
  EXPECT_GT(report["components_matched"].get<int>(), 4);
  const json a = views(), b = read_json(back)["views"];
  ASSERT_EQ(b.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    const std::string name = a[i]["name"];
    EXPECT_EQ(b[i]["name"], a[i]["name"]);
    EXPECT_EQ(b[i]["title"], a[i]["title"]) << name;
    EXPECT_EQ(b[i]["kind"], a[i]["kind"]) << name;
    EXPECT_EQ(b[i]["subject"], a[i]["subject"]) << name;
    EXPECT_EQ(b[i]["attributes"], a[i]["attributes"]) << name;
    for (const char* key : {"eye", "target", "up"})
      expect_vec_near(b[i]["camera"][key], a[i]["camera"][key], 1e-9, name + " camera." + key);
    EXPECT_DOUBLE_EQ(b[i]["camera"]["fov_deg"].get<double>(), a[i]["camera"]["fov_deg"].get<double>())
        << name;
    EXPECT_EQ(b[i].value("section", json()), a[i].value("section", json())) << name;
    EXPECT_EQ(b[i].value("style", json()), a[i].value("style", json())) << name;
    EXPECT_EQ(b[i].value("colours", json()), a[i].value("colours", json())) << name;
  }
}

TEST_F(Bcf, ASeeThroughSubjectColourIsWrittenArgb) {
  const fs::path unzipped = dir() / "unzipped-argb";
  python("import zipfile\nzipfile.ZipFile('" + (dir() / "out.bcf").string() + "').extractall('" +
             unzipped.string() + "')\n",
         dir());
  std::vector<std::string> colours;
  for (const auto& e : fs::recursive_directory_iterator(unzipped)) {
    if (e.path().filename() != "viewpoint.bcfv") continue;
    std::ifstream in(e.path());
    const std::string xml((std::istreambuf_iterator<char>(in)), {});
    for (size_t at = xml.find("<Color Color=\""); at != std::string::npos; at = xml.find("<Color Color=\"", at + 1))
      colours.push_back(xml.substr(at + 14, xml.find('"', at + 14) - at - 14));
  }
  // kSeeThroughSubjectAlpha (0.35) of 255 is 0x59; then the colour's RGB.
  EXPECT_NE(std::find(colours.begin(), colours.end(), "5914AFEB"), colours.end());
}

TEST_F(Bcf, ExportIsStableAndAtomic) {
  // The same views of the same store give the same GUIDs, whichever command writes them.
  const fs::path again = dir() / "again.bcf";
  Outcome r = run(plantview("bcf export --views " + (dir() / "views.json").string() + " --images " +
                            (dir() / "images").string() + " --store " + store() + " --out " + again.string()),
                  dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string list =
      "python3 -c 'import sys,zipfile; print(sorted(zipfile.ZipFile(sys.argv[1]).namelist()))' ";
  const Outcome first = run(list + (dir() / "out.bcf").string(), dir()),
                second = run(list + again.string(), dir());
  ASSERT_EQ(first.status, 0) << first.err;
  EXPECT_EQ(first.out, second.out);
  // A view without its image: exit 1, the view named, no file and no temporary left.
  fs::create_directories(dir() / "partial");
  for (const auto& e : fs::directory_iterator(dir() / "images"))
    if (e.path().extension() == ".png" && e.path().stem() != "P-01-002A")
      fs::copy(e.path(), dir() / "partial");
  r = run(plantview("bcf export --views " + (dir() / "views.json").string() + " --images " +
                    (dir() / "partial").string() + " --out " + (dir() / "partial.bcf").string()),
          dir());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("P-01-002A"), std::string::npos) << r.err;
  for (const auto& e : fs::directory_iterator(dir()))
    EXPECT_EQ(e.path().filename().string().find("partial.bcf"), std::string::npos) << e.path();
  // --bcf without --views is a usage error.
  r = run(plantview("render --store " + store() + " --out " + (dir() / "x.png").string() + " --bcf y.bcf"),
          dir());
  EXPECT_EQ(r.status, 2);
}

TEST_F(Bcf, ColouringSaysTheColoursTheSnapshotShows) {
  // The coloured view's Coloring gives each value the colour its rendered frame's legend shows.
  const fs::path script = dir() / "colours.py";
  std::ofstream(script) << R"(import glob, json, sys, zipfile
import xml.etree.ElementTree as ET
images, bcf = sys.argv[1], sys.argv[2]
legend = None
for part in glob.glob(images + '/manifest.*-of-*.json'):
    for record in json.load(open(part))['views']:
        if 'legend' in record.get('stats', {}):
            legend = record['stats']['legend']
drawn = {e['colour'][1:].upper() for e in legend['entries']}
written = set()
with zipfile.ZipFile(bcf) as z:
    for name in z.namelist():
        if name.endswith('.bcfv'):
            for colour in ET.fromstring(z.read(name)).iter('Color'):
                written.add(colour.get('Color').upper())
print(json.dumps({'drawn': sorted(drawn), 'written': sorted(written), 'key': legend['key']}))
)";
  const Outcome r = run("python3 " + script.string() + " " + (dir() / "images").string() + " " +
                            (dir() / "out.bcf").string(),
                        dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const json colours = json::parse(r.out);
  EXPECT_EQ(colours["key"], "Material");
  EXPECT_FALSE(colours["written"].empty()) << r.out;
  // Every colour the frame drew a value in is written for that value (values of objects out of
  // the view take BCF's own palette as well).
  for (const json& c : colours["drawn"])
    EXPECT_NE(std::find(colours["written"].begin(), colours["written"].end(), c), colours["written"].end())
        << c << " in " << r.out;
}

TEST_F(Bcf, IndependentReaderSeesEveryTopicCameraPlaneComponentAndSnapshot) {
  if (!have("node")) GTEST_SKIP() << "node is not installed";
  if (!fs::exists(kModules / "@parametricos/bcf-js/package.json"))
    GTEST_SKIP() << "@parametricos/bcf-js is not installed under .tools/npm (run scripts/deps.sh)";
  const Outcome r = run("node " + (kSource / "tests/bcf/read_bcf.js").string() + " " + kModules.string() +
                            " " + (dir() / "out.bcf").string(),
                        dir());
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const json read = json::parse(r.out);
  EXPECT_EQ(read["version"], "2.1");
  const json v = views();
  ASSERT_EQ(read["topics"].size(), v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    // bcf-js keeps the archive's order, which is the views'.
    const json& topic = read["topics"][i];
    const std::string name = v[i]["name"];
    EXPECT_EQ(topic["title"], v[i]["title"]);
    EXPECT_TRUE(topic["creation_date"].get<std::string>().ends_with("Z")) << topic["creation_date"];
    ASSERT_EQ(topic["viewpoints"].size(), 1u) << name;
    const json& vp = topic["viewpoints"][0];
    const json& camera = v[i]["camera"];
    expect_vec_near(vp["camera"]["eye"], camera["eye"], 1e-12, name + " eye");
    json direction = json::array();
    double length = 0;
    for (int k = 0; k < 3; ++k)
      length += std::pow(camera["target"][k].get<double>() - camera["eye"][k].get<double>(), 2);
    for (int k = 0; k < 3; ++k)
      direction.push_back((camera["target"][k].get<double>() - camera["eye"][k].get<double>()) /
                          std::sqrt(length));
    expect_vec_near(vp["camera"]["direction"], direction, 1e-12, name + " direction");
    expect_vec_near(vp["camera"]["up"], camera["up"], 1e-12, name + " up");
    EXPECT_DOUBLE_EQ(vp["camera"]["fov"].get<double>(), camera["fov_deg"].get<double>()) << name;
    // Clipping planes: the box's six faces, then the planes.
    const json section = v[i].value("section", json::object());
    const size_t planes = (section.contains("box") ? 6 : 0) + section.value("planes", json::array()).size();
    ASSERT_EQ(vp["clipping_planes"].size(), planes) << name;
    if (section.contains("box")) {
      expect_vec_near(vp["clipping_planes"][0]["direction"], {-1, 0, 0}, 0, name + " box -x");
      EXPECT_EQ(vp["clipping_planes"][0]["location"][0], section["box"]["min"][0]);
      EXPECT_EQ(vp["clipping_planes"][5]["location"][2], section["box"]["max"][2]);
    }
    if (section.contains("planes")) {
      const json& last = vp["clipping_planes"][planes - 1];
      expect_vec_near(last["location"], section["planes"][0]["point"], 1e-12, name + " plane point");
      expect_vec_near(last["direction"], section["planes"][0]["normal"], 1e-12, name + " plane normal");
    }
    // Components: the subject by its tag; hide and only as visibility exceptions; colours.
    EXPECT_EQ(vp["selection_count"], 1) << name;
    EXPECT_EQ(vp["selection"], json::array({v[i]["attributes"]["tag"]})) << name;
    const json style = v[i].value("style", json::object());
    EXPECT_EQ(vp["default_visibility"], style.contains("only") ? "false" : "true") << name;
    EXPECT_EQ(vp["exceptions"].empty(), style.empty()) << name;
    if (style.contains("only")) {
      for (const json& id : vp["exceptions"]) EXPECT_TRUE(id.get<std::string>().starts_with("P-01-")) << id;
      EXPECT_FALSE(vp["coloring"].empty()) << name;
      size_t coloured = 0;
      for (const json& g : vp["coloring"]) {
        EXPECT_EQ(g["color"].get<std::string>().size(), 6u);
        coloured += g["ids"].size();
      }
      EXPECT_EQ(coloured, vp["exceptions"].size()) << name << ": every shown pump part has a Material";
    }
    // The snapshot is the rendered image, byte for byte as long.
    EXPECT_TRUE(vp["snapshot_is_png"].get<bool>()) << name;
    EXPECT_EQ(vp["snapshot_bytes"].get<uintmax_t>(), fs::file_size(dir() / "images" / (name + ".png")))
        << name;
  }
}

TEST_F(Bcf, FilesFollowTheBcf21Schemas) {
  if (!have("xmllint")) GTEST_SKIP() << "xmllint is not installed (libxml2-utils)";
  const fs::path unzipped = dir() / "unzipped";
  python("import zipfile\nzipfile.ZipFile('" + (dir() / "out.bcf").string() + "').extractall('" +
             unzipped.string() + "')\n",
         dir());
  const fs::path schemas = kSource / "tests/data/bcf";
  size_t checked = 0;
  for (const auto& e : fs::recursive_directory_iterator(unzipped)) {
    const std::string name = e.path().filename().string();
    const char* schema = name == "markup.bcf"       ? "markup.xsd"
                         : name == "viewpoint.bcfv" ? "visinfo.xsd"
                         : name == "bcf.version"    ? "version.xsd"
                                                    : nullptr;
    if (!schema) continue;
    const Outcome r =
        run("xmllint --noout --schema " + (schemas / schema).string() + " " + e.path().string(), dir());
    // The one known departure: the view whose field of view (70) is outside 2.1's 45..60.
    if (r.status != 0 && r.err.find("FieldOfView") != std::string::npos &&
        r.err.find("'70'") != std::string::npos)
      continue;
    EXPECT_EQ(r.status, 0) << e.path() << ": " << r.err;
    ++checked;
  }
  EXPECT_EQ(checked, 1u + 4u + 3u);  // bcf.version, 4 markups, 3 viewpoints within 45..60
}

// Another tool's BCF: IFC GUIDs only, one perspective and one orthogonal camera, a topic without
// viewpoint, a Coloring plantview cannot take.
TEST_F(Bcf, AnotherToolsBcfImportsWithAReport) {
  const fs::path file = dir() / "other.bcf";
  std::string script = R"PY(
import zipfile
vp = '''<?xml version="1.0" encoding="UTF-8"?>
<VisualizationInfo Guid="{g}"><Components><Selection>
<Component IfcGuid="2MF28NhmDBiRVyFakgdbCT"><OriginatingSystem>Revit</OriginatingSystem></Component>
<Component IfcGuid="0ZP5tgQa5DvxNUXPb7Z3jv"/></Selection>
<Visibility DefaultVisibility="true"/><Coloring><Color Color="FF0000"><Component IfcGuid="2MF28NhmDBiRVyFakgdbCT"/></Color></Coloring>
</Components>{camera}</VisualizationInfo>'''
persp = '''<PerspectiveCamera><CameraViewPoint><X>10</X><Y>-20</Y><Z>5</Z></CameraViewPoint>
<CameraDirection><X>0</X><Y>1</Y><Z>0</Z></CameraDirection><CameraUpVector><X>0</X><Y>0</Y><Z>1</Z></CameraUpVector>
<FieldOfView>60</FieldOfView></PerspectiveCamera>'''
ortho = '''<OrthogonalCamera><CameraViewPoint><X>0</X><Y>0</Y><Z>100</Z></CameraViewPoint>
<CameraDirection><X>0</X><Y>0</Y><Z>-1</Z></CameraDirection><CameraUpVector><X>0</X><Y>1</Y><Z>0</Z></CameraUpVector>
<ViewToWorldScale>40</ViewToWorldScale></OrthogonalCamera>'''
def markup(guid, title, vp_guid):
    vps = f'<Viewpoints Guid="{vp_guid}"><Viewpoint>viewpoint.bcfv</Viewpoint></Viewpoints>' if vp_guid else ''
    return f'''<?xml version="1.0" encoding="UTF-8"?><Markup><Topic Guid="{guid}"><Title>{title}</Title>
<CreationDate>2024-01-02T03:04:05+01:00</CreationDate><CreationAuthor>someone@example.com</CreationAuthor></Topic>{vps}</Markup>'''
with zipfile.ZipFile('FILE', 'w') as z:
    z.writestr('bcf.version', '<?xml version="1.0"?><Version VersionId="2.1"><DetailedVersion>2.1</DetailedVersion></Version>')
    z.writestr('aaaaaaaa-0000-4000-8000-000000000001/markup.bcf', markup('aaaaaaaa-0000-4000-8000-000000000001', 'Clash: duct / beam', 'bbbbbbbb-0000-4000-8000-000000000001'))
    z.writestr('aaaaaaaa-0000-4000-8000-000000000001/viewpoint.bcfv', vp.format(g='bbbbbbbb-0000-4000-8000-000000000001', camera=persp))
    z.writestr('aaaaaaaa-0000-4000-8000-000000000002/markup.bcf', markup('aaaaaaaa-0000-4000-8000-000000000002', 'Plan view', 'bbbbbbbb-0000-4000-8000-000000000002'))
    z.writestr('aaaaaaaa-0000-4000-8000-000000000002/viewpoint.bcfv', vp.format(g='bbbbbbbb-0000-4000-8000-000000000002', camera=ortho))
    z.writestr('aaaaaaaa-0000-4000-8000-000000000003/markup.bcf', markup('aaaaaaaa-0000-4000-8000-000000000003', 'A note', ''))
)PY";
  script.replace(script.find("'FILE'"), 6, "'" + file.string() + "'");
  python(script, dir());
  const fs::path out = dir() / "other.json";
  const Outcome r =
      run(plantview("bcf import " + file.string() + " --store " + store() + " --json --out " + out.string()),
          dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const json report = json::parse(r.out);
  EXPECT_EQ(report["topics"], 3);
  EXPECT_EQ(report["topics_without_viewpoint"], 1);
  EXPECT_EQ(report["imported"], 2);
  EXPECT_EQ(report["orthogonal_converted"], 1);
  EXPECT_EQ(report["components_matched"], 0);
  EXPECT_EQ(report["components_unknown"], 4);  // the selections (colourings are not matched)
  EXPECT_EQ(report["components_ifc_only"], 4);
  EXPECT_NE(r.err.find("IfcGuid 2MF28NhmDBiRVyFakgdbCT (Revit)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Coloring"), std::string::npos) << r.err;
  const json v = read_json(out)["views"];
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v[0]["name"], "Clash-duct-beam");
  EXPECT_EQ(v[0]["kind"], "overview");  // nothing matched
  expect_vec_near(v[0]["camera"]["eye"], {10, -20, 5}, 0, "eye");
  EXPECT_EQ(v[0]["camera"]["fov_deg"], 60.0);
  // The orthogonal camera: 40 m of height seen at its view point, from behind it.
  const double back = 20.0 / std::tan(25.0 * M_PI / 180.0);
  expect_vec_near(v[1]["camera"]["eye"], {0, 0, 100 + back}, 1e-9, "ortho eye");
  expect_vec_near(v[1]["camera"]["target"], {0, 0, 100}, 1e-9, "ortho target");
}

TEST_F(Bcf, BadFilesFailWithWhatAndWhereAndWriteNothing) {
  const fs::path good = dir() / "out.bcf";
  const fs::path bad = dir() / "bad";
  fs::create_directories(bad);
  // Truncated: the first half of a good file.
  {
    std::ifstream in(good, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(bad / "truncated.bcf", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  std::ofstream(bad / "text.bcf") << "this is not a zip archive\n";
  python(
      "import zipfile\n"
      "with zipfile.ZipFile('" +
          (bad / "escape.bcf").string() +
          "', 'w') as z:\n"
          "    z.writestr('../x', 'gotcha')\n"
          "with zipfile.ZipFile('" +
          (bad / "nocamera.bcf").string() +
          "', 'w') as z:\n"
          "    z.writestr('t/markup.bcf', '<Markup><Topic Guid=\"x\"><Title>No camera</Title></Topic>"
          "<Viewpoints Guid=\"y\"><Viewpoint>viewpoint.bcfv</Viewpoint></Viewpoints></Markup>')\n"
          "    z.writestr('t/viewpoint.bcfv', '<VisualizationInfo Guid=\"y\"><Components><Visibility/>"
          "</Components></VisualizationInfo>')\n",
      dir());
  const std::pair<const char*, const char*> cases[] = {
      {"truncated.bcf", "not a readable zip archive"},
      {"text.bcf", "not a readable zip archive"},
      {"escape.bcf", "entry '../x' escapes"},
      {"nocamera.bcf", "t/viewpoint.bcfv (topic 'No camera'): the viewpoint has no camera"},
  };
  for (const auto& [name, message] : cases) {
    const fs::path out = bad / (std::string(name) + ".json");
    const Outcome r = run(plantview("bcf import " + (bad / name).string() + " --out " + out.string()), dir());
    EXPECT_EQ(r.status, 1) << name;
    EXPECT_NE(r.err.find(message), std::string::npos) << name << ": " << r.err;
    EXPECT_NE(r.err.find((bad / name).string()), std::string::npos) << name << ": " << r.err;
    EXPECT_FALSE(fs::exists(out)) << name;
  }
}

// The farm: every shard gets --bcf (a relative name made absolute by farm submit); the shard
// that finds the job complete writes the whole file.
TEST_F(Bcf, FarmShardsWriteOneCompleteFile) {
  const Outcome r = run("cd " + dir().string() + " && " +
                            plantview("farm submit --scheduler local --tasks 2 --views views.json --store " +
                                      store() + " --out farm --size 160x90 --bcf farm.bcf"),
                        dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const Outcome listed = run("python3 -c 'import sys,zipfile; n=zipfile.ZipFile(sys.argv[1]).namelist(); "
                             "print(sum(x.endswith(\"/markup.bcf\") for x in n), "
                             "sum(x.endswith(\"/snapshot.png\") for x in n))' " +
                                 (dir() / "farm.bcf").string(),
                             dir());
  ASSERT_EQ(listed.status, 0) << listed.err;
  EXPECT_EQ(listed.out, "4 4\n");
}

// The size caps, through the library: an entry over max_entry_bytes, and entries over
// max_total_bytes together.
TEST_F(Bcf, OversizedEntriesAreRefused) {
  std::vector<plantview::ReviewView> out;
  plantview::BcfReadReport report;
  std::string error;
  plantview::BcfReadOptions options;
  options.max_entry_bytes = 4096;  // below the first viewpoint's (its hidden list) and every snapshot's size
  EXPECT_FALSE(plantview::read_bcf(dir() / "out.bcf", nullptr, options, out, report, error));
  EXPECT_NE(error.find("' is "), std::string::npos) << error;
  EXPECT_NE(error.find("over the limit of 4096"), std::string::npos) << error;
  options = {};
  options.max_total_bytes = 3000;  // a few XML entries
  EXPECT_FALSE(plantview::read_bcf(dir() / "out.bcf", nullptr, options, out, report, error));
  EXPECT_NE(error.find("over 3000 bytes uncompressed"), std::string::npos) << error;
  EXPECT_TRUE(out.empty());
  // A directory that does not exist: exit 1, and no temporary left anywhere near.
  const Outcome r =
      run(plantview("bcf export --views " + (dir() / "views.json").string() + " --images " +
                    (dir() / "images").string() + " --out " + (dir() / "nowhere/x.bcf").string()),
          dir());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("nowhere/x.bcf"), std::string::npos) << r.err;
}

}  // namespace
