// A full-screen triangle from gl_VertexID (vertices 0..2, no vertex data): the vertex shader
// of the ambient occlusion, depth reduction and finishing passes.
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
