// Finishing: from the drawn frame (u_scale x the output's size) to the output image, a pixel
// each: supersampled frames averaged down, the edge filter, the ambient occlusion
// (ambient_occlusion.frag.glsl) blurred and applied, the object ids copied (one sample per
// output pixel). Depth reversed (0: nothing drawn).
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uint o_pick;
uniform sampler2D u_colour;     // linear filtering
uniform sampler2D u_depth;
uniform usampler2D u_pick;
uniform sampler2D u_occlusion;  // per 2x2 output pixels: occlusion, depth
uniform int u_scale;            // 1, or 2 when supersampled
uniform bool u_edge_filter;
uniform bool u_occlusion_on;
ivec2 frame_size;

// FXAA-like edge filter (after Lottes' FXAA 3.11 console version): blends along the edge
// direction found from the luma of the four diagonal neighbours.
vec3 edge_filtered(ivec2 q) {
  vec2 texel = 1.0 / vec2(frame_size);
  vec2 uv = (vec2(q) + 0.5) * texel;
  const vec3 kLuma = vec3(0.299, 0.587, 0.114);
  vec3 m = texelFetch(u_colour, q, 0).rgb;
  float lm = dot(m, kLuma);
  float nw = dot(texture(u_colour, uv + vec2(-0.5, 0.5) * texel).rgb, kLuma);
  float ne = dot(texture(u_colour, uv + vec2(0.5, 0.5) * texel).rgb, kLuma);
  float sw = dot(texture(u_colour, uv + vec2(-0.5, -0.5) * texel).rgb, kLuma);
  float se = dot(texture(u_colour, uv + vec2(0.5, -0.5) * texel).rgb, kLuma);
  float lo = min(lm, min(min(nw, ne), min(sw, se))), hi = max(lm, max(max(nw, ne), max(sw, se)));
  if (hi - lo < max(0.04, hi * 0.125)) return m;
  vec2 dir = vec2(-((nw + ne) - (sw + se)), (ne + se) - (nw + sw));  // y up
  float reduce = max((nw + ne + sw + se) * 0.03125, 1.0 / 128.0);
  dir = clamp(dir / (min(abs(dir.x), abs(dir.y)) + reduce), -8.0, 8.0) * texel;
  vec3 a = 0.5 * (texture(u_colour, uv - dir / 6.0).rgb + texture(u_colour, uv + dir / 6.0).rgb);
  vec3 b = 0.5 * a + 0.25 * (texture(u_colour, uv - dir * 0.5).rgb + texture(u_colour, uv + dir * 0.5).rgb);
  float lb = dot(b, kLuma);
  return (lb < lo || lb > hi) ? a : b;
}

// The change of depth per framebuffer pixel along `step` at p, from the neighbour on the side
// whose depth is nearer p's (the surface's side at a silhouette), or the one drawn; 0 where
// neither is.
float depth_slope(ivec2 p, ivec2 step, float depth) {
  float before = texelFetch(u_depth, clamp(p - step, ivec2(0), frame_size - 1), 0).r;
  float after = texelFetch(u_depth, clamp(p + step, ivec2(0), frame_size - 1), 0).r;
  bool has_before = before > 0.0, has_after = after > 0.0;
  float s = !has_before ? (has_after ? after - depth : 0.0)
          : !has_after || abs(depth - before) <= abs(after - depth) ? depth - before
          : after - depth;
  return s / float(max(abs(step.x), abs(step.y)));
}

void main() {
  frame_size = textureSize(u_depth, 0);
  ivec2 out_px = ivec2(gl_FragCoord.xy);
  ivec2 q = out_px * u_scale;  // the framebuffer pixel at the output pixel's first corner
  vec3 c;
  if (u_scale == 2)  // the four samples' mean, one bilinear fetch at their common corner
    c = texture(u_colour, vec2(q + 1) / vec2(frame_size)).rgb;
  else if (u_edge_filter)
    c = edge_filtered(q);
  else
    c = texelFetch(u_colour, q, 0).rgb;
  if (u_occlusion_on) {
    // The occlusion of the 4x4 occlusion pixels around, weighted by a tent over their distance
    // (so that it changes smoothly from one output pixel to the next: a window that jumped
    // every second pixel left steps) and kept where they lie on this pixel's surface: within 5%
    // of the depth this pixel's tangent plane predicts there (reversed depth is affine in screen
    // space over a plane; its own depth rejected most taps where a surface turns away from the
    // eye). The patterns of turns average out; edges stay sharp.
    ivec2 ao_size = textureSize(u_occlusion, 0);
    vec2 ao_at = (vec2(out_px) + 0.5) * 0.5;  // in occlusion pixels (each 2x2 output pixels)
    ivec2 base = ivec2(floor(ao_at - 0.5)) - 1;
    ivec2 at = q + ivec2(u_scale - 1);
    float depth = texelFetch(u_depth, at, 0).r;
    vec2 slope = vec2(depth_slope(at, ivec2(u_scale, 0), depth),
                      depth_slope(at, ivec2(0, u_scale), depth)) * float(u_scale);
    float sum = 0.0, weight = 0.0;
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) {
        ivec2 tap = clamp(base + ivec2(x, y), ivec2(0), ao_size - 1);
        vec2 t = texelFetch(u_occlusion, tap, 0).rg;
        vec2 d = min(abs(vec2(tap) + 0.5 - ao_at), vec2(2.0));
        // The tap's depth was read at output pixel 2 tap + 1 (ambient_occlusion.frag.glsl).
        float expected = depth + dot(slope, vec2(2 * tap + 1 - out_px));
        float w = abs(t.g - expected) <= 0.05 * depth ? (2.0 - d.x) * (2.0 - d.y) : 0.0;
        sum += w * t.r;
        weight += w;
      }
    float a = weight > 0.0 ? sum / weight : 1.0;
    c *= mix(1.0, a, 0.6);
  }
  o_colour = vec4(c, 1.0);
  o_pick = texelFetch(u_pick, q + ivec2(u_scale - 1), 0).r;
}
