#version 430
// Geometry-shader method (Zeleny 2011, ch. 6.2.2), pass 1, vertex stage: one GL_POINTS vertex per
// spring carries its end points (a, b), stiffness D and rest length |l0|; the force on a is
// computed once, D (|l| - |l0|) / |l| l with l = x_b - x_a (zero when |l| = 0), and handed to the
// geometry stage, which adds it at a's texel and subtracts it at b's.
layout(location = 0) in ivec2 a_ends;
layout(location = 1) in vec2 a_spring;  // (D, |l0|)

uniform sampler2D u_positions;  // RGBA32F, point i at texel (i % width, i / width)
uniform int u_width;

out Spring {
  vec3 force;
  flat ivec2 ends;
} vs_out;

void main() {
  const vec3 xa = texelFetch(u_positions, ivec2(a_ends.x % u_width, a_ends.x / u_width), 0).xyz;
  const vec3 xb = texelFetch(u_positions, ivec2(a_ends.y % u_width, a_ends.y / u_width), 0).xyz;
  const vec3 l = xb - xa;
  const float len = sqrt(dot(l, l));
  vs_out.force = len != 0.0 ? (a_spring.x * (len - a_spring.y) / len) * l : vec3(0.0);
  vs_out.ends = a_ends;
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
