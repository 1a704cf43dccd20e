#version 430 core
// Turns each line segment into a screen-space ribbon (a quad) of the segment's width in pixels;
// the core profile has no wide lines. Each end is extended by half the width along the segment,
// so consecutive segments of a polyline overlap at their joints instead of leaving a notch.
// Where two lines coincide (a template's fibre along a cube edge), the wider one is drawn on top:
// its depth is pulled towards the viewer by a tiny amount per pixel of width.
layout(lines) in;
layout(triangle_strip, max_vertices = 4) out;

in vec4 v_colour[];
in float v_width[];

uniform vec2 u_viewport;      // view size in pixels
uniform float u_width_scale;  // multiplies every width

out vec4 g_colour;
out float g_across;  // -1 .. 1 across the ribbon

void main() {
  vec2 half_viewport = 0.5 * u_viewport;
  vec4 p0 = gl_in[0].gl_Position, p1 = gl_in[1].gl_Position;
  vec3 n0 = p0.xyz / p0.w, n1 = p1.xyz / p1.w;  // normalised device coordinates
  vec2 d = (n1.xy - n0.xy) * half_viewport;      // pixels
  float len = length(d);
  vec2 dir = len > 1e-4 ? d / len : vec2(1.0, 0.0);
  vec2 across = vec2(-dir.y, dir.x);
  // Depth change per pixel along the segment: the extended ends continue the segment's depth,
  // so a cap does not poke in front of or behind what the line itself would be.
  float depth_per_pixel = len > 1e-4 ? (n1.z - n0.z) / len : 0.0;
  for (int e = 0; e < 2; ++e) {
    float h = 0.5 * v_width[e] * u_width_scale;
    float sign_along = e == 0 ? -1.0 : 1.0;
    vec3 n = e == 0 ? n0 : n1;
    float w = e == 0 ? p0.w : p1.w;
    float depth = n.z + sign_along * depth_per_pixel * h - 2e-5 * h;
    for (int side = -1; side <= 1; side += 2) {
      vec2 offset = (dir * (sign_along * h) + across * (h * float(side))) / half_viewport;
      gl_Position = vec4((n.xy + offset) * w, depth * w, w);
      g_colour = v_colour[e];
      g_across = float(side);
      EmitVertex();
    }
  }
  EndPrimitive();
}
