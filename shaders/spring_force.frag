#version 430
// Geometry-shader method, pass 1, fragment stage: writes the force; blending adds it up.
in vec3 g_force;
layout(location = 0) out vec4 o_force;

void main() { o_force = vec4(g_force, 0.0); }
