#version 430
// One damped Verlet step (Zeleny 2011, formula 3.8) on a structured n_x x n_y x n_z lattice,
// gather formulation: each invocation owns one point, sums the springs of its 3 (model-6) or
// 13 (model-26) half directions from both ends (neighbour p + o[d] and p - o[d]) at the current
// positions, and writes its new position over its previous one. No atomics: the result does
// not depend on scheduling. Forces as the CPU structured path: stiffness k = 1 / rest length,
// so a spring's force on p is (k - 1 / |l|) l with l = x_q - x_p.
//   x_new = x + b (x - x_prev) + a F,  a = dt^2 / m,  b = 1 - c dt / m;  fixed points: x_new = x.
// Positions are vec4: xyz and w = 1 for a fixed point, 0 for a free one.
// With u_measure, each work group also writes the largest |F|^2 over its free points (+Inf for
// NaN/Inf) to partial[group]: the residual reduction, finished on the host over a few values.
// With u_power, each group also writes its sum of F . (x - x_prev) (the momentum static solver's
// restart test, O'Donoghue and Candes 2015) to power_partial[group].
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Current { vec4 cur[]; };
layout(std430, binding = 1) buffer Previous { vec4 prev[]; };  // overwritten with the new positions
layout(std430, binding = 2) readonly buffer Stiffness { float stiffness[]; };  // [d * n + p], 0 = none
layout(std430, binding = 3) readonly buffer Coefficients { vec2 coef[]; };     // (a, b) per point
layout(std430, binding = 4) writeonly buffer Partial { float partial[]; };
layout(std430, binding = 6) writeonly buffer Power { float power_partial[]; };

uniform ivec3 u_size;
uniform int u_n;
uniform int u_directions;
uniform ivec3 u_dir[13];
uniform int u_offset[13];
uniform bool u_uniform;   // one stiffness per direction (u_k) and one (a, b) for every point
uniform float u_k[13];
uniform vec2 u_ab;
uniform bool u_write;     // false: measure only (residual at the current positions)
uniform bool u_measure;

uniform bool u_uniform_ab;  // one (a, b) for every point: u_ab (the momentum solver sets b each step)
uniform bool u_power;       // write the group's sum of F . (x - x_prev) over free points to power_partial

shared float s_max[256];
shared float s_sum[256];

void main() {
  const uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  const int p = int(group * 256u + gl_LocalInvocationIndex);
  float f2 = 0.0, fv = 0.0;
  if (p < u_n) {
    const ivec3 ijk = ivec3(p % u_size.x, (p / u_size.x) % u_size.y, p / (u_size.x * u_size.y));
    const vec4 x4 = cur[p];
    const vec3 x = x4.xyz;
    vec3 f = vec3(0.0);
    for (int d = 0; d < u_directions; ++d) {
      const ivec3 o = u_dir[d];
      const ivec3 up = ijk + o;
      if (all(greaterThanEqual(up, ivec3(0))) && all(lessThan(up, u_size))) {
        const vec3 l = cur[p + u_offset[d]].xyz - x;
        const float w = (u_uniform ? u_k[d] : stiffness[d * u_n + p]) - 1.0 / sqrt(dot(l, l));
        f += w * l;
      }
      const ivec3 down = ijk - o;
      if (all(greaterThanEqual(down, ivec3(0))) && all(lessThan(down, u_size))) {
        const int q = p - u_offset[d];
        const vec3 l = cur[q].xyz - x;
        const float w = (u_uniform ? u_k[d] : stiffness[d * u_n + q]) - 1.0 / sqrt(dot(l, l));
        f += w * l;
      }
    }
    const bool fixed_point = x4.w != 0.0;
    if (u_power && !fixed_point) fv = dot(f, x - prev[p].xyz);
    if (u_write) {
      const vec2 ab = u_uniform_ab ? u_ab : coef[p];
      prev[p] = fixed_point ? x4 : vec4(x + ab.y * (x - prev[p].xyz) + ab.x * f, 0.0);
    }
    if (!fixed_point) {
      f2 = dot(f, f);
      if (isnan(f2) || isinf(f2)) f2 = uintBitsToFloat(0x7f800000u);
    }
  }
  if (u_measure) {
    s_max[gl_LocalInvocationIndex] = f2;
    barrier();
    for (uint stride = 128u; stride > 0u; stride >>= 1) {
      if (gl_LocalInvocationIndex < stride)
        s_max[gl_LocalInvocationIndex] = max(s_max[gl_LocalInvocationIndex], s_max[gl_LocalInvocationIndex + stride]);
      barrier();
    }
    if (gl_LocalInvocationIndex == 0u) partial[group] = s_max[0];
  }
  if (u_power) {
    s_sum[gl_LocalInvocationIndex] = fv;
    barrier();
    for (uint stride = 128u; stride > 0u; stride >>= 1) {
      if (gl_LocalInvocationIndex < stride) s_sum[gl_LocalInvocationIndex] += s_sum[gl_LocalInvocationIndex + stride];
      barrier();
    }
    if (gl_LocalInvocationIndex == 0u) power_partial[group] = s_sum[0];
  }
}
