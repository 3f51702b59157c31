// glTF export (plantview/gltf.h): what the Khronos validator says of the files, the triangles
// and bounds read back from them against the store (oracles: plan_mesh's counts and errors per
// primitive, object_bounds), the files a split writes, the errors that leave nothing behind,
// the CLI's exit statuses, and f3d drawing a small selection.
#include <gtest/gtest.h>
#include <fnmatch.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include <glm/gtc/quaternion.hpp>
#include <tiny_gltf.h>

#include "plantview/generate.h"
#include "plantview/gltf.h"
#include "plantview/image.h"
#include "plantview/ingest.h"
#include "plantview/store.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

// The shared data: $PLANTVIEW_SHARED_DIR when set (a worktree outside the usual layout), else
// beside the repository.
const fs::path kHuldra = fs::path(std::getenv("PLANTVIEW_SHARED_DIR") ? std::getenv("PLANTVIEW_SHARED_DIR")
                                                                      : PLANTVIEW_SHARED_DIR) / "data" / "huldra";
const fs::path kValidator = fs::path(PLANTVIEW_SOURCE_DIR) / ".tools/npm/node_modules/gltf-validator";
const fs::path kValidateScript = fs::path(PLANTVIEW_SOURCE_DIR) / "tests/gltf/validate.js";

struct Outcome {
  int status = -1;
  std::string out;
};

Outcome run(const std::string& command) {
  Outcome r;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buffer[4096];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, p)) > 0) r.out.append(buffer, n);
  const int raw = ::pclose(p);
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return r;
}

uint64_t object_count(const Store& store) {
  std::string error;
  const auto view = store.read(error);
  return view ? view->info().objects : 0;
}

bool have(const std::string& program) { return run("command -v " + program + " >/dev/null").status == 0; }

// The validator's report, or a skip reason.
std::string validate(const fs::path& file, nlohmann::json& report) {
  if (!have("node")) return "node is not installed";
  if (!fs::exists(kValidator / "package.json"))
    return "gltf-validator is not installed under .tools/npm (run scripts/deps.sh)";
  const Outcome r = run("node " + kValidateScript.string() + " " + kValidator.string() + " " + file.string());
  if (r.status == 2) return "the validator could not run: " + r.out;
  report = nlohmann::json::parse(r.out.substr(0, r.out.find('\n')), nullptr, false);
  return {};
}

void expect_no_errors(const fs::path& file) {
  nlohmann::json report;
  const std::string skip = validate(file, report);
  if (!skip.empty()) GTEST_SKIP() << skip;
  ASSERT_TRUE(report.is_object()) << "validator output is not JSON";
  EXPECT_EQ(report["issues"]["numErrors"], 0) << report["issues"].dump(1);
  EXPECT_EQ(report["issues"]["numWarnings"], 0) << report["issues"].dump(1);
}

// The stores every test reads: preset a and (when the shared data is there) Huldra.
class GltfExport : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    fs::create_directories(dir_->path());
    std::string error;
    preset_a_ = Store::open((dir_->path() / "a").string(), Store::Mode::read_write, error).release();
    ASSERT_NE(preset_a_, nullptr) << error;
    GenerateOptions g;
    g.preset = 'a';
    ASSERT_TRUE(ingest_generated(*preset_a_, g));
    if (fs::exists(kHuldra / "WD1-PSUP.RVM")) {
      const std::vector<std::string> files{(kHuldra / "WD1-PSUP.RVM").string()};
      const auto plan = plan_import(files, error);
      ASSERT_TRUE(plan) << error;
      huldra_ = Store::open((dir_->path() / "huldra").string(), Store::Mode::read_write, error).release();
      ASSERT_NE(huldra_, nullptr) << error;
      ASSERT_TRUE(ingest_files(*huldra_, *plan));
    }
  }
  static void TearDownTestSuite() {
    delete preset_a_;
    delete huldra_;
    delete dir_;
  }
  fs::path out(const std::string& name) { return dir_->path() / name; }

  static GltfExportSummary export_ok(const Store& store, GltfExportOptions options) {
    GltfExportSummary summary;
    std::string error;
    EXPECT_EQ(export_gltf(store, options, summary, error), GltfExportStatus::ok) << error;
    return summary;
  }

  static inline TempDir* dir_ = nullptr;
  static inline Store* preset_a_ = nullptr;
  static inline Store* huldra_ = nullptr;
};

