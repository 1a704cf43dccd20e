#pragma once
/// \file read_points.h
/// Landmark point files, in the frame and unit of the mesh they belong to:
/// - rows of three numbers, separated by blanks, commas or semicolons (the origin/insertion files
///   under ../shared/data/muscles/lhdl/); `#` starts a comment, blank lines are ignored;
/// - CSV with a header row naming the columns: x, y and z (any case, quoted or not), or
///   ParaView's Points:0, Points:1, Points:2; other columns are ignored;
/// - 3D Slicer's markups: .fcsv (its "# columns = id,x,y,z,..." comment names the columns) and
///   .mrk.json (every control point's "position" of every markup). Coordinates are read as
///   written: Slicer writes LPS by default, as it writes its models.

#include "geometry/mesh.h"
#include "geometry/mesh_io.h"

#include <string>
#include <vector>

namespace fascicle {

/// Reads landmark points (#points, file units, usually mm). Without a header, a row holding other
/// than three numbers (before an optional comment) is malformed. Throws InputError (file_missing,
/// file_empty when no point is given, bad_number, malformed, too_large when there are more than
/// options.max_elements points or the file exceeds options.max_file_bytes) naming the file and line.
std::vector<Vec3> read_points(const std::string& path, const ReadOptions& options = {});

}  // namespace fascicle
