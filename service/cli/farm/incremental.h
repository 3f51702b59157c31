// The incremental farm: what each rendered view drew, and whether a later state of the store can
// change its image (docs/farm.md, "Incremental re-renders").
//
// Files in an output directory DIR (each written atomically, output_dir.h):
//   objects/<identity>.bin  the store's objects at one state (store_identity, job_inputs.h): per
//                           object its id, content hash and model-space bounds, by id. Written
//                           by `farm submit` (or the first shard that needs it), kept while a
//                           record refers to it.
//   drawn/<view>.drawn      what the view's image was drawn from (render.h:
//                           FrameStats::drawn_slots and drawn_regions): the (id, content hash)
//                           of every object that gave it pixels, by id, and the bounds of the
//                           nodes drawn whole.
// A view's record (manifest.h) names both (its "store" and "drawn") and holds the view's
// frustum inputs (camera, "size") and its section ("section"), and the digest of its global
// inputs ("global": what the image depends on beyond its own settings and the objects it drew,
// the model bounds where the ground or a section box uses them).
//
// The rule: a view rendered at store state P is stale at state C when
//   - its settings (the view, the size, the render options) changed: the settings hash;
//   - its global inputs changed;
//   - an object it drew was modified or removed, or a node it drew whole held one (the old
//     bounds of a removed or modified object meet the node's bounds), or a pipeline it drew a
//     member of changed or gained, lost or changed a member its branches list (pipeline runs
//     merge such members, in view or not);
//   - an added or modified object's new bounds enter its frustum (no far plane, a margin of a
//     few pixels) and are not wholly removed by its section.
// Otherwise its image is byte-identical to what rendering it at C would write (the renderer
// draws by id, not by slot: render.h), and it is kept.
// Content hashes: the store's (ReadView::content_hash: its record and attributes).
// Errors: false with a message naming the file or the object.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "plantview/render.h"

namespace plantview {
class ReadView;
}

namespace plantview::cli::farm {

// One object of a store state.
struct ObjectState {
  uint64_t id = 0, hash = 0;
  uint64_t pipeline_id = 0;  // whose branches list it (0: none; pipeline HLOD runs)
  DAabb bounds;  // model space; empty for objects without geometry
};

// Every object of the snapshot, by id (one pass over the store).
bool store_objects(const ReadView& read, std::vector<ObjectState>& out, std::string& error);

std::filesystem::path objects_file(const std::filesystem::path& dir, const std::string& identity);
bool write_objects_file(const std::filesystem::path& path, const std::vector<ObjectState>& objects,
                        std::string& error);
bool read_objects_file(const std::filesystem::path& path, std::vector<ObjectState>& objects,
                       std::string& error);
// DIR's objects file of the snapshot (identity: store_identity(read)), written from a pass
// over the store unless it exists.
bool ensure_objects_file(const std::filesystem::path& dir, const std::string& identity,
                         const ReadView& read, std::string& error);

// What one view's image was drawn from.
struct DrawnSet {
  std::vector<std::pair<uint64_t, uint64_t>> objects;  // (id, content hash), by id, unique
  std::vector<DAabb> regions;                          // nodes drawn whole, model space
  // Pipelines with a member drawn (sorted, unique): whether a pipe is drawn merged into a run
  // (render.h, pipeline HLOD) depends on every member of its pipeline.
  std::vector<uint64_t> pipelines;
};
// From a frame's FrameStats::drawn_slots and drawn_regions, read through the renderer's
// snapshot (`read`), hashes from `objects` (that snapshot's objects, by id).
bool drawn_set(const ReadView& read, const FrameStats& stats,
               const std::vector<ObjectState>& objects, DrawnSet& out, std::string& error);
// 16 hex digits over the (id, hash) pairs and the regions.
std::string drawn_digest(const DrawnSet& drawn);
std::filesystem::path drawn_file(const std::filesystem::path& dir, const std::string& view_name);
bool write_drawn_file(const std::filesystem::path& path, const DrawnSet& drawn, std::string& error);
bool read_drawn_file(const std::filesystem::path& path, DrawnSet& drawn, std::string& error);

// Whether a view's image depends on the model bounds: where the ground is drawn (its level and
// extent) or its section has a box (which box faces clip).
bool uses_model_bounds(const RenderOptions& view_options);
// The digest of a view's global inputs: the model bounds where it uses them, else nothing.
std::string global_inputs_hash(const DAabb& model_bounds, bool uses_bounds);

nlohmann::json section_json(const Section& section);
bool parse_section_json(const nlohmann::json& json, Section& out);

// The change between two states of the store.
struct StoreChange {
  std::vector<uint64_t> gone;         // removed or modified: ids, sorted
  std::vector<DAabb> gone_bounds;     // their bounds before (non-empty ones)
  std::vector<ObjectState> arrived;   // added or modified: as they are now
  std::vector<uint64_t> pipelines;    // with a member (or themselves) changed: sorted ids
  size_t added = 0, removed = 0, modified = 0;
};
StoreChange diff_states(const std::vector<ObjectState>& before, const std::vector<ObjectState>& after);

// Why a view is stale; `fresh` when it is not.
struct Staleness {
  enum class Reason { fresh, settings, global_input, changed_object, added_in_view, no_record };
  Reason reason = Reason::fresh;
  std::string detail;  // "object 1234abcd... modified or removed", ...
};
// "fresh", "settings", "global input", "changed object", "added object in view", "no record".
const char* staleness_name(Staleness::Reason reason);

// Judges done views rendered at earlier store states against the current one (`current`: its
// identity; its objects read from DIR's objects file). Loads each earlier state's objects file
// once.
class StalenessJudge {
 public:
  StalenessJudge(std::filesystem::path dir, std::string current_identity)
      : dir_(std::move(dir)), current_(std::move(current_identity)) {}
  // `record`: a done record (manifest.h); `settings_hash`: what the view's settings hash is now
  // (empty: not known, not compared); `global_hash`: its global inputs' digest now.
  // False on a read error of the current state's objects file.
  bool judge(const nlohmann::json& record, const std::string& settings_hash,
             const std::string& global_hash, Staleness& out, std::string& error);

 private:
  std::filesystem::path dir_;
  std::string current_;
  std::vector<ObjectState> current_objects_;
  bool loaded_ = false;
  std::map<std::string, std::unique_ptr<StoreChange>> changes_;  // by earlier identity (null: no file)
};

}  // namespace plantview::cli::farm
