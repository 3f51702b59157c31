// plantview/clash.h: clash detection. Every place where two objects of a store interpenetrate
// deeper than a tolerance (hard clashes) or come closer than a clearance (clearance clashes),
// less what the model's topology says is meant to touch; with stable ids, so that a later run
// says which clashes are new, still active or resolved.
//
// How clashes are found
//   - Broad phase on the store's spatial index, out of core: the work is a list of block pairs
//     (a block with itself, and with every later block whose top bounds come within the
//     clearance of its own), taken in block order by a pool of threads, each with its own
//     sibling view; a task holds its two blocks and the objects of its candidate pairs, and
//     drops them when done, so memory follows the threads, not the plant. Candidates: entries
//     whose bounds (the index's, rounded outward) come within the clearance of each other.
//   - Each object lies in one block, so each pair is met by exactly one task; a shard I/N takes
//     the tasks whose first block lies in the I-th of N consecutive runs of blocks (blocks follow
//     the Morton order of their objects: a run is a spatial region), so N shards check each pair
//     exactly once, and their merged results equal one process's.
//   - Narrow phase per candidate pair on the objects' primitives (measure.h's MeasureShapes:
//     exact FCL primitives for boxes, cylinders, cones and spheres, else meshes within
//     kMeasureMeshErrorM, stated as error_m). Overlapping parts give contact points and a
//     depth: between two exact convex parts FCL's penetration depth; where a part is a mesh, the
//     deepest vertex (a mesh's on the true surface) of either part inside the other (box corners and 32 points on each circular
//     rim count as an exact part's vertices), measured to the other's surface (a mesh's inside
//     is behind its nearest triangle). A part buried in a mesh part without any vertex inside
//     is not seen (measure.h: meshes are surfaces).
//   - Hard clash: depth > tolerance_m. Clearance clash (clearance_m > 0): not a hard clash and
//     the distance < clearance_m (touching or shallower than the tolerance: distance 0).
//   - One clash per pair of objects, however many places they meet: `points_m` lists the
//     places (contact points at least kClashPointSpacingM apart, deepest first, at most
//     kClashMaxPoints; a clearance clash: the midpoint of the two closest points).
//
// What is not a clash (each a named rule, ClashRule; include_connected switches them all off)
//   - same_pipeline: two pipes or components (fittings, valves, supports) of one pipeline
//     (pipeline_id equal and not 0): the line's own parts meet by construction.
//   - connected: two objects with a connection point in common (positions within 2 mm,
//     directions opposite): flanges bolted face to face, a pipe's end on an equipment nozzle.
//   - support: a pipe support (attribute Type "SUPP", or a name whose last part starts with
//     "SUPP") and a pipe or component that its connection point lies on (within the larger of
//     its centreline's radius and 5 cm of a centreline segment): the support carrying the pipe.
//   - nozzle: a pipe or component and an equipment item that its own pipeline connects to (a
//     branch's first or last member has a connection point within 2 mm of one of the item's),
//     where every clash point lies within 0.5 m + 2 nozzle diameters of such a nozzle: the
//     line's flanges and elbows at the nozzle it starts from (decided after the narrow phase,
//     from the points).
//   - An object and itself is never a pair (not switchable).
//
// Ids, groups and status
//   - A clash's id: 64-bit FNV-1a of the two object ids (lower first) and its first point
//     quantised to kClashIdGridM, written as 16 hex digits. With a previous result (status), a
//     clash that matches a previous one (same pair, first points within kClashMatchM) is
//     "active" and keeps the previous id, so an id survives small edits across runs chained by
//     --since; others are "new"; previous clashes matched by none are "resolved" (listed with
//     their previous values). Without a previous result every clash is "new".
//   - Group: each object's owner (a pipe's or component's pipeline, else the object itself),
//     named by its tag; a clash's group is the two owners' tags, sorted, joined by " x ". Clashes
//     of the same two pipelines or equipment items share a group.
//   - Order: clashes sorted by (group, object a id, object b id, id): the same for the same store
//     and settings, whatever the threads or shards.
//   - With revisions (store.h): a new clash names the object of its pair that changed between
//     the previous run's revision and this one (name_changed_objects: Clash::changed_id).
//
// Units: metres, model space. Threads: find_clashes runs a pool of its own (settings.threads,
// 0 = hardware threads) and calls progress from its workers one at a time. Errors: false with
// a message naming the store, block or object that could not be read, or the set that matches
// nothing.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "plantview/model.h"
#include "plantview/review.h"

