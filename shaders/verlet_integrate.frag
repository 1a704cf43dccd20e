#version 430
// Geometry-shader method, pass 2: the Verlet step (Zeleny 2011, formula 3.8) per texel, from the
// current and previous position textures and the accumulated force texture, into a third
// position texture (the three rotate). Position w = 1 marks a fixed point, which keeps x.
//   x_new = x + b (x - x_prev) + a F,  a = dt^2 / m,  b = 1 - c dt / m.
uniform sampler2D u_current;
uniform sampler2D u_previous;
uniform sampler2D u_force;
uniform sampler2D u_coefficients;  // (a, b) per point when not uniform
uniform bool u_uniform;
uniform vec2 u_ab;

layout(location = 0) out vec4 o_position;

void main() {
  const ivec2 t = ivec2(gl_FragCoord.xy);
  const vec4 x4 = texelFetch(u_current, t, 0);
  const vec3 x = x4.xyz;
  const vec3 f = texelFetch(u_force, t, 0).xyz;
  const vec2 ab = u_uniform ? u_ab : texelFetch(u_coefficients, t, 0).xy;
  o_position = x4.w != 0.0 ? x4 : vec4(x + ab.y * (x - texelFetch(u_previous, t, 0).xyz) + ab.x * f, 0.0);
}
