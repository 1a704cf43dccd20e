#pragma once
/// \file mesh.h
/// The plain data that crosses module boundaries: polygon soups as read from files,
/// triangle meshes, polylines. No CGAL types here; the repair module converts internally.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <string>
#include <utility>
#include <vector>

namespace fascicle {

/// A point or vector in 3-D, in the input file's units (usually millimetres).
using Vec3 = Eigen::Vector3d;

/// Three vertex indices of a triangle, counter-clockwise when seen from outside.
using Triangle = std::array<int, 3>;

/// A polygon soup exactly as a file stored it.
/// - `points`: #P positions, file units. Every coordinate is finite (readers reject NaN/Inf).
/// - `polygons`: index lists into `points`, each of any length as stored (a face with fewer
///   than three indices, or with repeated indices, is kept: the repair stage counts and drops it).
///   Every index is in [0, #P) (readers reject others).
struct PolygonSoup {
  std::vector<Vec3> points;
  std::vector<std::vector<int>> polygons;
};

/// A triangle mesh: #V positions and #F triangles indexing them.
/// Convention: triangles are counter-clockwise seen from outside (outward normals), so a closed
/// mesh has positive signed volume.
struct TriangleMesh {
  std::vector<Vec3> positions;
  std::vector<Triangle> triangles;
};

/// Four vertex indices of a tetrahedron, positively oriented: (b - a) x (c - a) . (d - a) > 0.
using Tetrahedron = std::array<int, 4>;

/// A tetrahedral mesh of a closed surface's volume: #V positions (the surface's units), #T
/// positively oriented tetrahedra, and #V flags, 1 for the vertices that lie on the surface.
struct TetMesh {
  std::vector<Vec3> positions;
  std::vector<Tetrahedron> tets;
  std::vector<char> boundary;
};

/// A named per-line (cell) data array attached to a set of polylines, one value per line.
struct CellArray {
  std::string name;
  std::vector<double> values;
};

/// A set of polylines (for example muscle fibres), each an ordered list of points.
struct Polylines {
  std::vector<std::vector<Vec3>> lines;
  std::vector<CellArray> cell_data;  ///< each array holds lines.size() values
};

/// Converts a triangle mesh to a soup (same points, one polygon per triangle).
PolygonSoup to_soup(const TriangleMesh& mesh);

}  // namespace fascicle
