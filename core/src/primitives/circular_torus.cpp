// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const CircularTorus&, MeshPlan&, TemplateKey&) {}
void build_template_CircularTorus(const TemplateKey&, TemplateBuilder&) {}
void write(const CircularTorus&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const CircularTorus&) { return {}; }

}  // namespace plantview::detail
