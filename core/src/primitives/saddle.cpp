// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Saddle&, MeshPlan&, TemplateKey&) {}
void build_template_Saddle(const TemplateKey&, TemplateBuilder&) {}
void write(const Saddle&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Saddle&) { return {}; }

}  // namespace plantview::detail
