#version 430 core
// Ribbon shading: brightest along the middle, darker towards the edges like a lit tube, which
// also outlines light colours on a white background. Brightness only: the hue stays the map's.
in vec4 g_colour;
in float g_across;

out vec4 f_colour;

void main() {
  float s = clamp(abs(g_across), 0.0, 1.0);
  float shade = mix(0.55, 1.0, sqrt(max(1.0 - s * s, 0.0)));
  f_colour = vec4(g_colour.rgb * shade, 1.0);
}
