// The default static solver: truncated Newton with a matrix-free preconditioned conjugate
// gradient inner solve and a backtracking line search on the spring energy.
//
// Energy E(x) = sum_s D_s / 2 (|l_s| - r_s)^2, l_s = x_a - x_b. The Hessian block of one spring
// is D [n n^T + (1 - r / |l|) (I - n n^T)], n = l / |l|; its transverse part is negative for a
// compressed spring, so far from equilibrium the Hessian can be indefinite. Each Newton step
// solves H p = f (f = -grad E, the spring forces) with conjugate gradients, preconditioned by
// the 3 x 3 point blocks of the Hessian with the transverse parts clamped at 0 (positive
// definite), to a relative accuracy eta = min(0.5, sqrt(|f| / |f0|)) (inexact Newton, Eisenstat
// and Walker 1996), stopping early on negative curvature (truncated Newton, Nocedal and Wright,
// "Numerical Optimization", algorithm 7.1); it then backtracks from the full step until the
// energy decreases sufficiently (Armijo). Clamping the Hessian itself (projected Newton) was
// measured slower: it converges only linearly when springs stay compressed at equilibrium.
// Fixed points are not unknowns.
//
// Why not only the prefactored local-global iteration (static_solver.cpp): it converges
// linearly at a rate that degrades with the lattice size and with compressed springs, and a
// sparse Cholesky factor of a 3-D lattice grows much faster than the lattice (fill-in), so
// neither its setup nor its iterations scale to 100^3. Newton-CG needs only passes over the
// springs, parallel and in fixed blocks (deterministic).

#include "geometry/errors.h"
#include "springs/solvers_internal.h"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <functional>
#include <limits>

namespace fascicle::springs::detail {

namespace {
int find_root(std::vector<int>& parent, int v) {
  while (parent[v] != v) v = parent[v] = parent[parent[v]];
  return v;
}
}  // namespace

void check_anchored(const SpringSystem& system) {
  const int n = static_cast<int>(system.positions.size());
  std::vector<int> parent(n);
  for (int i = 0; i < n; ++i) parent[i] = i;
  for (const Spring& s : system.springs) parent[find_root(parent, s.a)] = find_root(parent, s.b);
  std::vector<char> anchored(n, 0);
  for (int i = 0; i < n; ++i)
    if (system.fixed[i]) anchored[find_root(parent, i)] = 1;
  for (int i = 0; i < n; ++i)
    if (!system.fixed[i] && !anchored[find_root(parent, i)])
      throw SolverError("static: point " + std::to_string(i) +
                        " is in a part of the spring system with no fixed point, so its "
                        "equilibrium is not unique; fix a point there or use --solver verlet");
}

namespace {

constexpr int kBlock = 2048;

class NewtonSolver final : public SpringSolver {
 public:
  NewtonSolver(const SpringSystem& system, const SettleOptions& options) : options_(options), input_(system.positions) {
    n_ = static_cast<int>(system.positions.size());
    fixed_ = system.fixed;
    check_anchored(system);
    SpringRows rows = spring_rows(system);
    row_ = std::move(rows.row);
    neighbour_ = std::move(rows.neighbour);
    stiffness_ = std::move(rows.stiffness);
    rest_ = std::move(rows.rest);
    const std::size_t entries = neighbour_.size();
    direction_.resize(3 * entries);
    transverse_.resize(entries);
    x_.resize(3 * static_cast<std::size_t>(n_));
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < 3; ++c) x_[3 * i + c] = system.positions[i][c];
    force_.assign(x_.size(), 0.0);
    block_inverse_.assign(9 * static_cast<std::size_t>(n_), 0.0);
    blocks_ = std::max(1, (n_ + kBlock - 1) / kBlock);
    partial_.assign(blocks_, 0.0);
    partial_max_.assign(blocks_, 0.0);
    scale_ = residual_force_scale(system);
    evaluate();
    initial_force_norm_ = std::max(force_norm_, 1e-300);
  }

