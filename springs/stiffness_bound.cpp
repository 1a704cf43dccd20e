// The step of the momentum static solver: an estimate of the largest eigenvalue of the spring
// energy's Hessian over the free points, by the Lanczos method (Lanczos 1950; as in Golub and
// Van Loan, "Matrix Computations", ch. 10.1), a few steps from a fixed pseudo-random start.
//
// The matrix is an upper bound of the Hessian at the starting positions: a spring's 3 x 3 block
// is D (u u^T + max(0, 1 - |l0| / |l|) (I - u u^T)) (u = l / |l|), i.e. its compressed springs
// count with no sideways stiffness instead of a negative one. Its largest eigenvalue is far
// below the Gershgorin bound 2 max_i sum_j D_ij when the springs are near rest: a spring is
// stiff only along itself (measured about 2x below on model-6, 3x on model-26 lattices).

#include "springs/solvers_internal.h"

#include <Eigen/Eigenvalues>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace fascicle::springs::detail {

namespace {

constexpr long kBlock = 4096;  // points per parallel block (fixed: deterministic sums)

// out = M v over free points (fixed points' rows and columns are zero); gather over the rows,
// each point's on its own (any split among threads gives the same bits: in ranges of 512 points,
// so that a decomposition's lattice of a few thousand uses both cores).
void multiply(const SpringSystem& system, const SpringRows& rows, const std::vector<double>& v,
              std::vector<double>& out) {
  const long n = static_cast<long>(system.positions.size());
  tbb::parallel_for(tbb::blocked_range<long>(0, n, 512), [&](const tbb::blocked_range<long>& range) {
    for (long p = range.begin(); p != range.end(); ++p) {
      double r[3] = {0.0, 0.0, 0.0};
      if (!system.fixed[p]) {
        for (int slot = rows.row[p]; slot < rows.row[p + 1]; ++slot) {
          const int q = rows.neighbour[slot];
          const Vec3 l = system.positions[q] - system.positions[p];
          const double length = l.norm();
          if (!(length > 0.0)) continue;
          const Vec3 u = l / length;
          const double side = std::max(0.0, 1.0 - rows.rest[slot] / length);
          // d = v_p - v_q (v is 0 at fixed points); block D (u u^T + side (I - u u^T)) d
          Vec3 d(v[3 * p], v[3 * p + 1], v[3 * p + 2]);
          if (!system.fixed[q]) d -= Vec3(v[3 * q], v[3 * q + 1], v[3 * q + 2]);
          const double along = u.dot(d);
          const Vec3 f = rows.stiffness[slot] * (along * u + side * (d - along * u));
          for (int c = 0; c < 3; ++c) r[c] += f[c];
        }
      }
      for (int c = 0; c < 3; ++c) out[3 * p + c] = r[c];
    }
  });
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  const long m = static_cast<long>(a.size());
  const long blocks = (m + 3 * kBlock - 1) / (3 * kBlock);
  std::vector<double> partial(static_cast<std::size_t>(std::max(1L, blocks)), 0.0);
  tbb::parallel_for(tbb::blocked_range<long>(0, blocks, 1), [&](const tbb::blocked_range<long>& range) {
    for (long blk = range.begin(); blk != range.end(); ++blk) {
      double s = 0.0;
      const long end = std::min(m, (blk + 1) * 3 * kBlock);
      for (long i = blk * 3 * kBlock; i < end; ++i) s += a[i] * b[i];
      partial[blk] = s;
    }
  });
  double s = 0.0;
  for (double v : partial) s += v;
  return s;
}

}  // namespace

double largest_stiffness_eigenvalue(const SpringSystem& system, int steps) {
  const long n = static_cast<long>(system.positions.size());
  const SpringRows rows = spring_rows(system);
  std::vector<double> v(3 * n, 0.0), previous(3 * n, 0.0), w(3 * n, 0.0);
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (long p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) v[3 * p + c] = system.fixed[p] ? 0.0 : uniform(rng);
  double norm = std::sqrt(dot(v, v));
  if (!(norm > 0.0)) return 0.0;
  for (double& x : v) x /= norm;
  std::vector<double> alpha, beta;
  double beta_previous = 0.0, estimate = 0.0;
  for (int step = 0; step < steps; ++step) {
    multiply(system, rows, v, w);
    for (long i = 0; i < 3 * n; ++i) w[i] -= beta_previous * previous[i];
    const double a = dot(w, v);
    for (long i = 0; i < 3 * n; ++i) w[i] -= a * v[i];
    alpha.push_back(a);
    // Largest eigenvalue of the tridiagonal matrix so far: the Ritz value, a lower bound.
    Eigen::VectorXd diagonal = Eigen::Map<const Eigen::VectorXd>(alpha.data(), static_cast<long>(alpha.size()));
    Eigen::VectorXd off = beta.empty()
                              ? Eigen::VectorXd()
                              : Eigen::Map<const Eigen::VectorXd>(beta.data(), static_cast<long>(beta.size())).eval();
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver;
    solver.computeFromTridiagonal(diagonal, off, Eigen::EigenvaluesOnly);
    const double ritz = solver.eigenvalues().maxCoeff();
    const bool settled = step >= 4 && ritz <= estimate * (1.0 + 1e-4);
    estimate = std::max(estimate, ritz);
    if (settled) break;
    const double b = std::sqrt(dot(w, w));
    if (!(b > 1e-12 * std::abs(estimate))) break;  // an invariant subspace: the estimate is exact
    beta.push_back(b);
    beta_previous = b;
    previous.swap(v);
    for (long i = 0; i < 3 * n; ++i) v[i] = w[i] / b;
  }
  return estimate;
}

}  // namespace fascicle::springs::detail
