#pragma once
/// \file settle.h
/// Settling a mass-spring system: the interior points move until the spring forces on every free
/// point balance (Zeleny 2011, ch. 6.2.3). Two solvers behind one interface:
///
/// - `verlet`: the thesis's damped Verlet integration (formula 3.8)
///       x(t+dt) = F_tot / m dt^2 + 2 x(t) - x(t-dt),
///       F_tot = F_springs - c (x(t) - x(t-dt)) / dt,
///   forces computed from the current positions only, so the result does not depend on
///   traversal order. Fixed points are written to both current and previous positions.
/// - `static`: the equilibrium directly (fixed points given, zero net force elsewhere). Method
///   `momentum` (default): accelerated gradient descent on the spring energy run by the Verlet
///   kernels (unit masses, step 1 / L with L = 1.25 x a Lanczos estimate of the stiffness's largest
///   eigenvalue, capped by its Gershgorin bound; Nesterov's
///   momentum k / (k + 3), restarted whenever the velocity opposes the force: O'Donoghue and
///   Candes 2015, "Adaptive restart for accelerated gradient schemes"). On a lattice of more
///   than coarse_start_points points it starts from the settled lattice of every other point,
///   interpolated (coarse_start.h; recursively). Method `newton`:
///   truncated Newton with matrix-free block-Jacobi preconditioned conjugate gradients and an
///   Armijo line search (see newton_solver.cpp). Method `local-global`: the
///   local-global iteration of Liu, Bargteil, O'Brien
///   and Kavan 2013, "Fast simulation of mass-spring systems" (ACM TOG 32(6)): the constant
///   matrix L = sum_s D_s A_s A_s^T over free points is factored once (Eigen SimplicialLDLT);
///   each iteration projects every spring onto its rest length (local step) and back-substitutes
///   (global step). Optionally Anderson-accelerated with an energy safeguard (Peng, Deng, Zhang
///   and Liu 2018, "Anderson acceleration for geometry optimization and physics simulation").
///   With zero rest lengths the first iteration is the exact answer. Method `multigrid`
///   (lattices: a LatticeShape whose grid holds every spring between neighbours): the free
///   points start at the harmonic interpolation of the fixed points, then accelerated gradient
///   steps preconditioned by one geometric-multigrid V-cycle on the spring Laplacian
///   (multigrid.h, multigrid_solver.cpp); its iteration count does not grow with the lattice for
///   model-26 lattices, it does for model-6 (springs near their rest length resist sideways
///   motion little), measured by `fascicle bench springs` (docs/BENCHMARKS.md). Other spring
///   systems run the momentum method instead (report backend "momentum-...").
///
/// Verlet runs on one of two data paths that agree to rounding: `structured` (a lattice from
/// lattice.h: struct of arrays, implicit neighbour offsets, per-direction stiffness arrays,
/// TBB-parallel rows, inner loops the compiler vectorises; requires stiffness = 1 / rest length)
/// and `general` (any spring list, compressed rows).
///
/// Stopping: relative residual = largest spring force at a free point / residual_force_scale()
/// (spring_system.h) <= tolerance. Divergence (NaN, Inf, energy above a bound) throws SolverError
/// naming the likely cause and the option to change; no NaN is ever returned.

#include "springs/lattice.h"
#include "springs/spring_system.h"

#include <memory>
#include <string>
#include <vector>

