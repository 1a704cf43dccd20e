#pragma once
/// \file inside_grid.h
/// A uniform grid over a closed surface's box that answers most inside tests without one: cells
/// whose closed box meets no triangle's (padded) box form regions that do not touch the surface,
/// so each face-connected region lies on one side, found once by an exact test at a cell centre.
/// A point in such a cell has that side; a point in a cell near the surface gets no answer here
/// and goes to the exact test (SurfaceQuery::side). Plain data, no CGAL.

#include "geometry/mesh.h"
#include "geometry/mesh_stats.h"

#include <array>
#include <functional>
#include <vector>

namespace fascicle {

/// Integer cell coordinates of a uniform grid of cubic cells over a box.
struct UniformGrid {
  Vec3 origin = Vec3::Zero();
  double h = 1.0;  ///< cell edge, mesh units
  std::array<int, 3> n{1, 1, 1};

  /// A grid over `box` padded by `pad` on every side, with about `target` cells (at most 4096 a
  /// side; a flat or needle-thin box gets fewer, longer cells that still cover it).
  static UniformGrid over(const BoundingBox& box, double pad, double target);
  long cells() const { return static_cast<long>(n[0]) * n[1] * n[2]; }
  /// Cell coordinate of x along `axis`, clamped to [-1, n[axis]].
  int coordinate(double x, int axis) const;
  long index(int i, int j, int k) const { return i + static_cast<long>(n[0]) * (j + static_cast<long>(n[1]) * k); }
  Vec3 centre(int i, int j, int k) const { return origin + h * Vec3(i + 0.5, j + 0.5, k + 0.5); }
};

/// The classified grid of one closed triangle mesh (immutable once built; thread-safe reads).
class InsideGrid {
 public:
  /// What the grid knows of a point.
  enum class Known { inside, outside, unknown };

  /// Classifies about `target_cells` cells over the mesh's box (padded by 1 % of its diagonal);
  /// `exact` is the exact side test, called once per free region.
  InsideGrid(const TriangleMesh& mesh, const std::function<bool(const Vec3&)>& exact_inside,
             double target_cells = 64.0 * 64.0 * 64.0);

  /// Inside or outside where the grid is sure (outside the mesh's box, or in a cell that does not
  /// touch the surface), else unknown.
  Known classify(const Vec3& p) const;

  /// Cells that may hold points inside the mesh (inside, or near the surface): their union
  /// contains the mesh's interior.
  std::vector<long> candidate_cells() const;
  /// Lowest corner of cell `c` (an index of UniformGrid::index).
  Vec3 cell_corner(long c) const;
  double cell_size() const { return grid_.h; }
  /// Face-connected regions of cells away from the surface (one exact test each).
  int regions() const { return regions_; }

 private:
  static constexpr char kFree = 0, kNear = 1, kInside = 2, kOutside = 3;
  UniformGrid grid_;
  BoundingBox bounds_;
  std::vector<char> state_;
  int regions_ = 0;
};

}  // namespace fascicle
