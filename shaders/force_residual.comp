#version 430
// Residual of the geometry-shader method: per work group, the largest |F|^2 of the force texture
// over free points (position w = 0), +Inf for NaN/Inf; the host takes the maximum of the groups.
layout(local_size_x = 256) in;

uniform sampler2D u_force;
uniform sampler2D u_positions;
uniform int u_width;
uniform int u_n;

layout(std430, binding = 4) writeonly buffer Partial { float partial[]; };
shared float s_max[256];

void main() {
  const uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  const int p = int(group * 256u + gl_LocalInvocationIndex);
  float f2 = 0.0;
  if (p < u_n) {
    const ivec2 t = ivec2(p % u_width, p / u_width);
    if (texelFetch(u_positions, t, 0).w == 0.0) {
      const vec3 f = texelFetch(u_force, t, 0).xyz;
      f2 = dot(f, f);
      if (isnan(f2) || isinf(f2)) f2 = uintBitsToFloat(0x7f800000u);
    }
  }
  s_max[gl_LocalInvocationIndex] = f2;
  barrier();
  for (uint stride = 128u; stride > 0u; stride >>= 1) {
    if (gl_LocalInvocationIndex < stride)
      s_max[gl_LocalInvocationIndex] = max(s_max[gl_LocalInvocationIndex], s_max[gl_LocalInvocationIndex + stride]);
    barrier();
  }
  if (gl_LocalInvocationIndex == 0u) partial[group] = s_max[0];
}