// ---- Reading a file back (tinygltf's loader), independent of the writer's bookkeeping.

struct ReadBack {
  glm::dvec3 origin_m{0.0};
  std::map<uint64_t, uint64_t> triangles_by_id;  // per object node (extras.id)
  std::map<uint64_t, DAabb> bounds_by_id;        // model space, from every vertex
  DAabb bounds;
  uint64_t object_nodes = 0;
  std::map<uint64_t, std::map<std::string, std::string>> attributes_by_id;  // extras but id and class
  uint64_t quantized_positions = 0;  // POSITION accessors of normalized int16
  bool quantization_required = false;  // KHR_mesh_quantization in extensionsRequired
};

bool read_back(const fs::path& file, ReadBack& out, std::string& error) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string warning;
  const bool ok = file.extension() == ".glb" ? loader.LoadBinaryFromFile(&model, &error, &warning, file.string())
                                             : loader.LoadASCIIFromFile(&model, &error, &warning, file.string());
  if (!ok) return false;
  const tinygltf::Value& origin = model.asset.extras.Get("origin_m");
  if (!origin.IsArray() || origin.ArrayLen() != 3) {
    error = "asset.extras.origin_m missing";
    return false;
  }
  for (int a = 0; a < 3; ++a) out.origin_m[a] = origin.Get(a).GetNumberAsDouble();
  out.quantization_required = std::find(model.extensionsRequired.begin(), model.extensionsRequired.end(),
                                        "KHR_mesh_quantization") != model.extensionsRequired.end();
  // Every node's world transform (parents first: walk from the scene's roots).
  std::vector<glm::dmat4> world(model.nodes.size(), glm::dmat4(1.0));
  std::vector<int> stack(model.scenes.at(0).nodes.begin(), model.scenes.at(0).nodes.end());
  std::vector<int> parent(model.nodes.size(), -1);
  for (size_t i = 0; i < model.nodes.size(); ++i)
    for (int c : model.nodes[i].children) parent[size_t(c)] = int(i);
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    const tinygltf::Node& n = model.nodes[size_t(i)];
    glm::dmat4 local(1.0);
    if (n.translation.size() == 3) local = glm::translate(local, glm::dvec3(n.translation[0], n.translation[1], n.translation[2]));
    if (n.rotation.size() == 4)
      local *= glm::mat4_cast(glm::dquat(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]));
    if (n.scale.size() == 3) local = glm::scale(local, glm::dvec3(n.scale[0], n.scale[1], n.scale[2]));
    world[size_t(i)] = (parent[size_t(i)] >= 0 ? world[size_t(parent[size_t(i)])] : glm::dmat4(1.0)) * local;
    for (int c : n.children) stack.push_back(c);
  }
  for (size_t i = 0; i < model.nodes.size(); ++i) {
    const tinygltf::Node& n = model.nodes[i];
    // The object a node draws: its own id, or its parent's for a split-off geometry node.
    const tinygltf::Node& owner = n.name == "geometry" && parent[i] >= 0 ? model.nodes[size_t(parent[i])] : n;
    uint64_t id = 0;
    if (owner.extras.Has("id")) {
      id = std::stoull(owner.extras.Get("id").Get<std::string>(), nullptr, 16);
      if (&owner == &n) {
        out.object_nodes += 1;
        std::map<std::string, std::string>& attributes = out.attributes_by_id[id];
        for (const std::string& key : n.extras.Keys())
          if (key != "id" && key != "class") attributes[key] = n.extras.Get(key).Get<std::string>();
      }
    }
    if (n.mesh < 0) continue;
    for (const tinygltf::Primitive& p : model.meshes[size_t(n.mesh)].primitives) {
      const tinygltf::Accessor& index = model.accessors[size_t(p.indices)];
      if (p.mode == TINYGLTF_MODE_TRIANGLES) out.triangles_by_id[id] += index.count / 3;
      const tinygltf::Accessor& pos = model.accessors[size_t(p.attributes.at("POSITION"))];
      const tinygltf::BufferView& view = model.bufferViews[size_t(pos.bufferView)];
      const unsigned char* base = model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + pos.byteOffset;
      const size_t stride = pos.ByteStride(view);
      // float32, or (KHR_mesh_quantization) normalized int16 dequantized by the node's transform.
      if (pos.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT &&
          !(pos.componentType == TINYGLTF_COMPONENT_TYPE_SHORT && pos.normalized)) {
        error = "POSITION accessor of component type " + std::to_string(pos.componentType);
        return false;
      }
      out.quantized_positions += pos.componentType == TINYGLTF_COMPONENT_TYPE_SHORT;
      for (size_t v = 0; v < pos.count; ++v) {
        double xyz[3];
        if (pos.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
          float f[3];
          std::memcpy(f, base + v * stride, sizeof f);
          for (int a = 0; a < 3; ++a) xyz[a] = f[a];
        } else {
          int16_t q[3];
          std::memcpy(q, base + v * stride, sizeof q);
          for (int a = 0; a < 3; ++a) xyz[a] = std::max(q[a] / 32767.0, -1.0);
        }
        const glm::dvec3 p_m = glm::dvec3(world[i] * glm::dvec4(xyz[0], xyz[1], xyz[2], 1.0)) + out.origin_m;
        out.bounds.extend(p_m);
        out.bounds_by_id[id].extend(p_m);
      }
    }
  }
  return true;
}

