// The static solver: local-global iteration of Liu, Bargteil, O'Brien and Kavan 2013, "Fast
// simulation of mass-spring systems", without the inertia term (we want the equilibrium, not a
// trajectory). Energy E(x) = sum_s D_s / 2 (|x_a - x_b| - r_s)^2
//                          = min over |d_s| = r_s of sum_s D_s / 2 |x_a - x_b - d_s|^2.
// Local step: d_s = r_s (x_a - x_b) / |x_a - x_b|. Global step: L x = J d + (fixed terms), with
// L = sum_s D_s A_s A_s^T over free points: constant, so it is factored once (SimplicialLDLT)
// and each iteration is one back-substitution for the three coordinates. Each iteration lowers
// E. Anderson acceleration (window m) extrapolates the fixed-point map x -> G(x); an
// extrapolated iterate is kept only when it lowers the energy below the previous iterate's,
// else the plain G(x) is taken and the history cleared (Peng et al. 2018).

#include "geometry/errors.h"
#include "springs/solvers_internal.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <cmath>
#include <memory>

namespace fascicle::springs {

// The factor and what it was made for (points, fixed flags, spring ends and stiffnesses), so that
// a factor given for another system is refused instead of solving the wrong equations.
class SpringMatrixFactor {
 public:
  explicit SpringMatrixFactor(const SpringSystem& system) : fixed_(system.fixed) {
    const int n = static_cast<int>(system.positions.size());
    detail::check_anchored(system);  // a part without a fixed point would make L singular
    free_id.assign(n, -1);
    for (int i = 0; i < n; ++i)
      if (!system.fixed[i]) free_id[i] = free_count++;
    std::vector<Eigen::Triplet<double>> triplets;
    springs_.reserve(system.springs.size());
    for (const Spring& s : system.springs) {
      springs_.push_back({s.a, s.b, 0.0, s.stiffness});
      const int fa = free_id[s.a], fb = free_id[s.b];
      if (fa >= 0) triplets.emplace_back(fa, fa, s.stiffness);
      if (fb >= 0) triplets.emplace_back(fb, fb, s.stiffness);
      if (fa >= 0 && fb >= 0) {
        triplets.emplace_back(fa, fb, -s.stiffness);
        triplets.emplace_back(fb, fa, -s.stiffness);
      }
    }
    Eigen::SparseMatrix<double> laplacian(free_count, free_count);
    laplacian.setFromTriplets(triplets.begin(), triplets.end());
    if (free_count > 0) {
      ldlt.compute(laplacian);
      if (ldlt.info() != Eigen::Success)
        throw SolverError(
            "static: factorizing the spring matrix failed (a part of the system has no "
            "fixed point?); fix points or use --solver verlet");
    }
  }

  bool made_for(const SpringSystem& system) const {
    if (system.fixed != fixed_ || system.springs.size() != springs_.size()) return false;
    for (std::size_t i = 0; i < springs_.size(); ++i) {
      const Spring& s = system.springs[i];
      if (s.a != springs_[i].a || s.b != springs_[i].b || s.stiffness != springs_[i].stiffness) return false;
    }
    return true;
  }

  std::vector<int> free_id;  // free point index of each point, -1 for a fixed one
  int free_count = 0;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;

 private:
  std::vector<char> fixed_;
  std::vector<Spring> springs_;  // ends and stiffness (rest lengths play no part)
};

std::shared_ptr<const SpringMatrixFactor> factor_spring_matrix(const SpringSystem& system) {
  validate(system);
  return std::make_shared<const SpringMatrixFactor>(system);
}

namespace detail {
namespace {

class StaticSolver final : public SpringSolver {
 public:
  StaticSolver(const SpringSystem& system, const SettleOptions& options,
               std::shared_ptr<const SpringMatrixFactor> factor)
      : options_(options),
        system_(system),
        x_(system.positions),
        factor_(factor ? std::move(factor) : std::make_shared<const SpringMatrixFactor>(system)),
        free_id_(factor_->free_id),
        free_count_(factor_->free_count),
        ldlt_(factor_->ldlt) {
    if (!factor_->made_for(system))
      throw Error(ErrorCode::internal, "static: the spring matrix factor given was made for another spring system");
    fixed_rhs_ = Eigen::MatrixXd::Zero(free_count_, 3);
    for (const Spring& s : system.springs) {
      const int fa = free_id_[s.a], fb = free_id_[s.b];
      if (fa >= 0 && fb < 0) fixed_rhs_.row(fa) += s.stiffness * system.positions[s.b].transpose();
      if (fb >= 0 && fa < 0) fixed_rhs_.row(fb) += s.stiffness * system.positions[s.a].transpose();
    }
    scale_ = residual_force_scale(system);
    current_ = gather(x_);
    evaluate(x_, &energy_, &residual_);
  }