namespace fascicle::springs {

/// Which solver.
enum class SolverKind { verlet, static_equilibrium };
/// Which data path the Verlet solver runs on.
enum class Backend { automatic, structured, general };
/// How the Verlet damping coefficient c is chosen.
enum class DampingMode {
  estimate,  ///< the thesis's estimate, formula 7.2, c = sqrt(4 k6 2 m), k6 = 2 + 4 L
  critical,  ///< per point c_i = sqrt(4 k_i m_i), k_i the mean stiffness of its springs (3.5)
  value,     ///< the value in SettleOptions::damping for every point
};
/// How the static solver finds the equilibrium.
enum class StaticMethod {
  momentum,      ///< accelerated gradient on the Verlet kernels: Nesterov's momentum schedule with
                 ///< gradient restarts (O'Donoghue and Candes 2015), unit masses, step 1 / L
  newton,        ///< truncated Newton, matrix-free preconditioned CG, line search (newton_solver.cpp)
  local_global,  ///< Liu et al. 2013: prefactored sparse Cholesky, one back-substitution per iteration
  multigrid,     ///< Newton-CG preconditioned by a geometric multigrid V-cycle on the spring
                 ///< Laplacian (multigrid.h); lattices only: without a fitting LatticeShape it
                 ///< runs the momentum method (report backend "momentum-...")
};
/// Acceleration of the local-global method.
enum class Acceleration { none, anderson };

/// Parse helpers for the command line. Each throws OptionError naming the option and value.
SolverKind parse_solver_kind(const std::string& name);      ///< "verlet" | "static"
StaticMethod parse_static_method(const std::string& name);  ///< "momentum" | "newton" | "local-global" | "multigrid"
Backend parse_backend(const std::string& name);             ///< "auto" | "structured" | "general"
const char* solver_name(SolverKind kind);
const char* backend_name(Backend backend);

/// Options of a settle. The command line maps its flags one-to-one onto these fields.
struct SettleOptions {
  SolverKind solver = SolverKind::verlet;  ///< solver (default verlet, the thesis's)
  double tolerance = 1e-6;                 ///< stop at this relative residual; 0 runs max_iterations (default 1e-6)
  int max_iterations = 100000;             ///< iteration cap, >= 1 (default 100000)
  Backend backend = Backend::automatic;    ///< Verlet data path; automatic = structured when a fitting
                                           ///< lattice shape is given (default automatic)
  /// Structured path: the portable spring loop, bit-identical on any x86-64 processor and thread
  /// count (true), or the fastest one the processor has, AVX-512/AVX2 (false) (default false).
  bool portable_loop = false;
  // Verlet
  double mass = 0.0;  ///< point mass override, > 0; 0 keeps the system's masses (default 0)
  DampingMode damping_mode = DampingMode::estimate;  ///< (default estimate, formula 7.2)
  double damping = 0.0;                ///< c for DampingMode::value, >= 0, force time per length (default 0)
  double dt = 0.0;                     ///< time step, > 0; 0 = automatic: 0.9 of the largest stable step of the
                                       ///< damped scheme under a Gershgorin bound of the stiffness (default 0)
  int energy_interval = 16;            ///< Verlet energy computed every this many iterations, >= 1 (default 16)
  double energy_growth_bound = 100.0;  ///< SolverError when the energy exceeds this times the
                                       ///< initial energy, > 1 (default 100)
  bool record_energy = false;          ///< energy at every iteration into the report (default false)
  // Static
  StaticMethod static_method = StaticMethod::momentum;  ///< (default momentum: fastest on large lattices,
                                                        ///< measured by `fascicle bench springs`)
  Acceleration acceleration = Acceleration::anderson;   ///< (default anderson)
  int anderson_window = 5;                              ///< Anderson history length, >= 1 (default 5)
  double multigrid_step = 0.9;           ///< multigrid: step along the preconditioned force, (0, 2] (default 0.9)
  bool multigrid_harmonic_start = true;  ///< multigrid: start from the harmonic interpolation of the
                                         ///< fixed points, not the given free positions (default true)
  bool multigrid_directional = false;    ///< multigrid: precondition by directional stiffness (Hessian
                                         ///< diagonal blocks), not the Laplacian (default false: slower)
  int multigrid_smoothing_steps = 1;     ///< multigrid: smoothing steps before and after each coarse
                                         ///< correction, 1..20 (default 1: faster than 2)
  int coarse_start_points = 4096;        ///< static momentum: above this many points, start from the settled
                                         ///< every-other-point lattice (coarse_start.h); 0 off, >= 8 (default 4096)
  double coarse_start_tolerance = 1e-6;  ///< coarse lattices' residual (at least tolerance), (0, 1)
                                         ///< (default 1e-6: model-26 lattices need accurate coarse starts)
  /// Model-6 coarse start: offset each interpolated free point by a fixed hashed jitter of this share of
  /// the rest length, [0, 1], 0 = none (default 0.2: a smooth start sits near a saddle when springs buckle).
  double coarse_start_perturbation = 0.2;
  int multigrid_coarsest_points = 4096;  ///< multigrid: levels of at most this many points are
                                         ///< solved directly, 8..200000 (default 4096)

