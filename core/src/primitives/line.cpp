// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Line&, MeshPlan&, TemplateKey&) {}
void build_template_Line(const TemplateKey&, TemplateBuilder&) {}
void write(const Line&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Line&) { return {}; }

}  // namespace plantview::detail
