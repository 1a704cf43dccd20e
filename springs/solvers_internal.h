#pragma once
// Private to springs/: the solver classes behind make_solver (settle.h).

#include "springs/settle.h"

#include <memory>

namespace fascicle::springs::detail {

/// Per-point Verlet coefficients shared by both data paths.
struct VerletCoefficients {
  double dt = 0.0;
  std::vector<double> a;  ///< dt^2 / m_i
  std::vector<double> b;  ///< 1 - c_i dt / m_i
  std::vector<double> mass;
  double mean_damping = 0.0;
  double min_mass = 0.0, max_point_stiffness = 0.0;  ///< for error messages
};

/// The springs in compressed rows: the springs of point p are slots row[p] .. row[p+1]-1, each
/// holding the other end, the stiffness and the rest length (every spring appears at both ends).
struct SpringRows {
  std::vector<int> row;        ///< #points + 1 offsets
  std::vector<int> neighbour;  ///< 2 #springs
  std::vector<double> stiffness, rest;
};

/// Builds the compressed rows of `system` (used by the general Verlet, Newton and GPU paths).
SpringRows spring_rows(const SpringSystem& system);

/// Throws SolverError when a free point lies in a part of the spring graph without a fixed
/// point (its static equilibrium is not unique). Used by the static solvers.
void check_anchored(const SpringSystem& system);

/// Masses, damping and time step from the options (see SettleOptions).
VerletCoefficients verlet_coefficients(const SpringSystem& system, const SettleOptions& options);

/// Coefficients of the momentum (accelerated gradient) static solver: unit masses, step
/// a = 1 / L, the same for every point, with L = min(Gershgorin bound 2 max_i sum_j k_ij,
/// 1.25 x largest_stiffness_eigenvalue); b is set each step by the solver.
VerletCoefficients momentum_coefficients(const SpringSystem& system);

/// Estimate (a lower bound, within a few per cent) of the largest eigenvalue of the spring
/// energy's Hessian over the free points at the current positions, compressed springs counted
/// without sideways stiffness: at most `steps` Lanczos steps from a fixed pseudo-random start
/// (stiffness_bound.cpp). 0 when nothing is free.
double largest_stiffness_eigenvalue(const SpringSystem& system, int steps);

/// Throws SolverError for a Verlet run that produced NaN/Inf or too much energy.
[[noreturn]] void throw_verlet_divergence(int iteration, double energy, double initial_energy,
                                          const VerletCoefficients& coefficients, const SettleOptions& options);

/// An energy below which growth is not divergence: 1e-20 of the energy of every spring
/// stretched by its rest length (or 1e-300 when that is 0).
double energy_floor(const SpringSystem& system);

/// The momentum static solver on the structured path, started from the settled coarse lattice
/// (coarse_start.h); nullptr when the lattice does not qualify (too small, coarse start off, not a
/// structured lattice).
std::unique_ptr<SpringSolver> make_coarse_started_momentum(const SpringSystem& system, const SettleOptions& options,
                                                           const LatticeShape& shape);

/// Verlet solvers; with `momentum` the same kernels run the momentum static solver.
std::unique_ptr<SpringSolver> make_general_verlet(const SpringSystem& system, const SettleOptions& options,
                                                  bool momentum = false);
/// Whether general solvers built from now on may evaluate each spring once when the system fits
/// one block of points (default true; tests switch it off to check the per-point gather against
/// it bit for bit).
void set_general_spring_once(bool enabled);
/// Returns null when `system` is not exactly the lattice `shape` with stiffness 1 / rest.
std::unique_ptr<SpringSolver> make_structured_verlet(const SpringSystem& system, const SettleOptions& options,
                                                     const LatticeShape& shape, bool momentum = false);
/// Whether structured solvers built from now on may use a vector spring loop (default true; tests
/// switch it off to check the portable loop against it): the AVX-512 one where the processor has
/// AVX-512, else the AVX2 one where it has AVX2 and FMA (springs/fused_row.h).
void set_structured_simd(bool enabled);
/// Whether that vector loop may be the AVX-512 one (default true; tests switch it off so that the
/// AVX2 loop runs on processors with AVX-512 too).
void set_structured_avx512(bool enabled);
/// True when a structured solver built now would use a vector spring loop.
bool structured_simd_active();
/// The spring loop a structured solver built now would use: "avx512", "avx2" or "plain".
const char* structured_simd_name();

std::unique_ptr<SpringSolver> make_newton_solver(const SpringSystem& system, const SettleOptions& options);
/// The multigrid static method: accelerated gradient preconditioned by a multigrid V-cycle on
/// the spring Laplacian (multigrid_solver.cpp). `shape` must satisfy multigrid_fits.
std::unique_ptr<SpringSolver> make_multigrid_solver(const SpringSystem& system, const SettleOptions& options,
                                                    const LatticeShape& shape);
/// True when `shape` describes `system` as a grid the multigrid solver can use: nx ny nz ==
/// #points, each >= 2, and every spring joins grid neighbours.
bool multigrid_fits(const SpringSystem& system, const LatticeShape* shape);
/// The local-global static method; `factor` null: factorized here (factor_spring_matrix).
std::unique_ptr<SpringSolver> make_static_solver(const SpringSystem& system, const SettleOptions& options,
                                                 std::shared_ptr<const SpringMatrixFactor> factor = nullptr);

}  // namespace fascicle::springs::detail
