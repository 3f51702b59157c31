// plantview/gltf.h: any part of a plant, at a level of detail the caller chooses, as glTF 2.0
// (binary .glb or text .gltf + .bin) for the tools people already use (Blender, three.js,
// Babylon, f3d, Cesium, game-engine importers).
//
// What is written
//   - One node per object, named by the object's name, its extras {"id": "<16 hex digits>",
//     "class": "pipe", key: value...}: each attribute of the object a key of its own beside id
//     and class (Blender shows them as the object's custom properties, three.js as userData);
//     attributes named "id" or "class" go to "attributes": {...} instead; a key repeated: its
//     first value; attribute bytes that are not UTF-8 are read as Latin-1. Nodes sit in the model's hierarchy: a node per site (the object's
//     source: the RVM file or "gen:<preset>"), below it a node per zone (the object's "Zone",
//     else "Area" attribute, where it has one), below that the objects; a pipe or component
//     hangs under its pipeline's node (a node with the pipeline's own name and attributes, also
//     when the pipeline itself was not selected).
//   - Geometry: each object is tessellated by core's templates (plantview/primitives.h) at the
//     levels "Levels" says, its primitives in one mesh with one material (the object's colour:
//     sRGB to linear baseColorFactor, alpha < 255 blended); facet groups and lines included
//     (lines as a LINES primitive). Vertex-cache and vertex-fetch order by meshoptimizer.
//   - Quantization (KHR_mesh_quantization, unless `quantize` is off): a mesh's positions are
//     written as normalized int16 on a grid of its own, centred on its box and scaled by the
//     smallest of 1, 1.5, 2, 3, 4, 6, 8, ... m that holds its half extent; its normals as
//     normalized int8 (within 0.5 degree); the dequantization (grid centre and scale) is folded
//     into the translation and scale of every node (or GPU instance) that draws the mesh, so
//     a mesh up to 2 m across needs no node scale at all. The grid's worst error, half a step
//     on each axis as a distance (sqrt(3)/2 * scale / 32767: 26 um at scale 1, 0.42 mm at 16),
//     is kept within a tenth of the tolerance (kQuantizationShare; 0.5 mm at 5 mm) or, at full
//     resolution and for a camera, within kQuantizationErrorM (0.05 mm); a mesh whose grid
//     would be coarser stays float32, and so does a unit shape's (below: node scales stretch
//     it). So an object's error is at most 1.1x the tolerance (plus the translations' 0.05 mm
//     rounding; rotations are written to 6 decimals, 2e-6 rad, 0.06 mm at 30 m from a node's
//     origin). Indices are uint8 where a mesh has under 255 vertices. Meshes that differ only
//     in colour share their accessors. The extension is then
//     listed in extensionsRequired (the int16 and int8 attributes are not core glTF). Readers:
//     three.js, Babylon.js, Blender's importer, Cesium and gltf-transform read it; f3d 1.3
//     (VTK 9.1) does not list it but reads the attributes and draws the file the same.
//   - Instancing: objects that are the same up to a rigid transform (same primitives, shapes,
//     relative placements to 0.1 mm / 1e-5, colour and levels) share one mesh; their nodes
//     carry the rotation and translation (glTF's own "data instancing", which every reader
//     supports). An object of one box or one cylinder is also shared across sizes: the mesh is
//     the unit shape and the node's scale carries the box's sides or the cylinder's height, so
//     that every pipe of a diameter shares one mesh. With gpu_instancing, a mesh used by at
//     least kGpuInstancingMin objects under one parent node is drawn by one node with
//     EXT_mesh_gpu_instancing (TRANSLATION, ROTATION and, where sizes differ, SCALE per
//     instance) instead of a node per object; the objects' names, ids and
//     attributes are then listed, in instance order, in that node's extras "objects". The
//     extension defines no fallback (a reader without it would draw one copy), so it is then
//     listed in both extensionsUsed and extensionsRequired.
//   - With split, one file per group (site, zone, pipeline or equipment item) named
//     <stem>-<group>.<ext> beside `path` (the group's name made safe for file names, a number
//     added where two come out the same), and an index <stem>.json beside them:
//     {"version": 1, "split": "pipeline", "origin_m": [x,y,z],
//      "files": [{"file": "...", "group": "...", "objects": N, "triangles": N, "bytes": N,
//                 "bounds_m": {"min": [..], "max": [..]}}]} (bounds of the meshes' boxes); objects outside every group of
//     that kind (e.g. structure when splitting by pipeline) go to the group "other".
//
// Units and coordinates: metres; glTF's axes are the model's (x east, y north, z up: readers
//   that assume y up show the plant lying on its side unless they convert; Blender's importer
//   does). Every coordinate is relative to one origin, kept in the asset's extras as
//   {"origin_m": [x, y, z]} (and in the split index): the centre of the selection's bounds,
//   rounded to whole metres, so that plants kilometres from the model origin keep float
//   precision.
//
// Levels: by default full resolution (level 0). tolerance_m > 0: each primitive of each object
//   at its coarsest level whose error (primitives.h, metres) is at most tolerance_m, so that
//   every object's error is at most tolerance_m (an object's parts differ in size: one level
//   for the whole object would keep a vessel's shell as fine as its smallest nozzle needs).
//   With camera: the renderer's own frame plan (cull and choose, render/src/frame_plan.h) for
//   that view at width x height and pixel_error: only what the renderer would draw is written,
//   at the level it would draw it; pipeline runs it would merge are written as one cylinder
//   node (named "<first member> (merged run)") under their pipeline, unless hlod is off; a
//   pipe it would draw as its centreline is written at its coarsest level; tree nodes it would
//   draw as boxes are left out.
//
// Selection: an object is written when it passes every filter given: `globs` (fnmatch
//   patterns; an object matches by its name, a pipe or component also by its pipeline's
//   name), `classes` (its class; "pipeline" also takes the pipeline's pipes and components),
//   `box` (its bounds intersect the box, model space). No filter: every object.
//
// Memory: the store is read twice (selection, then writing); the geometry is tessellated one
//   object at a time and streamed to temporary files beside the output, with the document's
//   accessors, meshes and nodes as JSON text (a .glb is assembled from them at the end). What
//   stays in memory is about 12 bytes per selected object (80 with gpu_instancing, whose
//   grouping waits for the end) and about 300 per distinct mesh, besides the store's read view: not
//   the tessellated plant. Measured peak resident memory: preset c (40,746 objects) about
//   20 MB at any tolerance; preset c at scale 100 (4.07 million objects) 270 MB at 5 mm (2.2 GB written).
// Files: written to a temporary name in the destination directory and renamed when complete:
//   an error leaves no partial file behind (nor any file of a split).
// Threads: export_gltf() runs on the calling thread and reads the store through a view of its
//   own; progress is called on that thread.
// Errors: export_gltf() returns a status and fills `error` with what and where: an empty
//   selection, a store that cannot be read, a file that cannot be written (the path and the
//   system's reason).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/camera.h"
#include "plantview/model.h"
#include "plantview/view_filters.h"

