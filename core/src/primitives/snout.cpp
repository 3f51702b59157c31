// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const Snout&, MeshPlan&, TemplateKey&) {}
void build_template_Snout(const TemplateKey&, TemplateBuilder&) {}
void write(const Snout&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const Snout&) { return {}; }

}  // namespace plantview::detail
