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
vec3 lit_colour(vec3 base, vec3 n, vec3 to_eye);
void main() {
  vec3 to_eye = -normalize(u_ray * vec3(gl_FragCoord.xy * u_window_scale - 1.0, -1.0));
  float n_length = length(v_normal);
  vec3 n = n_length > 0.5 ? v_normal / n_length : to_eye;
  o_colour = vec4(lit_colour(v_colour.rgb, n, to_eye), v_colour.a * u_alpha);
  o_pick = v_pick;
}
