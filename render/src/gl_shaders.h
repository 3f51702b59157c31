// GLSL sources of the GL backend (gl_backend.cpp compiles and links them).
//
// Programs
//   - surfaces: every triangle of the objects, lit per fragment;
//   - proxy boxes: the faces the eye sees of each, lit as surfaces;
//   - centrelines: pipes drawn as their centreline, expanded by a geometry shader into a
//     screen-aligned quad as wide as the pipe's projected diameter (at least a pixel, feathered
//     by a pixel), its coverage the diameter when that is under a pixel, and lit like the pipe's
//     side that faces the eye; a centreline vertex's normal word holds the diameter (float bits);
//   - ground: a full-screen triangle that intersects each pixel's ray with the ground plane;
//   - occlusion: a full-screen triangle computing ambient occlusion per output pixel;
//   - depth reduction: a full-screen triangle over a coarse grid of cells, each the farthest
//     depth (reversed: the least) drawn over every sample of the pixels it overlaps, for
//     occlusion culling's second phase (occlusion.h);
//   - finish: a full-screen triangle from the drawn frame to the output image: supersampled
//     frames averaged down, the edge filter, the ambient occlusion blurred and applied, the
//     object ids copied.
//
// Frames: positions are relative to the eye in model axes ("camera-relative": z up), so plants
//   kilometres from the origin keep float precision. Depth is reversed and infinite:
//   depth = near / distance along the view axis (0 at infinity).
// Highlight modes (u_mode): 0 draws every object, 1 only the subject (objects with a pick
//   value), 2 only the context (pick 0); the rejected ones are moved outside the clip volume by
//   the vertex shader.
#pragma once

namespace plantview::detail::shaders {

// Lighting shared by surfaces and centrelines: a hemisphere light (sky above, warm ground
// below), a key light from above behind the eye's left shoulder, a fill from the eye and a
// little specular on the key, so that the faces of a box and the sides of a pipe differ.
inline constexpr const char* kLighting = R"(
uniform vec3 u_key;  // unit, towards the key light, camera-relative
vec3 lit_colour(vec3 base, vec3 n, vec3 to_eye) {
  if (dot(n, to_eye) < 0.0) n = -n;  // two-sided: open meshes and facet groups
  float hemisphere = 0.5 + 0.5 * n.z;
  vec3 ambient = mix(vec3(0.42, 0.40, 0.38), vec3(0.78, 0.82, 0.90), hemisphere);
  float key = max(dot(n, u_key), 0.0);
  float fill = max(dot(n, to_eye), 0.0);
  vec3 h = normalize(u_key + to_eye);
  float specular = key > 0.0 ? pow(max(dot(n, h), 0.0), 32.0) : 0.0;
  vec3 c = base * (0.42 * ambient + 0.55 * key + 0.22 * fill) + vec3(0.12 * specular);
  return min(c, vec3(1.0));
}
)";

// The faces the eye (the origin) sees of a box lo..hi, for a draw of 18 vertices a box:
// per axis, the face on the eye's side if the eye is not between its two planes (else the face
// is collapsed to a point), two triangles (0 1 2, 0 2 3) of its quad. Vector selects, not
// variable indices: llvmpipe compiles an index into a vector or an array as a trip through
// memory, which cost proxy boxes about 130 ns a vertex.
inline constexpr const char* kBoxFace = R"(
vec3 box_face_corner(vec3 lo, vec3 hi, int corner, out vec3 normal) {
  int face = corner / 6, k = corner % 6;
  int q = k < 3 ? k : (k == 3 ? 0 : k - 2);  // the quad's corner: 0 1 2, 0 2 3
  vec3 along = vec3(equal(ivec3(face), ivec3(0, 1, 2)));
  vec3 sees_high = vec3(lessThan(hi, vec3(0.0)));  // per axis: the eye beyond the high face
  normal = along * (2.0 * sees_high - 1.0);
  if (dot(along, vec3(lessThanEqual(lo, vec3(0.0))) * vec3(greaterThanEqual(hi, vec3(0.0)))) > 0.5)
    return lo;  // not seen: collapsed
  return along * mix(lo, hi, sees_high) + along.zxy * (q == 1 || q == 2 ? hi : lo) +
         along.yzx * (q >= 2 ? hi : lo);
}
)";

// TableEntry::pick's fields and the tie-break's step (gl_backend.h: kTieBits).
#define PLANTVIEW_TIE_CONSTANTS \
  "const uint kPickMask = 0x3ffffffu;\nconst uint kTieShift = 26u;\nconst float kTieStep = 1.0 / 4194304.0;\n"

