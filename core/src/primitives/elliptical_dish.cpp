// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const EllipticalDish&, MeshPlan&, TemplateKey&) {}
void build_template_EllipticalDish(const TemplateKey&, TemplateBuilder&) {}
void write(const EllipticalDish&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const EllipticalDish&) { return {}; }

}  // namespace plantview::detail
