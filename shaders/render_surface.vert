#version 430 core
// Translucent surfaces of `fascicle render` (render_view.cpp): positions relative to the scene's
// centre, smooth normals (zero where unknown), one colour per vertex.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec4 a_colour;

uniform mat4 u_view;        // scene -> view space: x right, y up, z towards the viewer
uniform mat4 u_projection;  // view space -> clip space (orthographic)

out vec3 v_view_position;
out vec3 v_view_normal;
out vec4 v_colour;

void main() {
  vec4 p = u_view * vec4(a_position, 1.0);
  v_view_position = p.xyz;
  v_view_normal = mat3(u_view) * a_normal;
  v_colour = a_colour;
  gl_Position = u_projection * p;
}
