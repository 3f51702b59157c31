// Selection for glTF export (rules in selection.h and plantview/gltf.h).
#include "selection.h"

#include <fnmatch.h>

#include <algorithm>
#include <cctype>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview::detail::gltf {

namespace {

bool glob_matches(const std::vector<std::string>& globs, const std::string& name) {
  for (const std::string& g : globs)
    if (::fnmatch(g.c_str(), name.c_str(), 0) == 0) return true;
  return false;
}

bool class_listed(const std::vector<ObjectClass>& classes, ObjectClass c) {
  return std::find(classes.begin(), classes.end(), c) != classes.end();
}

bool intersects(const DAabb& a, const DAabb& b) {
  if (a.empty() || b.empty()) return false;
  for (int i = 0; i < 3; ++i)
    if (a.max[i] < b.min[i] || b.max[i] < a.min[i]) return false;
  return true;
}

bool is_member(const Object& o) {
  return o.pipeline_id != 0 && (o.object_class == ObjectClass::pipe || o.object_class == ObjectClass::component);
}

// What the renderer draws for the view: slot -> level, and the merged runs.
struct CameraChoice {
  std::unordered_map<uint32_t, uint8_t> levels;
  std::vector<SelectedRun> runs;
  std::vector<DAabb> run_bounds;
};

bool choose_as_renderer(const ReadView& view, const GltfExportOptions& options, CameraChoice& out,
                        std::string& error) {
  RenderOptions render;
  render.lod_policy = LodPolicy::screen_space;
  render.pixel_error = options.pixel_error;
  render.hlod = options.hlod;
  render.section = options.selection.section;
  ViewPlan plan;
  if (!plan_view(view, *options.camera, options.width, options.height, render, plan, error))
    return false;
  // A pipe drawn as its centreline is written at its coarsest level.
  for (const PlannedObject& o : plan.objects)
    out.levels[o.slot] = o.centreline ? uint8_t(o.level_count - 1) : o.level;
  for (const PlannedRun& r : plan.runs) {
    const uint8_t level = r.centreline ? uint8_t(r.level_count - 1) : r.level;
    out.runs.push_back({r.first_member, r.pipeline_id, level, r.cylinder, r.origin_m, r.colour});
    out.run_bounds.push_back(r.bounds);
  }
  return true;
}

// An object that passed the box filter, until the pipelines' names are all known.
struct Candidate {
  uint32_t slot;
  uint8_t level;
  ObjectClass object_class;
  bool name_matches;
  uint64_t pipeline_id;  // members: their pipeline
  uint32_t group;        // index into group_names (split) or 0
  float min[3], max[3];  // bounds relative to the spatial origin
};

}  // namespace

std::string zone_of(const Object& object) {
  auto find = [&](std::string_view key) -> const std::string* {
    for (const Attribute& a : object.attributes) {
      if (a.key.size() != key.size()) continue;
      bool same = true;
      for (size_t i = 0; i < key.size() && same; ++i)
        same = std::tolower(static_cast<unsigned char>(a.key[i])) == key[i];
      if (same) return &a.value;
    }
    return nullptr;
  };
  if (const std::string* z = find("zone")) return *z;
  if (const std::string* a = find("area")) return *a;
  return {};
}

