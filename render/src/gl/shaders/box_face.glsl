// The faces the eye (the origin) sees of a box lo..hi (camera-relative metres, lo <= hi), for a
// draw of 18 vertices a box (corner 0..17): per axis, the face on the eye's side if the eye is
// not between its two planes (else the face is collapsed to a point), two triangles (0 1 2,
// 0 2 3) of its quad; `normal` the face's outward unit normal. A vertex shader of its own in
// the proxy and box-test programs, which declare box_face_corner. Vector selects, not variable
// indices: llvmpipe compiles an index into a vector or an array as a trip through memory,
// which cost proxy boxes about 130 ns a vertex.
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