namespace plantview {

class ReadView;

inline constexpr double kClashDefaultToleranceM = 0.001;
inline constexpr double kClashPointSpacingM = 0.25;
inline constexpr uint32_t kClashMaxPoints = 8;
inline constexpr double kClashIdGridM = 1.0;
inline constexpr double kClashMatchM = 1.0;
// The largest tolerance or clearance accepted (an absurd one is a caller bug in the library,
// a usage error in the CLI).
inline constexpr double kClashMaxDistanceM = 10.0;

enum class ClashRule : uint8_t { same_pipeline, connected, support, nozzle };
inline constexpr int kClashRuleCount = 4;
// "same_pipeline", "connected", "support", "nozzle"
std::string_view clash_rule_name(ClashRule rule);

// A set of objects for --between / --and: a class name (model.h) or a glob (fnmatch) on the
// name (as stored, or without its leading '/') or the Tag attribute. Empty: every object.
struct ClashSet {
  std::string word;
  bool empty() const { return word.empty(); }
  bool contains(const Object& object) const;
};

struct ClashShard {
  uint32_t index = 0, count = 1;  // index < count
};

struct ClashSettings {
  double tolerance_m = kClashDefaultToleranceM;  // 0 <= tolerance_m <= kClashMaxDistanceM
  double clearance_m = 0;                        // 0: off; else > tolerance-free distance
  ClashSet between, with;     // pairs with one object in each (both empty: all pairs)
  bool include_connected = false;
  ClashShard shard;
  unsigned threads = 0;       // 0: hardware threads
  double mesh_error_m = 0.0005;
  // Fraction of block pairs done, (0, 1], from a worker thread (serialised).
  std::function<void(double fraction, uint64_t clashes)> progress;
};

// An immutable text shared by the clashes that name it: an object's tag, a group. A run at 4
// million objects holds millions of clashes, most of whose objects and groups recur; a copy is a
// reference (8 bytes), not a string. Null-terminated; empty when default-made. Copies may be
// used and dropped on different threads (the count is atomic).
class ClashText {
 public:
  ClashText() = default;
  explicit ClashText(std::string_view text);
  ClashText(const ClashText& other) noexcept;
  ClashText(ClashText&& other) noexcept : block_(other.block_) { other.block_ = nullptr; }
  ClashText& operator=(ClashText other) noexcept {
    std::swap(block_, other.block_);
    return *this;
  }
  ~ClashText();
  std::string_view view() const;
  operator std::string_view() const { return view(); }
  std::string str() const { return std::string(view()); }
  const char* c_str() const;
  bool empty() const { return view().empty(); }
  friend bool operator==(const ClashText& x, const ClashText& y) { return x.view() == y.view(); }
  friend bool operator==(const ClashText& x, std::string_view y) { return x.view() == y; }
  friend auto operator<=>(const ClashText& x, const ClashText& y) { return x.view() <=> y.view(); }

