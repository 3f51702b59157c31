// Surfaces and proxy boxes, lit per fragment (lighting.glsl, linked as a fragment shader of
// its own): colour (location 0) with the object's alpha x u_alpha, pick value (location 1).
// The direction to the eye is rebuilt from the window position (fewer interpolated values);
// a zero normal (under 0.5 long) is lit as facing the eye.
in vec3 v_normal;
flat in vec4 v_colour;
flat in uint v_pick;
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uint o_pick;
// The ray through a window position: u_ray * vec3(position * u_window_scale - 1, -1), in the
// camera-relative frame (not normalised).
uniform mat3 u_ray;
uniform vec2 u_window_scale;
uniform float u_alpha;  // multiplies the object's alpha (see-through passes)
// A see-through subject's outline (0: none): the alpha taken this share of the way to opaque
// where the surface is seen edge on, less as it turns to face the eye.
uniform float u_rim;
// Caps (gl/backend.h: sections): while the closed solids a section cuts are drawn, a back face
// is the inside of a cut solid: shaded as its cap, flat in the object's colour, darker, facing
// along the cutting plane where the view ray enters the kept region (the farthest crossing of a
// half-space, camera-relative (xyz, w): removed where dot(xyz, p) + w > 0, that the eye is in);
// its depth is moved onto that plane afterwards (cap_plane.vert.glsl). In the programs' section
// variants only (SECTIONS defined).
vec3 lit_colour(vec3 base, vec3 n, vec3 to_eye);
#ifdef SECTIONS
uniform bool u_cap;
uniform int u_clip_count;
uniform vec4 u_clip[8];
vec3 cap_normal(vec3 ray, vec3 to_eye) {
  float enter = 0.0;
  vec3 n = to_eye;
  for (int i = 0; i < u_clip_count; ++i) {
    float along = dot(u_clip[i].xyz, ray);
    if (u_clip[i].w > 0.0 && along < 0.0 && -u_clip[i].w / along > enter) {
      enter = -u_clip[i].w / along;
      n = u_clip[i].xyz;
    }
  }
  return n;
}
#endif
void main() {
  vec3 ray = u_ray * vec3(gl_FragCoord.xy * u_window_scale - 1.0, -1.0);
  vec3 to_eye = -normalize(ray);
  o_pick = v_pick;
#ifdef SECTIONS
  if (u_cap && !gl_FrontFacing) {
    o_colour = vec4(lit_colour(0.6 * v_colour.rgb, cap_normal(ray, to_eye), to_eye), v_colour.a * u_alpha);
    return;
  }
#endif
  float n_length = length(v_normal);
  vec3 n = n_length > 0.5 ? v_normal / n_length : to_eye;
  float alpha = v_colour.a * u_alpha;
  float edge_on = 1.0 - abs(dot(n, to_eye));
  alpha = mix(alpha, 1.0, u_rim * edge_on * edge_on);
  o_colour = vec4(lit_colour(v_colour.rgb, n, to_eye), alpha);
}
