#pragma once
/// \file shader_sources.h
/// The GLSL files of shaders/ (*.comp, *.vert, *.geom, *.frag), embedded into the library at
/// build time by embed_shaders.cmake, so the program needs no shader files at run time.

#include <string>
#include <vector>

namespace fascicle::shaders {

/// Source text of the embedded GLSL file `name` (file name only, e.g. "verlet_lattice.comp"),
/// or nullptr when there is no such file.
const char* embedded_shader(const std::string& name);

/// Names of all embedded GLSL files, in build order.
std::vector<std::string> embedded_shader_names();

}  // namespace fascicle::shaders
