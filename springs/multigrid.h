#pragma once
/// \file multigrid.h
/// Geometric multigrid for the stiffness-weighted graph Laplacian of a spring system laid out
/// on a regular nx x ny x nz index grid (a lattice from lattice.h, point (i, j, k) at index
/// i + nx (j + ny k)): L = sum over springs of D_s A_s A_s^T over the free points, fixed points as
/// Dirichlet conditions (their unknowns are zero). This is the constant matrix of the
/// local-global method (Liu et al. 2013) and the preconditioner of the `multigrid` static
/// method (settle.h).
///
/// Hierarchy: each grid dimension longer than 3 points is coarsened from n to n / 2 + 1 points
/// (coarse point I sits on fine point min(2 I, n - 1)); interpolation P is trilinear in the index
/// (weights 1 and 1/2 per dimension), with zero rows at fixed fine points; restriction is P^T;
/// the coarse operators are Galerkin products P^T L P (a 27-point stencil on every coarse level,
/// whatever the fine stencil: model-6, model-26 or any spring list on the grid, any per-spring
/// stiffness). The coarsest level (at most `coarsest_points` points, or every dimension at most 3)
/// is solved by a sparse Cholesky factorization (Eigen SimplicialLDLT). Smoother: `smoothing_steps`
/// steps of a Chebyshev polynomial in T^-1 A on the interval [rho / 5, rho] x 1.1 (rho: a
/// power-iteration estimate of the spectral radius of T^-1 A on that level), where T is the
/// tridiagonal part of A along the grid axis of its strongest couplings, factored line by line
/// (line smoothing; MultigridOptions::line_smoothing false: T = the diagonal). The same
/// polynomial before and after the coarse correction, so one V-cycle from a zero start is a
/// symmetric positive definite operator (usable as a conjugate-gradient preconditioner). Every
/// pass over a level is a TBB parallel loop over fixed blocks of rows or lines; results do not
/// depend on the thread count. Measured V-cycle residual factors on the bench lattices:
/// 0.11-0.14 (model-6) and 0.07 (model-26) at 17^3 and 33^3 (tests/springs_solver_test.cpp
/// checks < 0.3 at 9^3, 17^3, 33^3).
///
/// Vectors hold 3 values per point (x, y, z interleaved, #N * 3): the Laplacian is the same
/// for the three coordinates.

#include "springs/settle.h"
#include "springs/spring_system.h"

#include <array>
#include <memory>
#include <vector>

namespace fascicle::springs {

/// Options of the multigrid hierarchy.
struct MultigridOptions {
  int smoothing_steps = 2;     ///< smoothing steps (Chebyshev degree) before and after each coarse
                               ///< correction, 1..20 (default 2)
  int coarsest_points = 4096;  ///< a level with at most this many points is solved directly,
                               ///< 8..200000 (default 4096)
  bool line_smoothing = true;  ///< smooth each coordinate line by line along the grid axis of
                               ///< its strongest couplings (tridiagonal solves: robust when
                               ///< springs resist one direction much more than the others);
                               ///< false: point smoothing (default true)
  /// Throws OptionError naming the bad field and value.
  void validate() const;
};

/// The multigrid hierarchy of one spring system (built once; cycles reuse its buffers, so one
/// object must not run two cycles at once).
class LatticeMultigrid {
 public:
  /// Builds the levels for the Laplacian of `system`'s springs. `shape` must describe
  /// `system` (nx ny nz == #points, each >= 2) and every spring must join grid neighbours:
  /// else OptionError. `weights`, when given (#springs, each > 0), replaces the stiffness of
  /// spring s by weights[s][c] in the operator of coordinate c (three Laplacians on one
  /// sparsity pattern, e.g. the diagonal of each spring's Hessian block).
  LatticeMultigrid(const SpringSystem& system, const LatticeShape& shape, const MultigridOptions& options = {},
                   const std::vector<std::array<double, 3>>* weights = nullptr);
  ~LatticeMultigrid();
  LatticeMultigrid(const LatticeMultigrid&) = delete;
  LatticeMultigrid& operator=(const LatticeMultigrid&) = delete;

  /// x = one V-cycle applied to b from a zero start (an approximation of L^-1 b); b and x have
  /// #N * 3 entries; entries of fixed points in x are 0 (those of b are ignored). Returns b . x
  /// over the free points.
  double precondition(const std::vector<double>& b, std::vector<double>& x);
  /// One V-cycle on L x = b improving x in place (any start; fixed entries set to 0).
  void cycle(const std::vector<double>& b, std::vector<double>& x);
  /// r = b - L x over the free points (0 at fixed points); returns |r| (Euclidean).
  double residual(const std::vector<double>& b, const std::vector<double>& x, std::vector<double>& r);
  /// Number of levels (1 = the fine grid is solved directly).
  int levels() const;
  /// Points of each level, finest first (for reports and tests).
  std::vector<int> level_points() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fascicle::springs
