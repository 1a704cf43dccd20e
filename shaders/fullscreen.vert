#version 430
// A triangle covering the whole viewport (no vertex buffer: positions from gl_VertexID), for the
// passes that run a fragment per texel.
void main() {
  const vec2 corner = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
