#pragma once
/// \file mesh_io.h
/// Reading and writing meshes and polylines in the formats users of muscle models exchange.
///
/// Readers: OFF, OBJ (polygons, negative indices, `\` continuations), STL (ASCII and binary),
/// PLY (ASCII, binary little/big endian; `face` lists and `tristrips`), legacy VTK polydata
/// (ASCII and BINARY; POLYGONS and TRIANGLE_STRIPS; tolerant of the blank header line written
/// by ALBA/NMSBuilder), and the thesis text format (surface triangles; see thesis_format.h).
///
/// Why our own readers and not CGAL::IO: every bad file must give a one-line error naming the
/// file, the line or byte offset and the problem, with a distinct exit code, and a header that
/// declares absurd counts must not allocate. CGAL's readers return only a bool, may return partial
/// data on failure, read PLY triangle strips as zero faces and reject the `OFF8` header
/// (../shared/docs/CGAL-NOTES.md). The test suite checks our readers against CGAL's on every
/// corpus file CGAL reads.
///
/// Writers: OFF, OBJ, PLY (binary little endian, double), STL (binary, float32 by the format's
/// definition), legacy VTK polydata (ASCII). Text coordinates use max_digits10 so a file means
/// exactly what was computed. Every output is written atomically (atomic_file.h).

#include "geometry/mesh.h"

#include <cstdint>
#include <string>

namespace fascicle {

/// Mesh file formats, chosen by extension (case-insensitive).
enum class MeshFormat { off, obj, stl, ply, vtk, thesis };

/// Limits that protect against hostile input. Defaults admit any real scan.
struct ReadOptions {
  /// Largest point or face count a file may declare or contain (default 100 million).
  std::uint64_t max_elements = 100'000'000;
  /// Largest file size read, bytes (default 4 GiB).
  std::uint64_t max_file_bytes = 4ULL << 30;
};

/// Format for a path from its extension: off, obj, stl, ply, vtk, txt (thesis).
/// Throws InputError(unknown_format) naming the file otherwise.
MeshFormat mesh_format_from_path(const std::string& path);

/// Reads a polygon soup from `path` (format by extension).
/// Returns every point and every face as stored; all indices in range, all coordinates finite.
/// STL facets give three points each (no welding); PLY/VTK triangle strips are split into
/// triangles with alternating winding (degenerate ones from repeated indices kept); OBJ negative
/// indices are resolved; extra per-vertex values (colours, normals, texture indices) are ignored.
/// Throws InputError with code file_missing, file_empty (also when the file holds no face),
/// unknown_format, truncated, index_out_of_range, bad_number, too_large or malformed, and a
/// one-line message naming the file and the line (text) or byte offset (binary). A declared
/// count is checked against the file size and options.max_elements before anything is allocated.
PolygonSoup read_polygon_soup(const std::string& path, const ReadOptions& options = {});

/// Reads polylines from `path`: .vtk (legacy polydata LINES; scalar CELL_DATA arrays of the
/// lines become `cell_data`) or .obj (`l` elements; no cell data), the formats write_polylines
/// writes. Throws InputError as read_polygon_soup (file_empty when the file holds no line).
Polylines read_polylines(const std::string& path, const ReadOptions& options = {});

/// Writes a triangle mesh to `path`, format by extension (off, obj, stl, ply, vtk), atomically.
/// Throws IoError (output_failed) or InputError(unknown_format) for an unsupported extension.
void write_triangle_mesh(const std::string& path, const TriangleMesh& mesh);

/// Writes polylines to `path`: .vtk (legacy polydata LINES with the cell data arrays) or
/// .obj (`l` elements), atomically.
void write_polylines(const std::string& path, const Polylines& lines);

}  // namespace fascicle
