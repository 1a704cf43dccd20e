// The `multigrid` static method: accelerated gradient descent on the spring energy,
// preconditioned by one multigrid V-cycle on the spring Laplacian (multigrid.h).
//
// Energy E(x) = sum_s D_s / 2 (|l_s| - r_s)^2; f = -grad E are the spring forces. The Hessian
// block of a spring, D [n n^T + (1 - r / |l|) (I - n n^T)], is at most D I, so the Hessian is
// at most the Laplacian L = sum_s D_s A_s A_s^T (the local-global matrix of Liu et al. 2013):
// in the metric of L the energy's gradient is 1-Lipschitz, whatever the lattice size. One
// iteration:
//   y = x_k + beta_k (x_k - x_{k-1}),  beta_k = k / (k + 3)      (Nesterov's momentum)
//   x_{k+1} = y + alpha B f(y)                                   (B: one V-cycle, about L^-1)
// with alpha = SettleOptions::multigrid_step, and the momentum restarted (k = 0) when the step
// opposes the force, f(y) . (x_{k+1} - x_k) < 0, or when the energy at y rose above that of the
// previous y (gradient and function restarts, O'Donoghue and Candes 2015, "Adaptive restart for
// accelerated gradient schemes"). With alpha = 1 and no momentum this is the local-global
// iteration with the global solve replaced by one V-cycle. The iteration count then depends on
// how far the Hessian falls below L (springs near their rest length resist sideways motion
// little), not on the number of points, while a plain gradient method's count grows with it.
// The residual is measured at y, and y is the returned position. Before the first iteration
// the free points move to the harmonic interpolation of the fixed points (L x = 0 over the free
// points, V-cycles to 1e-8; SettleOptions::multigrid_harmonic_start): with the boundary moved
// by many lattice spacings the given interior is tangled, and untangling it took most of the
// iterations (model-26 at 50^3: 975 iterations from the template positions, 32 from the
// harmonic start). SettleOptions::multigrid_directional replaces L by three operators, one per
// coordinate, with each spring weighted by the diagonal of its Hessian block at the start
// (transverse factor clamped to [0.5, 1]); measured slower on model-6 lattices (8792
// iterations at 50^3 against 1222), so off by default.

#include "geometry/errors.h"
#include "springs/multigrid.h"
#include "springs/solvers_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>

namespace fascicle::springs::detail {
namespace {

constexpr int kBlock = 4096;

class MultigridSolver final : public SpringSolver {
 public:
  MultigridSolver(const SpringSystem& system, const SettleOptions& options, const LatticeShape& shape)
      : options_(options), input_(system.positions), fixed_(system.fixed) {
    n_ = static_cast<int>(system.positions.size());
    check_anchored(system);
    SpringRows rows = spring_rows(system);
    row_ = std::move(rows.row);
    neighbour_ = std::move(rows.neighbour);
    stiffness_ = std::move(rows.stiffness);
    rest_ = std::move(rows.rest);
    x_.resize(3 * static_cast<std::size_t>(n_));
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < 3; ++c) x_[3 * i + c] = system.positions[i][c];
    previous_ = x_;
    y_ = x_;
    force_.assign(x_.size(), 0.0);
    step_.assign(x_.size(), 0.0);
    blocks_ = std::max(1, (n_ + kBlock - 1) / kBlock);
    partial_.assign(blocks_, 0.0);
    partial_max_.assign(blocks_, 0.0);
    scale_ = residual_force_scale(system);
    MultigridOptions mg;
    mg.smoothing_steps = options.multigrid_smoothing_steps;
    mg.coarsest_points = options.multigrid_coarsest_points;
    multigrid_ = std::make_unique<LatticeMultigrid>(system, shape, mg);
    if (options.multigrid_harmonic_start) harmonic_start();
    if (options.multigrid_directional) {
      // the preconditioner from here on: per coordinate, the springs weighted by the diagonal of
      // their Hessian blocks at the start positions, the transverse factor 1 - r / |l| clamped
      // to [0.5, 1] (0.05 .. 0.3 diverged or stalled at alpha 0.9 on the bench lattices)
      std::vector<std::array<double, 3>> weights(system.springs.size());
      const double floor = 0.5;
      for (std::size_t s = 0; s < system.springs.size(); ++s) {
        const Spring& spring = system.springs[s];
        double l[3], len2 = 0.0;
        for (int c = 0; c < 3; ++c) {
          l[c] = x_[3 * static_cast<std::size_t>(spring.a) + c] - x_[3 * static_cast<std::size_t>(spring.b) + c];
          len2 += l[c] * l[c];
        }
        const double len = std::sqrt(len2);
        const double beta = len > 0.0 ? std::clamp(1.0 - spring.rest / len, floor, 1.0) : 1.0;
        for (int c = 0; c < 3; ++c) {
          const double along = len > 0.0 ? l[c] * l[c] / len2 : 1.0 / 3.0;
          weights[s][c] = spring.stiffness * (along + beta * (1.0 - along));
        }
      }
      multigrid_ = std::make_unique<LatticeMultigrid>(system, shape, mg, &weights);
    }
    previous_ = x_;
    y_ = x_;
    evaluate(y_);
    watch_ = DivergenceWatch(system, options, energy_);
    last_energy_ = energy_;
  }

