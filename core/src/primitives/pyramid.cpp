// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Pyramid&, MeshPlan&, TemplateKey&) {}
void build_template_Pyramid(const TemplateKey&, TemplateBuilder&) {}
void write(const Pyramid&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Pyramid&) { return {}; }

}  // namespace plantview::detail
