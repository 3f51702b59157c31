// Ambient occlusion, and its depth, at half the output's resolution (occlusion varies slowly;
// a quarter of the pixels costs a quarter), into a two-channel texture (r: occlusion, 1 none;
// g: the reversed depth it was read at) that finish.frag.glsl blurs and brings up to size.
// Scalable ambient obscurance (McGuire et al. 2012) from depth alone: the normal from the
// nearer neighbours (no smearing across silhouettes), 12 samples on a golden-angle spiral of at
// most 20 output pixels, turned by one of 16 angles in a 4x4 pattern (the blur over 4x4 pixels
// then sees 192 directions), each counting how far it rises above the surface's tangent plane.
layout(location = 0) out vec4 o_occlusion;
uniform sampler2D u_depth;
uniform int u_scale;         // 1, or 2 when supersampled
uniform int u_step;          // framebuffer pixels per occlusion pixel: 2 x u_scale
uniform float u_near;        // metres
uniform vec2 u_ndc_to_view;  // view-space x, y per NDC unit at 1 m: (aspect / focal, 1 / focal)
uniform float u_focal_px;    // framebuffer pixels a metre spans at 1 m
uniform float u_radius_m;    // the reach
ivec2 frame_size;

// View-space position of a framebuffer pixel (z < 0 ahead); w = 0 where nothing was drawn.
vec4 position_at(ivec2 q) {
  q = clamp(q, ivec2(0), frame_size - 1);
  float d = texelFetch(u_depth, q, 0).r;
  if (d <= 0.0) return vec4(0.0);
  float z = u_near / d;
  vec2 ndc = (vec2(q) + 0.5) / vec2(frame_size) * 2.0 - 1.0;
  return vec4(ndc * u_ndc_to_view * z, -z, 1.0);
}

float occlusion(ivec2 q, ivec2 out_px) {
  vec4 c = position_at(q);
  if (c.w == 0.0) return 1.0;
  vec3 p = c.xyz;
  vec4 l = position_at(q - ivec2(1, 0)), r = position_at(q + ivec2(1, 0));
  vec4 d = position_at(q - ivec2(0, 1)), u = position_at(q + ivec2(0, 1));
  vec3 dx = (r.w > 0.0 && (l.w == 0.0 || abs(r.z - p.z) < abs(p.z - l.z))) ? r.xyz - p : p - l.xyz;
  vec3 dy = (u.w > 0.0 && (d.w == 0.0 || abs(u.z - p.z) < abs(p.z - d.z))) ? u.xyz - p : p - d.xyz;
  vec3 n = cross(dx, dy);
  if (dot(n, n) < 1e-20) return 1.0;
  n = normalize(n);
  if (dot(n, p) > 0.0) n = -n;
  float radius_px = u_radius_m * u_focal_px / -p.z;
  if (radius_px < 1.5) return 1.0;
  radius_px = min(radius_px, 20.0 * float(u_scale));  // longer reaches streak behind edges
  radius_px = max(radius_px, float(u_step));
  const int kSamples = 12;
  // Every 2x2 block holds four turns a quarter turn apart (and the 4x4 all 16): a blur that
  // keeps only some taps (a small or curved surface) still averages directions spread evenly.
  int quarter = (out_px.x & 1) + 2 * (out_px.y & 1);
  int block = ((out_px.x >> 1) & 1) + 2 * ((out_px.y >> 1) & 1);
  float turn = float(4 * quarter + block) * (6.2831853 / 16.0);
  // Sample i at i x the golden angle + turn: constant directions, turned once (a sine and a
  // cosine a pixel, not a sample: measured 29 -> 25 ms a frame for this pass on llvmpipe).
  const vec2 kDirections[kSamples] = vec2[](
      vec2(1.0000000, 0.0000000), vec2(-0.7373689, 0.6754903), vec2(0.0874257, -0.9961710),
      vec2(0.6084389, 0.7936007), vec2(-0.9847135, -0.1741818), vec2(0.8437552, -0.5367282),
      vec2(-0.2596041, 0.9657151), vec2(-0.4609072, -0.8874483), vec2(0.9393214, 0.3430384),
      vec2(-0.9243455, 0.3815567), vec2(0.4238457, -0.9057344), vec2(0.2992842, 0.9541640));
  mat2 turned = mat2(cos(turn), sin(turn), -sin(turn), cos(turn));
  float r2 = u_radius_m * u_radius_m, sum = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    float a = (float(i) + 0.5) / float(kSamples);
    vec2 offset = (turned * kDirections[i]) * (a * radius_px);
    vec4 s = position_at(q + ivec2(round(offset)));
    if (s.w == 0.0) continue;
    vec3 v = s.xyz - p;
    float vv = dot(v, v), vn = dot(v, n);
    float f = max(r2 - vv, 0.0);
    sum += f * f * f * max((vn - 0.02 * u_radius_m) / (vv + 0.01 * r2), 0.0);
  }
  return clamp(1.0 - sum * (5.0 / (r2 * r2 * r2)) / float(kSamples), 0.0, 1.0);
}

void main() {
  frame_size = textureSize(u_depth, 0);
  ivec2 ao_px = ivec2(gl_FragCoord.xy);
  ivec2 q = ao_px * u_step + ivec2(u_step / 2);
  // With the depth beside it, for the blur's weights (one fetch a tap there).
  o_occlusion = vec4(occlusion(q, ao_px), texelFetch(u_depth, q, 0).r, 0.0, 0.0);
}
