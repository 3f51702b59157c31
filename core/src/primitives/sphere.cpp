// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Sphere&, MeshPlan&, TemplateKey&) {}
void build_template_Sphere(const TemplateKey&, TemplateBuilder&) {}
void write(const Sphere&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Sphere&) { return {}; }

}  // namespace plantview::detail
