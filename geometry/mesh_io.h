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
/// definition), legacy VTK polydata (ASCII); polylines also as VTK XML PolyData (.vtp) and CSV. Text coordinates use max_digits10 so a file means
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

  /// Throws OptionError naming the field when a limit is 0 (nothing could be read).
  void validate() const;
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
/// count is checked before anything is allocated: too_large when it exceeds
/// options.max_elements or cannot fit in the whole file even at the smallest size of one
/// element; truncated when the file then ends before the declared data.
/// OBJ: an index must refer to a vertex defined above the face (as the format requires).
PolygonSoup read_polygon_soup(const std::string& path, const ReadOptions& options = {});

/// Whether `ext` (lower case, no dot) is a polyline format read_polylines / write_polylines take:
/// vtk, vtp, vtu, obj, csv.
bool is_polyline_extension(const std::string& ext);

/// Reads polylines from `path`, the formats write_polylines writes:
/// - .vtk: legacy polydata LINES; one-component CELL_DATA arrays of the lines (SCALARS blocks
///   and the arrays of FIELD blocks) become `cell_data`;
/// - .vtp: VTK XML PolyData with format="ascii" DataArrays: one <Piece>, <Points> (3 components,
///   any float or integer type), <Lines> `connectivity` + `offsets`, and the one-component
///   <CellData> arrays (their lines' slice) as `cell_data`; binary or appended arrays are
///   refused (unknown_format), other arrays skipped;
/// - .vtu: VTK XML UnstructuredGrid, the same with NumberOfCells and <Cells> `connectivity`,
///   `offsets` and `types`, every cell a line (3) or poly-line (4); with a cell array `fibre`,
///   consecutive cells of the same `fibre` value are joined into one polyline (the layout
///   write_polylines writes) and the other arrays keep their first cell's value;
/// - .obj: `l` elements; no cell data;
/// - .csv: header exactly `fibre,r,s,point,x,y,z`, then one row per point (fibre and point
///   non-negative integers, the rest numbers); rows are grouped by `fibre` (lines in increasing
///   fibre number, gaps allowed), each line's points ordered by `point` (gaps allowed, a repeated
///   point is an error); r and s come back as the cell arrays `fibre_r` and `fibre_s` (they must
///   be the same on every row of a fibre).
/// Throws InputError as read_polygon_soup (file_empty when the file holds no line), with the
/// line number for text errors.
Polylines read_polylines(const std::string& path, const ReadOptions& options = {});

/// Writes a triangle mesh to `path`, format by extension (off, obj, stl, ply, vtk), atomically.
/// - .off / .obj / .vtk (legacy ASCII POLYDATA, POINTS double + POLYGONS): text, coordinates with
///   max_digits10, so reading back gives the same doubles;
/// - .ply: binary_little_endian, `double x y z`, `list uchar int vertex_indices` (exact);
/// - .stl: binary, float32 coordinates and unit facet normals, an 80-byte header that does not
///   start with "solid".
/// Throws InputError(unknown_format) for an unsupported extension before anything is written,
/// IoError (output_failed) when the file cannot be written, Error(internal) when a triangle
/// index is out of range or a position is not finite.
void write_triangle_mesh(const std::string& path, const TriangleMesh& mesh);

/// Writes a tetrahedral mesh to `path` as VTK XML UnstructuredGrid (.vtu, ASCII): Float64 points
/// (max_digits10), tetra cells (VTK type 10), and the per-cell 3-vector array `name` holding
/// `cell_vectors` (#T) when it is not empty; readable by VTK and meshio. Throws
/// InputError(unknown_format) for another extension, IoError when it cannot be written,
/// Error(internal) when an array does not hold one vector per tetrahedron or a value is not finite.
void write_tetrahedra(const std::string& path, const TetMesh& mesh, const std::string& name = {},
                      const std::vector<Vec3>& cell_vectors = {});

/// Writes polylines to `path`, atomically, all coordinates with max_digits10 (exact round trip):
/// - .vtk: legacy ASCII POLYDATA: POINTS double, LINES, and CELL_DATA with one FIELD block
///   holding every cell_data entry as a one-component array (blanks in names become '_'), so
///   that VTK's default readers (vtkPolyDataReader, vtkDataSetReader) load all of them;
/// - .vtp: VTK XML PolyData, ASCII: Float64 Points, Int64 `connectivity`/`offsets` Lines, one
///   CellData array per cell_data entry;
/// - .vtu: VTK XML UnstructuredGrid, ASCII: the same points, one line cell (VTK type 3) per
///   segment, with the cell array `fibre` (the line's number) and every cell_data entry per
///   segment: meshio reads line cells (not poly-lines), VTK either;
/// - every cell array whose values are all integers is written as integers (int, Int32), others
///   as doubles;
/// - .obj: `v` and `l` elements; cell data is not written;
/// - .csv: header `fibre,r,s,point,x,y,z`, one row per point, fibres in order, points from the
///   first (origin) to the last; r and s are the fibre's `fibre_r` / `fibre_s` values when both
///   arrays exist, else r = the fibre's index and s = 0; other cell arrays are not written. Throws InputError(unknown_format) for another extension before anything is
/// written, IoError when the file cannot be written, Error(internal) when a cell array does not
/// hold one value per line or a value is not finite.
void write_polylines(const std::string& path, const Polylines& lines);

}  // namespace fascicle
