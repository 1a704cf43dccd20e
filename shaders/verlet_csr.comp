#version 430
// One damped Verlet step (Zeleny 2011, formula 3.8) for any spring list, gather formulation over
// compressed rows: point p's springs are slots row[p] .. row[p+1]-1, each naming the other end
// point, the stiffness D and the rest length |l0|. Hooke (3.1) as the CPU general path: the force
// on p is D (|l| - |l0|) / |l| l with l = x_q - x_p (skipped when |l| = 0). No atomics.
//   x_new = x + b (x - x_prev) + a F,  a = dt^2 / m,  b = 1 - c dt / m;  fixed points: x_new = x.
// Positions are vec4 (w = 1 fixed, 0 free). u_measure: per-group largest |F|^2 at free points.
// With u_power, each group also writes its sum of F . (x - x_prev) (the momentum static solver's
// restart test, O'Donoghue and Candes 2015) to power_partial[group].
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Current { vec4 cur[]; };
layout(std430, binding = 1) buffer Previous { vec4 prev[]; };
layout(std430, binding = 2) readonly buffer Rows { int row[]; };
struct Slot {
  int q;       // the other end point
  float k;     // stiffness D
  float rest;  // rest length |l0|
  float pad;
};
layout(std430, binding = 3) readonly buffer Slots { Slot slot[]; };
layout(std430, binding = 4) writeonly buffer Partial { float partial[]; };
layout(std430, binding = 6) writeonly buffer Power { float power_partial[]; };
layout(std430, binding = 5) readonly buffer Coefficients { vec2 coef[]; };

uniform int u_n;
uniform vec2 u_ab;
uniform bool u_write;
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
    const vec4 x4 = cur[p];
    const vec3 x = x4.xyz;
    vec3 f = vec3(0.0);
    const int end = row[p + 1];
    for (int s = row[p]; s < end; ++s) {
      const Slot spring = slot[s];
      const vec3 l = cur[spring.q].xyz - x;
      const float len = sqrt(dot(l, l));
      if (len != 0.0) f += (spring.k * (len - spring.rest) / len) * l;
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
