// plan_view (plantview/render.h): a frame's cull and level choice without GL.
#include <string>

#include "decoded_objects.h"
#include "frame_plan.h"
#include "hlod.h"
#include "plantview/render.h"
#include "plantview/store.h"

namespace plantview {

bool plan_view(const ReadView& view, const Camera& camera, uint32_t width, uint32_t height,
               const RenderOptions& options, ViewPlan& out, std::string& error) {
  using namespace detail;
  out = {};
  DecodedObjects objects;
  objects.reset(view);
  FramePlan plan;
  FrameStats stats;
  const FrameView frame_view = make_frame_view(camera, width, height, view.spatial_origin());
  if (!plan.cull(view, frame_view, options, stats, error)) return false;
  if (!objects.decode(plan.visible(), options.hlod, error)) return false;
  plan.choose(objects, frame_view, options, 1, stats);
  for (const Draw& d : plan.draws()) {
    const uint8_t level_count = d.known->level_count;
    if ((d.key & kRunKeyBit) == 0) {
      out.objects.push_back({d.key, d.level, level_count, d.centreline});
      continue;
    }
    const PipelineRun& run = objects.run(d.key & ~kRunKeyBit);
    if (run.members.empty() || d.known->primitives.empty()) continue;
    out.runs.push_back({run.members.front(), d.known->id, d.level, level_count, d.centreline,
                        d.known->primitives.front(), d.known->origin_m, d.known->colour,
                        run.bounds});
  }
  return true;
}

}  // namespace plantview
