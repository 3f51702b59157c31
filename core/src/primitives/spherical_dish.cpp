// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const SphericalDish&, MeshPlan&, TemplateKey&) {}
void build_template_SphericalDish(const TemplateKey&, TemplateBuilder&) {}
void write(const SphericalDish&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const SphericalDish&) { return {}; }

}  // namespace plantview::detail
