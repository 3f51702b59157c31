// The ground: a square about the plant's centre as wide as the fade (u_reach_m), on the plane
// at the plant's lowest level, so that its depth comes from rasterising (the depth test can
// reject it where the plant hides it before it is shaded) and is written where it shows (so
// that ambient occlusion darkens it under the plant). Its depth is drawn a little farther than
// the plane (twice the tie-break's most: tie_constants.glsl, which comes first), so that what
// lies on the plane is drawn over it. Six vertices, no vertex data. A section never clips it
// (gl/ground.cpp).
uniform mat4 u_view_projection;
uniform float u_ground_z;  // the plane's height relative to the eye
uniform vec2 u_centre;     // the plant's centre (x, y) relative to the eye
uniform float u_reach_m;   // half the square's side: where the fade ends
void main() {
  const vec2 kCorners[6] = vec2[](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
                                  vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0));
  vec3 p = vec3(u_centre + kCorners[gl_VertexID] * u_reach_m, u_ground_z);
  gl_Position = u_view_projection * vec4(p, 1.0);
  gl_Position.z *= 1.0 - 2.0 * float((1u << (32u - kTieShift)) - 1u) * kTieStep;
}
