#version 430 core
// Opaque polylines of `fascicle render` (render_view.cpp), drawn as GL_LINES: positions relative
// to the scene's centre, a colour and a width in pixels per vertex.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_colour;
layout(location = 2) in float a_width;

uniform mat4 u_view;
uniform mat4 u_projection;

out vec4 v_colour;
out float v_width;

void main() {
  gl_Position = u_projection * (u_view * vec4(a_position, 1.0));
  v_colour = a_colour;
  v_width = a_width;
}
