#pragma once
/// \file read_points.h
/// Landmark point files: one `x y z` per line, `#` starts a comment, blank lines ignored
/// (the origin/insertion files under ../shared/data/muscles/lhdl/).

#include "geometry/mesh.h"
#include "geometry/mesh_io.h"

#include <string>
#include <vector>

namespace fascicle {

/// Reads landmark points (#points, file units, usually mm). A line holding other than three
/// numbers (before an optional comment) is malformed. Throws InputError (file_missing,
/// file_empty when no point is given, bad_number, malformed, too_large when there are more than
/// options.max_elements points or the file exceeds options.max_file_bytes) naming the file and line.
std::vector<Vec3> read_points(const std::string& path, const ReadOptions& options = {});

}  // namespace fascicle
