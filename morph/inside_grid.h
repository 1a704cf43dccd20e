#pragma once
/// \file inside_grid.h
/// Fast exact inside tests on a closed surface: a uniform grid over the surface's box, classified
/// once. Cells whose closed box meets no triangle's (padded) box form regions that do not touch
/// the surface, so each face-connected region lies on one side, found with one exact test at a
/// cell centre. A point in such a cell needs no further test; a point in a cell near the surface
/// goes to the exact test given to the constructor. The answers are those of the exact test.

#include "geometry/mesh.h"
#include "geometry/mesh_stats.h"
#include "morph/surface_query.h"

#include <array>
#include <functional>
#include <vector>

namespace fascicle {

/// Integer cell coordinates of a uniform grid over a box.
struct UniformGrid {
  Vec3 origin = Vec3::Zero();
  double h = 1.0;
  std::array<int, 3> n{1, 1, 1};

  /// A grid over `box` (padded by `pad` on every side) with about `target` cubic cells, at most
  /// 4096 per axis.
  static UniformGrid over(const BoundingBox& box, double pad, double target);
  long cells() const { return static_cast<long>(n[0]) * n[1] * n[2]; }
  /// Cell coordinate of x along `axis`, clamped to [-1, n[axis]].
  int coordinate(double x, int axis) const;
  long index(int i, int j, int k) const { return i + static_cast<long>(n[0]) * (j + static_cast<long>(n[1]) * k); }
  Vec3 centre(int i, int j, int k) const { return origin + h * Vec3(i + 0.5, j + 0.5, k + 0.5); }
};

/// Side of points with respect to a closed surface: grid classification, exact test near the
/// surface.
class InsideGrid {
 public:
  /// Exact side of a point (e.g. CGAL's Side_of_triangle_mesh through SurfaceQuery).
  using ExactSide = std::function<Side(const Vec3&)>;
  /// Classifies a grid of about 64^3 cells over `mesh` (closed, #V positions, any units; a few
  /// milliseconds: finer grids cost more to classify than they save in exact tests, measured on
  /// 8k- and 54k-triangle muscles), one call of `exact` per free region. `exact` must outlive
  /// the grid.
  InsideGrid(const TriangleMesh& mesh, ExactSide exact);

  /// Side of p, the same as exact(p) (thread-safe once constructed when `exact` is).
  Side side(const Vec3& p) const;

  const BoundingBox& bounds() const { return bounds_; }
  /// Cells that may hold points inside the muscle (classified inside, or near the surface);
  /// their union contains the muscle.
  std::vector<long> candidate_cells() const;
  /// Lowest corner of a cell, and the cell size.
  Vec3 cell_corner(long c) const;
  double cell_size() const { return grid_.h; }

 private:
  static constexpr char kFree = 0, kNear = 1, kInside = 2, kOutside = 3;
  ExactSide exact_;
  UniformGrid grid_;
  BoundingBox bounds_;
  std::vector<char> state_;
  int regions_ = 0;
};

}  // namespace fascicle
