// Centrelines: the pixels of the quad inside the pipe's width (feathered by a pixel), alpha
// its coverage (discarded under 0.02: blended, writing depth like the pipe), lit like the side
// of the pipe that faces the eye (lighting.glsl, linked as a fragment shader of its own).
in vec3 v_position;
noperspective in float v_across;
flat in float v_half_px;
flat in float v_coverage;
flat in vec4 v_colour;
flat in uint v_pick;
flat in vec3 v_axis;
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uint o_pick;
uniform float u_alpha;
vec3 lit_colour(vec3 base, vec3 n, vec3 to_eye);
void main() {
  float inside = clamp(v_half_px + 0.5 - abs(v_across), 0.0, 1.0);
  float alpha = inside * v_coverage * v_colour.a * u_alpha;
  if (alpha < 0.02) discard;
  vec3 to_eye = -normalize(v_position);
  // The pipe's side facing the eye, turned across it as the fragment lies off the centreline.
  vec3 facing = to_eye - dot(to_eye, v_axis) * v_axis;
  vec3 n = length(facing) > 1e-5 ? normalize(facing) : to_eye;
  vec3 side = cross(v_axis, n);
  float s = clamp(v_across / max(v_half_px, 1.0), -1.0, 1.0) * 0.8;
  n = normalize(n * sqrt(1.0 - s * s) + side * s);
  o_colour = vec4(lit_colour(v_colour.rgb, n, to_eye), alpha);
  o_pick = v_pick;
}