  double step() override {
    if (force_norm_ == 0.0) return residual_;
    std::vector<double> p(x_.size(), 0.0);
    int cg = 0;
    if (steps_ < kWarmSteps) {
      // Warm start: a local-global step (Liu et al. 2013), x += L^-1 f with L the stiffness-
      // weighted graph Laplacian, here solved by CG. It carries the displacement of the fixed
      // points into the interior (nearly their harmonic extension), where Newton's quadratic
      // model of the nonconvex energy is still poor.
      use_laplacian();
      cg = conjugate_gradient(force_, p, 1e-2);
    } else {
      // Inexact Newton: solve H p = f to relative accuracy eta.
      const double eta = std::min(0.5, std::sqrt(force_norm_ / initial_force_norm_));
      cg = conjugate_gradient(force_, p, eta);
    }
    ++steps_;
    inner_iterations_ += cg;
    // Armijo backtracking on the energy along p (a descent direction: f . p > 0). Near the
    // solution the energy decrease falls below its rounding error (|E| eps): a step that
    // keeps the energy within that noise is taken when it lowers the force norm.
    const double slope = dot(force_, p);
    if (!(slope > 0.0)) p = force_;  // CG broke down: steepest descent
    const double descent = std::max(dot(force_, p), 0.0);
    const double energy0 = energy_;
    const double noise = 64.0 * std::numeric_limits<double>::epsilon() * std::abs(energy0);
    std::vector<double> trial(x_.size());
    double alpha = 1.0;
    bool accepted = false;
    for (int attempt = 0; attempt < 40 && !accepted; ++attempt, alpha *= 0.5) {
      for_blocks([&](int, int begin, int end) {
        for (std::size_t k = 3 * static_cast<std::size_t>(begin); k < 3 * static_cast<std::size_t>(end); ++k)
          trial[k] = x_[k] + alpha * p[k];
      });
      const double e = energy_at(trial);
      if (e <= energy0 - 1e-4 * alpha * descent)
        accepted = true;
      else if (e <= energy0 + noise && force_norm_at(trial) < force_norm_)
        accepted = true;
      if (accepted) break;
    }
    stalled_ = !accepted;
    if (accepted) x_.swap(trial);
    evaluate();
    if (!std::isfinite(residual_) || !std::isfinite(energy_))
      throw SolverError(
          "static: the solve produced NaN/Inf (springs of zero length?); check the "
          "input or use --solver verlet");
    return residual_;
  }

  double residual() override { return residual_; }
  double energy() override { return energy_; }
  std::vector<Vec3> positions() const override {
    std::vector<Vec3> out = input_;
    for (int i = 0; i < n_; ++i)
      if (!fixed_[i]) out[i] = Vec3(x_[3 * i], x_[3 * i + 1], x_[3 * i + 2]);
    return out;
  }
  std::string backend() const override { return "newton-cg"; }
  int inner_iterations() const override { return inner_iterations_; }
  bool stalled() const override { return stalled_; }

 private:
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

  double dot(const std::vector<double>& a, const std::vector<double>& b) {
    for_blocks([&](int blk, int begin, int end) {
      double s = 0.0;
      for (std::size_t k = 3 * static_cast<std::size_t>(begin); k < 3 * static_cast<std::size_t>(end); ++k)
        s += a[k] * b[k];
      partial_[blk] = s;
    });
    return sum_partials();
  }

  // Replaces the Hessian data by the Laplacian's (isotropic spring blocks D I).
  void use_laplacian() {
    for_blocks([&](int, int begin, int end) {
      for (int i = begin; i < end; ++i) {
        double diagonal = 0.0;
        for (int s = row_[i]; s < row_[i + 1]; ++s) {
          transverse_[s] = stiffness_[s];
          diagonal += stiffness_[s];
        }
        double* inv = &block_inverse_[9 * static_cast<std::size_t>(i)];
        for (int c = 0; c < 9; ++c) inv[c] = 0.0;
        if (!fixed_[i] && diagonal > 0.0) inv[0] = inv[4] = inv[8] = 1.0 / diagonal;
      }
    });
  }

