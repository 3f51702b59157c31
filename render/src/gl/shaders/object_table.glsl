// The object table as the vertex shaders of objects, proxy boxes and centrelines read it
// (gl/backend.h: TableEntry, two vec4 an entry, std430 at binding 0): an entry's
// camera-relative offset (metres) and colour (RGBA8), its scale, its pick value, the factor its
// tie-break applies to clip-space z, and whether the highlight mode draws it. Highlight modes
// (u_mode): 0 draws every object, 1 only the subject (objects with a pick value), 2 only the
// context (pick 0), 3 only the opaque subject (alpha 1), 4 only the see-through subject (a
// subject with alpha under 1: gl/backend.h, Look::subject_colours); a vertex shader moves the
// rejected ones outside the clip volume. Compiled
// after tie_constants.glsl and ahead of each of those shaders' source, in the same shader.
layout(std430, binding = 0) readonly buffer Objects { vec4 objects[]; };
uniform int u_mode;
struct Entry { vec3 offset; vec3 scale; vec4 colour; uint pick; float tie; bool drawn; };
Entry object_entry(uint object) {
  vec4 a = objects[2u * object];
  vec4 b = objects[2u * object + 1u];
  uint word = floatBitsToUint(b.w);
  Entry e;
  e.offset = a.xyz;
  e.scale = b.xyz;
  e.colour = unpackUnorm4x8(floatBitsToUint(a.w));
  e.pick = word & kPickMask;
  e.tie = 1.0 - float(word >> kTieShift) * kTieStep;
  e.drawn = !((u_mode == 1 && e.pick == 0u) || (u_mode == 2 && e.pick != 0u) ||
              (u_mode == 3 && (e.pick == 0u || e.colour.a < 1.0)) ||
              (u_mode == 4 && (e.pick == 0u || e.colour.a == 1.0)));
  return e;
}
