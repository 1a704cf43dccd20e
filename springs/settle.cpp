// The settle interface: options, solver choice, the one-call loop, shared Verlet coefficients.

#include "springs/settle.h"

#include "geometry/errors.h"
#include "springs/multigrid.h"
#include "springs/solvers_internal.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

namespace fascicle::springs {

SolverKind parse_solver_kind(const std::string& name) {
  if (name == "verlet") return SolverKind::verlet;
  if (name == "static") return SolverKind::static_equilibrium;
  throw OptionError("solver: unknown solver '" + name + "' (valid: verlet, static)");
}

StaticMethod parse_static_method(const std::string& name) {
  if (name == "momentum") return StaticMethod::momentum;
  if (name == "newton") return StaticMethod::newton;
  if (name == "local-global") return StaticMethod::local_global;
  if (name == "multigrid") return StaticMethod::multigrid;
  throw OptionError("static-method: unknown method '" + name + "' (valid: momentum, newton, local-global, multigrid)");
}

Backend parse_backend(const std::string& name) {
  if (name == "auto") return Backend::automatic;
  if (name == "structured") return Backend::structured;
  if (name == "general") return Backend::general;
  throw OptionError("backend: unknown backend '" + name + "' (valid: auto, structured, general)");
}

const char* solver_name(SolverKind kind) { return kind == SolverKind::verlet ? "verlet" : "static"; }

const char* backend_name(Backend backend) {
  switch (backend) {
    case Backend::automatic: return "auto";
    case Backend::structured: return "structured";
    case Backend::general: return "general";
  }
  return "auto";
}

void SettleOptions::validate() const {
  auto str = [](double v) {
    std::ostringstream out;
    out << v;
    return out.str();
  };
  if (!(tolerance >= 0.0) || !std::isfinite(tolerance))
    throw OptionError("tolerance: must be >= 0, got " + str(tolerance));
  if (max_iterations < 1) throw OptionError("max_iterations: must be >= 1, got " + std::to_string(max_iterations));
  if (!(mass >= 0.0) || !std::isfinite(mass))
    throw OptionError("mass: must be > 0 (or 0 to keep the model's masses), got " + str(mass));
  if (!(damping >= 0.0) || !std::isfinite(damping)) throw OptionError("damping: must be >= 0, got " + str(damping));
  if (!(dt >= 0.0) || !std::isfinite(dt)) throw OptionError("dt: must be > 0 (or 0 for automatic), got " + str(dt));
  if (energy_interval < 1) throw OptionError("energy_interval: must be >= 1, got " + std::to_string(energy_interval));
  if (!(energy_growth_bound > 1.0))
    throw OptionError("energy_growth_bound: must be > 1, got " + str(energy_growth_bound));
  if (anderson_window < 1 || anderson_window > 50)
    throw OptionError("anderson_window: must be in 1..50, got " + std::to_string(anderson_window));
  if (!(multigrid_step > 0.0 && multigrid_step <= 2.0))
    throw OptionError("multigrid_step: must be in (0, 2], got " + str(multigrid_step));
  MultigridOptions multigrid;
  if (coarse_start_points != 0 && coarse_start_points < 8)
    throw OptionError("coarse_start_points: must be 0 (off) or >= 8, got " + std::to_string(coarse_start_points));
  if (!(coarse_start_perturbation >= 0.0 && coarse_start_perturbation <= 1.0))
    throw OptionError("coarse_start_perturbation: must be in [0, 1], got " + str(coarse_start_perturbation));
  if (!(coarse_start_tolerance > 0.0 && coarse_start_tolerance < 1.0))
    throw OptionError("coarse_start_tolerance: must be in (0, 1), got " + str(coarse_start_tolerance));
  multigrid.smoothing_steps = multigrid_smoothing_steps;
  multigrid.coarsest_points = multigrid_coarsest_points;
  multigrid.validate();
}

std::unique_ptr<SpringSolver> make_solver(const SpringSystem& system, const SettleOptions& options,
                                          const LatticeShape* shape) {
  return make_solver(system, options, shape, nullptr);
}

std::unique_ptr<SpringSolver> make_solver(const SpringSystem& system, const SettleOptions& options,
                                          const LatticeShape* shape,
                                          const std::shared_ptr<const SpringMatrixFactor>& factor) {
  options.validate();
  validate(system);
  if (options.solver == SolverKind::static_equilibrium) {
    if (options.static_method == StaticMethod::newton) return detail::make_newton_solver(system, options);
    if (options.static_method == StaticMethod::local_global) return detail::make_static_solver(system, options, factor);
    if (options.static_method == StaticMethod::multigrid && detail::multigrid_fits(system, shape))
      return detail::make_multigrid_solver(system, options, *shape);
    // momentum, or multigrid on a system that is not a lattice grid: the momentum method
    if (shape && options.backend != Backend::general) {
      auto started = detail::make_coarse_started_momentum(system, options, *shape);
      if (started) return started;
      auto solver = detail::make_structured_verlet(system, options, *shape, true);
      if (solver) return solver;
    }
    return detail::make_general_verlet(system, options, true);
  }
  if (options.backend == Backend::general) return detail::make_general_verlet(system, options);
  if (shape) {
    auto solver = detail::make_structured_verlet(system, options, *shape);
    if (solver) return solver;
  }
  if (options.backend == Backend::structured)
    throw OptionError(
        "backend: structured needs a lattice whose springs are exactly its model-6/26 neighbours "
        "with stiffness 1 / rest length; use --path general or auto");
  return detail::make_general_verlet(system, options);
}

SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape) {
  return settle(system, options, shape, nullptr);
}

SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape,
                    const std::shared_ptr<const SpringMatrixFactor>& factor) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  std::unique_ptr<SpringSolver> solver = make_solver(system, options, shape, factor);
  const auto t1 = clock::now();
  SettleReport report;
  report.solver = solver_name(options.solver);
  report.backend = solver->backend();
  report.dt = solver->time_step();
  report.mean_damping = solver->mean_damping();
  report.start_levels = solver->start_levels();
  report.start_iterations = solver->start_iterations();
  if (options.record_energy) report.energy_history.push_back(solver->energy());
  double residual = solver->residual();
  report.residual_history.push_back(residual);
  const bool run_all = options.tolerance == 0.0;
  if (run_all || residual > options.tolerance) {
    for (int it = 0; it < options.max_iterations; ++it) {
      const double measured = solver->step();
      ++report.iterations;
      report.residual_history.push_back(measured);
      if (options.record_energy) report.energy_history.push_back(solver->energy());
      if (solver->stalled()) break;  // at the attainable accuracy
      if (!run_all && measured <= options.tolerance) {
        // The Verlet residual is measured before its step: confirm at the returned positions.
        residual = solver->residual();
        if (residual <= options.tolerance) break;
      }
    }
    residual = solver->residual();
  }
  report.seconds = std::chrono::duration<double>(clock::now() - t1).count();
  report.setup_seconds = std::chrono::duration<double>(t1 - t0).count();
  report.residual = residual;
  report.inner_iterations = solver->inner_iterations();
  report.converged = !run_all && residual <= options.tolerance;
  std::vector<Vec3> positions = solver->positions();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (system.fixed[i]) continue;  // fixed points keep their exact input bits
    if (!positions[i].allFinite())
      throw SolverError("settle: point " + std::to_string(i) +
                        " is not finite after the solve; use a smaller --dt or a larger --mass");
    system.positions[i] = positions[i];
  }
  return report;
}

namespace detail {

VerletCoefficients verlet_coefficients(const SpringSystem& system, const SettleOptions& options) {
  const std::size_t n = system.positions.size();
  VerletCoefficients out;
  out.mass = system.mass;
  if (options.mass > 0.0) std::fill(out.mass.begin(), out.mass.end(), options.mass);
  std::vector<double> stiffness_sum(n, 0.0);
  std::vector<int> valence(n, 0);
  double rest_sum = 0.0;
  for (const Spring& s : system.springs) {
    stiffness_sum[s.a] += s.stiffness;
    stiffness_sum[s.b] += s.stiffness;
    ++valence[s.a];
    ++valence[s.b];
    rest_sum += s.rest;
  }
  const double mean_rest = system.springs.empty() ? 0.0 : rest_sum / system.springs.size();
  std::vector<double> damping(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    switch (options.damping_mode) {
      case DampingMode::estimate: damping[i] = thesis_damping_estimate(mean_rest, out.mass[i]); break;
      case DampingMode::critical:
        damping[i] = valence[i] ? std::sqrt(4.0 * stiffness_sum[i] / valence[i] * out.mass[i]) : 0.0;
        break;
      case DampingMode::value: damping[i] = options.damping; break;
    }
  }
  // Stability of x+ = x + (1 - b)(x - x-) - a K x for one mode of eigenvalue lambda of M^-1 K:
  // a lambda + 2 b < 4 with a = dt^2, b = c dt / m (Jury's test on z^2 - (2 - a - b) z + 1 - b).
  // Gershgorin bounds the Hessian's row by 2 sum_j k_ij, per point.
  double dt = options.dt;
  if (dt == 0.0) {
    dt = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < n; ++i) {
      if (system.fixed[i] || valence[i] == 0) continue;
      const double a = 2.0 * stiffness_sum[i] / out.mass[i];
      const double b = 2.0 * damping[i] / out.mass[i];
      const double c = 4.0 * 0.9;
      const double root = 2.0 * c / (b + std::sqrt(b * b + 4.0 * a * c));  // stable form
      dt = std::min(dt, root);
    }
    if (!std::isfinite(dt)) dt = 1.0;
  }
  out.dt = dt;
  out.a.resize(n);
  out.b.resize(n);
  double damping_sum = 0.0;
  out.min_mass = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) {
    out.a[i] = dt * dt / out.mass[i];
    out.b[i] = 1.0 - damping[i] * dt / out.mass[i];
    damping_sum += damping[i];
    out.min_mass = std::min(out.min_mass, out.mass[i]);
    out.max_point_stiffness = std::max(out.max_point_stiffness, stiffness_sum[i]);
  }
  out.mean_damping = n ? damping_sum / n : 0.0;
  return out;
}

