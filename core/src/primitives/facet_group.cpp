// PLACEHOLDER: to be implemented (see kinds.h for the contract).
#include "kinds.h"

namespace plantview::detail {

void plan(const FacetGroup&, MeshPlan&, TemplateKey&) {}

void write(const FacetGroup&, const MeshPlan&, const VertexSink&) {}
Aabb bounds(const FacetGroup&) { return {}; }

}  // namespace plantview::detail

namespace plantview {
uint32_t FacetGroup::triangulate() { triangles.clear(); return 0; }
}  // namespace plantview
