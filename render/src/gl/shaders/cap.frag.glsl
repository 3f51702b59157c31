// Caps of cut closed solids (gl/backend.h: sections): drawn where a back face of a closed solid
// is seen (marked in the stencil by the pass before: nothing of the frame lies in front of it),
// which is the inside of a solid the section cut open. The cut face lies where the view ray
// enters the kept region: the farthest crossing of a half-space the eye lies in (w > 0) and the
// ray leaves. The fragment is moved there (gl_FragDepth: reversed depth near / distance along
// the view axis), shaded flat in the object's colour, darker, facing along that plane's normal,
// with the object's pick value, so that ambient occlusion, the id buffer and picks see the cap.
// With the eye inside the kept region a back face is the inside of a solid the eye is in: no cap.
flat in vec4 v_colour;
flat in uint v_pick;
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uint o_pick;
uniform mat3 u_ray;
uniform vec2 u_window_scale;
uniform float u_near;
uniform int u_clip_count;
uniform vec4 u_clip[8];
vec3 lit_colour(vec3 base, vec3 n, vec3 to_eye);
void main() {
  vec3 ray = u_ray * vec3(gl_FragCoord.xy * u_window_scale - 1.0, -1.0);  // 1 along the view axis
  float enter = 0.0;
  vec3 n = vec3(0.0);
  for (int i = 0; i < u_clip_count; ++i) {
    float along = dot(u_clip[i].xyz, ray);
    if (u_clip[i].w > 0.0 && along < 0.0) {
      float s = -u_clip[i].w / along;
      if (s > enter) {
        enter = s;
        n = u_clip[i].xyz;
      }
    }
  }
  if (enter <= 0.0) discard;
  gl_FragDepth = min(u_near / enter, 1.0);
  vec3 to_eye = -normalize(ray);
  o_colour = vec4(lit_colour(0.6 * v_colour.rgb, n, to_eye), v_colour.a);
  o_pick = v_pick;
}
