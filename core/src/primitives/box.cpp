// Box: six flat-shaded faces, each with its own four vertices and the face normal, so that the
// edges stay sharp. One level, no error (the mesh is the shape).
//
// Vertex layout (24 vertices): face f = 0..5 is -x, +x, -y, +y, -z, +z and owns [4f, 4f + 4),
// its corners counter-clockwise seen from outside. Two triangles per face.
#include "kinds.h"

namespace plantview::detail {

namespace {

// Corner signs of a face in its own (i, j) axes, where (i, j, k) is a cyclic permutation of
// (x, y, z) and k the face's normal axis: counter-clockwise about +k.
constexpr float kCornerSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};

}  // namespace

void plan(const Box& b, MeshPlan& plan, TemplateKey& key) {
  if (sane(b.size_x_m) == 0.0f || sane(b.size_y_m) == 0.0f || sane(b.size_z_m) == 0.0f) return;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = 1;
  plan.vertex_count = 24;
  plan.error_m[0] = 0.0f;
  key.kind = uint8_t(PrimitiveKind::box);
}

void build_template_Box(const TemplateKey&, TemplateBuilder& out) {
  out.begin_level();
  for (uint32_t f = 0; f < 6; ++f) out.quad(4 * f, 4 * f + 1, 4 * f + 2, 4 * f + 3);
}

void write(const Box& b, const MeshPlan&, const VertexSink& sink) {
  const glm::vec3 half = 0.5f * glm::vec3(sane(b.size_x_m), sane(b.size_y_m), sane(b.size_z_m));
  for (uint32_t f = 0; f < 6; ++f) {
    const int k = int(f / 2), i = (k + 1) % 3, j = (k + 2) % 3;
    const float side = (f % 2) ? 1.0f : -1.0f;
    glm::vec3 normal(0.0f);
    normal[k] = side;
    const uint32_t packed = sink.normal(normal);
    for (uint32_t c = 0; c < 4; ++c) {
      // A negative face runs its corners the other way round to stay counter-clockwise.
      const float* s = kCornerSigns[side > 0 ? c : (4 - c) % 4];
      glm::vec3 p;
      p[k] = side * half[k];
      p[i] = s[0] * half[i];
      p[j] = s[1] * half[j];
      sink.put(4 * f + c, p, packed);
    }
  }
}

Aabb bounds(const Box& b) {
  const glm::vec3 half = 0.5f * glm::vec3(sane(b.size_x_m), sane(b.size_y_m), sane(b.size_z_m));
  return {-half, half};
}

}  // namespace plantview::detail
