// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Box&, MeshPlan&, TemplateKey&) {}
void build_template_Box(const TemplateKey&, TemplateBuilder&) {}
void write(const Box&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Box&) { return {}; }

}  // namespace plantview::detail
