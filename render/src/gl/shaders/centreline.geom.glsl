// Centrelines: each segment, clipped to the near plane, expanded into a screen-aligned quad as
// wide as the pipe's projected diameter (at least a pixel) plus a pixel of feather on each side,
// its coverage the diameter when that is under a pixel. Pixels are the framebuffer's
// (u_viewport); the tie-break scales clip z as for surfaces.
layout(lines) in;
layout(triangle_strip, max_vertices = 4) out;
in vec3 g_position[];
flat in vec4 g_colour[];
flat in uint g_pick[];
flat in float g_diameter[];
flat in float g_tie[];
flat in int g_drawn[];
uniform mat4 u_view_projection;
uniform vec2 u_viewport;   // pixels of the framebuffer
uniform float u_focal_px;  // pixels a metre spans at 1 m, in framebuffer pixels
uniform float u_near;      // metres
out vec3 v_position;
noperspective out float v_across;  // pixels from the centreline
flat out float v_half_px;          // half the drawn core width, pixels
flat out float v_coverage;         // the pipe's share of a pixel when thinner than one
flat out vec4 v_colour;
flat out uint v_pick;
flat out vec3 v_axis;
void main() {
  if (g_drawn[0] == 0) return;
  vec3 p0 = g_position[0], p1 = g_position[1];
  vec4 c0 = u_view_projection * vec4(p0, 1.0), c1 = u_view_projection * vec4(p1, 1.0);
  // Clip to the near plane (w is the distance along the view axis).
  if (c0.w < u_near && c1.w < u_near) return;
  if (c0.w < u_near || c1.w < u_near) {
    float t = (u_near - c0.w) / (c1.w - c0.w);
    vec3 p = mix(p0, p1, t);
    vec4 c = u_view_projection * vec4(p, 1.0);
    if (c0.w < u_near) { p0 = p; c0 = c; } else { p1 = p; c1 = c; }
  }
  vec2 s0 = c0.xy / c0.w * 0.5 * u_viewport, s1 = c1.xy / c1.w * 0.5 * u_viewport;
  vec2 along = s1 - s0;
  vec2 dir = length(along) > 1e-4 ? normalize(along) : vec2(1.0, 0.0);
  vec2 across = vec2(-dir.y, dir.x);
  vec3 axis = p1 - p0;
  v_axis = length(axis) > 0.0 ? normalize(axis) : vec3(0.0, 0.0, 1.0);
  v_colour = g_colour[0];
  v_pick = g_pick[0];
  float width0 = g_diameter[0] * u_focal_px / c0.w, width1 = g_diameter[0] * u_focal_px / c1.w;
  for (int i = 0; i < 2; ++i) {
    vec4 c = i == 0 ? c0 : c1;
    float width = i == 0 ? width0 : width1;
    v_coverage = clamp(width, 0.05, 1.0);
    v_half_px = 0.5 * max(width, 1.0);
    float reach = v_half_px + 1.0;  // a pixel of feather on each side
    for (int side = -1; side <= 1; side += 2) {
      vec2 offset = across * (float(side) * reach) / (0.5 * u_viewport);
      gl_Position = vec4(c.xy + offset * c.w, c.z * g_tie[0], c.w);
      v_across = float(side) * reach;
      v_position = i == 0 ? p0 : p1;
      clip_section(v_position);  // section_clip.glsl, ahead in the same shader
      EmitVertex();
    }
  }
  EndPrimitive();
}
