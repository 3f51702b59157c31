// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const RectangularTorus&, MeshPlan&, TemplateKey&) {}
void build_template_RectangularTorus(const TemplateKey&, TemplateBuilder&) {}
void write(const RectangularTorus&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const RectangularTorus&) { return {}; }

}  // namespace plantview::detail
