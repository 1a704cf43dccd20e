#include "morph/parallel_ldlt.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstdint>

// The row step is the up-looking LDL' of T. A. Davis, "Algorithm 849: a concise sparse Cholesky
// factorization package", ACM TOMS 31(4), 2005, written so that each row performs Eigen 3.4's
// operations in Eigen's order (SimplicialCholeskyBase::factorize_preordered, LDLT branch, shift
// scale and offset applied the same way).

namespace fascicle {

namespace {

using Index = int;

// One task of the factorisation: its sub-tasks (independent subtrees, run side by side), then
// its rows in increasing order (a topological order of the elimination tree: parents follow
// children).
struct Task {
  std::vector<int> items;
  std::vector<Index> rows;
};

struct Work {
  std::vector<double> y;
  std::vector<Index> pattern, tags;
  explicit Work(Index n)
      : y(static_cast<std::size_t>(n), 0.0),
        pattern(static_cast<std::size_t>(n)),
        tags(static_cast<std::size_t>(n), -1) {}
};

}  // namespace

struct ParallelLDLT::Plan {
  Matrix permuted;          // P A P' (upper triangle), values gathered per factorize
  std::vector<int> gather;  // per slot of `permuted`: slot of `a` it comes from
  std::vector<Task> tasks;  // tasks.back() is the root task
};

ParallelLDLT::ParallelLDLT() : plan_(std::make_unique<Plan>()) {}
ParallelLDLT::~ParallelLDLT() = default;

int ParallelLDLT::task_count() const { return static_cast<int>(plan_->tasks.size()); }

void ParallelLDLT::analyzePattern(const Matrix& a) {
  Eigen::SimplicialLDLT<Matrix>::analyzePattern(a);
  Plan& plan = *plan_;
  const Index n = static_cast<Index>(a.cols());
  // The permutation's slots: the same permutation applied to the slot numbers as values.
  {
    Matrix numbered = a;
    numbered.makeCompressed();
    for (Eigen::Index s = 0; s < numbered.nonZeros(); ++s) numbered.valuePtr()[s] = static_cast<double>(s);
    plan.permuted.resize(n, n);
    plan.permuted.selfadjointView<Eigen::Upper>() = numbered.selfadjointView<Eigen::Lower>().twistedBy(m_P);
    plan.permuted.makeCompressed();
    plan.gather.resize(static_cast<std::size_t>(plan.permuted.nonZeros()));
    for (Eigen::Index s = 0; s < plan.permuted.nonZeros(); ++s)
      plan.gather[static_cast<std::size_t>(s)] = static_cast<int>(plan.permuted.valuePtr()[s]);
  }
  const int threads = std::max(1, tbb::this_task_arena::max_concurrency());
  plan.tasks.clear();
  if (threads == 1) {  // one task: every row in order, as Eigen
    Task all;
    all.rows.resize(static_cast<std::size_t>(n));
    for (Index k = 0; k < n; ++k) all.rows[static_cast<std::size_t>(k)] = k;
    plan.tasks.push_back(std::move(all));
    return;
  }
  // Each row's work: the column entries its triangular solve reads (a symbolic run).
  std::vector<double> cost(static_cast<std::size_t>(n), 0.0);
  {
    std::vector<Index> count(static_cast<std::size_t>(n), 0), tags(static_cast<std::size_t>(n), -1);
    const int* outer = plan.permuted.outerIndexPtr();
    const int* inner = plan.permuted.innerIndexPtr();
    for (Index k = 0; k < n; ++k) {
      tags[k] = k;
      double c = 1.0;
      for (int p = outer[k]; p < outer[k + 1]; ++p)
        for (Index i = inner[p]; i < k && tags[i] != k; i = m_parent[i]) {
          tags[i] = k;
          c += 1.0 + count[i];
          ++count[i];
        }
      cost[k] = c;
    }
  }
  // Subtree work and children.
  std::vector<double> subtree(cost);
  std::vector<std::vector<Index>> children(static_cast<std::size_t>(n));
  std::vector<Index> roots;
  for (Index k = 0; k < n; ++k) {
    if (m_parent[k] >= 0) {
      subtree[m_parent[k]] += subtree[k];
      children[m_parent[k]].push_back(k);
    } else {
      roots.push_back(k);
    }
  }
  double total = 0.0;
  for (Index r : roots) total += subtree[r];
  // Subtrees below this much work run as one task.
  const double grain = std::max(total / (8.0 * threads), 2000.0);
  // Every node of the subtree of r, appended to `out` (in no order: callers sort).
  auto collect = [&](Index r, std::vector<Index>& out) {
    std::vector<Index> stack{r};
    while (!stack.empty()) {
      const Index v = stack.back();
      stack.pop_back();
      out.push_back(v);
      for (Index c : children[v]) stack.push_back(c);
    }
  };
  // The task of a set of sibling subtrees: big ones get their own tasks, small ones are grouped
  // (each group one task of at least a grain's work where there is that much).
  struct Builder {
    const std::vector<double>& subtree;
    const std::vector<std::vector<Index>>& children;
    double grain;
    std::vector<Task>& tasks;
    decltype(collect)& collect_nodes;

    // Tasks for sibling subtrees `tops`; returns their task indices.
    std::vector<int> siblings(const std::vector<Index>& tops) {
      std::vector<int> out;
      Task group;
      double group_work = 0.0;
      for (Index c : tops) {
        if (subtree[c] > grain) {
          out.push_back(subtree_task(c));
        } else {
          collect_nodes(c, group.rows);
          group_work += subtree[c];
          if (group_work >= grain) {
            std::sort(group.rows.begin(), group.rows.end());
            tasks.push_back(std::move(group));
            out.push_back(static_cast<int>(tasks.size()) - 1);
            group = Task{};
            group_work = 0.0;
          }
        }
      }
      if (!group.rows.empty()) {
        std::sort(group.rows.begin(), group.rows.end());
        tasks.push_back(std::move(group));
        out.push_back(static_cast<int>(tasks.size()) - 1);
      }
      return out;
    }

    // A big subtree: down from r while a node has one big child (the chain), the small
    // subtrees hanging off the chain and the children where it ends as this task's items, the
    // chain as its rows. So the tasks nest only where two big subtrees branch (at most about
    // total / grain deep), however long the chains.
    int subtree_task(Index r) {
      Task task;
      std::vector<Index> hanging;
      Index v = r;
      for (;;) {
        task.rows.push_back(v);
        Index big = -1;
        int bigs = 0;
        for (Index c : children[v])
          if (subtree[c] > grain) big = c, ++bigs;
        if (bigs == 1) {
          for (Index c : children[v])
            if (c != big) hanging.push_back(c);
          v = big;
          continue;
        }
        for (Index c : children[v]) hanging.push_back(c);
        break;
      }
      task.items = siblings(hanging);
      std::reverse(task.rows.begin(), task.rows.end());
      tasks.push_back(std::move(task));
      return static_cast<int>(tasks.size()) - 1;
    }
  } builder{subtree, children, grain, plan.tasks, collect};
  Task root;
  root.items = builder.siblings(roots);
  plan.tasks.push_back(std::move(root));
}

void ParallelLDLT::factorize(const Matrix& a) {
  Plan& plan = *plan_;
  const Index n = static_cast<Index>(plan.permuted.cols());
  eigen_assert(a.isCompressed() && a.cols() == n);
  // P A P' by the gather found in analyzePattern.
  double* values = plan.permuted.valuePtr();
  const double* from = a.valuePtr();
  for (std::size_t s = 0; s < plan.gather.size(); ++s) values[s] = from[plan.gather[s]];
  m_diag.resize(n);
  const int* outer = plan.permuted.outerIndexPtr();
  const int* inner = plan.permuted.innerIndexPtr();
  const int* Lp = m_matrix.outerIndexPtr();
  int* Li = m_matrix.innerIndexPtr();
  double* Lx = m_matrix.valuePtr();
  int* count = m_nonZerosPerCol.data();
  const int* parent = m_parent.data();
  double* diag = m_diag.data();
  const double scale = m_shiftScale, offset = m_shiftOffset;
  std::atomic<bool> zero_pivot{false};
  tbb::enumerable_thread_specific<Work> works([n] { return Work(n); });

  auto row = [&](Index k, Work& w) {
    double* y = w.y.data();
    Index* pattern = w.pattern.data();
    Index* tags = w.tags.data();
    y[k] = 0.0;
    Index top = n;
    tags[k] = k;
    count[k] = 0;
    for (int p = outer[k]; p < outer[k + 1]; ++p) {
      Index i = inner[p];
      if (i > k) continue;
      y[i] += values[p];
      Index len = 0;
      for (; tags[i] != k; i = parent[i]) {
        pattern[len++] = i;
        tags[i] = k;
      }
      while (len > 0) pattern[--top] = pattern[--len];
    }
    double d = y[k] * scale + offset;
    y[k] = 0.0;
    for (; top < n; ++top) {
      const Index i = pattern[top];
      const double yi = y[i];
      y[i] = 0.0;
      const double l_ki = yi / diag[i];
      const int end = Lp[i] + count[i];
      int p = Lp[i];
      for (; p < end; ++p) y[Li[p]] -= Lx[p] * yi;
      d -= l_ki * yi;
      Li[p] = k;
      Lx[p] = l_ki;
      ++count[i];
    }
    diag[k] = d;
    if (d == 0.0) zero_pivot.store(true, std::memory_order_relaxed);
  };

  struct Runner {
    const std::vector<Task>& tasks;
    decltype(row)& do_row;
    tbb::enumerable_thread_specific<Work>& works;
    std::atomic<bool>& failed;
    void run(int t) const {
      const Task& task = tasks[static_cast<std::size_t>(t)];
      if (task.items.size() == 1) {
        run(task.items[0]);
      } else if (task.items.size() > 1) {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, task.items.size(), 1),
            [&](const tbb::blocked_range<std::size_t>& r) {
              for (std::size_t i = r.begin(); i != r.end(); ++i) run(task.items[i]);
            },
            tbb::simple_partitioner());
      }
      if (task.rows.empty() || failed.load(std::memory_order_relaxed)) return;
      Work& w = works.local();
      for (Index k : task.rows) do_row(k, w);
    }
  } runner{plan.tasks, row, works, zero_pivot};
  runner.run(static_cast<int>(plan.tasks.size()) - 1);
  m_info = zero_pivot.load() ? Eigen::NumericalIssue : Eigen::Success;
  m_factorizationIsOk = true;
}

Eigen::MatrixXd ParallelLDLT::solve_columns(const Eigen::MatrixXd& b) const {
  Eigen::MatrixXd x(b.rows(), b.cols());
  tbb::parallel_for(Eigen::Index(0), b.cols(), [&](Eigen::Index j) {
    const Eigen::VectorXd column = b.col(j);
    x.col(j) = solve(column);
  });
  return x;
}

}  // namespace fascicle
