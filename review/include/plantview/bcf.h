// plantview/bcf.h: review views as BCF 2.1 (BIM Collaboration Format, buildingSMART BCF-XML
// release_2_1) and back. A BCF file is a zip of topic folders; plantview writes one topic per
// review view, each with markup.bcf (the topic), viewpoint.bcfv (camera, clipping planes,
// components) and snapshot.png (the view's rendered image), and reads the viewpoints of any
// tool's BCF back into review views that `render --views` renders.
//
// Mapping (export; import reads the same back):
//   - Topic and viewpoint GUIDs: UUID-formatted hashes of `seed` (the store's identity) and the
//     view's name, so the same views of the same store get the same GUIDs.
//   - Topic: Title = view title; Description = its caption lines (review.h: caption_lines), one a
//     line; CreationDate = the export's date (ISO 8601, UTC, "Z"); CreationAuthor = author;
//     TopicType "Review"; one Viewpoints entry naming viewpoint.bcfv and snapshot.png.
//   - PerspectiveCamera: CameraViewPoint = eye, CameraDirection = unit(target - eye),
//     CameraUpVector = up, FieldOfView = fov_deg, the VERTICAL field of view in degrees (BCF
//     2.1's text calls it horizontal, its schema leaves it open and BCF 3.0 settles on vertical,
//     as most tools read it). The 2.1 schema limits FieldOfView to 45..60; a view whose fov_deg
//     lies outside (placement widens up to 90) is written as it is, and the report says so.
//     BCF has no target: import puts it on the view line at the distance the view's plantview
//     document gives, else at the selection's centre, else 10 m ahead.
//   - ClippingPlanes: a section box as six planes first (-x, +x, -y, +y, -z, +z faces; each
//     Direction points out of the box, into the removed side), then the section's planes
//     (Location = point, Direction = normal: both conventions point into the removed side).
//     Import reads six planes in that order back as the box; other planes beyond
//     kMaxClipPlanes are dropped and reported.
//   - Components, each with OriginatingSystem "plantview" and AuthoringToolId = the object's
//     Tag attribute if it has one, else its decimal store id:
//       Selection = the subject;
//       Visibility: DefaultVisibility true, Exceptions = the objects style.hide removes; with
//         style.only, DefaultVisibility false and the shown objects as Exceptions when they are
//         at most max_listed (BCF's guidance: about 1000), else DefaultVisibility true and no
//         exceptions (the report says so);
//       Coloring: with style.colour_by, one Color (RGB hex, "RRGGBB") per attribute value over
//         the objects the style shows, for at most max_listed objects in all (else none,
//         reported). Each value's colour is the one its snapshot shows it in (the rendered
//         frame's legend, BcfWriteOptions::legends); a value the legend does not list (no object
//         of it in view, or beyond its palette) or a view without a legend takes a colour of a
//         fixed palette by hash of the value. A view's subject colours (ReviewView::colours:
//         a clash's two objects) add one Color each, RGB, or ARGB ("AARRGGBB", alpha
//         kSeeThroughSubjectAlpha) for a see-through one.
//     Visibility and Coloring need the store (they list objects); without one they are left
//     at DefaultVisibility true and no Coloring, and the report says so.
//   - What BCF cannot state (the camera's target distance, kind, name, attributes, capped, the
//     style's words) goes with each topic in plantview-view.json: the view in the views-file
//     format (review.h), referenced from the markup as a DocumentReference (which the schema
//     allows). Import takes camera eye, direction, up and field of view, the clipping planes
//     and the selection from the viewpoint (another tool may have changed them) and the rest
//     from that document where it is present.
//
// Import of any tool's BCF: each topic's viewpoints (markup.bcf's Viewpoints, else its folder's
// viewpoint.bcfv) become views named by the topic title made safe (review.h's rules; a second
// viewpoint or a repeated title gets -2, -3...). Components are matched to store objects by
// AuthoringToolId (a decimal store id, else a Tag attribute or object name); components with
// only an IfcGuid never match plantview objects and are counted as unknown. The kind is the
// document's, else "equipment" for one selected object, "area" for several, "overview" for
// none. Hidden exceptions become style.hide words (their tags or names); visible exceptions
// under DefaultVisibility false become style.only words. An OrthogonalCamera becomes a
// perspective camera (fov 50 degrees, eye pulled back so that ViewToWorldScale metres fit the
// height) and is counted as converted.
//
// Bad input (the call fails, nothing is returned): a file that is not a zip or is truncated
// (libzip's consistency check and CRCs), an entry with an absolute path, a drive letter or a
// '..' part, an entry over max_entry_bytes uncompressed (or all over max_total_bytes),
// markup or viewpoint XML that does not parse, and a viewpoint with neither camera. Each error
// names the file, the entry and, for XML, the topic.
//
// Units: metres, degrees. Threads: plain functions, callable from any thread (the store's
// ReadView is used on the calling thread). Errors: false with the message in `error`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "plantview/render.h"
#include "plantview/review.h"

