// Occlusion's box test (GlBackend::test_boxes): boxes from eye-relative (min, max) pairs at
// binding 1 (metres; the eye is outside every box), each drawn as the faces the eye sees
// (box_face.glsl), 18 vertices a box, in one draw.
layout(std430, binding = 1) readonly buffer Boxes { vec4 boxes[]; };
uniform mat4 u_view_projection;
flat out uint v_box;
vec3 box_face_corner(vec3 lo, vec3 hi, int corner, out vec3 normal);
void main() {
  int box = gl_VertexID / 18;
  vec3 normal;
  vec3 p = box_face_corner(boxes[2 * box].xyz, boxes[2 * box + 1].xyz, gl_VertexID % 18, normal);
  v_box = uint(box);
  gl_Position = u_view_projection * vec4(p, 1.0);
}