  // Forces, energy, residual, the projected Hessian's per-spring data and block-diagonal inverse.
  void evaluate() {
    for_blocks([&](int blk, int begin, int end) {
      double e = 0.0, largest = 0.0;
      for (int i = begin; i < end; ++i) {
        double f[3] = {0.0, 0.0, 0.0};
        Eigen::Matrix3d block = Eigen::Matrix3d::Zero();
        for (int s = row_[i]; s < row_[i + 1]; ++s) {
          const int q = neighbour_[s];
          const double l[3] = {x_[3 * q] - x_[3 * i], x_[3 * q + 1] - x_[3 * i + 1], x_[3 * q + 2] - x_[3 * i + 2]};
          const double len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
          const double k = stiffness_[s];
          e += 0.25 * k * (len - rest_[s]) * (len - rest_[s]);
          if (len == 0.0) {
            for (int c = 0; c < 3; ++c) direction_[3 * s + c] = 0.0;
            transverse_[s] = k;  // isotropic: a zero-length spring resists every direction alike
            block.diagonal().array() += k;
            continue;
          }
          const double w = k * (len - rest_[s]) / len;
          for (int c = 0; c < 3; ++c) {
            f[c] += w * l[c];
            direction_[3 * s + c] = l[c] / len;
          }
          const double beta = k * std::max(0.0, 1.0 - rest_[s] / len);
          transverse_[s] = k * (1.0 - rest_[s] / len);  // exact Hessian: negative when compressed
          const Eigen::Vector3d nvec(l[0] / len, l[1] / len, l[2] / len);
          block += beta * Eigen::Matrix3d::Identity() + (k - beta) * nvec * nvec.transpose();
        }
        double* inv = &block_inverse_[9 * static_cast<std::size_t>(i)];
        if (fixed_[i]) {
          for (int c = 0; c < 3; ++c) force_[3 * i + c] = 0.0;
          for (int c = 0; c < 9; ++c) inv[c] = 0.0;
          continue;
        }
        for (int c = 0; c < 3; ++c) force_[3 * i + c] = f[c];
        const double f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
        if (f2 > largest || std::isnan(f2)) largest = f2;
        bool invertible = false;
        Eigen::Matrix3d inverse;
        double det = 0.0;
        block.computeInverseAndDetWithCheck(inverse, det, invertible, 1e-300);
        if (!invertible || !inverse.allFinite())
          inverse = Eigen::Matrix3d::Identity() / std::max(block.trace() / 3.0, 1e-300);
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) inv[3 * r + c] = inverse(r, c);
      }
      partial_[blk] = e;
      partial_max_[blk] = largest;
    });
    energy_ = sum_partials();
    double largest = 0.0;
    for (int blk = 0; blk < blocks_; ++blk)
      if (partial_max_[blk] > largest || std::isnan(partial_max_[blk])) largest = partial_max_[blk];
    residual_ = std::sqrt(largest) / scale_;
    force_norm_ = std::sqrt(dot(force_, force_));
  }

  // Euclidean norm of the spring forces at the free points at x.
  double force_norm_at(const std::vector<double>& x) {
    for_blocks([&](int blk, int begin, int end) {
      double sum = 0.0;
      for (int i = begin; i < end; ++i) {
        if (fixed_[i]) continue;
        double f[3] = {0.0, 0.0, 0.0};
        for (int s = row_[i]; s < row_[i + 1]; ++s) {
          const int q = neighbour_[s];
          const double l[3] = {x[3 * q] - x[3 * i], x[3 * q + 1] - x[3 * i + 1], x[3 * q + 2] - x[3 * i + 2]};
          const double len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
          if (len == 0.0) continue;
          const double w = stiffness_[s] * (len - rest_[s]) / len;
          for (int c = 0; c < 3; ++c) f[c] += w * l[c];
        }
        sum += f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
      }
      partial_[blk] = sum;
    });
    return std::sqrt(sum_partials());
  }

