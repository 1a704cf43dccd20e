#version 430
// Geometry-shader method, pass 1, geometry stage: emits the spring's force as two points, +F at
// end point a's texel and -F at b's; additive blending (GL_ONE, GL_ONE) into the RGBA32F force
// texture sums every point's springs.
layout(points) in;
layout(points, max_vertices = 2) out;

in Spring {
  vec3 force;
  flat ivec2 ends;
} gs_in[];

uniform ivec2 u_size;  // force texture width, height
out vec3 g_force;

vec4 texel_centre(int i) {
  const vec2 t = vec2(float(i % u_size.x), float(i / u_size.x)) + 0.5;
  return vec4(t / vec2(u_size) * 2.0 - 1.0, 0.0, 1.0);
}

void main() {
  g_force = gs_in[0].force;
  gl_Position = texel_centre(gs_in[0].ends.x);
  EmitVertex();
  EndPrimitive();
  g_force = -gs_in[0].force;
  gl_Position = texel_centre(gs_in[0].ends.y);
  EmitVertex();
  EndPrimitive();
}
