#pragma once
/// \file thesis_format.h
/// The text format of the 2011 thesis's test application (Zeleny 2011, appendix 2; digest in
/// ../shared/docs/METHOD.md): points marked surface ('m') or inner ('i'), surface triangles,
/// springs with stiffness, fibres, origin and insertion area point indices.
///
///     N O            number of points, number of surface points
///     x y z m|i      N lines
///     T              number of surface triangles
///     i1 i2 i3       T lines
///     S              number of springs
///     i1 i2 k        S lines: end points and stiffness
///     F              number of fibres
///     i1 i2          F lines
///     OA             number of origin-area points, then OA lines of one index
///     IA             number of insertion-area points, then IA lines of one index

#include "geometry/mesh.h"
#include "geometry/mesh_io.h"

#include <array>
#include <string>
#include <vector>

namespace fascicle {

/// A spring system in the thesis format. All indices are 0-based into `points`.
struct ThesisModel {
  struct Spring {
    int a = 0, b = 0;
    double stiffness = 1.0;  ///< Hooke constant D_ij, force units per length unit
  };
  std::vector<Vec3> points;                ///< N positions
  std::vector<char> surface;               ///< N flags: 1 for 'm' (surface, fixed), 0 for 'i'
  std::vector<Triangle> triangles;         ///< T surface triangles
  std::vector<Spring> springs;             ///< S springs
  std::vector<std::array<int, 2>> fibres;  ///< F fibres, each from one point index to another
  std::vector<int> origin;                 ///< origin-area point indices
  std::vector<int> insertion;              ///< insertion-area point indices
};

/// Reads a thesis-format file. Indices in the file are 0-based; every section (counts included)
/// is required, one record per line; '#' starts a comment. The declared surface-point count O
/// must equal the number of 'm' lines. Throws InputError (codes as read_polygon_soup: truncated
/// when a section is missing or short, index_out_of_range, bad_number, too_large, malformed)
/// naming the file and line.
ThesisModel read_thesis_model(const std::string& path, const ReadOptions& options = {});

/// Writes a thesis-format file atomically, coordinates and stiffnesses with max_digits10, the
/// surface count O computed from `surface`. Throws IoError when the file cannot be written,
/// Error(internal) when `surface` does not hold one flag per point, an index is out of range
/// or a value is not finite.
void write_thesis_model(const std::string& path, const ThesisModel& model);

}  // namespace fascicle
