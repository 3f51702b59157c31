// Sections on the GPU (plantview/view_filters.h; gl/backend.h: sections): up to eight
// half-spaces, each camera-relative (x, y, z, w) removing the points p where
// dot(xyz, p) + w > 0, clipped per vertex by gl_ClipDistance (the backend enables the first
// u_clip_count). The offsets w are computed in double precision on the CPU. A part of the vertex
// (or geometry) shader that writes a vertex's camera-relative position, ahead of its main().
// Only the programs' section variants define SECTIONS (program_sources.h): writing clip
// distances costs llvmpipe about a fifth of a frame's drawing even with none enabled.
#ifdef SECTIONS
out float gl_ClipDistance[8];
uniform int u_clip_count;  // 0..8
uniform vec4 u_clip[8];
void clip_section(vec3 p) {
  for (int i = 0; i < u_clip_count; ++i) gl_ClipDistance[i] = -(dot(u_clip[i].xyz, p) + u_clip[i].w);
}
#else
void clip_section(vec3 p) {}
#endif
