// Line (RVM line): a segment on the local x axis, drawn as Topology::lines. One level, no error.
//
// Vertex layout (2 vertices): 0 at start_x, 1 at end_x; one line {0, 1}. Lines are not lit, but
// every vertex carries a unit normal: local +z, perpendicular to the segment.
// Non-finite ends read as zero; a segment of zero length is empty.
#include <algorithm>

#include "kinds.h"

namespace plantview::detail {

void plan(const Line& l, MeshPlan& plan, TemplateKey& key) {
  if (finite_or_zero(l.start_x_m) == finite_or_zero(l.end_x_m)) return;
  plan.topology = Topology::lines;
  plan.closed = false;
  plan.level_count = 1;
  plan.vertex_count = 2;
  plan.error_m[0] = 0.0f;
  key.kind = uint8_t(PrimitiveKind::line);
}

void build_template_Line(const TemplateKey&, TemplateBuilder& out) {
  out.begin_level();
  out.line(0, 1);
}

void write(const Line& l, const MeshPlan&, const VertexSink& sink) {
  const uint32_t normal = sink.normal({0, 0, 1});
  sink.put(0, {finite_or_zero(l.start_x_m), 0, 0}, normal);
  sink.put(1, {finite_or_zero(l.end_x_m), 0, 0}, normal);
}

Aabb bounds(const Line& l) {
  const float a = finite_or_zero(l.start_x_m), b = finite_or_zero(l.end_x_m);
  return {{std::min(a, b), 0, 0}, {std::max(a, b), 0, 0}};
}

}  // namespace plantview::detail