namespace plantview {

class ReadView;

struct BcfWriteOptions {
  std::string seed;                  // GUIDs' seed: the store's identity (farm: store_identity)
  std::string author = "plantview";  // CreationAuthor
  std::string date;                  // CreationDate, ISO 8601 with zone; "" now (UTC)
  size_t max_listed = 1000;          // most objects listed in Visibility, or in Coloring
  // The legends of the rendered views' frames (FrameStats::legend), parallel to the views, or
  // empty: Coloring then gives each value the colour its snapshot shows it in. A view whose
  // legend is missing (key empty or another key) falls back to the fixed palette.
  std::vector<FrameLegend> legends;
};

// What was written, and what could not be said exactly (one line each, for stderr).
struct BcfWriteReport {
  size_t topics = 0;
  size_t snapshots_converted = 0;  // JPEG images re-encoded as PNG
  std::vector<std::string> notes;
};

// Writes `views` as a BCF 2.1 file at `path`: to "PATH.tmp-XXXXXX" in the same directory, then
// renamed over `path`; on failure the temporary file is removed and `path` is untouched.
// `snapshots` is parallel to `views`: each view's rendered image (PNG as it is; JPEG read and
// re-encoded as PNG through the image module); an empty path writes no snapshot. `store` may be
// null (see Visibility and Coloring above). Errors: an unreadable image, an image of another
// format, a store read failure, a failed write or rename; each names the file or view.
// Preconditions (asserted): snapshots.size() == views.size(), views valid as parse_review_views
// returns them.
bool write_bcf(const std::filesystem::path& path, const std::vector<ReviewView>& views,
               const std::vector<std::filesystem::path>& snapshots, const ReadView* store,
               const BcfWriteOptions& options, BcfWriteReport& report, std::string& error);

struct BcfReadOptions {
  double aspect = 16.0 / 9.0;                       // the views' aspect (BCF 2.1 has none)
  uint64_t max_entry_bytes = 64ull << 20;           // one entry, uncompressed
  uint64_t max_total_bytes = 2ull << 30;            // all entries read, uncompressed
};

// What an import found (written on stderr, and with --json as JSON).
struct BcfReadReport {
  size_t topics = 0;                  // markup.bcf files read
  size_t topics_without_viewpoint = 0;
  size_t viewpoints = 0;              // viewpoints read
  size_t imported = 0;                // views made
  size_t orthogonal_converted = 0;
  size_t components_matched = 0;      // component references resolved to store objects
  size_t components_unknown = 0;      // not resolved (IfcGuid only, unknown tag or id)
  size_t components_ifc_only = 0;     // of the unknown: those with an IfcGuid and no AuthoringToolId
  std::vector<std::string> unknown_examples;  // the first few, "topic 'T': IfcGuid 3Xy..."
  std::vector<std::string> notes;     // other losses (planes dropped, colours not imported...)
  std::string to_json() const;        // {"topics": .., ..., "unknown_examples": [..], "notes": [..]}
  std::string to_text() const;        // a few lines for people
};

// Reads the BCF file at `path` (BCF 2.0 or 2.1; bcf.version is not required) into `out`,
// matching components against `store` (null: decimal AuthoringToolIds are taken as ids
// unchecked; tags cannot be matched and count as unknown). The views satisfy
// parse_review_views' rules. On failure `out` is unchanged.
bool read_bcf(const std::filesystem::path& path, const ReadView* store, const BcfReadOptions& options,
              std::vector<ReviewView>& out, BcfReadReport& report, std::string& error);

// A UUID-formatted (8-4-4-4-12 lowercase hex, version 5 layout) stable hash of `text`.
std::string bcf_guid(std::string_view text);

}  // namespace plantview
