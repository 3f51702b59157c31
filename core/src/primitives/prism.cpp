// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Prism&, MeshPlan&, TemplateKey&) {}
void build_template_Prism(const TemplateKey&, TemplateBuilder&) {}
void write(const Prism&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Prism&) { return {}; }

}  // namespace plantview::detail