// The object table as the vertex shaders of objects, proxy boxes and centrelines read it
// (gl_backend.h: TableEntry): an entry's camera-relative offset and colour, its scale, its pick
// value, the factor its tie-break applies to clip-space z, and whether the highlight mode
// (u_mode) draws it. Compiled ahead of each of those shaders' source, in the same shader.
inline constexpr const char* kObjectTable = PLANTVIEW_TIE_CONSTANTS R"(
layout(std430, binding = 0) readonly buffer Objects { vec4 objects[]; };
uniform int u_mode;
struct Entry { vec3 offset; vec3 scale; vec4 colour; uint pick; float tie; bool drawn; };
Entry object_entry(uint object) {
  vec4 a = objects[2u * object];
  vec4 b = objects[2u * object + 1u];
  uint word = floatBitsToUint(b.w);
  Entry e;
  e.offset = a.xyz;
  e.scale = b.xyz;
  e.colour = unpackUnorm4x8(floatBitsToUint(a.w));
  e.pick = word & kPickMask;
  e.tie = 1.0 - float(word >> kTieShift) * kTieStep;
  e.drawn = !((u_mode == 1 && e.pick == 0u) || (u_mode == 2 && e.pick != 0u));
  return e;
}
)";

inline constexpr const char* kSurfaceVertex = R"(
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_normal;
layout(location = 2) in uint a_object;
uniform mat4 u_view_projection;
// Per-object values are flat, and the view direction is rebuilt per fragment from its window
// position: fewer interpolated values make each triangle cheaper to set up and to bin.
out vec3 v_normal;
flat out vec4 v_colour;
flat out uint v_pick;
void main() {
  Entry e = object_entry(a_object);
  v_pick = e.pick;
  if (!e.drawn) {
    gl_Position = vec4(0.0, 0.0, -1.0, 1.0);  // outside: clipped
    return;
  }
  vec3 p = a_position * e.scale + e.offset;
  v_normal = a_normal.xyz;
  v_colour = e.colour;
  gl_Position = u_view_projection * vec4(p, 1.0);
  gl_Position.z *= e.tie;
}
)";

// Proxy boxes (far-field proxies, node boxes), lit like surfaces (kSurfaceFragment): each box
// an object-table entry (its camera-relative lower corner and colour, its size and pick word)
// named by the proxy table, drawn as the faces the eye sees (kBoxFace) in one draw.
inline constexpr const char* kProxyVertex = R"(
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
  gl_Position = u_view_projection * vec4(p, 1.0);
  gl_Position.z *= e.tie;
}
)";

inline constexpr const char* kSurfaceFragment = R"(#version 450 core
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
)";

inline constexpr const char* kCentrelineVertex = R"(
layout(location = 0) in vec3 a_position;
layout(location = 2) in uint a_object;
layout(location = 3) in uint a_diameter;  // float bits: the pipe's outside diameter, metres
out vec3 g_position;  // camera-relative
flat out vec4 g_colour;
flat out uint g_pick;
flat out float g_diameter;
flat out float g_tie;
flat out int g_drawn;
void main() {
  Entry e = object_entry(a_object);
  g_pick = e.pick;
  g_tie = e.tie;
  g_drawn = e.drawn ? 1 : 0;
  g_position = a_position * e.scale + e.offset;
  g_colour = e.colour;
  g_diameter = uintBitsToFloat(a_diameter);
}
)";

inline constexpr const char* kCentrelineGeometry = R"(#version 450 core
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
      EmitVertex();
    }
  }
  EndPrimitive();
}
)";

inline constexpr const char* kCentrelineFragment = R"(#version 450 core
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
)";

// A full-screen triangle from gl_VertexID (no vertex data).
inline constexpr const char* kFullScreenVertex = R"(#version 450 core
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

