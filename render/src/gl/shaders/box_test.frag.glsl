// Occlusion's box test: a box's fragment that passed the depth test (tested before shading)
// marks the box seen (binding 2, one word a box, cleared by the caller).
layout(early_fragment_tests) in;
layout(std430, binding = 2) writeonly buffer Seen { uint seen[]; };
flat in uint v_box;
void main() { seen[v_box] = 1u; }
