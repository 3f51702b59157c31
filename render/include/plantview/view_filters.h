// plantview/view_filters.h: what a view shows of the model besides its camera — sections (clip
// planes and a section box) and object styling (colour by an attribute, hide, show only). Every
// place a view is described carries them: RenderOptions (render.h), review views and their
// views file (review.h), the service's frame, stats and pick parameters, the farm, glTF export
// and BCF viewpoints.
//
// Conventions
//   - A clip plane removes the half-space its normal points into, as a BCF ClippingPlane's
//     Direction does ("points in the invisible direction"): `--clip 0,0,12,0,0,1` cuts away all
//     above 12 m, a plan cut seen from above. A point on the plane itself is kept.
//   - A section box keeps what lies inside it (its faces included) and removes the rest.
//   - Planes and box apply together: what survives is inside the box and behind every plane.
//   - Cut solids are capped (the cut face filled in the object's colour, darker) unless
//     Section::capped is false.
//   - Styling: `hide` and `only` hold words, each a class name (equipment, pipeline, pipe,
//     component, structure, other) or a shell glob (fnmatch) matched against an object's name
//     and its Tag attribute. `only` empty shows every object; else those matching one of its
//     words. `hide` then removes those matching one of its words. `colour_by` names an attribute
//     key ("" keeps the model's colours).
// Units: metres, model space. Threads: plain values and pure functions.
// Errors: the parsers return false and fill `error` naming the option and what is wrong.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "plantview/model.h"

namespace plantview {

inline constexpr size_t kMaxClipPlanes = 6;

struct ClipPlane {
  glm::dvec3 point_m{0.0};       // a point on the plane
  glm::dvec3 normal{0, 0, 1};    // unit length; points into the half-space removed
  bool operator==(const ClipPlane&) const = default;
};

struct Section {
  std::vector<ClipPlane> planes;  // at most kMaxClipPlanes
  bool has_box = false;
  DAabb box;                      // kept inside, when has_box
  bool capped = true;             // cut faces of closed solids filled
  bool empty() const { return planes.empty() && !has_box; }
  bool operator==(const Section& o) const {
    return planes == o.planes && has_box == o.has_box && capped == o.capped &&
           (!has_box || (box.min == o.box.min && box.max == o.box.max));
  }
};

// True if `point` is removed by the section.
bool section_removes(const Section& section, const glm::dvec3& point_m);
// True if every point of `bounds` is removed (an object or tree node wholly on the clipped
// side: neither decoded, tessellated nor drawn). Conservative: false when unsure.
bool section_removes_all(const Section& section, const DAabb& bounds);
// True if no point of `bounds` is removed (nothing to cut, no cap needed).
bool section_keeps_all(const Section& section, const DAabb& bounds);

// "PX,PY,PZ,NX,NY,NZ": a point and a normal (normalised here). Errors: not six finite numbers,
// a zero normal. `what` names the option in the message ("--clip", "clip").
bool parse_clip_plane(std::string_view text, std::string_view what, ClipPlane& out,
                      std::string& error);
// "MINX,MINY,MINZ,MAXX,MAXY,MAXZ". Errors: not six finite numbers, min > max on an axis.
bool parse_section_box(std::string_view text, std::string_view what, DAabb& out,
                       std::string& error);
// The planes and box of the command line's `--clip` options (each "PX,PY,PZ,NX,NY,NZ") and
// `--section-box` ("" for none) into `out`'s planes and box (`capped` is left as it is). Errors:
// as the two parsers above (naming --clip or --section-box), and more than kMaxClipPlanes planes.
bool parse_section_options(const std::vector<std::string>& clips, std::string_view box, Section& out,
                           std::string& error);
// At most kMaxClipPlanes planes, unit finite normals, finite points, a box with min <= max.
bool validate_section(const Section& section, std::string& error);

struct ObjectStyle {
  std::string colour_by;          // attribute key; "" the model's colours
  std::vector<std::string> hide;  // class names or globs (see the conventions above)
  std::vector<std::string> only;  // empty: every object
  bool empty() const { return colour_by.empty() && hide.empty() && only.empty(); }
  bool operator==(const ObjectStyle&) const = default;
};

// A subject drawn in a colour of its own (RenderOptions::subject_colours): a clash view's two
// objects, the first red and the second cyan (clash.h). `label` is its legend entry's text
// ("first: P-1001-01"). `see_through`: drawn see-through in its colour, at
// kSeeThroughSubjectAlpha where it faces the eye, rising towards opaque along its outline
// (kSeeThroughSubjectRim: the share of the way there seen edge on), so that what it holds
// inside shows through it (a clash's part buried in a column); the colour's own alpha is not
// used.
inline constexpr double kSeeThroughSubjectAlpha = 0.35;
inline constexpr double kSeeThroughSubjectRim = 0.8;
struct SubjectColour {
  uint64_t id = 0;  // store id
  Colour colour;
  std::string label;
  bool see_through = false;
  bool operator==(const SubjectColour&) const = default;
};

// "a,b,c" into words (empty words dropped). Errors: an empty list. `what` names the option.
bool parse_word_list(std::string_view text, std::string_view what, std::vector<std::string>& out,
                     std::string& error);

// A change image's range of revisions (render.h: RenderOptions::changes; store.h: Revision,
// ReadView::changes): what changed in the store after `from`, drawn over the snapshot.
struct ChangeRange {
  uint32_t from = 0;  // the earlier revision (0: the empty store)
  uint32_t to = 0;    // the later one: 0 for the snapshot's; else it must be the snapshot's
                      // (the renderer draws the store as the snapshot holds it)
  bool operator==(const ChangeRange&) const = default;
};
// "R1" or "R1..R2": whole numbers, R1 < R2. False with a message quoting the text (a caller
// prefixes the option's or parameter's name).
bool parse_change_range(std::string_view text, ChangeRange& out, std::string& error);
// "R1" or "R1..R2", as parse_change_range reads it.
std::string change_range_text(const ChangeRange& range);

}  // namespace plantview