  /// Throws OptionError naming the bad field and value.
  void validate() const;
};

/// What a settle did.
struct SettleReport {
  std::string solver;                    ///< "verlet" | "static"
  std::string backend;                   ///< Verlet: "structured", "structured-uniform", "general"; static:
                                         ///< the same prefixed "momentum-", or "newton-cg", "ldlt",
                                         ///< "multigrid-<number of levels>"
  int iterations = 0;                    ///< iterations run (Newton steps for static newton)
  int inner_iterations = 0;              ///< conjugate-gradient iterations (static newton), else 0
  bool converged = false;                ///< final residual <= tolerance (false when tolerance is 0)
  double residual = 0.0;                 ///< relative residual at the returned positions
  std::vector<double> residual_history;  ///< relative residual per iteration
  std::vector<double> energy_history;    ///< energies as recorded (see record_energy)
  double setup_seconds = 0.0;            ///< building buffers, factorizing
  double seconds = 0.0;                  ///< iterating (wall time, excluding setup)
  double dt = 0.0;                       ///< Verlet time step used
  double mean_damping = 0.0;             ///< Verlet mean damping coefficient used
  int start_levels = 0;                  ///< static momentum: coarse lattices settled for the start
                                         ///< (coarse_start.h; their time is in setup_seconds)
  int start_iterations = 0;              ///< iterations on those coarse lattices
};

/// The shape of a lattice, for the structured path.
struct LatticeShape {
  int nx = 0, ny = 0, nz = 0;
  SpringModel model = SpringModel::model6;
};

/// A solver object: build once (buffers, factorization), then step many times.
class SpringSolver {
 public:
  virtual ~SpringSolver() = default;
  /// One iteration. Returns the relative residual it measured (Verlet: at the positions before
  /// the step, computed with the step's forces; static: at the positions after it).
  /// Throws SolverError on divergence.
  virtual double step() = 0;
  /// Relative residual at the current positions (one force evaluation).
  virtual double residual() = 0;
  /// Total energy at the current state (kinetic + potential for Verlet, potential for static).
  virtual double energy() = 0;
  /// Current positions, #N.
  virtual std::vector<Vec3> positions() const = 0;
  /// Name of the data path ("structured", "general", "newton-cg", "ldlt").
  virtual std::string backend() const = 0;
  /// Verlet time step (0 for static) and mean damping coefficient.
  virtual double time_step() const { return 0.0; }
  virtual double mean_damping() const { return 0.0; }
  /// Inner (conjugate-gradient) iterations so far; 0 for solvers without an inner solve.
  virtual int inner_iterations() const { return 0; }
  /// True when the last step could not make progress in double precision (the solve is then at
  /// its attainable accuracy; further steps change nothing).
  virtual bool stalled() const { return false; }
  /// Coarse lattices settled for the start and their iterations (coarse_start.h); 0 without.
  virtual int start_levels() const { return 0; }
  virtual int start_iterations() const { return 0; }
};

/// Builds a solver for `system` (validated; copied). `shape`, when given, describes `system` as
/// a lattice (build_lattice order) so Verlet can take the structured path.
/// Throws OptionError for bad options or a structured backend that does not fit the system,
/// SolverError for a static solve without a fixed point in some connected part.
std::unique_ptr<SpringSolver> make_solver(const SpringSystem& system, const SettleOptions& options,
                                          const LatticeShape* shape = nullptr);

/// The factorized constant matrix of the local-global static method, L = sum_s D_s A_s A_s^T
/// over the free points (Eigen SimplicialLDLT). It depends only on which points the springs join,
/// their stiffness and the fixed flags, not on positions or rest lengths, so it can be made ahead
/// of the positions (the decomposition makes it beside the sphere map) and given to make_solver
/// and settle, which then skip the factorization. Opaque; immutable once made.
class SpringMatrixFactor;

/// Factorizes L for `system` (validated). Throws SolverError as make_solver does for a connected
/// part of the springs without a fixed point.
std::shared_ptr<const SpringMatrixFactor> factor_spring_matrix(const SpringSystem& system);

/// make_solver with a matrix factor made ahead: `factor`, when not null, is used by the
/// local-global static method (and ignored by the others) instead of factorizing; it must have
/// been made for a system with the same points, fixed flags, spring ends and stiffnesses as
/// `system` (else Error with ErrorCode::internal). The result is the same to the bit as without it.
std::unique_ptr<SpringSolver> make_solver(const SpringSystem& system, const SettleOptions& options,
                                          const LatticeShape* shape,
                                          const std::shared_ptr<const SpringMatrixFactor>& factor);

/// Settles `system` in one call: steps until the relative residual <= tolerance,
/// max_iterations, or a stalled step (SpringSolver::stalled), and writes the final positions into system.positions. Fixed points are
/// bitwise unchanged. Throws as make_solver and SpringSolver::step.
SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape = nullptr);
/// The same with a matrix factor made ahead (make_solver above).
SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape,
                    const std::shared_ptr<const SpringMatrixFactor>& factor);

/// The shape of a lattice built by build_lattice or regular_lattice.
inline LatticeShape shape_of(const Lattice& lattice) { return {lattice.nx, lattice.ny, lattice.nz, lattice.model}; }

}  // namespace fascicle::springs
