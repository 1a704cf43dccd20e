#version 430
// Total energy of a Verlet state on the GPU, for the divergence check of the settle (the CPU
// solver's test, springs/settle.h): kinetic 1/2 m |x - x_prev|^2 / dt^2 = 1/2 |x - x_prev|^2 / a
// (a = dt^2 / m) at free points, plus potential 1/2 D (|l| - |l0|)^2 of every spring. Each work
// group writes the sum of its invocations to partial[group]; the host adds the groups in double.
// A NaN or Inf anywhere makes that group's sum NaN or Inf, which the host reports as divergence.
// Compiled in one of three layouts (a define after #version):
//   LATTICE:  the structured kernel's buffers; invocation p adds its point and the springs of
//             its half directions (each spring once, from its first end), rest length 1 / k.
//   CSR:      the compressed-row kernel's buffers; invocation p adds its point and half of each
//             of its springs (every spring is listed at both ends).
//   TEXTURES: the geometry-shader method: positions in textures, springs as the vertex buffers
//             (ends, (D, |l0|)) bound as storage; invocation g adds point g and spring g.
layout(local_size_x = 256) in;

layout(std430, binding = 4) writeonly buffer Partial { float partial[]; };

#if defined(LATTICE)
layout(std430, binding = 0) readonly buffer Current { vec4 cur[]; };
layout(std430, binding = 1) readonly buffer Previous { vec4 prev[]; };
layout(std430, binding = 2) readonly buffer Stiffness { float stiffness[]; };  // [d * n + p], 0 = none
layout(std430, binding = 3) readonly buffer Coefficients { vec2 coef[]; };     // (a, b) per point
uniform ivec3 u_size;
uniform int u_directions;
uniform ivec3 u_dir[13];
uniform int u_offset[13];
uniform bool u_uniform;
uniform float u_k[13];
uniform vec2 u_ab;
#elif defined(CSR)
layout(std430, binding = 0) readonly buffer Current { vec4 cur[]; };
layout(std430, binding = 1) readonly buffer Previous { vec4 prev[]; };
layout(std430, binding = 2) readonly buffer Rows { int row[]; };
struct Slot {
  int q;
  float k;
  float rest;
  float pad;
};
layout(std430, binding = 3) readonly buffer Slots { Slot slot[]; };
layout(std430, binding = 5) readonly buffer Coefficients { vec2 coef[]; };
#else  // TEXTURES
uniform sampler2D u_current;
uniform sampler2D u_previous;
uniform sampler2D u_coefficients;
uniform bool u_uniform;
uniform vec2 u_ab;
uniform int u_width;
uniform int u_springs;
layout(std430, binding = 0) readonly buffer Ends { ivec2 ends[]; };
layout(std430, binding = 1) readonly buffer Params { vec2 params[]; };  // (D, |l0|)
vec3 texel_position(sampler2D s, int i) { return texelFetch(s, ivec2(i % u_width, i / u_width), 0).xyz; }
#endif

uniform int u_n;
shared float s_sum[256];

void main() {
  const uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  const int p = int(group * 256u + gl_LocalInvocationIndex);
  float e = 0.0;
#if defined(LATTICE) || defined(CSR)
  if (p < u_n) {
    const vec4 x4 = cur[p];
    const vec3 x = x4.xyz;
    if (x4.w == 0.0) {
#if defined(LATTICE)
      const float a = u_uniform ? u_ab.x : coef[p].x;
#else
      const float a = coef[p].x;
#endif
      const vec3 v = x - prev[p].xyz;
      e += 0.5 * dot(v, v) / a;
    }
#if defined(LATTICE)
    const ivec3 ijk = ivec3(p % u_size.x, (p / u_size.x) % u_size.y, p / (u_size.x * u_size.y));
    for (int d = 0; d < u_directions; ++d) {
      const ivec3 up = ijk + u_dir[d];
      if (any(lessThan(up, ivec3(0))) || any(greaterThanEqual(up, u_size))) continue;
      const float k = u_uniform ? u_k[d] : stiffness[d * u_n + p];
      const vec3 l = cur[p + u_offset[d]].xyz - x;
      const float stretch = k * sqrt(dot(l, l)) - 1.0;  // k (|l| - 1 / k)
      e += 0.5 * stretch * stretch / k;
    }
#else
    const int end = row[p + 1];
    for (int s = row[p]; s < end; ++s) {
      const Slot spring = slot[s];
      const vec3 l = cur[spring.q].xyz - x;
      const float stretch = sqrt(dot(l, l)) - spring.rest;
      e += 0.25 * spring.k * stretch * stretch;
    }
#endif
  }
#else  // TEXTURES
  if (p < u_n) {
    const vec4 x4 = texelFetch(u_current, ivec2(p % u_width, p / u_width), 0);
    if (x4.w == 0.0) {
      const float a = u_uniform ? u_ab.x : texelFetch(u_coefficients, ivec2(p % u_width, p / u_width), 0).x;
      const vec3 v = x4.xyz - texel_position(u_previous, p);
      e += 0.5 * dot(v, v) / a;
    }
  }
  if (p < u_springs) {
    const ivec2 ab = ends[p];
    const vec3 l = texel_position(u_current, ab.y) - texel_position(u_current, ab.x);
    const float stretch = sqrt(dot(l, l)) - params[p].y;
    e += 0.5 * params[p].x * stretch * stretch;
  }
#endif
  s_sum[gl_LocalInvocationIndex] = e;
  barrier();
  for (uint stride = 128u; stride > 0u; stride >>= 1) {
    if (gl_LocalInvocationIndex < stride) s_sum[gl_LocalInvocationIndex] += s_sum[gl_LocalInvocationIndex + stride];
    barrier();
  }
  if (gl_LocalInvocationIndex == 0u) partial[group] = s_sum[0];
}
