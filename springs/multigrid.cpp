// Geometric multigrid for the spring Laplacian on a lattice grid (multigrid.h).

#include "springs/multigrid.h"

#include "geometry/errors.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

namespace fascicle::springs {

void MultigridOptions::validate() const {
  if (smoothing_steps < 1 || smoothing_steps > 20)
    throw OptionError("multigrid_smoothing_steps: must be in 1..20, got " + std::to_string(smoothing_steps));
  if (coarsest_points < 8 || coarsest_points > 200000)
    throw OptionError("multigrid_coarsest_points: must be in 8..200000, got " + std::to_string(coarsest_points));
}

namespace {

constexpr std::size_t kGrain = 4096;  // rows per parallel block (fixed: sums do not depend on threads)
constexpr int kReach = 3;             // Galerkin accumulation window: offsets -3..3 per dimension
constexpr int kWindow = 2 * kReach + 1;

int coarse_size(int n) { return n > 3 ? n / 2 + 1 : n; }

// Interpolation along one dimension: fine point i takes w0 of coarse p0 and w1 of coarse p1
// (p1 = -1 when it sits on a coarse point); children list, per coarse point, the fine points
// it interpolates to, with their weights.
struct DimMap {
  int fine = 0, coarse = 0;
  std::vector<int> p0, p1;
  std::vector<double> w0, w1;
  std::vector<int> child_ptr, child;
  std::vector<double> child_w;
};

DimMap make_map(int n, bool coarsen) {
  DimMap m;
  m.fine = n;
  m.coarse = coarsen ? coarse_size(n) : n;
  m.p0.assign(n, -1);
  m.p1.assign(n, -1);
  m.w0.assign(n, 0.0);
  m.w1.assign(n, 0.0);
  if (m.coarse == n) {
    for (int i = 0; i < n; ++i) {
      m.p0[i] = i;
      m.w0[i] = 1.0;
    }
  } else {
    std::vector<int> pos(m.coarse);
    for (int c = 0; c < m.coarse; ++c) pos[c] = std::min(2 * c, n - 1);
    for (int c = 0; c + 1 < m.coarse; ++c) {
      const int a = pos[c], b = pos[c + 1];
      for (int i = a; i < b; ++i) {
        const double t = static_cast<double>(i - a) / (b - a);
        m.p0[i] = c;
        m.w0[i] = 1.0 - t;
        if (i > a) {
          m.p1[i] = c + 1;
          m.w1[i] = t;
        }
      }
    }
    m.p0[n - 1] = m.coarse - 1;
    m.w0[n - 1] = 1.0;
  }
  std::vector<int> count(m.coarse, 0);
  for (int i = 0; i < n; ++i) {
    ++count[m.p0[i]];
    if (m.p1[i] >= 0) ++count[m.p1[i]];
  }
  m.child_ptr.assign(m.coarse + 1, 0);
  for (int c = 0; c < m.coarse; ++c) m.child_ptr[c + 1] = m.child_ptr[c] + count[c];
  m.child.resize(m.child_ptr.back());
  m.child_w.resize(m.child_ptr.back());
  std::vector<int> fill(m.child_ptr.begin(), m.child_ptr.end() - 1);
  for (int i = 0; i < n; ++i) {
    m.child[fill[m.p0[i]]] = i;
    m.child_w[fill[m.p0[i]]++] = m.w0[i];
    if (m.p1[i] >= 0) {
      m.child[fill[m.p1[i]]] = i;
      m.child_w[fill[m.p1[i]]++] = m.w1[i];
    }
  }
  return m;
}

struct Level {
  int nx = 0, ny = 0, nz = 0;
  std::size_t points = 0;
  // CSR rows, 3 values an entry (one operator per coordinate, same pattern); inactive rows
  // (fixed or empty) are left out of every pass
  std::vector<std::size_t> ptr;
  std::vector<int> col;
  std::vector<double> val;
  bool uniform = false;  // one value an entry, the same operator for the three coordinates
  double value(std::size_t e, int c) const { return uniform ? val[e] : val[3 * e + c]; }
  // Smoother preconditioner T (per coordinate c): the tridiagonal part of A_c along grid axis
  // axis[c] (line smoothing), or its diagonal; factored per line (Thomas): 3 values a point.
  int axis[3] = {0, 1, 2};
  std::vector<double> lo, cp, inv;
  double rho[3] = {1.0, 1.0, 1.0};  // estimated spectral radius of T^-1 A per coordinate
  std::vector<double> d, z;         // Chebyshev update, T^-1 r
  std::vector<char> active;
  std::vector<double> b, x, r;  // 3 values a point (coarse levels' right side and solution)
  DimMap mx, my, mz;            // interpolation from the next coarser level (not on the last)
};

template <typename Body>
void for_rows(std::size_t rows, Body&& body) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, kGrain),
                    [&](const tbb::blocked_range<std::size_t>& range) { body(range.begin(), range.end()); });
}