// The oracle: every primitive at its coarsest level whose error is at most the tolerance,
// counted by the templates (plan_mesh), with a loop of its own.
uint64_t template_triangles(const Object& o, double tolerance_m) {
  uint64_t triangles = 0;
  for (const Primitive& p : o.primitives) {
    const MeshPlan plan = plan_mesh(p);
    if (plan.topology != Topology::triangles || plan.vertex_count == 0) continue;
    uint32_t level = 0;
    while (tolerance_m > 0 && level + 1 < plan.level_count && plan.error_m[level + 1] <= tolerance_m) ++level;
    triangles += element_count(plan, level);
  }
  return triangles;
}

void expect_objects_match_store(const Store& store, const ReadBack& back, double tolerance_m,
                                uint64_t expected_objects) {
  std::string error;
  const auto view = store.read(error);
  ASSERT_TRUE(view) << error;
  uint64_t checked = 0;
  for (const auto& [id, triangles] : back.triangles_by_id) {
    if (id == 0) continue;
    const std::optional<uint32_t> slot = view->slot_of(id);
    ASSERT_TRUE(slot) << std::hex << id;
    Object o;
    ASSERT_TRUE(view->object(*slot, o, true, error)) << error;
    EXPECT_EQ(triangles, template_triangles(o, tolerance_m)) << o.name;
    // Its attributes (ASCII in these stores), each key's first value, as the extras' keys.
    std::map<std::string, std::string> attributes;
    for (const Attribute& a : o.attributes) attributes.emplace(a.key, a.value);
    ASSERT_EQ(back.attributes_by_id.count(id), 1u) << o.name;
    EXPECT_EQ(back.attributes_by_id.at(id), attributes) << o.name;
    // Every vertex within the object's bounds, up to the tolerance (and float rounding).
    const DAabb b = object_bounds(o), got = back.bounds_by_id.at(id);
    const double slack = tolerance_m + 1e-3;
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(got.min[a], b.min[a] - slack) << o.name << " axis " << a;
      EXPECT_LE(got.max[a], b.max[a] + slack) << o.name << " axis " << a;
    }
    ++checked;
  }
  EXPECT_GT(checked, 0u);
  EXPECT_EQ(back.object_nodes, expected_objects);
}

TEST_F(GltfExport, PresetAAtToleranceValidatesAndMatchesTheTemplates) {
  GltfExportOptions o;
  o.path = out("a.gltf").string();  // the text form, with its .bin
  o.tolerance_m = 0.02;
  const GltfExportSummary s = export_ok(*preset_a_, o);
  ASSERT_EQ(s.files.size(), 1u);
  EXPECT_TRUE(fs::exists(out("a.bin")));
  EXPECT_EQ(s.objects, object_count(*preset_a_));
  ReadBack back;
  std::string error;
  ASSERT_TRUE(read_back(out("a.gltf"), back, error)) << error;
  EXPECT_EQ(back.origin_m, s.origin_m);
  EXPECT_TRUE(back.quantization_required);  // the default
  expect_objects_match_store(*preset_a_, back, o.tolerance_m, s.objects);
  expect_no_errors(out("a.gltf"));
}