// The ground: a plane at the plant's lowest level, a light floor with a grid of u_grid_m
// squares and heavier lines every ten, fading out from 5 m + 1.2 to 20 m + 3 plant radii from
// the plant's centre, and where the grid gets denser than a few pixels. Drawn as a square
// about the plant's centre as wide as the fade, so that its depth comes from rasterising (the
// depth test can then reject it where the plant hides it before it is shaded: a plane found
// per fragment, writing its depth, was shaded everywhere) and is written where it shows (so
// that ambient occlusion darkens it under the plant). Its depth is drawn a little farther than
// the plane (twice the tie-break's most, PLANTVIEW_TIE_CONSTANTS), so that what lies on the
// plane is drawn over it.
inline constexpr const char* kGroundVertex = "#version 450 core\n" PLANTVIEW_TIE_CONSTANTS R"(
uniform mat4 u_view_projection;
uniform float u_ground_z;  // the plane's height relative to the eye
uniform vec2 u_centre;     // the plant's centre (x, y) relative to the eye
uniform float u_reach_m;   // half the square's side: where the fade ends
void main() {
  const vec2 kCorners[6] = vec2[](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
                                  vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0));
  gl_Position = u_view_projection * vec4(u_centre + kCorners[gl_VertexID] * u_reach_m, u_ground_z, 1.0);
  gl_Position.z *= 1.0 - 2.0 * float((1u << (32u - kTieShift)) - 1u) * kTieStep;
}
)";

inline constexpr const char* kGroundFragment = R"(#version 450 core
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
)";

// Ambient occlusion, and its depth, at half the output's resolution (occlusion varies slowly;
// a quarter of the pixels costs a quarter) into a two-channel texture (the finishing pass
// blurs it and brings it up to size). Scalable ambient obscurance (McGuire et al. 2012) from depth alone: the normal from the
// nearer neighbours (no smearing across silhouettes), 12 samples on a golden-angle spiral of at
// most 20 output pixels, turned by one of 16 angles in a 4x4 pattern (the blur over
// 4x4 pixels then sees 192 directions), each counting how far it rises above the surface's
// tangent plane.
inline constexpr const char* kOcclusionFragment = R"(#version 450 core
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
)";

// From the drawn frame (u_scale x the output's size) to the output image.
// The depth reduction (after the version line; for a multisampled depth, kMultisampled; where
// every cell holds whole pixels, STEP_X, STEP_Y and SAMPLES defined). Cell c
// covers framebuffer pixels [c * source / cells, ceil((c + 1) * source / cells)): every pixel
// it overlaps, whole.
inline constexpr const char* kMultisampled = "#define MULTISAMPLED 1\n";
inline constexpr const char* kDepthReduceFragment = R"(
layout(location = 0) out float o_depth;
uniform ivec2 u_source;  // framebuffer pixels
uniform ivec2 u_cells;   // the grid
uniform int u_samples;   // samples per pixel
#ifdef MULTISAMPLED
uniform sampler2DMS u_depth;
float depth_at(ivec2 p, int s) { return texelFetch(u_depth, p, s).r; }
#else
uniform sampler2D u_depth;
float depth_at(ivec2 p, int s) { return texelFetch(u_depth, p, 0).r; }
#endif
void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  float farthest = 1.0;
#ifdef STEP_X
  // Whole pixels per cell, known when compiled: loops of constant length (unrolled).
  ivec2 lo = c * ivec2(STEP_X, STEP_Y);
  for (int y = 0; y < STEP_Y; ++y)
    for (int x = 0; x < STEP_X; ++x)
      for (int s = 0; s < SAMPLES; ++s) farthest = min(farthest, depth_at(lo + ivec2(x, y), s));
#else
  ivec2 lo = (c * u_source) / u_cells;
  ivec2 hi = min(((c + 1) * u_source + u_cells - 1) / u_cells, u_source);
  for (int y = lo.y; y < hi.y; ++y)
    for (int x = lo.x; x < hi.x; ++x)
      for (int s = 0; s < u_samples; ++s) farthest = min(farthest, depth_at(ivec2(x, y), s));
#endif
  o_depth = farthest;
}
)";

inline constexpr const char* kFinishFragment = R"(#version 450 core
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
        // The tap's depth was read at output pixel 2 tap + 1 (kOcclusionFragment).
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
)";

// Occlusion's box test (GlBackend::test_boxes): boxes from eye-relative (min, max) pairs (the
// eye is outside every box), each drawn as the faces the eye sees (kBoxFace), in one draw.
inline constexpr const char* kBoxTestVertex = R"(#version 450 core
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
)";

// A box's fragment that passed the depth test (tested before shading) marks the box seen.
inline constexpr const char* kBoxTestFragment = R"(#version 450 core
layout(early_fragment_tests) in;
layout(std430, binding = 2) writeonly buffer Seen { uint seen[]; };
flat in uint v_box;
void main() { seen[v_box] = 1u; }
)";

}  // namespace plantview::detail::shaders