// Sum of per-block partial values in block order (independent of the thread count).
template <typename Body>
double reduce_rows(std::size_t rows, Body&& body) {
  const std::size_t blocks = (rows + kGrain - 1) / kGrain;
  std::vector<double> partial(blocks, 0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t blk = range.begin(); blk != range.end(); ++blk)
      partial[blk] = body(blk * kGrain, std::min(rows, (blk + 1) * kGrain));
  });
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

}  // namespace

struct LatticeMultigrid::Impl {
  MultigridOptions options;
  // Chebyshev interval [upper / 5, upper]: measured best of 3..30 on 17^3 and 33^3 lattices
  // (V-cycle residual factors 0.13 model-6, 0.08 model-26; 0.18 and 0.17 with 8, 0.58 and 0.56 with 30)
  double chebyshev_ratio = 5.0;
  std::vector<Level> levels;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> coarsest[3];
  bool coarsest_direct = false;

  // r = b - A x at active rows, 0 elsewhere.
  static void residual(const Level& L, const double* b, const double* x, double* r) {
    for_rows(L.points, [&](std::size_t begin, std::size_t end) {
      for (std::size_t i = begin; i < end; ++i) {
        if (!L.active[i]) {
          r[3 * i] = r[3 * i + 1] = r[3 * i + 2] = 0.0;
          continue;
        }
        double s0 = b[3 * i], s1 = b[3 * i + 1], s2 = b[3 * i + 2];
        if (L.uniform) {
          for (std::size_t e = L.ptr[i]; e < L.ptr[i + 1]; ++e) {
            const std::size_t j = static_cast<std::size_t>(L.col[e]);
            const double a = L.val[e];
            s0 -= a * x[3 * j];
            s1 -= a * x[3 * j + 1];
            s2 -= a * x[3 * j + 2];
          }
        } else {
          for (std::size_t e = L.ptr[i]; e < L.ptr[i + 1]; ++e) {
            const std::size_t j = static_cast<std::size_t>(L.col[e]);
            s0 -= L.val[3 * e] * x[3 * j];
            s1 -= L.val[3 * e + 1] * x[3 * j + 1];
            s2 -= L.val[3 * e + 2] * x[3 * j + 2];
          }
        }
        r[3 * i] = s0;
        r[3 * i + 1] = s1;
        r[3 * i + 2] = s2;
      }
    });
  }

  static std::size_t stride(const Level& L, int axis) {
    return axis == 0 ? 1 : axis == 1 ? static_cast<std::size_t>(L.nx) : static_cast<std::size_t>(L.nx) * L.ny;
  }
  static int extent(const Level& L, int axis) { return axis == 0 ? L.nx : axis == 1 ? L.ny : L.nz; }
  // First point of line `line` along `axis` (lines numbered by the other two coordinates).
  static std::size_t line_start(const Level& L, int axis, std::size_t line) {
    if (axis == 0) return line * L.nx;
    if (axis == 1) return (line % L.nx) + static_cast<std::size_t>(L.nx) * L.ny * (line / L.nx);
    return line;
  }