TEST_F(GltfExport, HuldraAtFullResolutionValidatesAndMatchesTheTemplates) {
  if (!huldra_) GTEST_SKIP() << "Huldra is not in " << kHuldra;
  GltfExportOptions o;
  o.path = out("huldra.glb").string();
  const GltfExportSummary s = export_ok(*huldra_, o);
  std::string error;
  const auto view = huldra_->read(error);
  EXPECT_EQ(s.triangles, view->info().statistics.triangles);  // level 0 of everything
  ReadBack back;
  ASSERT_TRUE(read_back(out("huldra.glb"), back, error)) << error;
  expect_objects_match_store(*huldra_, back, 0.0, s.objects);
  // The whole model: the file's bounds are the store's (within float rounding).
  const DAabb store_bounds = view->info().statistics.bounds;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(back.bounds.min[a], store_bounds.min[a], 2e-3) << "axis " << a;
    EXPECT_NEAR(back.bounds.max[a], store_bounds.max[a], 2e-3) << "axis " << a;
  }
  expect_no_errors(out("huldra.glb"));
}

TEST_F(GltfExport, SelectionBoundsEqualTheStoresWithinTheTolerance) {
  GltfExportOptions o;
  o.path = out("selection.glb").string();
  o.tolerance_m = 0.005;
  o.selection.globs = {"/P-01-00*"};  // pipelines by name: their pipes and components come along
  o.gpu_instancing = false;
  const GltfExportSummary s = export_ok(*preset_a_, o);
  // The oracle: every object whose name, or whose pipeline's name, matches.
  std::string error;
  const auto view = preset_a_->read(error);
  std::map<uint64_t, std::string> pipelines;
  std::vector<Object> objects;
  ASSERT_TRUE(view->for_each_object([&](uint32_t, Object&& obj) {
    if (obj.object_class == ObjectClass::pipeline) pipelines[obj.id] = obj.name;
    objects.push_back(std::move(obj));
    return true;
  }, false, error));
  DAabb expected;
  uint64_t selected = 0;
  for (const Object& obj : objects) {
    const auto it = pipelines.find(obj.pipeline_id);
    const std::string& by = (obj.object_class != ObjectClass::pipeline && it != pipelines.end()) ? it->second : obj.name;
    if (::fnmatch("/P-01-00*", obj.name.c_str(), 0) != 0 && ::fnmatch("/P-01-00*", by.c_str(), 0) != 0) continue;
    expected.extend(object_bounds(obj));
    ++selected;
  }
  ASSERT_GT(selected, 10u);
  EXPECT_EQ(s.objects, selected);
  ReadBack back;
  ASSERT_TRUE(read_back(out("selection.glb"), back, error)) << error;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(back.bounds.min[a], expected.min[a], o.tolerance_m + 1e-3) << "axis " << a;
    EXPECT_NEAR(back.bounds.max[a], expected.max[a], o.tolerance_m + 1e-3) << "axis " << a;
  }
  expect_objects_match_store(*preset_a_, back, o.tolerance_m, s.objects);
  expect_no_errors(out("selection.glb"));
}

TEST_F(GltfExport, GpuInstancingValidatesAndCountsEveryObject) {
  GltfExportOptions o;
  o.path = out("instanced.glb").string();
  o.tolerance_m = 0.02;
  o.gpu_instancing = true;
  const GltfExportSummary s = export_ok(*preset_a_, o);
  ASSERT_EQ(s.files.size(), 1u);
  EXPECT_GT(s.files[0].instanced_objects, 0u);
  EXPECT_EQ(s.objects, object_count(*preset_a_));
  expect_no_errors(out("instanced.glb"));
}

