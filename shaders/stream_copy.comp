#version 430
// The GPU stream probe (stream_bandwidth.h): every invocation copies one vec4 from src to dst (a
// two-dimensional grid of work groups covers the buffer), so each byte is read once and written
// once; the time of a dispatch gives the memory bandwidth a streaming kernel reaches on this
// device.
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Source { vec4 src[]; };
layout(std430, binding = 1) writeonly buffer Destination { vec4 dst[]; };

uniform uint u_count;  // vec4s to copy

void main() {
  const uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  const uint i = group * 256u + gl_LocalInvocationIndex;
  if (i < u_count) dst[i] = src[i];
}