  double step() override {
    if (free_count_ == 0) return 0.0;
    const Eigen::VectorXd g = global_step(x_);
    Eigen::VectorXd next = g;
    if (options_.acceleration == Acceleration::anderson) {
      const Eigen::VectorXd f = g - current_;
      if (have_last_) {
        push_history(f - last_f_, g - last_g_);
        const Eigen::VectorXd accelerated = anderson(g, f);
        std::vector<Vec3> trial = scatter(accelerated);
        double trial_energy = 0.0, trial_residual = 0.0;
        evaluate(trial, &trial_energy, &trial_residual);
        if (std::isfinite(trial_energy) && trial_energy < energy_) {
          last_f_ = f;
          last_g_ = g;
          accept(accelerated, std::move(trial), trial_energy, trial_residual);
          return residual_;
        }
        clear_history();  // extrapolation raised the energy: take the plain step, restart
      }
      last_f_ = f;
      last_g_ = g;
      have_last_ = true;
    }
    std::vector<Vec3> positions = scatter(next);
    double e = 0.0, r = 0.0;
    evaluate(positions, &e, &r);
    if (!std::isfinite(e) || !std::isfinite(r))
      throw SolverError(
          "static: the solve produced NaN/Inf (springs of zero length with nonzero "
          "rest length?); check the input or use --solver verlet");
    accept(next, std::move(positions), e, r);
    return residual_;
  }

  double residual() override { return residual_; }
  double energy() override { return energy_; }
  std::vector<Vec3> positions() const override { return x_; }
  std::string backend() const override { return "ldlt"; }

 private:
  Eigen::VectorXd gather(const std::vector<Vec3>& positions) const {
    Eigen::VectorXd v(3 * static_cast<Eigen::Index>(free_count_));
    for (std::size_t i = 0; i < positions.size(); ++i)
      if (free_id_[i] >= 0) v.segment<3>(3 * free_id_[i]) = positions[i];
    return v;
  }

  std::vector<Vec3> scatter(const Eigen::VectorXd& v) const {
    std::vector<Vec3> positions = system_.positions;  // fixed points: the input's exact bits
    for (std::size_t i = 0; i < positions.size(); ++i)
      if (free_id_[i] >= 0) positions[i] = v.segment<3>(3 * free_id_[i]);
    return positions;
  }

  // Local step (project every spring onto its rest length) and global step (back-substitution).
  Eigen::VectorXd global_step(const std::vector<Vec3>& positions) {
    Eigen::MatrixXd rhs = fixed_rhs_;
    for (const Spring& s : system_.springs) {
      const int fa = free_id_[s.a], fb = free_id_[s.b];
      if (fa < 0 && fb < 0) continue;
      const Vec3 l = positions[s.a] - positions[s.b];
      const double len = l.norm();
      if (len == 0.0 || s.rest == 0.0) continue;  // zero rest length: d = 0
      const Vec3 d = (s.stiffness * s.rest / len) * l;
      if (fa >= 0) rhs.row(fa) += d.transpose();
      if (fb >= 0) rhs.row(fb) -= d.transpose();
    }
    const Eigen::MatrixXd solution = ldlt_.solve(rhs);
    Eigen::VectorXd v(3 * static_cast<Eigen::Index>(free_count_));
    for (int i = 0; i < free_count_; ++i) v.segment<3>(3 * i) = solution.row(i).transpose();
    return v;
  }

  void evaluate(const std::vector<Vec3>& positions, double* energy, double* residual) const {
    *energy = potential_energy(system_, positions);
    *residual = relative_residual(system_, positions);
  }

  void accept(const Eigen::VectorXd& v, std::vector<Vec3>&& positions, double e, double r) {
    current_ = v;
    x_ = std::move(positions);
    energy_ = e;
    residual_ = r;
  }

  void push_history(const Eigen::VectorXd& df, const Eigen::VectorXd& dg) {
    if (static_cast<int>(df_.size()) == options_.anderson_window) {
      df_.erase(df_.begin());
      dg_.erase(dg_.begin());
    }
    df_.push_back(df);
    dg_.push_back(dg);
  }

  void clear_history() {
    df_.clear();
    dg_.clear();
    have_last_ = false;
  }

  // Type-II Anderson: gamma = argmin |f - dF gamma|, x = g - dG gamma (normal equations with a
  // small Tikhonov term; the history is short).
  Eigen::VectorXd anderson(const Eigen::VectorXd& g, const Eigen::VectorXd& f) const {
    const int m = static_cast<int>(df_.size());
    Eigen::MatrixXd gram(m, m);
    Eigen::VectorXd rhs(m);
    for (int i = 0; i < m; ++i) {
      rhs(i) = df_[i].dot(f);
      for (int j = 0; j <= i; ++j) gram(i, j) = gram(j, i) = df_[i].dot(df_[j]);
    }
    const double trace = gram.trace();
    gram.diagonal().array() += 1e-12 * (trace > 0.0 ? trace : 1.0);
    const Eigen::VectorXd gamma = gram.ldlt().solve(rhs);
    Eigen::VectorXd x = g;
    for (int i = 0; i < m; ++i) x -= gamma(i) * dg_[i];
    return x;
  }

  SettleOptions options_;
  SpringSystem system_;
  std::vector<Vec3> x_;
  std::shared_ptr<const SpringMatrixFactor> factor_;
  const std::vector<int>& free_id_;
  const int free_count_;
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt_;
  Eigen::MatrixXd fixed_rhs_;
  Eigen::VectorXd current_, last_f_, last_g_;
  bool have_last_ = false;
  std::vector<Eigen::VectorXd> df_, dg_;
  double scale_ = 1.0, energy_ = 0.0, residual_ = 0.0;
};

}  // namespace

std::unique_ptr<SpringSolver> make_static_solver(const SpringSystem& system, const SettleOptions& options,
                                                 std::shared_ptr<const SpringMatrixFactor> factor) {
  return std::make_unique<StaticSolver>(system, options, std::move(factor));
}

}  // namespace detail
}  // namespace fascicle::springs
