// Change images (render.h: RenderOptions::changes): what a frame needs of a range of revisions,
// read once per range and snapshot. The changed objects that the snapshot holds (added,
// modified) are drawn by the frame like any object, as the subject of a highlight in their
// change's colour; the shapes that it does not hold (removed objects, and modified objects'
// previous shapes) are ghosts, kept here apart from the slot-keyed caches (decoded objects,
// residency), tessellated once into a small mesh of their own that the GL backend draws
// see-through after the frame's objects (gl/backend.h: draw_ghosts).
//
// Rules
//   - A modified object whose previous shape is its current one (a recolour, an attribute
//     edit) gets no ghost: the ghost would only veil it.
//   - Ghosts are tessellated at the finest level whose error is under kGhostErrorM, with their
//     vertices on the surface; line primitives are left out (a ghost is a surface).
//   - The ghosts' mesh holds at most kMaxGhostVertices (64 MB): a revision that moves a whole
//     plant draws the ghosts that fit, in id order, and leaves the rest out (ghosts_left_out();
//     the changed objects themselves are all drawn).
//   - Counts (FrameStats::changes, the legend) are the range's, over the whole store.
// Units: metres; vertices relative to each ghost's origin (double precision until the frame
//   subtracts the eye).
// Threads: the renderer's thread. Memory: the ghosts' mesh, a few thousand vertices for the few
//   objects a revision changes (a plant-wide change costs what its shapes tessellate to).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "gl/backend.h"
#include "plantview/render.h"

namespace plantview {
class ReadView;
}

namespace plantview::detail {

inline constexpr double kGhostErrorM = 0.005;
inline constexpr size_t kMaxGhostVertices = size_t(1) << 22;

// The ghosts' mesh: triangles over vertices that carry a ghost's index (GhostMesh::ghosts).
struct GhostMesh {
  struct Ghost {
    uint64_t id = 0;
    glm::dvec3 origin_m{0.0};
    Colour colour;
  };
  std::vector<Ghost> ghosts;
  std::vector<PackedVertex> vertices;  // relative to their ghost's origin
  std::vector<uint32_t> vertex_ghosts;  // per vertex: its index in ghosts
  std::vector<uint32_t> indices;        // triangles, counter-clockwise outward where closed
  bool empty() const { return indices.empty(); }
};

class ChangeSet {
 public:
  // Reads the range's changes and previous shapes through `view` unless already read for this
  // range since the last reset() (which the renderer calls with each new snapshot). False with
  // a message, and nothing loaded: one starting "changes R1[..R2]: " when the range does not
  // end at the snapshot's revision, starts at or after it, or the store cannot give its changes
  // (a revision pruned or never made: the store's message after the prefix); the store's
  // message alone when a previous record cannot be read.
  bool load(const ReadView& view, const ChangeRange& range, std::string& error);
  // The highlight's subject: the ids of the added and modified objects, sorted; {0} (an id no
  // object has) when there are none, so that the rest is ghosted all the same.
  const std::vector<uint64_t>& subject_ids() const { return subject_ids_; }
  // Their colours (RGBA8 as TableEntry::colour), sorted by id.
  const std::vector<std::pair<uint64_t, uint32_t>>& subject_colours() const {
    return subject_colours_;
  }
  const GhostMesh& ghosts() const { return ghosts_; }
  uint64_t ghosts_left_out() const { return ghosts_left_out_; }
  const FrameStats::Changes& summary() const { return summary_; }
  const FrameLegend& legend() const { return legend_; }
  void reset() { loaded_ = false; }

 private:
  bool loaded_ = false;
  ChangeRange range_;
  std::vector<uint64_t> subject_ids_;
  std::vector<std::pair<uint64_t, uint32_t>> subject_colours_;
  GhostMesh ghosts_;
  uint64_t ghosts_left_out_ = 0;
  FrameStats::Changes summary_;
  FrameLegend legend_;
  std::vector<PackedVertex> scratch_;
  // False (nothing added) when its vertices would not fit under kMaxGhostVertices.
  bool add_ghost(const Object& previous, Colour colour);
};

// RGBA8 as TableEntry::colour holds it.
inline uint32_t packed_colour(Colour c) {
  return uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | uint32_t(c.a) << 24;
}

}  // namespace plantview::detail