bool plan_export(const ReadView& view, const GltfExportOptions& options, ExportPlan& plan,
                 const std::function<void(double)>& progress, std::string& error) {
  const GltfSelection& sel = options.selection;
  plan = ExportPlan{};
  CameraChoice camera;
  if (options.camera && !choose_as_renderer(view, options, camera, error)) return false;

  // 1. One pass: the filters an object decides alone, the pipelines' names, the group keys.
  const glm::dvec3 spatial_origin = view.spatial_origin();
  const uint64_t total = view.info().objects;
  const bool with_attributes = options.split == GltfSplit::zone;
  std::unordered_set<uint64_t> pipelines_matching;
  std::unordered_map<uint64_t, std::string> pipeline_names;  // split by pipeline only
  std::vector<std::string> group_names;
  std::map<std::string, uint32_t, std::less<>> group_index;
  auto group_of = [&](const std::string& key) {
    const auto it = group_index.find(key);
    if (it != group_index.end()) return it->second;
    group_names.push_back(key);
    return group_index[key] = uint32_t(group_names.size() - 1);
  };
  // An object is decided as soon as what decides it is known: at once, unless it is a member
  // whose name does not match and whose pipeline's has not been seen yet (RVM files list a
  // pipeline after its members): those wait for the end of the pass.
  const bool pipelines_listed = class_listed(sel.classes, ObjectClass::pipeline);
  std::unordered_set<uint64_t> pipelines_seen;
  std::vector<Candidate> waiting;
  std::vector<int> group_slot;           // group key -> index in plan.groups
  std::vector<uint32_t> key_of_group;    // plan.groups index -> group key
  auto accept = [&](const Candidate& c) {
    if (group_slot.size() <= c.group) group_slot.resize(c.group + 1, -1);
    int& g = group_slot[c.group];
    if (g < 0) {
      g = int(plan.groups.size());
      plan.groups.emplace_back();
      key_of_group.push_back(c.group);
    }
    plan.groups[size_t(g)].objects.push_back({c.slot, c.level});
    plan.objects += 1;
    if (c.min[0] <= c.max[0]) {
      plan.bounds.extend(spatial_origin + glm::dvec3(c.min[0], c.min[1], c.min[2]));
      plan.bounds.extend(spatial_origin + glm::dvec3(c.max[0], c.max[1], c.max[2]));
    }
  };
  uint64_t done = 0;
  const bool ok = view.for_each_object(
      [&](uint32_t slot, Object&& o) {
        if (progress && (++done & 1023) == 0) progress(double(done) / double(std::max<uint64_t>(total, 1)));
        const bool name_matches = !sel.globs.empty() && glob_matches(sel.globs, o.name);
        if (o.object_class == ObjectClass::pipeline) {
          pipelines_seen.insert(o.id);
          if (name_matches) pipelines_matching.insert(o.id);
          if (options.split == GltfSplit::pipeline) pipeline_names[o.id] = o.name;
        }
        uint8_t level = kLevelByTolerance;
        if (options.camera) {
          const auto it = camera.levels.find(slot);
          if (it == camera.levels.end()) return true;  // not drawn for that view
          level = it->second;
        }
        const uint64_t pipeline_id = is_member(o) ? o.pipeline_id : 0;
        if (!sel.classes.empty() && !class_listed(sel.classes, o.object_class) && !(pipeline_id != 0 && pipelines_listed))
          return true;
        if (!sel.globs.empty() && !name_matches && pipeline_id == 0) return true;
        const DAabb bounds = object_bounds(o);
        if (sel.box && !intersects(bounds, *sel.box)) return true;
        if (section_removes_all(sel.section, bounds)) return true;
        Candidate c{slot, level, o.object_class, name_matches, pipeline_id, 0, {}, {}};
        for (int a = 0; a < 3; ++a) {
          c.min[a] = bounds.empty() ? 0.0f : float(bounds.min[a] - spatial_origin[a]);
          c.max[a] = bounds.empty() ? -1.0f : float(bounds.max[a] - spatial_origin[a]);
        }
        switch (options.split) {
          case GltfSplit::none: break;
          case GltfSplit::site: c.group = group_of(o.source); break;
          case GltfSplit::zone: {
            const std::string zone = zone_of(o);
            c.group = group_of(zone.empty() ? o.source : o.source + "/" + zone);
            break;
          }
          case GltfSplit::pipeline:
            // Named after the pipeline below; the id stands in meanwhile.
            c.group = o.object_class == ObjectClass::pipeline ? group_of("#" + std::to_string(o.id))
                      : pipeline_id != 0                      ? group_of("#" + std::to_string(pipeline_id))
                                                              : group_of("other");
            break;
          case GltfSplit::equipment:
            c.group = group_of(o.object_class == ObjectClass::equipment ? o.name : std::string("other"));
            break;
        }
        if (sel.globs.empty() || name_matches || pipelines_matching.count(pipeline_id)) accept(c);
        else if (!pipelines_seen.count(pipeline_id)) waiting.push_back(c);
        return true;
      },
      with_attributes, error);
  if (!ok) return false;

  // 2. The members that waited for their pipeline's name; the groups' names.
  for (const Candidate& c : waiting)
    if (pipelines_matching.count(c.pipeline_id)) accept(c);
  if (options.split == GltfSplit::pipeline) {
    for (std::string& name : group_names) {
      if (name.empty() || name[0] != '#') continue;
      const auto it = pipeline_names.find(std::stoull(name.substr(1)));
      name = it != pipeline_names.end() ? it->second : "pipeline " + name.substr(1);
    }
  }
  for (size_t g = 0; g < plan.groups.size(); ++g)
    plan.groups[g].name = options.split == GltfSplit::none ? std::string() : group_names[key_of_group[g]];
  // Each group's objects in slot order: the writer reads them so (waiting ones came last).
  for (ExportGroup& g : plan.groups)
    std::sort(g.objects.begin(), g.objects.end(),
              [](const SelectedObject& a, const SelectedObject& b) { return a.slot < b.slot; });
  // Merged runs follow the pipeline filters; they go to the group of their first member.
  for (size_t r = 0; r < camera.runs.size(); ++r) {
    SelectedRun& run = camera.runs[r];
    if (!sel.globs.empty() && !pipelines_matching.count(run.pipeline_id)) continue;
    if (!sel.classes.empty() && !pipelines_listed && !class_listed(sel.classes, ObjectClass::pipe)) continue;
    if (sel.box && !intersects(camera.run_bounds[r], *sel.box)) continue;
    if (section_removes_all(sel.section, camera.run_bounds[r])) continue;
    ExportGroup* group = nullptr;
    if (options.split == GltfSplit::none) {
      if (plan.groups.empty()) plan.groups.push_back(ExportGroup{"", {}, {}});
      group = &plan.groups.front();
    } else {
      // The group its first member would be in.
      std::string name = "other";
      Object first;
      if (!view.object(run.first_member, first, options.split == GltfSplit::zone, error)) return false;
      if (options.split == GltfSplit::site) name = first.source;
      if (options.split == GltfSplit::zone) {
        const std::string zone = zone_of(first);
        name = zone.empty() ? first.source : first.source + "/" + zone;
      }
      if (options.split == GltfSplit::pipeline) {
        const auto it = pipeline_names.find(run.pipeline_id);
        name = it != pipeline_names.end() ? it->second : "pipeline " + std::to_string(run.pipeline_id);
      }
      const auto it = std::find_if(plan.groups.begin(), plan.groups.end(),
                                   [&](const ExportGroup& g) { return g.name == name; });
      group = it != plan.groups.end() ? &*it : &plan.groups.emplace_back(ExportGroup{name, {}, {}});
    }
    group->runs.push_back(run);
    plan.objects += 1;
    plan.bounds.extend(camera.run_bounds[r]);
  }
  if (progress) progress(1.0);
  return true;
}

}  // namespace plantview::detail::gltf
