// Centrelines: pipes drawn as their centreline, from the arena like surfaces, the normal word
// read as an integer (attribute 3): the pipe's outside diameter in metres (float bits). Passes
// the camera-relative ends and the entry's values to centreline.geom.glsl, which drops the
// segments the highlight mode rejects. Follows object_table.glsl in the same shader.
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