  // z = T^-1 r, coordinate by coordinate, line by line (lines are independent: parallel).
  static void apply_smoother(const Level& L, const double* r, double* z) {
    for (int c = 0; c < 3; ++c) {
      const int axis = L.axis[c];
      const std::size_t step = stride(L, axis);
      const int length = extent(L, axis);
      const std::size_t lines = L.points / static_cast<std::size_t>(length);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, lines, 64),
                        [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t line = range.begin(); line != range.end(); ++line) {
                            const std::size_t first = line_start(L, axis, line);
                            double previous = 0.0;
                            for (int t = 0; t < length; ++t) {
                              const std::size_t k = 3 * (first + t * step) + c;
                              previous = (r[k] - L.lo[k] * previous) * L.inv[k];
                              z[k] = previous;
                            }
                            for (int t = length - 2; t >= 0; --t) {
                              const std::size_t k = 3 * (first + t * step) + c;
                              z[k] -= L.cp[k] * z[k + 3 * step];
                            }
                          }
                        });
    }
  }

  // x += T^-1 r / rho (r = b - A x computed first: weighted line Jacobi, order-independent).
  void jacobi(Level& L, const double* b, double* x) {
    residual(L, b, x, L.r.data());
    apply_smoother(L, L.r.data(), L.z.data());
    for_rows(L.points, [&](std::size_t begin, std::size_t end) {
      for (std::size_t i = begin; i < end; ++i)
        for (int c = 0; c < 3; ++c) x[3 * i + c] += L.z[3 * i + c] / L.rho[c];
    });
  }

  // coarse b = P^T r (fine level `fine`, coarse level fine + 1).
  void restrict_to(std::size_t fine) {
    const Level& F = levels[fine];
    Level& C = levels[fine + 1];
    const DimMap &mx = F.mx, &my = F.my, &mz = F.mz;
    for_rows(C.points, [&](std::size_t begin, std::size_t end) {
      for (std::size_t I = begin; I < end; ++I) {
        double s[3] = {0.0, 0.0, 0.0};
        if (C.active[I]) {
          const int ci = static_cast<int>(I % C.nx), cj = static_cast<int>((I / C.nx) % C.ny),
                    ck = static_cast<int>(I / (static_cast<std::size_t>(C.nx) * C.ny));
          for (int a = mz.child_ptr[ck]; a < mz.child_ptr[ck + 1]; ++a)
            for (int bb = my.child_ptr[cj]; bb < my.child_ptr[cj + 1]; ++bb)
              for (int c = mx.child_ptr[ci]; c < mx.child_ptr[ci + 1]; ++c) {
                const std::size_t f =
                    static_cast<std::size_t>(mx.child[c]) +
                    static_cast<std::size_t>(F.nx) * (my.child[bb] + static_cast<std::size_t>(F.ny) * mz.child[a]);
                if (!F.active[f]) continue;
                const double w = mx.child_w[c] * my.child_w[bb] * mz.child_w[a];
                for (int d = 0; d < 3; ++d) s[d] += w * F.r[3 * f + d];
              }
        }
        for (int d = 0; d < 3; ++d) C.b[3 * I + d] = s[d];
      }
    });
  }

  // x += P (coarse x) at active fine points.
  void prolong_add(std::size_t fine, double* x) {
    const Level& F = levels[fine];
    const Level& C = levels[fine + 1];
    const DimMap &mx = F.mx, &my = F.my, &mz = F.mz;
    for_rows(F.points, [&](std::size_t begin, std::size_t end) {
      for (std::size_t f = begin; f < end; ++f) {
        if (!F.active[f]) continue;
        const int i = static_cast<int>(f % F.nx), j = static_cast<int>((f / F.nx) % F.ny),
                  k = static_cast<int>(f / (static_cast<std::size_t>(F.nx) * F.ny));
        const int pk[2] = {mz.p0[k], mz.p1[k]}, pj[2] = {my.p0[j], my.p1[j]}, pi[2] = {mx.p0[i], mx.p1[i]};
        const double wk[2] = {mz.w0[k], mz.w1[k]}, wj[2] = {my.w0[j], my.w1[j]}, wi[2] = {mx.w0[i], mx.w1[i]};
        double s[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < 2; ++a) {
          if (pk[a] < 0) continue;
          for (int bb = 0; bb < 2; ++bb) {
            if (pj[bb] < 0) continue;
            for (int c = 0; c < 2; ++c) {
              if (pi[c] < 0) continue;
              const std::size_t I = static_cast<std::size_t>(pi[c]) +
                                    static_cast<std::size_t>(C.nx) * (pj[bb] + static_cast<std::size_t>(C.ny) * pk[a]);
              const double w = wi[c] * wj[bb] * wk[a];
              for (int d = 0; d < 3; ++d) s[d] += w * C.x[3 * I + d];
            }
          }
        }
        for (int d = 0; d < 3; ++d) x[3 * f + d] += s[d];
      }
    });
  }

  void solve_coarsest(Level& L, const double* b, double* x) {
    if (!coarsest_direct) {  // factorization failed (singular coarse matrix): many Jacobi sweeps
      for (std::size_t i = 0; i < 3 * L.points; ++i) x[i] = 0.0;
      for (int s = 0; s < 200; ++s) jacobi(L, b, x);
      return;
    }
    Eigen::VectorXd rhs(static_cast<Eigen::Index>(L.points));
    for (int c = 0; c < 3; ++c) {
      for (std::size_t i = 0; i < L.points; ++i) rhs(static_cast<Eigen::Index>(i)) = L.active[i] ? b[3 * i + c] : 0.0;
      const Eigen::VectorXd sol = coarsest[c].solve(rhs);
      for (std::size_t i = 0; i < L.points; ++i) x[3 * i + c] = L.active[i] ? sol(static_cast<Eigen::Index>(i)) : 0.0;
    }
  }

  // Chebyshev smoother: `degree` steps of the Chebyshev iteration for D^-1 A on the interval
  // [upper / kRatio, upper], upper = 1.1 x the estimated spectral radius (the smooth part of the
  // spectrum below upper / kRatio is left to the coarse levels). A fixed polynomial in D^-1 A,
  // so the V-cycle stays symmetric. With zero_start, x is overwritten (x = 0 start).
  void smooth(Level& L, const double* b, double* x, bool zero_start) {
    double theta[3], delta[3], sigma[3], rho_old[3], keep[3], push[3];
    for (int c = 0; c < 3; ++c) {
      const double upper = 1.1 * L.rho[c], lower = upper / chebyshev_ratio;
      theta[c] = 0.5 * (upper + lower);
      delta[c] = 0.5 * (upper - lower);
      sigma[c] = theta[c] / delta[c];
      rho_old[c] = 1.0 / sigma[c];
    }
    std::vector<double>& d = L.d;
    for (int k = 0; k < options.smoothing_steps; ++k) {
      if (k == 0 && zero_start) {
        apply_smoother(L, b, L.z.data());
        for_rows(L.points, [&](std::size_t begin, std::size_t end) {
          for (std::size_t i = begin; i < end; ++i)
            for (int c = 0; c < 3; ++c) {
              d[3 * i + c] = L.z[3 * i + c] / theta[c];
              x[3 * i + c] = d[3 * i + c];
            }
        });
        continue;
      }
      residual(L, b, x, L.r.data());
      apply_smoother(L, L.r.data(), L.z.data());
      if (k == 0) {
        for_rows(L.points, [&](std::size_t begin, std::size_t end) {
          for (std::size_t i = begin; i < end; ++i)
            for (int c = 0; c < 3; ++c) {
              d[3 * i + c] = L.z[3 * i + c] / theta[c];
              x[3 * i + c] += d[3 * i + c];
            }
        });
        continue;
      }
      for (int c = 0; c < 3; ++c) {
        const double rho_new = 1.0 / (2.0 * sigma[c] - rho_old[c]);
        keep[c] = rho_new * rho_old[c];
        push[c] = 2.0 * rho_new / delta[c];
        rho_old[c] = rho_new;
      }
      for_rows(L.points, [&](std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i)
          for (int c = 0; c < 3; ++c) {
            d[3 * i + c] = keep[c] * d[3 * i + c] + push[c] * L.z[3 * i + c];
            x[3 * i + c] += d[3 * i + c];
          }
      });
    }
  }

  void vcycle(std::size_t l, const double* b, double* x, bool zero_start) {
    Level& L = levels[l];
    if (l + 1 == levels.size()) {
      solve_coarsest(L, b, x);
      return;
    }
    smooth(L, b, x, zero_start);
    residual(L, b, x, L.r.data());
    restrict_to(l);
    Level& C = levels[l + 1];
    vcycle(l + 1, C.b.data(), C.x.data(), true);
    prolong_add(l, x);
    smooth(L, b, x, false);
  }

  // The smoother of a level: per coordinate, the grid axis whose couplings in that
  // coordinate's operator are largest (line smoothing; else point smoothing, axis 0 with the
  // couplings left out), the tridiagonal part of the operator along it factored line by line,
  // and rho = spectral radius of T^-1 A by power iteration (12 steps from a fixed
  // pseudo-random start).
  void set_smoother(Level& L) {
    const std::size_t n = L.points;
    L.lo.assign(3 * n, 0.0);
    L.cp.assign(3 * n, 0.0);
    L.inv.assign(3 * n, 0.0);
    L.d.assign(3 * n, 0.0);
    L.z.assign(3 * n, 0.0);
    std::vector<double> up(3 * n, 0.0), dg(3 * n, 1.0);
    auto coordinate = [&](std::size_t i, int axis) {
      return axis == 0   ? static_cast<int>(i % L.nx)
             : axis == 1 ? static_cast<int>((i / L.nx) % L.ny)
                         : static_cast<int>(i / (static_cast<std::size_t>(L.nx) * L.ny));
    };
    for (int c = 0; c < 3; ++c) {
      int best = 0;
      if (options.line_smoothing) {
        double weight[3] = {0.0, 0.0, 0.0};
        for (std::size_t i = 0; i < n; ++i) {
          if (!L.active[i]) continue;
          for (std::size_t e = L.ptr[i]; e < L.ptr[i + 1]; ++e)
            for (int a = 0; a < 3; ++a)
              if (extent(L, a) > 1 && static_cast<std::size_t>(L.col[e]) == i + stride(L, a) &&
                  coordinate(i, a) + 1 < extent(L, a))
                weight[a] += std::abs(L.value(e, c));
        }
        for (int a = 1; a < 3; ++a)
          if (weight[a] > weight[best]) best = a;
      }
      L.axis[c] = best;
      const std::size_t step = stride(L, best);
      for (std::size_t i = 0; i < n; ++i) {
        if (!L.active[i]) continue;
        const int at = coordinate(i, best);
        for (std::size_t e = L.ptr[i]; e < L.ptr[i + 1]; ++e) {
          const std::size_t j = static_cast<std::size_t>(L.col[e]);
          if (j == i)
            dg[3 * i + c] = L.value(e, c);
          else if (options.line_smoothing && at > 0 && j + step == i && L.active[j])
            L.lo[3 * i + c] = L.value(e, c);
          else if (options.line_smoothing && at + 1 < extent(L, best) && j == i + step && L.active[j])
            up[3 * i + c] = L.value(e, c);
        }
      }
      // Thomas factorization of each line
      const int length = extent(L, best);
      const std::size_t lines = n / static_cast<std::size_t>(length);
      for (std::size_t line = 0; line < lines; ++line) {
        const std::size_t first = line_start(L, best, line);
        double previous_cp = 0.0;
        for (int t = 0; t < length; ++t) {
          const std::size_t k = 3 * (first + t * step) + c;
          const double denominator = dg[k] - L.lo[k] * previous_cp;
          L.inv[k] = denominator != 0.0 ? 1.0 / denominator : 0.0;
          L.cp[k] = up[k] * L.inv[k];
          previous_cp = L.cp[k];
        }
      }
    }
    for (std::size_t i = 0; i < n; ++i)
      if (!L.active[i])
        for (int c = 0; c < 3; ++c) L.inv[3 * i + c] = L.lo[3 * i + c] = L.cp[3 * i + c] = 0.0;
    // power iteration on T^-1 A, the three coordinates at once
    std::vector<double> v(3 * n, 0.0), av(3 * n, 0.0), zero(3 * n, 0.0);
    std::uint64_t seed = 0x9e3779b97f4a7c15ULL;
    for (std::size_t k = 0; k < 3 * n; ++k) {
      seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
      if (L.active[k / 3]) v[k] = static_cast<double>(seed >> 11) / 9007199254740992.0 - 0.5;
    }
    double rho[3] = {0.0, 0.0, 0.0};
    for (int it = 0; it < 12; ++it) {
      double norm[3] = {0.0, 0.0, 0.0};
      for (std::size_t k = 0; k < 3 * n; ++k) norm[k % 3] += v[k] * v[k];
      for (int c = 0; c < 3; ++c) norm[c] = std::sqrt(norm[c]);
      for (std::size_t k = 0; k < 3 * n; ++k) v[k] = norm[k % 3] > 0.0 ? v[k] / norm[k % 3] : 0.0;
      residual(L, zero.data(), v.data(), av.data());  // av = -A v
      for (double& value : av) value = -value;
      apply_smoother(L, av.data(), v.data());
      double next[3] = {0.0, 0.0, 0.0};
      for (std::size_t k = 0; k < 3 * n; ++k) next[k % 3] += v[k] * v[k];
      for (int c = 0; c < 3; ++c) rho[c] = std::sqrt(next[c]);
    }
    for (int c = 0; c < 3; ++c) L.rho[c] = rho[c] > 0.0 ? rho[c] : 1.0;
  }

  // Galerkin coarse level P^T A P of level `fine` (with its DimMaps set).
  Level galerkin(const Level& F) {
    Level C;
    C.nx = F.mx.coarse;
    C.ny = F.my.coarse;
    C.nz = F.mz.coarse;
    C.points = static_cast<std::size_t>(C.nx) * C.ny * C.nz;
    // one plane of coarse rows per task, then concatenated in plane order
    std::vector<std::vector<std::size_t>> plane_count(C.nz);
    std::vector<std::vector<int>> plane_col(C.nz);
    std::vector<std::vector<double>> plane_val(C.nz);
    const DimMap &mx = F.mx, &my = F.my, &mz = F.mz;
    const std::size_t fplane = static_cast<std::size_t>(F.nx) * F.ny;
    bool out_of_window = false;
    tbb::parallel_for(tbb::blocked_range<int>(0, C.nz, 1), [&](const tbb::blocked_range<int>& range) {
      std::vector<double> acc(3 * kWindow * kWindow * kWindow, 0.0);
      std::vector<char> used(kWindow * kWindow * kWindow, 0);
      for (int K = range.begin(); K != range.end(); ++K) {
        auto& counts = plane_count[K];
        auto& cols = plane_col[K];
        auto& vals = plane_val[K];
        counts.assign(static_cast<std::size_t>(C.nx) * C.ny, 0);
        for (int J = 0; J < C.ny; ++J)
          for (int I = 0; I < C.nx; ++I) {
            std::fill(acc.begin(), acc.end(), 0.0);
            std::fill(used.begin(), used.end(), 0);
            for (int a = mz.child_ptr[K]; a < mz.child_ptr[K + 1]; ++a)
              for (int bb = my.child_ptr[J]; bb < my.child_ptr[J + 1]; ++bb)
                for (int c = mx.child_ptr[I]; c < mx.child_ptr[I + 1]; ++c) {
                  const std::size_t f = static_cast<std::size_t>(mx.child[c]) +
                                        static_cast<std::size_t>(F.nx) * my.child[bb] + fplane * mz.child[a];
                  if (!F.active[f]) continue;
                  const double w = mx.child_w[c] * my.child_w[bb] * mz.child_w[a];
                  for (std::size_t e = F.ptr[f]; e < F.ptr[f + 1]; ++e) {
                    const std::size_t g = static_cast<std::size_t>(F.col[e]);
                    if (!F.active[g]) continue;
                    const int gi = static_cast<int>(g % F.nx), gj = static_cast<int>((g / F.nx) % F.ny),
                              gk = static_cast<int>(g / fplane);
                    const double av[3] = {w * F.value(e, 0), w * F.value(e, 1), w * F.value(e, 2)};
                    const int qk[2] = {mz.p0[gk], mz.p1[gk]}, qj[2] = {my.p0[gj], my.p1[gj]},
                              qi[2] = {mx.p0[gi], mx.p1[gi]};
                    const double vk[2] = {mz.w0[gk], mz.w1[gk]}, vj[2] = {my.w0[gj], my.w1[gj]},
                                 vi[2] = {mx.w0[gi], mx.w1[gi]};
                    for (int s = 0; s < 2; ++s) {
                      if (qk[s] < 0) continue;
                      for (int t = 0; t < 2; ++t) {
                        if (qj[t] < 0) continue;
                        for (int u = 0; u < 2; ++u) {
                          if (qi[u] < 0) continue;
                          const int dx = qi[u] - I + kReach, dy = qj[t] - J + kReach, dz = qk[s] - K + kReach;
                          if (dx < 0 || dy < 0 || dz < 0 || dx >= kWindow || dy >= kWindow || dz >= kWindow) {
                            out_of_window = true;
                            continue;
                          }
                          const int slot = dx + kWindow * (dy + kWindow * dz);
                          const double pw = vi[u] * vj[t] * vk[s];
                          for (int q = 0; q < (F.uniform ? 1 : 3); ++q) acc[3 * slot + q] += av[q] * pw;
                          used[slot] = 1;
                        }
                      }
                    }
                  }
                }
            std::size_t count = 0;
            for (int slot = 0; slot < static_cast<int>(used.size()); ++slot) {
              if (!used[slot] || (acc[3 * slot] == 0.0 && acc[3 * slot + 1] == 0.0 && acc[3 * slot + 2] == 0.0))
                continue;
              const int dx = slot % kWindow - kReach, dy = (slot / kWindow) % kWindow - kReach,
                        dz = slot / (kWindow * kWindow) - kReach;
              cols.push_back((I + dx) + C.nx * ((J + dy) + C.ny * (K + dz)));
              for (int q = 0; q < (F.uniform ? 1 : 3); ++q) vals.push_back(acc[3 * slot + q]);
              ++count;
            }
            counts[static_cast<std::size_t>(I) + static_cast<std::size_t>(C.nx) * J] = count;
          }
      }
    });
    if (out_of_window)
      throw SolverError(
          "multigrid: a coarse stencil reached beyond 3 points (springs between points "
          "that are not grid neighbours); use --static-method momentum");
    C.ptr.assign(C.points + 1, 0);
    C.active.assign(C.points, 0);
    std::size_t row = 0;
    for (int K = 0; K < C.nz; ++K)
      for (std::size_t count : plane_count[K]) {
        C.ptr[row + 1] = C.ptr[row] + count;
        ++row;
      }
    C.col.reserve(C.ptr.back());
    C.uniform = F.uniform;
    C.val.reserve((C.uniform ? 1 : 3) * C.ptr.back());
    for (int K = 0; K < C.nz; ++K) {
      C.col.insert(C.col.end(), plane_col[K].begin(), plane_col[K].end());
      C.val.insert(C.val.end(), plane_val[K].begin(), plane_val[K].end());
    }
    for (std::size_t i = 0; i < C.points; ++i)
      for (std::size_t e = C.ptr[i]; e < C.ptr[i + 1]; ++e)
        if (static_cast<std::size_t>(C.col[e]) == i && C.value(e, 0) > 0.0 && C.value(e, 1) > 0.0 &&
            C.value(e, 2) > 0.0)
          C.active[i] = 1;
    return C;
  }

  void factor_coarsest() {
    const Level& L = levels.back();
    const auto n = static_cast<Eigen::Index>(L.points);
    coarsest_direct = true;
    for (int c = 0; c < 3; ++c) {
      std::vector<Eigen::Triplet<double>> triplets;
      for (std::size_t i = 0; i < L.points; ++i) {
        if (!L.active[i]) {
          triplets.emplace_back(static_cast<int>(i), static_cast<int>(i), 1.0);
          continue;
        }
        for (std::size_t e = L.ptr[i]; e < L.ptr[i + 1]; ++e)
          if (L.active[static_cast<std::size_t>(L.col[e])])
            triplets.emplace_back(static_cast<int>(i), L.col[e], L.value(e, c));
      }
      Eigen::SparseMatrix<double> matrix(n, n);
      matrix.setFromTriplets(triplets.begin(), triplets.end());
      coarsest[c].compute(matrix);
      if (coarsest[c].info() != Eigen::Success)
        coarsest_direct = false;
      else {
        // a positive definite matrix has a positive diagonal in its LDL^T
        const auto d = coarsest[c].vectorD();
        for (Eigen::Index i = 0; i < d.size(); ++i)
          if (!(d(i) > 0.0)) coarsest_direct = false;
      }
    }
  }
};

