// Proxy boxes (far-field proxies, node boxes), lit like surfaces (surface.frag.glsl): each box
// an object-table entry (its camera-relative lower corner and colour, its size and pick word)
// named by the proxy table (binding 3), drawn as the faces the eye sees (box_face.glsl), 18
// vertices a box, no vertex data, in one draw, clipped by the section. Follows
// object_table.glsl and section_clip.glsl in the same shader.
layout(std430, binding = 3) readonly buffer Proxies { uint proxies[]; };
uniform mat4 u_view_projection;
out vec3 v_normal;
flat out vec4 v_colour;
flat out uint v_pick;
vec3 box_face_corner(vec3 lo, vec3 hi, int corner, out vec3 normal);
void main() {
  Entry e = object_entry(proxies[gl_VertexID / 18]);
  v_pick = e.pick;
  if (!e.drawn) {
    gl_Position = vec4(0.0, 0.0, -1.0, 1.0);  // outside: clipped
    return;
  }
  vec3 p = box_face_corner(e.offset, e.offset + e.scale, gl_VertexID % 18, v_normal);
  v_colour = e.colour;
  clip_section(p);
  gl_Position = u_view_projection * vec4(p, 1.0);
  gl_Position.z *= e.tie;
}