  double step() override {
    if (n_ == 0) return 0.0;
    // Gradient and function restart: the last step opposed the force or raised the energy.
    if (schedule_.restart(last_step_bad_)) previous_ = x_;
    const double beta = schedule_.next();
    if (iterations_ > 0) {  // the first y is x_0, already evaluated by the constructor
      for_blocks([&](int, int begin, int end) {
        for (std::size_t k = 3 * static_cast<std::size_t>(begin); k < 3 * static_cast<std::size_t>(end); ++k)
          y_[k] = x_[k] + beta * (x_[k] - previous_[k]);
      });
      evaluate(y_);
    }
    ++iterations_;
    if (watch_.diverged(energy_) || !std::isfinite(residual_)) {
      std::ostringstream out;
      out << "static multigrid diverged at iteration " << iterations_ << " (";
      if (std::isfinite(energy_))
        out << "energy " << energy_ << ", above " << options_.energy_growth_bound << " x the initial "
            << watch_.initial_energy();
      else
        out << "positions became NaN/Inf";
      out << "): use a smaller --multigrid-step (now " << options_.multigrid_step << ") or --static-method momentum";
      throw SolverError(out.str());
    }
    multigrid_->precondition(force_, step_);
    // x_{k+1} = y + alpha B f(y).
    const double alpha = options_.multigrid_step;
    const bool energy_rose = energy_ > last_energy_;
    for_blocks([&](int blk, int begin, int end) {
      double along = 0.0;
      for (std::size_t k = 3 * static_cast<std::size_t>(begin); k < 3 * static_cast<std::size_t>(end); ++k) {
        const double next = y_[k] + alpha * step_[k];
        along += force_[k] * (next - x_[k]);
        previous_[k] = x_[k];
        x_[k] = next;
      }
      partial_[blk] = along;
    });
    const double along = sum_partials();
    last_energy_ = energy_;
    last_step_bad_ = along < 0.0 || energy_rose;
    return residual_;
  }

  double residual() override { return residual_; }
  double energy() override { return energy_; }
  std::vector<Vec3> positions() const override {
    std::vector<Vec3> out = input_;
    for (int i = 0; i < n_; ++i)
      if (!fixed_[i]) out[i] = Vec3(y_[3 * i], y_[3 * i + 1], y_[3 * i + 2]);
    return out;
  }
  std::string backend() const override { return "multigrid-" + std::to_string(multigrid_->levels()); }

