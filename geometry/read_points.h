#pragma once
/// \file read_points.h
/// Landmark point files: one `x y z` per line, `#` starts a comment, blank lines ignored
/// (the origin/insertion files under ../shared/data/muscles/lhdl/).

#include "geometry/mesh.h"
#include "geometry/mesh_io.h"

#include <string>
#include <vector>

namespace fascicle {

/// Reads landmark points. Throws InputError (file_missing, file_empty when no point is given,
/// bad_number, malformed, too_large) naming the file and line.
std::vector<Vec3> read_points(const std::string& path, const ReadOptions& options = {});

}  // namespace fascicle
