// ParallelLDLT: the same factor, pivots and solves as Eigen's SimplicialLDLT, to the bit, on any
// number of threads.
#include "morph/parallel_ldlt.h"
#include "tests/morph_test_shapes.h"

#include <catch2/catch.hpp>
#include <tbb/task_arena.h>

#include <cstring>
#include <random>

using namespace fascicle;

namespace {

using Matrix = Eigen::SparseMatrix<double>;
using EigenLDLT = Eigen::SimplicialLDLT<Matrix>;

// A weighted graph Laplacian of the mesh's edges (random positive weights) plus `shift` on the
// diagonal: symmetric, positive definite for shift > 0, stored whole (both triangles).
Matrix mesh_laplacian(const TriangleMesh& mesh, unsigned seed, double shift) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> weight(0.1, 10.0);
  const int n = static_cast<int>(mesh.positions.size());
  std::vector<Eigen::Triplet<double>> entries;
  for (const Triangle& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      const double w = weight(rng);
      entries.emplace_back(a, b, -w);
      entries.emplace_back(b, a, -w);
      entries.emplace_back(a, a, w);
      entries.emplace_back(b, b, w);
    }
  for (int i = 0; i < n; ++i) entries.emplace_back(i, i, shift);
  Matrix a(n, n);
  a.setFromTriplets(entries.begin(), entries.end());
  a.makeCompressed();
  return a;
}

// New values on the same pattern.
void reweight(Matrix& a, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> factor(0.5, 2.0);
  Matrix upper = a.triangularView<Eigen::StrictlyUpper>();
  for (int k = 0; k < upper.outerSize(); ++k)
    for (Matrix::InnerIterator it(upper, k); it; ++it) it.valueRef() *= factor(rng);
  Matrix sym = Matrix(upper) + Matrix(upper.transpose());
  Eigen::VectorXd degree = -(sym * Eigen::VectorXd::Ones(a.cols()));
  for (int k = 0; k < a.outerSize(); ++k)
    for (Matrix::InnerIterator it(a, k); it; ++it)
      it.valueRef() = it.row() == it.col() ? degree[k] + 1e-3 : sym.coeff(it.row(), it.col());
}

bool same_bits(const double* a, const double* b, Eigen::Index n) {
  return std::memcmp(a, b, sizeof(double) * static_cast<std::size_t>(n)) == 0;
}

void require_same(const EigenLDLT& reference, const ParallelLDLT& ours, const Eigen::MatrixXd& rhs) {
  REQUIRE(ours.info() == reference.info());
  const Eigen::VectorXd d0 = reference.vectorD(), d1 = ours.vectorD();
  REQUIRE(d0.size() == d1.size());
  CHECK(same_bits(d0.data(), d1.data(), d0.size()));
  const Matrix l0 = reference.matrixL(), l1 = ours.matrixL();
  REQUIRE(l0.nonZeros() == l1.nonZeros());
  CHECK(same_bits(l0.valuePtr(), l1.valuePtr(), l0.nonZeros()));
  CHECK(std::memcmp(l0.innerIndexPtr(), l1.innerIndexPtr(), sizeof(int) * static_cast<std::size_t>(l0.nonZeros())) ==
        0);
  const Eigen::MatrixXd x0 = reference.solve(rhs), x1 = ours.solve(rhs), x2 = ours.solve_columns(rhs);
  CHECK(same_bits(x0.data(), x1.data(), x0.size()));
  CHECK(same_bits(x0.data(), x2.data(), x0.size()));
  // And it is a solution.
  CHECK(x0.allFinite());
}

}  // namespace

TEST_CASE("ParallelLDLT factors and solves to the bit as Eigen's SimplicialLDLT on one thread and on two",
          "[morph][ldlt]") {
  const TriangleMesh mesh = test::bent_capsule(1.0, 12.0, 48, 90.0);  // a few thousand unknowns
  Matrix a = mesh_laplacian(mesh, 7, 1e-3);
  const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(a.rows(), 2);
  for (int threads : {1, 2}) {
    DYNAMIC_SECTION("threads " << threads) {
      tbb::task_arena arena(threads);
      arena.execute([&] {
        EigenLDLT reference;
        ParallelLDLT ours;
        reference.analyzePattern(a);
        ours.analyzePattern(a);
        if (threads == 1)
          CHECK(ours.task_count() == 1);
        else
          CHECK(ours.task_count() > 2);  // independent subtrees exist and are used
        INFO("tasks " << ours.task_count() << ", unknowns " << a.rows());
        // Three factorisations on the same pattern with new values each time (the gather, the
        // per-call workspaces).
        Matrix values = a;
        for (unsigned round = 0; round < 3; ++round) {
          if (round > 0) reweight(values, round);
          reference.factorize(values);
          ours.factorize(values);
          require_same(reference, ours, rhs);
        }
        // The residual of a solve, against the matrix itself.
        const Eigen::MatrixXd x = ours.solve_columns(rhs);
        const double residual = (Matrix(values.selfadjointView<Eigen::Lower>()) * x - rhs).norm() / rhs.norm();
        CHECK(residual < 1e-8);
      });
    }
  }
}

TEST_CASE("ParallelLDLT reports a zero pivot as Eigen does, and handles a forest", "[morph][ldlt]") {
  // A diagonal matrix (its elimination tree is a forest of single nodes) with one zero entry.
  const int n = 5000;
  Matrix a(n, n);
  std::vector<Eigen::Triplet<double>> entries;
  for (int i = 0; i < n; ++i) entries.emplace_back(i, i, i == 1234 ? 0.0 : 1.0 + i);
  a.setFromTriplets(entries.begin(), entries.end());
  a.makeCompressed();
  tbb::task_arena arena(2);
  arena.execute([&] {
    EigenLDLT reference;
    ParallelLDLT ours;
    reference.compute(a);
    ours.compute(a);
    CHECK(reference.info() == Eigen::NumericalIssue);
    CHECK(ours.info() == Eigen::NumericalIssue);
    // Without the zero: the same pivots.
    a.coeffRef(1234, 1234) = 3.0;
    reference.factorize(a);
    ours.factorize(a);
    REQUIRE(ours.info() == Eigen::Success);
    require_same(reference, ours, Eigen::MatrixXd::Ones(n, 2));
  });
}

TEST_CASE("ParallelLDLT plans a long caterpillar elimination tree without deep nesting", "[morph][ldlt]") {
  // A path of m nodes with a leaf on each: elimination trees of such matrices are long chains
  // with small subtrees hanging off them (a task per chain node would nest m deep).
  const int m = 100000, n = 2 * m;
  std::vector<Eigen::Triplet<double>> entries;
  for (int i = 0; i < m; ++i) {
    entries.emplace_back(i, i, 4.0);
    entries.emplace_back(m + i, m + i, 2.0);
    entries.emplace_back(i, m + i, -1.0);
    entries.emplace_back(m + i, i, -1.0);
    if (i + 1 < m) {
      entries.emplace_back(i, i + 1, -1.0);
      entries.emplace_back(i + 1, i, -1.0);
    }
  }
  Matrix a(n, n);
  a.setFromTriplets(entries.begin(), entries.end());
  a.makeCompressed();
  tbb::task_arena arena(2);
  arena.execute([&] {
    EigenLDLT reference;
    ParallelLDLT ours;
    reference.compute(a);
    ours.compute(a);
    REQUIRE(ours.info() == Eigen::Success);
    require_same(reference, ours, Eigen::MatrixXd::Ones(n, 2));
  });
}
