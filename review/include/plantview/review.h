// plantview/review.h: review views — what to look at. A review view is a named, fitted camera on
// one subject of a plant (an equipment item, a pipeline, an area, or the whole plant), what
// `plantview views` writes to a views file and `render --views`, the farm and the viewer read.
// The module chooses subjects from a store, places cameras that see them (clear of walls and
// columns where it can) and reads and writes the views file; it uses the renderer's cameras
// (plantview/camera.h) and is not used by the renderer.
//
// Units: metres (model space), degrees where the name says _deg.
// Threads: plain values and pure functions, callable from any thread; make_review_views reads
// the store through a view of its own on the calling thread.
// Errors: fallible calls return false and fill `error` with what is wrong and where.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "plantview/camera.h"
#include "plantview/view_filters.h"

namespace plantview {

class Store;

// A review view: a named, fitted camera on one subject of the plant (an equipment item, a
// pipeline, an area, or the whole plant), what `plantview views` writes and `render --views`
// reads. `name` is unique in its file and safe as a file name ([A-Za-z0-9._-], not starting with
// '.'); `kind` is overview|equipment|pipeline|area; `aspect` is the width / height the camera was
// fitted for; `subject` lists the subject's store object ids (empty for an overview: the whole
// plant, nothing highlighted); `attributes` are the caption lines, in order (tag, type, ...).
struct ReviewView {
  std::string name, title, kind;
  Camera camera;
  double aspect = 16.0 / 9.0;
  std::vector<uint64_t> subject;
  std::vector<std::pair<std::string, std::string>> attributes;
  Section section;     // empty: nothing cut
  ObjectStyle style;   // empty: the model's colours, every object shown
  // Set: the view is a change image of this range (render.h: RenderOptions::changes); its
  // colours and highlight are the changes', whatever `subject` and `style.colour_by` say.
  std::optional<ChangeRange> changes;
  // Non-empty: these subjects drawn in these colours instead of their own, with a legend of the
  // labels (render.h: RenderOptions::subject_colours); a clash view's two objects.
  std::vector<SubjectColour> colours;
};

// The views file. JSON:
//   {"version": 1, "per": "equipment",
//    "views": [{"name": "P-101A", "title": "Pump P-101A", "kind": "equipment",
//               "camera": {"eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov_deg": 50},
//               "aspect": 1.7778, "subject": [12, 13], "attributes": {"tag": "P-101A", ...},
//               "section": {"planes": [{"point": [x,y,z], "normal": [x,y,z]}],
//                           "box": {"min": [x,y,z], "max": [x,y,z]}, "capped": true},
//               "style": {"colour_by": "Material", "hide": ["structure"], "only": ["P-*"]},
//               "changes": "12..14",
//               "colours": [{"id": 12, "colour": "#d72828", "label": "first: P-101A"},
//                           {"id": 13, "colour": "#14afeb", "label": "second: C-1 (see-through)",
//                            "see_through": true}]}]}
// `section` and `style` are optional (absent: nothing cut, the model's colours) and written
// only when not empty; each of their keys is optional too. `changes` (optional) is a range
// as parse_change_range reads it ("R1" or "R1..R2"). `colours` (optional, written when not
// empty): each entry's id must be in `subject`, once; its `see_through` (optional, a boolean,
// written only when true: SubjectColour::see_through) defaults to false.
// `per` is overview|equipment|pipeline|area. The writer keeps the views' and attributes' order
// (the parser reads that order back) and writes text that is not UTF-8 (attribute values are
// bytes as the model gave them) with U+FFFD in place of each invalid sequence. The parser rejects: text that is not JSON, a version other
// than 1, an unknown `per` or `kind`, a missing or mistyped field, an unknown key (a misspelt
// field is an error, not a default), an unsafe or repeated name, a camera validate_camera
// rejects, an aspect that is not a positive number, and an empty list. The error names the
// view by index and name and the field: "views file: view 3 ('P-101A'): 'camera.eye' must be a
// list of 3 numbers". On failure `out` is unchanged.
std::string review_views_json(const std::vector<ReviewView>& views, std::string_view per);
bool parse_review_views(std::string_view json, std::vector<ReviewView>& out, std::string& error);
// Review views of a store's model (what `plantview views` writes):
//   per overview:  the whole plant (subject empty), as default_camera frames it;
//   per equipment: each object of class equipment; named by its Tag attribute, else its name
//                  as the plant names it (without the path's leading '/': "/-ART1105BA-" is
//                  "-ART1105BA-" in the view's name, title and caption alike);
//   per pipeline:  each pipeline object with every object that names it (pipes, components,
//                  supports): the whole line; named by its "Line number", else its name
//                  (without the leading '/');
//   per change:    what changed in options.changes (docs/changes.md): one view per changed
//                  object (group object), per changed equipment object (group equipment) or
//                  per pipeline holding a changed object (group pipeline), fitted on the
//                  union of the shapes before and after; each view a change image of the range
//                  (ReviewView::changes, to the store's revision), titled with the kind of
//                  change, class and tag, captioned with the revisions;
//   per area:      the objects of one RVM zone (the importer's "Zone" attribute), of one unit
//                  of a generated plant ("Unit 01", from the names' area field), else of one RVM
//                  site, else of one source file.
// Each subject's camera is fit_camera on its bounds (kReviewFill), from the isometric
// direction, or with sides = 4 from each side (4 views, names suffixed -N, -E, -S, -W by where
// the eye is). Where that eye would stand inside another object's bounds or a large object (a
// wall, a column, a vessel: 1 m across both ways and a third of the subject's size) lies between
// it and the subject, the other isometric quadrants (or, for a side, nearby directions) are
// tried, then the eye is moved in front of the obstacle with a field of view widened up to 90
// degrees to keep the fill; failing all, the first fit stays (highlighting shows the subject
// through what is in front).
// Names: the subject's name made safe (each run of other characters becomes one '-', none at
// either end; leading '.' dropped; the name's own '-' kept); repeats get -2, -3... in the order of the subjects' names and first ids, so the
// same store gives the same names. `select` (a shell glob, fnmatch) keeps the subjects whose
// view name or model name matches.
struct ReviewViewOptions {
  std::string per = "equipment";  // overview|equipment|pipeline|area|change
  // per change: the range (to 0: the store's revision; the views get it explicitly) and how
  // changes are grouped into views: object|pipeline|equipment.
  ChangeRange changes;
  std::string group = "object";
  std::string select;             // empty: every subject
  int sides = 1;                  // 1 or 4
  double aspect = 16.0 / 9.0;     // width / height of the images to come
  double fov_deg = 50.0;
  double fill = kReviewFill;      // (the overview uses kOverviewFill)
  // "subject": each view but the overview gets a section box around its subject's bounds grown
  // by section_margin_m on every side (walls, decks and whatever else lies outside it are cut
  // away); "none": no section.
  std::string section = "none";
  double section_margin_m = 1.0;  // >= 0
};
struct ReviewViewsSummary {
  uint64_t subjects = 0;    // of the kind, before `select`
  uint64_t moved = 0;       // views whose eye left the first fit to stand clear
  uint64_t obstructed = 0;  // views left at the first fit with no clear place found
};
// False with a message when the store cannot be read, holds no subject of the kind ("the store
// has no pipelines"), or `select` matches none. Preconditions (asserted): a known `per`, sides 1
// or 4, aspect > 0, fov_deg in (0, 179), fill in (0, 1]. `progress` (may be empty) gets the
// fraction done, on the calling thread.
bool make_review_views(const Store& store, const ReviewViewOptions& options,
                       std::vector<ReviewView>& out, ReviewViewsSummary& summary,
                       std::string& error,
                       const std::function<void(double fraction)>& progress = {});

// The lines of a view's caption strip under its title: each attribute with a value, as "Key
// value" with the key capitalised ("Tag P-101A", "Type PUMP"), in the view's order. (The strip
// itself is drawn by add_caption, plantview/image.h.)
std::vector<std::string> caption_lines(const ReviewView& view);

// True for the kinds a view (and `per`) may name: overview, equipment, pipeline, area, clash
// (clash views come from a clashes file: clash.h's clash_views, not make_review_views).
bool is_review_kind(std::string_view kind);
// True if `name` is safe as a file name: 1..200 of [A-Za-z0-9._-], not starting with '.'.
bool is_safe_view_name(std::string_view name);

}  // namespace plantview
