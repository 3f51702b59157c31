// Pyramid (rectangular frustum, wedge, pyramid): flat-shaded faces, each with its own vertices and
// the face normal. One level, no error (the mesh is the shape).
//
// Corners c = 0..3 of each rectangle run counter-clockwise about +z from (-x, -y): signs
// (-,-), (+,-), (+,+), (-,+). Side s joins corners s and s+1 of both rectangles.
// Vertex layout: the faces with area, in the order bottom, top, side 0..3, each owning a
// consecutive block of its corners counter-clockwise seen from outside:
//   bottom b0 b3 b2 b1, top t0 t1 t2 t3, side s b_s b_{s+1} t_{s+1} t_s;
//   a side whose top edge collapsed keeps b_s b_{s+1} t_s, one whose bottom edge collapsed
//   keeps b_s t_{s+1} t_s.
// A face with area gives two triangles (one for a side with a collapsed edge), so a frustum has
// 24 vertices and 12 triangles, a wedge 18 and 8, a pyramid 16 and 6: level 0 uses every vertex.
// Which edges collapsed (a zero rectangle side) is the template key's flags.
#include "kinds.h"

namespace plantview::detail {

namespace {

// TemplateKey::flags: which rectangle sides are zero.
enum : uint8_t {
  kBottomXZero = 1,
  kBottomYZero = 2,
  kTopXZero = 4,
  kTopYZero = 8,
};

struct Sizes {
  float bottom_x, bottom_y, top_x, top_y, offset_x, offset_y, half_height;
};

Sizes sizes_of(const Pyramid& p) {
  return {sane(p.bottom_x_m),     sane(p.bottom_y_m),           sane(p.top_x_m),
          sane(p.top_y_m),        finite_or_zero(p.offset_x_m), finite_or_zero(p.offset_y_m),
          0.5f * sane(p.height_m)};
}

uint8_t flags_of(const Sizes& s) {
  return uint8_t((s.bottom_x == 0.0f ? kBottomXZero : 0) | (s.bottom_y == 0.0f ? kBottomYZero : 0) |
                 (s.top_x == 0.0f ? kTopXZero : 0) | (s.top_y == 0.0f ? kTopYZero : 0));
}

// Without height, or flat in x or in y (both rectangles without that side), there is no volume.
bool has_volume(const Sizes& s) {
  return s.half_height > 0.0f && (s.bottom_x > 0.0f || s.top_x > 0.0f) &&
         (s.bottom_y > 0.0f || s.top_y > 0.0f);
}

// A face with area: its corners in layout order, 0..3 bottom and 4..7 top.
struct Face {
  uint8_t corner[4];
  uint8_t count;  // 3 or 4
  int8_t side;    // 0..3, or -1 for the bottom and top
};

// The faces with area for the given flags, in layout order. Returns their number.
uint32_t faces_of(uint8_t flags, Face (&out)[6]) {
  uint32_t n = 0;
  if (!(flags & (kBottomXZero | kBottomYZero))) out[n++] = {{0, 3, 2, 1}, 4, -1};
  if (!(flags & (kTopXZero | kTopYZero))) out[n++] = {{4, 5, 6, 7}, 4, -1};
  for (uint8_t s = 0; s < 4; ++s) {
    // Sides 0 and 2 run along x, sides 1 and 3 along y.
    const bool bottom_gone = flags & (s % 2 == 0 ? kBottomXZero : kBottomYZero);
    const bool top_gone = flags & (s % 2 == 0 ? kTopXZero : kTopYZero);
    const uint8_t b0 = s, b1 = uint8_t((s + 1) % 4), t0 = uint8_t(4 + s), t1 = uint8_t(4 + b1);
    if (bottom_gone && top_gone) continue;
    if (top_gone) {
      out[n++] = {{b0, b1, t0, 0}, 3, int8_t(s)};
    } else if (bottom_gone) {
      out[n++] = {{b0, t1, t0, 0}, 3, int8_t(s)};
    } else {
      out[n++] = {{b0, b1, t1, t0}, 4, int8_t(s)};
    }
  }
  return n;
}

// Corners 0..3 of the bottom rectangle, then 0..3 of the top one.
void corners_of(const Sizes& s, glm::vec3 (&out)[8]) {
  static constexpr float kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  for (int c = 0; c < 4; ++c) {
    out[c] = {-0.5f * s.offset_x + kSigns[c][0] * 0.5f * s.bottom_x,
              -0.5f * s.offset_y + kSigns[c][1] * 0.5f * s.bottom_y, -s.half_height};
    out[4 + c] = {0.5f * s.offset_x + kSigns[c][0] * 0.5f * s.top_x,
                  0.5f * s.offset_y + kSigns[c][1] * 0.5f * s.top_y, s.half_height};
  }
}

}  // namespace

void plan(const Pyramid& p, MeshPlan& plan, TemplateKey& key) {
  const Sizes s = sizes_of(p);
  if (!has_volume(s)) return;
  const uint8_t flags = flags_of(s);
  Face faces[6];
  const uint32_t face_count = faces_of(flags, faces);
  uint32_t vertices = 0;
  for (uint32_t f = 0; f < face_count; ++f) vertices += faces[f].count;
  plan.topology = Topology::triangles;
  plan.closed = true;
  plan.level_count = 1;
  plan.vertex_count = vertices;
  plan.error_m[0] = 0.0f;
  key.kind = uint8_t(PrimitiveKind::pyramid);
  key.flags = flags;
}

void build_template_Pyramid(const TemplateKey& key, TemplateBuilder& out) {
  Face faces[6];
  const uint32_t face_count = faces_of(key.flags, faces);
  out.begin_level();
  uint32_t base = 0;
  for (uint32_t f = 0; f < face_count; ++f) {
    if (faces[f].count == 4) {
      out.quad(base, base + 1, base + 2, base + 3);
    } else {
      out.triangle(base, base + 1, base + 2);
    }
    base += faces[f].count;
  }
}

void write(const Pyramid& p, const MeshPlan&, const VertexSink& sink) {
  const Sizes s = sizes_of(p);
  glm::vec3 corner[8];
  corners_of(s, corner);
  Face faces[6];
  const uint32_t face_count = faces_of(flags_of(s), faces);
  uint32_t v = 0;
  for (uint32_t f = 0; f < face_count; ++f) {
    const Face& face = faces[f];
    glm::vec3 normal;
    if (face.side < 0) {
      normal = {0.0f, 0.0f, face.corner[0] < 4 ? -1.0f : 1.0f};
    } else {
      // The cross product of the full quad's diagonals: exact for a planar quad and still
      // right when one of its edges has collapsed to a point.
      const uint32_t b0 = uint32_t(face.side), b1 = (b0 + 1) % 4;
      normal = glm::cross(corner[4 + b1] - corner[b0], corner[4 + b0] - corner[b1]);
    }
    const uint32_t packed = sink.normal(normal);
    for (uint32_t c = 0; c < face.count; ++c) sink.put(v++, corner[face.corner[c]], packed);
  }
}

Aabb bounds(const Pyramid& p) {
  const Sizes s = sizes_of(p);
  const glm::vec2 bottom_centre = -0.5f * glm::vec2(s.offset_x, s.offset_y);
  const glm::vec2 top_centre = 0.5f * glm::vec2(s.offset_x, s.offset_y);
  const glm::vec2 bottom_half = 0.5f * glm::vec2(s.bottom_x, s.bottom_y);
  const glm::vec2 top_half = 0.5f * glm::vec2(s.top_x, s.top_y);
  const glm::vec2 lo = glm::min(bottom_centre - bottom_half, top_centre - top_half);
  const glm::vec2 hi = glm::max(bottom_centre + bottom_half, top_centre + top_half);
  return {{lo, -s.half_height}, {hi, s.half_height}};
}

}  // namespace plantview::detail
