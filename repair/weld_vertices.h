#pragma once
/// \file weld_vertices.h
/// Welding duplicate and near-duplicate vertices of a soup (no CGAL).

#include "geometry/mesh.h"

#include <vector>

namespace fascicle {

/// Result of welding: the representative of every input point.
struct WeldResult {
  std::vector<int> representative;  ///< #P: index of the kept point each point merges into
  long merged = 0;                  ///< points merged into another one
};

/// Finds the points closer than `tolerance` (absolute, in the points' units) to another point and
/// maps each to one representative, transitively (union-find over a hash grid of cell size
/// `tolerance`; expected O(#P)). The representative is the lowest index of its group and keeps
/// its position, so the geometry is never averaged. `tolerance` 0 merges exact duplicates only.
WeldResult weld_vertices(const std::vector<Vec3>& points, double tolerance);

}  // namespace fascicle