TEST_F(GltfExport, QuantizedVerticesStayWithinATenthOfTheToleranceOfTheFloatOnes) {
  GltfExportOptions quantized, plain;
  quantized.path = out("quantized.glb").string();
  plain.path = out("plain.glb").string();
  quantized.tolerance_m = plain.tolerance_m = 0.005;
  plain.quantize = false;
  const GltfExportSummary q = export_ok(*preset_a_, quantized), f = export_ok(*preset_a_, plain);
  EXPECT_EQ(q.triangles, f.triangles);
  EXPECT_LT(double(q.bytes), 0.85 * double(f.bytes));
  ReadBack qb, fb;
  std::string error;
  ASSERT_TRUE(read_back(out("quantized.glb"), qb, error)) << error;
  ASSERT_TRUE(read_back(out("plain.glb"), fb, error)) << error;
  EXPECT_TRUE(qb.quantization_required);
  EXPECT_GT(qb.quantized_positions, 0u);
  EXPECT_FALSE(fb.quantization_required);
  EXPECT_EQ(fb.quantized_positions, 0u);
  // Each object's vertices: the grid's error (at most a tenth of the tolerance, gltf.h) plus the
  // translations' 0.1 mm rounding, both files' float rounding.
  const double slack_m = kQuantizationShare * quantized.tolerance_m + 2e-4;
  ASSERT_EQ(qb.bounds_by_id.size(), fb.bounds_by_id.size());
  for (const auto& [id, b] : fb.bounds_by_id) {
    const DAabb& got = qb.bounds_by_id.at(id);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(got.min[a], b.min[a], slack_m) << std::hex << id << " axis " << a;
      EXPECT_NEAR(got.max[a], b.max[a], slack_m) << std::hex << id << " axis " << a;
    }
  }
  expect_no_errors(out("quantized.glb"));
}

TEST_F(GltfExport, SharingMeshesMakesTheFileSmallerAndKeepsTheTriangles) {
  GltfExportOptions shared, own;
  shared.path = out("shared.glb").string();
  own.path = out("own.glb").string();
  own.share_meshes = false;
  const GltfExportSummary a = export_ok(*preset_a_, shared), b = export_ok(*preset_a_, own);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_LT(a.meshes * 3, b.meshes);
  EXPECT_LT(a.bytes * 2, b.bytes);
}

TEST_F(GltfExport, SplitByPipelineWritesAFilePerGroupAndAnIndex) {
  GltfExportOptions o;
  o.path = out("split/plant.glb").string();
  fs::create_directories(out("split"));
  o.tolerance_m = 0.02;
  o.selection.classes = {ObjectClass::pipeline};
  o.split = GltfSplit::pipeline;
  const GltfExportSummary s = export_ok(*preset_a_, o);
  ASSERT_GT(s.files.size(), 5u);
  std::ifstream in(out("split/plant.json"));
  const nlohmann::json index = nlohmann::json::parse(in, nullptr, false);
  ASSERT_TRUE(index.is_object());
  EXPECT_EQ(index["split"], "pipeline");
  ASSERT_EQ(index["files"].size(), s.files.size());
  uint64_t objects = 0;
  for (const nlohmann::json& f : index["files"]) {
    EXPECT_TRUE(fs::exists(out("split") / f["file"].get<std::string>())) << f.dump();
    EXPECT_TRUE(f.contains("bounds_m")) << f.dump();
    objects += f["objects"].get<uint64_t>();
  }
  EXPECT_EQ(objects, s.objects);
  EXPECT_FALSE(fs::exists(out("split/plant.glb")));  // the name is the files' stem only
}