namespace plantview {

class Store;

inline constexpr uint32_t kGpuInstancingMin = 16;  // objects per mesh and parent to use EXT_mesh_gpu_instancing
// Quantization's error bound: this share of the tolerance; at full resolution or for a camera,
// kQuantizationErrorM (half the 0.1 mm to which objects are already taken as equal for sharing).
inline constexpr double kQuantizationShare = 0.1;
inline constexpr double kQuantizationErrorM = 5e-5;

enum class GltfSplit { none, site, zone, pipeline, equipment };
std::string_view gltf_split_name(GltfSplit split);
bool parse_gltf_split(std::string_view name, GltfSplit& split);

struct GltfSelection {
  std::vector<std::string> globs;     // fnmatch patterns on names
  std::vector<ObjectClass> classes;   // empty: every class
  std::optional<DAabb> box;           // model space, metres
  // Clip planes and a section box (view_filters.h): objects (and merged runs) it removes
  // wholly are left out; what it cuts is written whole (its triangles are not clipped).
  Section section;
};

struct GltfExportOptions {
  std::string path;                   // .glb (binary) or .gltf (text + .bin beside it); with
                                      // split, names the files and the index (see above)
  GltfSelection selection;
  double tolerance_m = 0;             // > 0: coarsest level with error <= this
  std::optional<Camera> camera;       // set: the renderer's levels for this view (valid camera)
  uint32_t width = 1920, height = 1080;  // with camera: the image the levels are chosen for
  double pixel_error = 1.0;           // with camera
  bool hlod = true;                   // with camera: merged pipeline runs as the renderer has them
  bool share_meshes = true;           // false: a mesh per object (for comparison: what sharing saves)
  bool gpu_instancing = false;        // EXT_mesh_gpu_instancing for meshes repeated often
  bool quantize = true;               // KHR_mesh_quantization where its error is within the bound
  GltfSplit split = GltfSplit::none;
  // Called with the fraction done (0..1) and what is being done; may be empty.
  std::function<void(double fraction, std::string_view stage)> progress;
};

struct GltfFileSummary {
  std::string path, group;
  uint64_t objects = 0, triangles = 0, lines = 0, bytes = 0;
  uint64_t meshes = 0, instanced_objects = 0;  // distinct meshes; objects drawn through EXT_mesh_gpu_instancing
  DAabb bounds;                        // model space, of the geometry written
};

struct GltfExportSummary {
  glm::dvec3 origin_m{0.0};
  uint64_t objects = 0, triangles = 0, lines = 0, bytes = 0, meshes = 0;
  DAabb bounds;
  std::vector<GltfFileSummary> files;  // one, or one per group with split
};

enum class GltfExportStatus { ok, empty_selection, failed };

// Writes the selected part of the store's current snapshot as glTF (rules above). On any status
// but ok, nothing is left at options.path (nor at any file of a split).
GltfExportStatus export_gltf(const Store& store, const GltfExportOptions& options,
                             GltfExportSummary& summary, std::string& error);

// Parses "X0,Y0,Z0,X1,Y1,Z1" (metres, model space; min and max may come in either order) into
// a box. False with the reason in `error`.
bool parse_box(std::string_view text, DAabb& box, std::string& error);

}  // namespace plantview