LatticeMultigrid::LatticeMultigrid(const SpringSystem& system, const LatticeShape& shape,
                                   const MultigridOptions& options, const std::vector<std::array<double, 3>>* weights)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  const std::size_t n = system.positions.size();
  if (weights && weights->size() != system.springs.size())
    throw OptionError("multigrid: " + std::to_string(weights->size()) + " spring weights for " +
                      std::to_string(system.springs.size()) + " springs");
  auto weight = [&](std::size_t s, int c) { return weights ? (*weights)[s][c] : system.springs[s].stiffness; };
  if (shape.nx < 2 || shape.ny < 2 || shape.nz < 2 || static_cast<std::size_t>(shape.nx) * shape.ny * shape.nz != n ||
      system.fixed.size() != n)
    throw OptionError("multigrid: the lattice shape " + std::to_string(shape.nx) + " x " + std::to_string(shape.ny) +
                      " x " + std::to_string(shape.nz) + " does not describe the " + std::to_string(n) +
                      " points of the spring system");
  impl_->options = options;
  Level fine;
  fine.nx = shape.nx;
  fine.ny = shape.ny;
  fine.nz = shape.nz;
  fine.points = n;
  std::vector<double> diag(3 * n, 0.0);
  std::vector<std::size_t> count(n, 1);  // the diagonal entry
  const std::size_t plane = static_cast<std::size_t>(shape.nx) * shape.ny;
  auto coords = [&](int p, int* c) {
    c[0] = static_cast<int>(p % shape.nx);
    c[1] = static_cast<int>((p / shape.nx) % shape.ny);
    c[2] = static_cast<int>(p / plane);
  };
  for (std::size_t s = 0; s < system.springs.size(); ++s) {
    const Spring& spring = system.springs[s];
    int ca[3], cb[3];
    coords(spring.a, ca);
    coords(spring.b, cb);
    for (int d = 0; d < 3; ++d)
      if (std::abs(ca[d] - cb[d]) > 1)
        throw OptionError("multigrid: spring " + std::to_string(s) + " joins points " + std::to_string(spring.a) +
                          " and " + std::to_string(spring.b) + ", which are not neighbours on the lattice grid");
    const bool fa = system.fixed[spring.a] != 0, fb = system.fixed[spring.b] != 0;
    for (int c = 0; c < 3; ++c) {
      if (!(weight(s, c) > 0.0) || !std::isfinite(weight(s, c)))
        throw OptionError("multigrid: spring " + std::to_string(s) + " has weight " + std::to_string(weight(s, c)) +
                          " in coordinate " + std::to_string(c) + "; weights must be > 0");
      if (!fa) diag[3 * static_cast<std::size_t>(spring.a) + c] += weight(s, c);
      if (!fb) diag[3 * static_cast<std::size_t>(spring.b) + c] += weight(s, c);
    }
    if (!fa && !fb) {
      ++count[spring.a];
      ++count[spring.b];
    }
  }
  fine.active.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) fine.active[i] = !system.fixed[i] && diag[3 * i] > 0.0;
  fine.ptr.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) fine.ptr[i + 1] = fine.ptr[i] + (fine.active[i] ? count[i] : 0);
  fine.col.resize(fine.ptr.back());
  fine.uniform = weights == nullptr;
  const std::size_t per_entry = fine.uniform ? 1 : 3;
  fine.val.resize(per_entry * fine.ptr.back());
  std::vector<std::size_t> fill(fine.ptr.begin(), fine.ptr.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    if (fine.active[i]) {
      fine.col[fill[i]] = static_cast<int>(i);
      for (std::size_t c = 0; c < per_entry; ++c) fine.val[per_entry * fill[i] + c] = diag[3 * i + c];
      ++fill[i];
    }
  for (std::size_t s = 0; s < system.springs.size(); ++s) {
    const Spring& spring = system.springs[s];
    if (!fine.active[spring.a] || !fine.active[spring.b]) continue;
    fine.col[fill[spring.a]] = spring.b;
    fine.col[fill[spring.b]] = spring.a;
    for (std::size_t c = 0; c < per_entry; ++c) {
      fine.val[per_entry * fill[spring.a] + c] = -weight(s, static_cast<int>(c));
      fine.val[per_entry * fill[spring.b] + c] = -weight(s, static_cast<int>(c));
    }
    ++fill[spring.a];
    ++fill[spring.b];
  }
  impl_->levels.push_back(std::move(fine));
  // coarsen while a dimension is longer than 3 and the level is larger than coarsest_points
  for (;;) {
    Level& F = impl_->levels.back();
    if (F.points <= static_cast<std::size_t>(options.coarsest_points)) break;
    if (F.nx <= 3 && F.ny <= 3 && F.nz <= 3) break;
    F.mx = make_map(F.nx, true);
    F.my = make_map(F.ny, true);
    F.mz = make_map(F.nz, true);
    Level C = impl_->galerkin(F);
    impl_->levels.push_back(std::move(C));
  }
  for (std::size_t l = 0; l < impl_->levels.size(); ++l) {
    Level& L = impl_->levels[l];
    if (l + 1 < impl_->levels.size()) impl_->set_smoother(L);
    L.r.assign(3 * L.points, 0.0);
    if (l > 0) {
      L.b.assign(3 * L.points, 0.0);
      L.x.assign(3 * L.points, 0.0);
    }
  }
  impl_->factor_coarsest();
  if (!impl_->coarsest_direct) impl_->set_smoother(impl_->levels.back());
}

