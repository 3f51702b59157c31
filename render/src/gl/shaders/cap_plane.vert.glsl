// Caps' depth (gl/backend.h: sections): a square lying on a cutting plane the eye is on the
// removed side of, as wide as the view could need (corners camera-relative, metres), drawn where
// the stencil marks a cut solid's inside so that the depth there becomes the plane's: where the
// view ray enters the kept region, the cut face. Four vertices (a triangle strip), no vertex
// data; not clipped by the section (it lies on it).
uniform mat4 u_view_projection;
uniform vec3 u_corners[4];
void main() {
  vec3 p = gl_VertexID == 0 ? u_corners[0]
           : gl_VertexID == 1 ? u_corners[1]
           : gl_VertexID == 2 ? u_corners[2]
                              : u_corners[3];
  gl_Position = u_view_projection * vec4(p, 1.0);
}
