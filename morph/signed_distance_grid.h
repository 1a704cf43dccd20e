#pragma once
/// \file signed_distance_grid.h
/// A signed distance to a closed surface, sampled on a regular grid and interpolated
/// trilinearly: a cheap, continuous field (with its gradient, piecewise smooth) for energies that
/// are evaluated many times at points that move little (the containment of the untangling,
/// fibres/untangle.h).
///
/// The grid is filled lazily: a node's value is computed on first use, from the closest surface
/// point (its distance) and the exact inside test (its sign), both SurfaceQuery's; the values do
/// not depend on the order of the queries, so the field is the same whatever touched it first.
/// Where a point lies outside the grid's box the exact signed distance is returned (gradient:
/// along the direction from the closest point). Not thread-safe (the cache).

#include "geometry/mesh.h"
#include "morph/surface_query.h"

#include <vector>

namespace fascicle {

class SignedDistanceGrid {
 public:
  /// The grid covers the box [low, high] (mesh units) with cubic cells of edge `cell` (> 0);
  /// when that would take more than `max_nodes` nodes the cell grows until it does not.
  /// `query` must outlive the grid. Throws InputError(internal) for an empty box or a cell <= 0.
  SignedDistanceGrid(const SurfaceQuery& query, const Vec3& low, const Vec3& high, double cell,
                     long max_nodes = 8'000'000);

  /// Signed distance at p (mesh units; negative inside, positive outside): the trilinear
  /// interpolation of the node values, its gradient into `gradient` when not null.
  double operator()(const Vec3& p, Vec3* gradient = nullptr);

  /// Exact signed distance at p: closest-point distance, negative when p is inside.
  double exact(const Vec3& p) const;

  double cell() const { return cell_; }
  long nodes_computed() const { return computed_; }  ///< node values filled so far

 private:
  double node(int i, int j, int k);
  const SurfaceQuery& query_;
  Vec3 low_;
  double cell_ = 1.0;
  int n_[3] = {0, 0, 0};
  std::vector<double> values_;  // NaN: not computed yet
  long computed_ = 0;
};

}  // namespace fascicle
