#pragma once
/// \file parallel_ldlt.h
/// Eigen's SimplicialLDLT (lower triangle, AMD ordering) with a numeric factorisation that runs
/// independent subtrees of the elimination tree on threads.
///
/// Eigen factorises row by row (the up-looking LDL' of Davis's LDL package): row k of L is a
/// sparse triangular solve that reads only the columns of k's descendants in the elimination
/// tree and appends one entry to each. Rows in disjoint subtrees therefore touch disjoint
/// columns, and a row's descendants are all it waits for. ParallelLDLT runs the subtrees side by
/// side and every row with the same operations in the same order as Eigen's serial loop, so the
/// factor, the pivots and every solve with them are the same to the bit as
/// Eigen::SimplicialLDLT's, on any number of threads.
///
/// For a matrix whose pattern stays while its values change (refactorised many times), the
/// symmetric permutation of the values is a gather through slots found once in analyzePattern
/// (Eigen permutes the whole matrix at every factorize).

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <memory>
#include <vector>

namespace fascicle {

class ParallelLDLT : public Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> {
 public:
  using Matrix = Eigen::SparseMatrix<double>;

  ParallelLDLT();
  ~ParallelLDLT();
  ParallelLDLT(const ParallelLDLT&) = delete;
  ParallelLDLT& operator=(const ParallelLDLT&) = delete;

  /// Ordering, elimination tree and column counts (Eigen's), then the task tree of the
  /// factorisation and the permutation's gather slots. `a`: square and compressed (makeCompressed), the lower
  /// triangle read (as Eigen's Lower).
  void analyzePattern(const Matrix& a);

  /// Numeric factorisation of `a`, which must have the pattern (and storage order of its
  /// entries) given to analyzePattern. info() is Success, or NumericalIssue on a zero pivot.
  void factorize(const Matrix& a);

  /// analyzePattern then factorize.
  void compute(const Matrix& a) {
    analyzePattern(a);
    factorize(a);
  }

  /// solve(b) column by column, the columns on threads: each column the same to the bit as
  /// solve(b)'s (Eigen's sparse triangular solves treat the columns one after the other).
  Eigen::MatrixXd solve_columns(const Eigen::MatrixXd& b) const;

  /// Tasks of the factorisation (leaves and inner nodes of the task tree); 1 when it is serial.
  int task_count() const;

 private:
  struct Plan;
  std::unique_ptr<Plan> plan_;
};

}  // namespace fascicle