 private:
  // x_f += u with L u = the forces of the springs at zero rest length: the free points move to
  // the harmonic interpolation of the fixed points (the zero-rest-length equilibrium), solved
  // by V-cycles to a relative residual of 1e-8 (at most 30 cycles).
  void harmonic_start() {
    std::vector<double> b(x_.size(), 0.0), u(x_.size(), 0.0), r;
    for_blocks([&](int, int begin, int end) {
      for (int i = begin; i < end; ++i) {
        if (fixed_[i]) continue;
        for (int s = row_[i]; s < row_[i + 1]; ++s)
          for (int c = 0; c < 3; ++c) b[3 * i + c] += stiffness_[s] * (x_[3 * neighbour_[s] + c] - x_[3 * i + c]);
      }
    });
    const double initial = multigrid_->residual(b, u, r);
    for (int cycle = 0; cycle < 30 && initial > 0.0; ++cycle) {
      multigrid_->cycle(b, u);
      if (multigrid_->residual(b, u, r) <= 1e-8 * initial) break;
    }
    for (std::size_t k = 0; k < x_.size(); ++k) x_[k] += u[k];
  }

  template <typename Body>
  void for_blocks(Body&& body) {
    tbb::parallel_for(tbb::blocked_range<int>(0, blocks_, 1), [&](const tbb::blocked_range<int>& range) {
      for (int blk = range.begin(); blk != range.end(); ++blk)
        body(blk, blk * kBlock, std::min(n_, (blk + 1) * kBlock));
    });
  }

  double sum_partials() const {
    double total = 0.0;
    for (int blk = 0; blk < blocks_; ++blk) total += partial_[blk];
    return total;
  }

  // Forces (0 at fixed points), energy and relative residual at x.
  void evaluate(const std::vector<double>& x) {
    for_blocks([&](int blk, int begin, int end) {
      double e = 0.0, largest = 0.0;
      for (int i = begin; i < end; ++i) {
        double f[3] = {0.0, 0.0, 0.0};
        for (int s = row_[i]; s < row_[i + 1]; ++s) {
          const int q = neighbour_[s];
          const double l[3] = {x[3 * q] - x[3 * i], x[3 * q + 1] - x[3 * i + 1], x[3 * q + 2] - x[3 * i + 2]};
          const double len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
          const double stretch = len - rest_[s];
          e += 0.25 * stiffness_[s] * stretch * stretch;  // every spring is seen from both ends
          if (len == 0.0) continue;
          const double w = stiffness_[s] * stretch / len;
          for (int c = 0; c < 3; ++c) f[c] += w * l[c];
        }
        if (fixed_[i]) f[0] = f[1] = f[2] = 0.0;
        for (int c = 0; c < 3; ++c) force_[3 * i + c] = f[c];
        const double f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
        if (f2 > largest || std::isnan(f2)) largest = f2;
      }
      partial_[blk] = e;
      partial_max_[blk] = largest;
    });
    energy_ = sum_partials();
    double largest = 0.0;
    for (int blk = 0; blk < blocks_; ++blk)
      if (partial_max_[blk] > largest || std::isnan(partial_max_[blk])) largest = partial_max_[blk];
    residual_ = std::sqrt(largest) / scale_;
  }

  SettleOptions options_;
  std::vector<Vec3> input_;
  std::vector<char> fixed_;
  int n_ = 0, blocks_ = 0, iterations_ = 0;
  std::vector<int> row_, neighbour_;
  std::vector<double> stiffness_, rest_;
  std::vector<double> x_, previous_, y_, force_, step_, partial_, partial_max_;
  std::unique_ptr<LatticeMultigrid> multigrid_;
  double scale_ = 1.0, energy_ = 0.0, residual_ = 0.0, last_energy_ = 0.0;
  bool last_step_bad_ = false;
  MomentumSchedule schedule_;
  DivergenceWatch watch_;
};

}  // namespace

std::unique_ptr<SpringSolver> make_multigrid_solver(const SpringSystem& system, const SettleOptions& options,
                                                    const LatticeShape& shape) {
  return std::make_unique<MultigridSolver>(system, options, shape);
}

}  // namespace fascicle::springs::detail
