#pragma once
// Private to springs/: the solver classes behind make_solver (settle.h).

#include "springs/settle.h"

#include <cmath>
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

/// Nesterov's momentum schedule b_k = k / (k + 3) with adaptive restart (O'Donoghue and Candes
/// 2015): the solver reports at the start of each step whether the last one went wrong (moved
/// against the force, or raised the energy); the schedule then starts again from b = 0 and the
/// solver drops its velocity. One schedule serves every momentum solver, CPU and GPU.
class MomentumSchedule {
 public:
  /// True when the solver must drop its velocity now: `last_step_bad` after at least one step
  /// with momentum since the last restart.
  bool restart(bool last_step_bad) {
    if (k_ == 0 || !last_step_bad) return false;
    k_ = 0;
    return true;
  }
  /// This step's momentum coefficient b_k; advances k.
  double next() {
    const double b = static_cast<double>(k_) / (k_ + 3.0);
    ++k_;
    return b;
  }
 private:
  int k_ = 0;
};

/// The divergence test every settle loop applies: NaN/Inf, or an energy above
/// SettleOptions::energy_growth_bound x the initial one, checked every energy_interval iterations.
class DivergenceWatch {
 public:
  DivergenceWatch() = default;
  /// `initial_energy` is raised to energy_floor(system), so growth from rest is not divergence.
  DivergenceWatch(const SpringSystem& system, const SettleOptions& options, double initial_energy);
  /// True when the energy should be measured after `iteration` steps.
  bool due(int iteration) const { return interval_ > 0 && iteration % interval_ == 0; }
  bool diverged(double energy) const { return !std::isfinite(energy) || energy > bound_ * initial_; }
  double initial_energy() const { return initial_; }
  /// Verlet and momentum solvers: throws SolverError (throw_verlet_divergence) when `energy`
  /// diverged after `iteration` steps.
  void check(int iteration, double energy, const VerletCoefficients& coefficients, const SettleOptions& options) const;
  /// The same for a step whose squared force came out NaN/Inf (`force2`).
  void check_force(int iteration, double force2, const VerletCoefficients& coefficients,
                   const SettleOptions& options) const;

 private:
  double initial_ = 0.0, bound_ = 0.0;
  int interval_ = 0;
};

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
