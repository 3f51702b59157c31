// Lighting shared by surfaces, proxy boxes and centrelines (a fragment shader of its own in
// each of their programs, which declare lit_colour): a hemisphere light (sky above, warm ground
// below), a key light from above behind the eye's left shoulder, a fill from the eye and a
// little specular on the key, so that the faces of a box and the sides of a pipe differ.
// Vectors camera-relative (model axes, z up); n and to_eye unit; colours linear 0..1.
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
