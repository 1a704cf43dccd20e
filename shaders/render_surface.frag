#version 430 core
// Headlight shading of a translucent surface, both faces: Lambert diffuse plus a Blinn-Phong
// highlight; opacity rises towards silhouettes (where the surface turns away from the viewer)
// so the outline reads while what lies inside stays visible. The normal is the interpolated
// smooth normal turned to the viewer, or the triangle's own (from screen derivatives) where the
// smooth one is missing or disagrees with it (an unrepaired mesh with flipped faces).
in vec3 v_view_position;
in vec3 v_view_normal;
in vec4 v_colour;

out vec4 f_colour;

void main() {
  vec3 face = cross(dFdx(v_view_position), dFdy(v_view_position));
  float face_length = length(face);
  vec3 flat_normal = face_length > 1e-30 ? face / face_length : vec3(0.0, 0.0, 1.0);
  if (flat_normal.z < 0.0) flat_normal = -flat_normal;
  vec3 n = flat_normal;
  float smooth_length = length(v_view_normal);
  if (smooth_length > 1e-30) {
    vec3 s = v_view_normal / smooth_length;
    if (dot(s, flat_normal) < 0.0) s = -s;
    if (dot(s, flat_normal) > 0.25) n = s;
  }
  const vec3 light = normalize(vec3(-0.35, 0.45, 1.0));
  const vec3 halfway = normalize(light + vec3(0.0, 0.0, 1.0));
  float diffuse = max(dot(n, light), 0.0);
  float highlight = pow(max(dot(n, halfway), 0.0), 48.0);
  vec3 rgb = v_colour.rgb * (0.30 + 0.70 * diffuse) + vec3(0.25 * highlight);
  float rim = 1.0 - abs(n.z);
  float alpha = v_colour.a + (1.0 - v_colour.a) * 0.6 * rim * rim;
  f_colour = vec4(min(rgb, vec3(1.0)), alpha);
}
