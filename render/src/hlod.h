// Pipeline HLOD (Su et al. section 5.3): runs of a branch's members that lie on one straight
// line (pipes, and inline components such as flanges, gaskets and valves whose connection
// points lie on the centreline) can be drawn as one cylinder when the view allows it.
//
// Rules
//   - A run is a maximal sequence of consecutive members of a branch, in flow order, each of
//     which has at most two connection points, all of its centreline and connection points on
//     the run's line (within 1 mm or 1% of the diameter), and the run's diameter at its
//     connections (within 2%): a tee (three connections), an elbow (a bent centreline) or a
//     reducer (another diameter) ends a run and is never merged.
//   - Only runs of two members or more are kept: one member alone gains nothing.
//   - merge_error_m is how far the merged cylinder departs from the members: the largest
//     radial extent of any member's primitives beyond the pipe's radius (a flange's collar,
//     a valve's body). The renderer merges a run when that error projects under its pixel
//     error, and draws its centreline when the diameter projects under a pixel (and under
//     the pixel error where that is finer: drawn_as_centreline).
//   - Splitting: runs are straight and local, so a long pipeline is many runs; the near part of
//     a pipeline keeps its detail while its far runs merge.
// Threads: pure functions.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "plantview/model.h"

namespace plantview::detail {

struct PipelineRun {
  glm::dvec3 start_m{0.0}, end_m{0.0};  // model space, along the flow
  float diameter_m = 0;
  float merge_error_m = 0;
  DAabb bounds;                          // of the members
  Colour colour;                         // of the first pipe
  std::vector<uint32_t> members;         // slots, in flow order
  uint64_t pipeline_id = 0;              // the pipeline it belongs to: the merged draw's id
};

// Whether a member ends every run it meets (so never lies in one): it is not straight, or its
// points do not lie on the line through its two farthest-apart ones (an elbow). The runs of a
// branch are therefore found stretch by stretch between such members, each stretch alone.
bool ends_runs(const Object& member);

// One branch's members in flow order with their slots. Appends the branch's runs to `out`.
void find_runs(const std::vector<std::pair<uint32_t, const Object*>>& branch,
               std::vector<PipelineRun>& out);

// The merged cylinder of a run, placed relative to `origin_m` (model space).
Primitive merged_cylinder(const PipelineRun& run, const glm::dvec3& origin_m);

}  // namespace plantview::detail