TEST_F(GltfExport, ErrorsLeaveNoFileBehind) {
  GltfExportSummary s;
  std::string error;
  GltfExportOptions empty;
  empty.path = out("empty.glb").string();
  empty.selection.globs = {"no such object*"};
  EXPECT_EQ(export_gltf(*preset_a_, empty, s, error), GltfExportStatus::empty_selection);
  EXPECT_NE(error.find("empty"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(empty.path));

  GltfExportOptions unwritable;
  unwritable.path = out("no-such-dir/plant.glb").string();
  EXPECT_EQ(export_gltf(*preset_a_, unwritable, s, error), GltfExportStatus::failed);
  EXPECT_NE(error.find("no-such-dir/plant.glb"), std::string::npos) << error;
  size_t left = 0;
  for (const auto& e : fs::directory_iterator(dir_->path())) left += e.path().filename().string().find(".tmp-") != std::string::npos;
  EXPECT_EQ(left, 0u);
}

TEST_F(GltfExport, CameraExportWritesWhatTheRendererDrawsForTheView) {
  std::string error;
  const DAabb bounds = preset_a_->read(error)->info().statistics.bounds;
  GltfExportOptions o;
  o.path = out("view.glb").string();
  Camera c = default_camera(bounds, 16.0 / 9.0);
  o.camera = c;
  o.width = 640;
  o.height = 360;
  o.pixel_error = 2;
  const GltfExportSummary far = export_ok(*preset_a_, o);
  GltfExportOptions full;
  full.path = out("full.glb").string();
  const GltfExportSummary all = export_ok(*preset_a_, full);
  EXPECT_GT(far.objects, 0u);
  EXPECT_LT(far.triangles, all.triangles / 2);  // a far view draws coarse levels and leaves out specks
  expect_no_errors(out("view.glb"));
}

TEST_F(GltfExport, CommandLineExitStatuses) {
  const std::string bin = PLANTVIEW_BIN;
  const std::string store = (dir_->path() / "a").string();
  EXPECT_EQ(run(bin + " export --store " + store + " --gltf " + out("x.txt").string()).status, 2);
  EXPECT_EQ(run(bin + " export --store " + store + " --gltf " + out("x.glb").string() + " --tolerance -1").status, 2);
  EXPECT_EQ(run(bin + " export --store " + store + " --gltf " + out("x.glb").string() + " --pixel-error 2").status, 2);
  EXPECT_EQ(run(bin + " export --store " + store + " --gltf " + out("x.glb").string() + " --class pumps").status, 2);
  EXPECT_EQ(run(bin + " export --store " + store + " --gltf " + out("x.glb").string() + " --box 1,2,3").status, 2);
  const Outcome empty = run(bin + " export --store " + store + " --gltf " + out("x.glb").string() + " --select 'nothing*'");
  EXPECT_EQ(empty.status, 1) << empty.out;
  EXPECT_NE(empty.out.find("empty"), std::string::npos) << empty.out;
  EXPECT_FALSE(fs::exists(out("x.glb")));
  const Outcome ok = run(bin + " export --store " + store + " --gltf " + out("x.glb").string() + " --class equipment --tolerance 10");
  ASSERT_EQ(ok.status, 0) << ok.out;
  const nlohmann::json j = nlohmann::json::parse(ok.out, nullptr, false);
  EXPECT_GT(j.value("objects", 0), 0);
  EXPECT_EQ(run(bin + " export --store " + store + " --xml " + out("x.xml").string() + " --no-quantization").status, 2);
  const Outcome plain = run(bin + " export --store " + store + " --gltf " + out("plain-cli.glb").string() +
                            " --class equipment --tolerance 10 --no-quantization");
  ASSERT_EQ(plain.status, 0) << plain.out;
  ReadBack back;
  std::string error;
  ASSERT_TRUE(read_back(out("plain-cli.glb"), back, error)) << error;
  EXPECT_FALSE(back.quantization_required);
  EXPECT_EQ(back.quantized_positions, 0u);
}

// With quantized vertices (the default): f3d 1.3 (VTK 9.1) does not list KHR_mesh_quantization
// among its extensions but reads normalized int16 and int8 attributes.
TEST_F(GltfExport, F3dDrawsASmallSelection) {
  if (!have("f3d") || !have("xvfb-run")) GTEST_SKIP() << "f3d or xvfb-run is not installed";
  GltfExportOptions o;
  o.path = out("small.glb").string();
  o.selection.globs = {"/C-01-001", "/V-01-01*"};
  o.tolerance_m = 0.01;
  export_ok(*preset_a_, o);
  const fs::path png = out("small.png");
  const Outcome r = run("timeout 60 xvfb-run -a f3d --output " + png.string() + " --resolution 320,240 --up +Z " + o.path);
  ASSERT_EQ(r.status, 0) << r.out;
  Image image;
  std::string error;
  ASSERT_TRUE(read_image(png.string(), image, error)) << error;
  // Not empty: some pixels differ from the background (the first pixel, a corner).
  size_t differing = 0;
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i)
    differing += std::memcmp(&image.rgba[i * 4], &image.rgba[0], 3) != 0;
  EXPECT_GT(differing, 100u) << "f3d drew nothing of " << o.path;
}

}  // namespace
}  // namespace plantview
