// The depth reduction for occlusion culling's second phase (occlusion.h): a full-screen
// triangle over a coarse grid of cells, each the farthest depth (reversed: the least; 1 where
// the cell covers no pixel) drawn over every sample of the pixels it overlaps. Cell c covers
// framebuffer pixels [c * source / cells, ceil((c + 1) * source / cells)): every pixel it
// overlaps, whole. Put in front of it (program_sources.cpp): MULTISAMPLED for a multisampled
// depth; STEP_X, STEP_Y and SAMPLES where every cell holds whole pixels (loops of constant
// length).
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
