#version 430
// The GPU stream probe (stream_bandwidth.h): every invocation copies vec4s from src to dst in a
// grid-stride loop, so each byte is read once and written once; the time of a dispatch gives
// the memory bandwidth a streaming kernel can reach on this device.
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Source { vec4 src[]; };
layout(std430, binding = 1) writeonly buffer Destination { vec4 dst[]; };

uniform uint u_count;  // vec4s to copy

void main() {
  const uint stride = gl_NumWorkGroups.x * 256u;
  for (uint i = gl_GlobalInvocationID.x; i < u_count; i += stride) dst[i] = src[i];
}
