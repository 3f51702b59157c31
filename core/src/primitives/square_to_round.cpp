// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const SquareToRound&, MeshPlan&, TemplateKey&) {}
void build_template_SquareToRound(const TemplateKey&, TemplateBuilder&) {}
void write(const SquareToRound&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const SquareToRound&) { return {}; }

}  // namespace plantview::detail