  double energy_at(const std::vector<double>& x) {
    for_blocks([&](int blk, int begin, int end) {
      double e = 0.0;
      for (int i = begin; i < end; ++i)
        for (int s = row_[i]; s < row_[i + 1]; ++s) {
          const int q = neighbour_[s];
          const double l[3] = {x[3 * q] - x[3 * i], x[3 * q + 1] - x[3 * i + 1], x[3 * q + 2] - x[3 * i + 2]};
          const double stretch = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]) - rest_[s];
          e += 0.25 * stiffness_[s] * stretch * stretch;
        }
      partial_[blk] = e;
    });
    const double e = sum_partials();
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  }

  // out = H v over free points (v is zero at fixed points); returns v . out.
  double hessian_times(const std::vector<double>& v, std::vector<double>& out) {
    for_blocks([&](int blk, int begin, int end) {
      double vh = 0.0;
      for (int i = begin; i < end; ++i) {
        double h[3] = {0.0, 0.0, 0.0};
        if (!fixed_[i]) {
          for (int s = row_[i]; s < row_[i + 1]; ++s) {
            const int q = neighbour_[s];
            const double d[3] = {v[3 * i] - v[3 * q], v[3 * i + 1] - v[3 * q + 1], v[3 * i + 2] - v[3 * q + 2]};
            const double* n = &direction_[3 * s];
            const double along = (stiffness_[s] - transverse_[s]) * (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]);
            for (int c = 0; c < 3; ++c) h[c] += transverse_[s] * d[c] + along * n[c];
          }
        }
        for (int c = 0; c < 3; ++c) {
          out[3 * i + c] = h[c];
          vh += v[3 * i + c] * h[c];
        }
      }
      partial_[blk] = vh;
    });
    return sum_partials();
  }

  // z = M^-1 r (block Jacobi); returns r . z.
  double precondition(const std::vector<double>& r, std::vector<double>& z) {
    for_blocks([&](int blk, int begin, int end) {
      double rz = 0.0;
      for (int i = begin; i < end; ++i) {
        const double* inv = &block_inverse_[9 * static_cast<std::size_t>(i)];
        for (int c = 0; c < 3; ++c) {
          z[3 * i + c] = inv[3 * c] * r[3 * i] + inv[3 * c + 1] * r[3 * i + 1] + inv[3 * c + 2] * r[3 * i + 2];
          rz += r[3 * i + c] * z[3 * i + c];
        }
      }
      partial_[blk] = rz;
    });
    return sum_partials();
  }

  // Preconditioned CG for H p = b from p = 0; stops at |r| <= eta |b|. Returns iterations.
  // Three fused parallel passes an iteration: q = H d with d . q; the p, r, z updates with
  // r . r and r . z; the new direction d.
  int conjugate_gradient(const std::vector<double>& b, std::vector<double>& p, double eta) {
    std::vector<double> r = b, z(b.size()), d(b.size()), q(b.size());
    double rz = precondition(r, z);
    d = z;
    const double target = eta * std::sqrt(dot(b, b));
    const int limit = std::max(50, 40 * static_cast<int>(std::cbrt(static_cast<double>(n_))));
    int it = 0;
    for (; it < limit; ++it) {
      const double dq = hessian_times(d, q);
      // Negative curvature (compressed springs make the exact Hessian indefinite far from
      // equilibrium): stop with the direction found so far (truncated Newton, Nocedal and
      // Wright, Numerical Optimization, algorithm 7.1); on the first iteration use d itself,
      // the preconditioned steepest descent direction.
      if (!(dq > 0.0)) {
        if (it == 0) p = d;
        break;
      }
      const double alpha = rz / dq;
      for_blocks([&](int blk, int begin, int end) {
        double rr = 0.0, rz_block = 0.0;
        for (int i = begin; i < end; ++i) {
          const double* inv = &block_inverse_[9 * static_cast<std::size_t>(i)];
          for (int c = 0; c < 3; ++c) {
            const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
            p[k] += alpha * d[k];
            r[k] -= alpha * q[k];
            rr += r[k] * r[k];
          }
          for (int c = 0; c < 3; ++c) {
            const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
            z[k] = inv[3 * c] * r[3 * i] + inv[3 * c + 1] * r[3 * i + 1] + inv[3 * c + 2] * r[3 * i + 2];
            rz_block += r[k] * z[k];
          }
        }
        partial_[blk] = rr;
        partial_max_[blk] = rz_block;
      });
      const double rr = sum_partials();
      double rz_next = 0.0;
      for (int blk = 0; blk < blocks_; ++blk) rz_next += partial_max_[blk];
      if (std::sqrt(rr) <= target) {
        ++it;
        break;
      }
      const double beta = rz_next / rz;
      rz = rz_next;
      for_blocks([&](int, int begin, int end) {
        for (std::size_t k = 3 * static_cast<std::size_t>(begin); k < 3 * static_cast<std::size_t>(end); ++k)
          d[k] = z[k] + beta * d[k];
      });
    }
    return it;
  }

  SettleOptions options_;
  std::vector<Vec3> input_;
  static constexpr int kWarmSteps = 1;  // measured best of 0..10 on the bench problem
  bool stalled_ = false;

  int n_ = 0, blocks_ = 0, inner_iterations_ = 0, steps_ = 0;
  std::vector<char> fixed_;
  std::vector<int> row_, neighbour_;
  std::vector<double> stiffness_, rest_, direction_, transverse_;
  std::vector<double> x_, force_, block_inverse_, partial_, partial_max_;
  double scale_ = 1.0, energy_ = 0.0, residual_ = 0.0, force_norm_ = 0.0, initial_force_norm_ = 1.0;
};

}  // namespace

std::unique_ptr<SpringSolver> make_newton_solver(const SpringSystem& system, const SettleOptions& options) {
  return std::make_unique<NewtonSolver>(system, options);
}

}  // namespace fascicle::springs::detail
