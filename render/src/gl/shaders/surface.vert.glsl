// Surfaces: every triangle of the objects from the vertex arena (position in object-local
// metres, normal, object-table index), placed camera-relative by the object's table entry.
// Depth is reversed and infinite (depth = near / distance along the view axis), the object's
// tie-break applied to clip z, clipped by the section (section_clip.glsl). Follows
// object_table.glsl and section_clip.glsl in the same shader.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_normal;
layout(location = 2) in uint a_object;
uniform mat4 u_view_projection;
// Per-object values are flat, and the view direction is rebuilt per fragment from its window
// position: fewer interpolated values make each triangle cheaper to set up and to bin.
out vec3 v_normal;
flat out vec4 v_colour;
flat out uint v_pick;
void main() {
  Entry e = object_entry(a_object);
  v_pick = e.pick;
  if (!e.drawn) {
    gl_Position = vec4(0.0, 0.0, -1.0, 1.0);  // outside: clipped
    return;
  }
  vec3 p = a_position * e.scale + e.offset;
  v_normal = a_normal.xyz;
  v_colour = e.colour;
  clip_section(p);
  gl_Position = u_view_projection * vec4(p, 1.0);
  gl_Position.z *= e.tie;
}