 private:
  struct Block;
  Block* block_ = nullptr;
};
std::ostream& operator<<(std::ostream& out, const ClashText& text);

struct ClashObject {
  uint64_t id = 0;
  ClashText tag;
  ObjectClass object_class = ObjectClass::other;
  uint64_t pipeline_id = 0;
};

enum class ClashKind : uint8_t { hard, clearance };
enum class ClashStatus : uint8_t { new_clash, active, resolved };
std::string_view clash_status_name(ClashStatus status);  // "new", "active", "resolved"

struct Clash {
  uint64_t id = 0;
  ClashKind kind = ClashKind::hard;
  ClashStatus status = ClashStatus::new_clash;
  ClashObject a, b;               // a.id < b.id
  double depth_m = 0;             // hard: the deepest penetration found
  double distance_m = 0;          // clearance: the minimum distance (0 touching)
  double error_m = 0;             // bound on depth/distance from tessellation (0: exact parts)
  std::vector<glm::dvec3> points_m;  // at least one
  ClashText group;
  uint64_t changed_id = 0;        // a new clash's object that changed since the previous run
                                  // (name_changed_objects; 0: none named). Its tag is written
                                  // beside it in clashes.json ("changed_tag") and the caption.
  // The tag of changed_id's object ("" when none).
  const ClashText& changed_tag() const;
};

struct ClashCounts {
  uint64_t block_pairs = 0, candidate_pairs = 0, narrow_pairs = 0;
  uint64_t skipped_by_rule[kClashRuleCount] = {};
};

// A run's header: the store and settings it ran on and what it counted (clashes.json but its
// clashes). Copied on its own where the clashes are not (a previous run's keys, merging).
struct ClashRun {
  std::string store_directory;   // canonical
  glm::dvec3 spatial_origin_m{0.0};
  uint64_t commit_id = 0;
  uint32_t revision = 0;
  uint64_t objects = 0;
  double tolerance_m = kClashDefaultToleranceM, clearance_m = 0;
  std::string between, with;
  bool include_connected = false;
  ClashShard shard;
  ClashCounts counts;
};

// What a run found, with its header.
struct ClashReport : ClashRun {
  // Sorted (above); resolved ones last, after status. A deque: it grows without moving what it
  // holds, so a run of millions of clashes holds each once (find_clashes' workers append to it).
  std::deque<Clash> clashes;
};

// Finds the clashes of the view's snapshot. `directory` is recorded as the store's identity.
bool find_clashes(const ReadView& view, const std::string& directory, const ClashSettings& settings,
                  ClashReport& out, std::string& error);

// Whether any object of the snapshot is in the set: a class from the statistics, a glob by a
// pass over the objects that stops at the first match. False with a message on a read error.
bool clash_set_matches(const ReadView& view, const ClashSet& set, bool& matches, std::string& error);

// Sets each clash's status against a previous report of the same store (new, active keeping
// its previous id, and appends the previous clashes no longer found as resolved), then sorts.
// False, naming the reason, when `previous` comes from another store (directory or spatial
// origin differ) or other settings (tolerance, clearance, sets).
bool apply_previous(ClashReport& report, const ClashReport& previous, std::string& error);

// --since against a previous run too large to hold twice (millions of clashes): its header and,
// per clash, what matching needs (about 50 bytes a clash, in the file's order).
struct ClashKey {
  uint64_t id = 0, a = 0, b = 0;  // the clash's id, its objects' ids
  glm::dvec3 first_point_m{0.0};
  bool resolved = false;
};
struct PreviousClashes {
  ClashRun header;
  std::vector<ClashKey> keys;
};
// Reads a clashes file's header and keys, never its clashes whole (errors as parse_clash_report).
bool read_previous_clashes(std::istream& input, PreviousClashes& out, std::string& error);
// apply_previous in two steps: the statuses and kept ids from the keys (false, naming why, for
// another store or other settings), `matched` saying which previous clashes are found again;
// then the previous file, read again, gives those neither matched nor resolved before, appended
// as resolved, and the clashes are sorted (false on a read error: the file changed meanwhile).
bool match_previous(ClashReport& report, const PreviousClashes& previous, std::vector<bool>& matched,
                    std::string& error);
bool append_resolved(ClashReport& report, std::istream& previous_file, const std::vector<bool>& matched,
                     std::string& error);
// After apply_previous: each new clash whose a or b changed (added or modified) between
// `since_revision` (the previous report's) and the view's revision (ReadView::changes) gets
// changed_id (a's where both changed). A range the store cannot give (its changes pruned, or
// a revision it never made) names nothing: false, with `note` saying why (not an error: the
// statuses stand). True with an empty note otherwise (also when the revisions are the same).
bool name_changed_objects(ClashReport& report, const ReadView& view, uint32_t since_revision,
                          std::string& note);

// Sorts the clashes (the order above); merge_reports() and find_clashes() call it.
void sort_clashes(std::deque<Clash>& clashes);

// The shards' reports as one: the same store and settings (else false, naming the file index),
// each shard index once; clashes merged and sorted; counts summed; shard 0/1.
// The shards are taken (moved from: pass std::move where they are not needed again).
bool merge_reports(std::vector<ClashReport> shards, ClashReport& out, std::string& error);

// clashes.json (version 1): {"version":1,"store":{...},"settings":{...},"counts":{...},
//  "clashes":[{"id":"hex16","status":"new","kind":"hard","a":{"id":"..","tag":"..",
//  "class":".."},"b":{..},"depth_m":..|"distance_m":..,"error_m":..,"points_m":[[x,y,z]],
//  "group":".."}]}. Pretty-printed with two spaces, ids as decimal strings.
std::string clash_report_json(const ClashReport& report);
// The same text in pieces, clash by clash, to `sink` (a file: clashes.json is never held whole;
// it stops at the first piece the sink refuses, returning false).
bool write_clash_report(const ClashReport& report, const std::function<bool(std::string_view)>& sink);
// Reads it back; false with a message for text that is not JSON, truncated, another version,
// or a missing or mistyped field (naming it and the clash index).
// The file is read as a stream of parser events: each clash is kept as a Clash, never the
// document's tree (a run at millions of clashes writes gigabytes).
bool parse_clash_report(std::string_view json, ClashReport& out, std::string& error);
bool read_clash_report(std::istream& input, ClashReport& out, std::string& error);
// The same keeping only the clashes `keep` accepts (each is read, given to it, and dropped
// unless kept): a selection from a file of millions is held alone.
bool read_clash_report(std::istream& input, ClashReport& out, std::string& error,
                       const std::function<bool(const Clash&)>& keep);

// Which clashes get a view (`views --per clash --status ... --select ...`): never resolved ones;
// new and active ones as the flags say; and, with `select` (a shell glob, fnmatch), those whose
// view name (clash-<id>), either object's tag (its id where it has none) or group matches.
struct ClashViewSelection {
  bool new_clashes = true, active = true;
  std::string select;  // empty: any
};
bool clash_view_selected(const Clash& clash, const ClashViewSelection& selection);

// Review views of the clashes (resolved ones left out): `views --per clash`. Each is named
// "clash-<id>", kind "clash", its subject the two objects (highlighted, the rest ghosted; the
// first in kClashFirstColour, the second in kClashSecondColour, as ReviewView::colours labelled
// "first: TAG" and "second: TAG"; their BCF Coloring the same), its
// camera fit_camera from the isometric direction on the clash region (the points' bounds grown
// by kClashViewMarginM, centred on the first point), a section box of that region grown by
// another half margin, and
// caption lines: Clash (id, status), A and B (tag and class), Depth or Distance (mm), Point
// (the first, model metres), Group. BCF export writes them as topics of TopicType "Clash".
// This form knows nothing of the objects' sizes: both opaque, the margin kClashViewMarginM.
inline constexpr double kClashViewMarginM = 1.5;
inline constexpr Colour kClashFirstColour{225, 35, 35, 255};    // red
inline constexpr Colour kClashSecondColour{20, 175, 235, 255};  // cyan-blue
std::vector<ReviewView> clash_views(const ClashReport& report, double aspect);
// The same with the objects' bounds read from the store (`views --per clash`), so that each
// image shows both objects and where they meet:
//   - each object's thickness where they meet: of its primitives within kClashViewMarginM
//     of the first point whose bounds meet (within kClashViewThinM) those of one of the
//     other's there, the largest middle of the three extents of its shape as placed (a
//     column's width, a pipe's diameter, however turned); failing any, that of its primitive
//     nearest the point. The one thicker by kClashViewContainerRatio or more is the container: drawn
//     see-through in its colour (SubjectColour::see_through, its label "... (see-through)";
//     BCF: its Color with that alpha), the other opaque inside it. Parts of about one size
//     (a valve on a pipe) are both opaque, as in the form above;
//   - the region is the points' box around the first (deepest) point grown by a margin of
//     kClashViewMarginSizes x the thinner one's thickness, within kClashViewMinMarginM ..
//     kClashViewMarginM (a pipe of 0.2 m: 0.6 m); the section box as above;
//   - the camera, from the isometric direction, is aimed at the first point and fitted on
//     the box centred there that holds the points and the opaque objects' parts in the region
//     (at least kClashViewMinFrameM each way): the buried part is large in the image.
// An object the snapshot no longer holds leaves the view as the form above makes it. False
// with a message naming the object on a read error (`out` unchanged).
inline constexpr double kClashViewThinM = 0.05;
inline constexpr double kClashViewMarginSizes = 3.0;
inline constexpr double kClashViewMinMarginM = 0.5;
inline constexpr double kClashViewMinFrameM = 0.3;
inline constexpr double kClashViewContainerRatio = 1.5;
bool clash_views(const ClashReport& report, double aspect, const ReadView& view,
                 std::vector<ReviewView>& out, std::string& error);

}  // namespace plantview