LatticeMultigrid::~LatticeMultigrid() = default;

double LatticeMultigrid::precondition(const std::vector<double>& b, std::vector<double>& x) {
  const Level& L = impl_->levels.front();
  x.assign(3 * L.points, 0.0);
  impl_->vcycle(0, b.data(), x.data(), true);
  return reduce_rows(L.points, [&](std::size_t begin, std::size_t end) {
    double s = 0.0;
    for (std::size_t i = begin; i < end; ++i) {
      if (!L.active[i]) {
        x[3 * i] = x[3 * i + 1] = x[3 * i + 2] = 0.0;
        continue;
      }
      for (int c = 0; c < 3; ++c) s += b[3 * i + c] * x[3 * i + c];
    }
    return s;
  });
}

void LatticeMultigrid::cycle(const std::vector<double>& b, std::vector<double>& x) {
  const Level& L = impl_->levels.front();
  x.resize(3 * L.points, 0.0);
  for (std::size_t i = 0; i < L.points; ++i)
    if (!L.active[i]) x[3 * i] = x[3 * i + 1] = x[3 * i + 2] = 0.0;
  impl_->vcycle(0, b.data(), x.data(), false);
}

double LatticeMultigrid::residual(const std::vector<double>& b, const std::vector<double>& x, std::vector<double>& r) {
  const Level& L = impl_->levels.front();
  r.resize(3 * L.points);
  Impl::residual(L, b.data(), x.data(), r.data());
  return std::sqrt(reduce_rows(L.points, [&](std::size_t begin, std::size_t end) {
    double s = 0.0;
    for (std::size_t k = 3 * begin; k < 3 * end; ++k) s += r[k] * r[k];
    return s;
  }));
}

int LatticeMultigrid::levels() const { return static_cast<int>(impl_->levels.size()); }

std::vector<int> LatticeMultigrid::level_points() const {
  std::vector<int> out;
  for (const Level& L : impl_->levels) out.push_back(static_cast<int>(L.points));
  return out;
}

}  // namespace fascicle::springs
