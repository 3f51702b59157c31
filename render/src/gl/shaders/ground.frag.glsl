// The ground: intersects each pixel's ray with the ground plane (only from above: discarded
// where the ray does not go down), a light floor with a grid of u_grid_m squares and heavier
// lines every ten, fading out from 5 m + 1.2 to 20 m + 3 plant radii from the plant's centre
// (alpha: blended, drawn where nothing else is) and where the grid gets denser than a few
// pixels. Colour only.
layout(location = 0) out vec4 o_colour;
uniform mat3 u_ray;
uniform vec2 u_window_scale;
uniform mat4 u_view_projection;
uniform float u_ground_z;     // the plane's height relative to the eye (negative: eye above)
uniform vec2 u_grid_phase;    // the eye's x, y modulo ten grid squares
uniform float u_grid_m;
uniform vec2 u_centre;        // the plant's centre (x, y) relative to the eye
uniform float u_radius_m;     // the plant's horizontal half-diagonal
float grid_lines(vec2 g) {
  vec2 w = fwidth(g);
  vec2 d = abs(fract(g - 0.5) - 0.5) / max(w, vec2(1e-6));
  float line = 1.0 - min(min(d.x, d.y), 1.0);
  return line * (1.0 - smoothstep(0.12, 0.35, max(w.x, w.y)));  // dense: fade out
}
void main() {
  vec3 ray = u_ray * vec3(gl_FragCoord.xy * u_window_scale - 1.0, -1.0);
  if (ray.z >= -1e-6) discard;
  vec3 p = ray * (u_ground_z / ray.z);
  float from_plant = length(p.xy - u_centre);
  float alpha = 1.0 - smoothstep(1.2 * u_radius_m + 5.0, 3.0 * u_radius_m + 20.0, from_plant);
  if (alpha < 0.02) discard;
  vec2 g = (p.xy + u_grid_phase) / u_grid_m;
  float minor = grid_lines(g), major = grid_lines(g * 0.1);
  vec3 floor_colour = vec3(0.70, 0.71, 0.69);
  vec3 c = mix(floor_colour, vec3(0.50, 0.52, 0.52), max(0.5 * minor, major));
  o_colour = vec4(c, alpha);
}