void throw_verlet_divergence(int iteration, double energy, double initial_energy, const VerletCoefficients& c,
                             const SettleOptions& options) {
  std::ostringstream out;
  out << "verlet diverged at iteration " << iteration << " (";
  if (std::isfinite(energy))
    out << "energy " << energy << ", above " << options.energy_growth_bound << " x the initial " << initial_energy;
  else
    out << "positions became NaN/Inf";
  out << "): time step " << c.dt << " is too large for point mass " << c.min_mass << ", point stiffness "
      << c.max_point_stiffness << " and mean damping " << c.mean_damping;
  if (options.dt > 0.0)
    out << "; use a smaller --dt (or --dt 0 for the automatic stable step) or a larger --mass";
  else
    out << "; use a larger --mass or less --damping";
  throw SolverError(out.str());
}

DivergenceWatch::DivergenceWatch(const SpringSystem& system, const SettleOptions& options, double initial_energy)
    : initial_(std::max(initial_energy, energy_floor(system))),
      bound_(options.energy_growth_bound),
      interval_(options.energy_interval) {}

void DivergenceWatch::check(int iteration, double energy, const VerletCoefficients& coefficients,
                            const SettleOptions& options) const {
  if (diverged(energy)) throw_verlet_divergence(iteration, energy, initial_, coefficients, options);
}

void DivergenceWatch::check_force(int iteration, double force2, const VerletCoefficients& coefficients,
                                  const SettleOptions& options) const {
  if (!std::isfinite(force2)) throw_verlet_divergence(iteration, NAN, initial_, coefficients, options);
}

VerletCoefficients momentum_coefficients(const SpringSystem& system) {
  const std::size_t n = system.positions.size();
  std::vector<double> stiffness_sum(n, 0.0);
  for (const Spring& s : system.springs) {
    stiffness_sum[s.a] += s.stiffness;
    stiffness_sum[s.b] += s.stiffness;
  }
  double bound = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    if (!system.fixed[i]) bound = std::max(bound, 2.0 * stiffness_sum[i]);
  // The Lanczos estimate is a lower bound of the largest eigenvalue of an upper bound of the
  // Hessian at the start; 1.25 covers its shortfall (2-3 per cent after 10 steps, measured on the bench lattices) and springs
  // that stretch further during the solve. Accelerated gradient stays stable up to a step of
  // about 4 / 3 of 1 / lambda_max, plain gradient (after a restart) up to 2; the Verlet energy
  // check remains behind it.
  const double estimate = bound > 0.0 ? largest_stiffness_eigenvalue(system, 10) : 0.0;
  const double lipschitz = estimate > 0.0 ? std::min(bound, 1.25 * estimate) : bound;
  VerletCoefficients out;
  const double a = lipschitz > 0.0 ? 1.0 / lipschitz : 1.0;
  out.dt = std::sqrt(a);
  out.a.assign(n, a);
  out.b.assign(n, 0.0);
  out.mass.assign(n, 1.0);
  out.min_mass = 1.0;
  out.max_point_stiffness = 0.5 * bound;
  return out;
}

bool multigrid_fits(const SpringSystem& system, const LatticeShape* shape) {
  if (!shape || shape->nx < 2 || shape->ny < 2 || shape->nz < 2) return false;
  const std::size_t n = system.positions.size();
  if (static_cast<std::size_t>(shape->nx) * shape->ny * shape->nz != n) return false;
  const std::size_t plane = static_cast<std::size_t>(shape->nx) * shape->ny;
  for (const Spring& s : system.springs) {
    const std::size_t a = static_cast<std::size_t>(s.a), b = static_cast<std::size_t>(s.b);
    const long di = static_cast<long>(a % shape->nx) - static_cast<long>(b % shape->nx);
    const long dj = static_cast<long>((a / shape->nx) % shape->ny) - static_cast<long>((b / shape->nx) % shape->ny);
    const long dk = static_cast<long>(a / plane) - static_cast<long>(b / plane);
    if (std::abs(di) > 1 || std::abs(dj) > 1 || std::abs(dk) > 1) return false;
  }
  return true;
}

double energy_floor(const SpringSystem& system) {
  double e = 0.0;
  for (const Spring& s : system.springs) e += 0.5 * s.stiffness * s.rest * s.rest;
  return e > 0.0 ? 1e-20 * e : 1e-300;
}

}  // namespace detail
}  // namespace fascicle::springs
