// Coarse start of the static momentum solve (see coarse_start.h).

#include "springs/coarse_start.h"

#include "geometry/errors.h"
#include "geometry/splitmix64.h"
#include "springs/solvers_internal.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>

namespace fascicle::springs {

namespace {

// Fine index of coarse index c on an axis of n fine and m coarse points: round(c (n-1) / (m-1)).
int fine_index(int c, int n, int m) { return static_cast<int>((2L * c * (n - 1) + (m - 1)) / (2L * (m - 1))); }

// Rest lengths by (half direction, first point); 0 where no spring.
struct RestTable {
  std::vector<std::array<int, 3>> dirs;
  std::vector<std::vector<double>> rest;
  // The rest length of the spring from fine point p along full direction e (any sign); 0 if none.
  double of(long p, const std::array<int, 3>& e, const LatticeShape& s) const {
    for (std::size_t d = 0; d < dirs.size(); ++d) {
      if (dirs[d] == e) return rest[d][p];
      if (dirs[d][0] == -e[0] && dirs[d][1] == -e[1] && dirs[d][2] == -e[2])
        return rest[d][p + e[0] + static_cast<long>(s.nx) * (e[1] + static_cast<long>(s.ny) * e[2])];
    }
    return 0.0;
  }
};

}  // namespace

CoarseStartReport coarse_start(SpringSystem& system, const LatticeShape& shape, const SettleOptions& options) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  CoarseStartReport report;
  const long n = static_cast<long>(shape.nx) * shape.ny * shape.nz;
  if (options.coarse_start_points <= 0 || n <= options.coarse_start_points || shape.nx < 5 || shape.ny < 5 ||
      shape.nz < 5 || static_cast<long>(system.positions.size()) != n)
    return report;
  RestTable table;
  table.dirs = half_offsets(shape.model);
  table.rest.assign(table.dirs.size(), std::vector<double>(static_cast<std::size_t>(n), 0.0));
  const long plane = static_cast<long>(shape.nx) * shape.ny;
  for (const Spring& s : system.springs) {
    const std::array<int, 3> delta = {static_cast<int>(s.b % shape.nx - s.a % shape.nx),
                                      static_cast<int>((s.b / shape.nx) % shape.ny - (s.a / shape.nx) % shape.ny),
                                      static_cast<int>(s.b / plane - s.a / plane)};
    bool found = false;
    for (std::size_t d = 0; d < table.dirs.size() && !found; ++d) {
      if (table.dirs[d] == delta) {
        table.rest[d][s.a] = s.rest;
        found = true;
      } else if (table.dirs[d][0] == -delta[0] && table.dirs[d][1] == -delta[1] && table.dirs[d][2] == -delta[2]) {
        table.rest[d][s.b] = s.rest;
        found = true;
      }
    }
    if (!found || !(s.rest > 0.0) || std::abs(s.stiffness * s.rest - 1.0) > 1e-12) return report;  // not our lattice
  }

  // Every neighbour pair of the lattice must carry its spring (as on the structured path).
  for (int k = 0; k < shape.nz; ++k)
    for (int j = 0; j < shape.ny; ++j)
      for (int i = 0; i < shape.nx; ++i)
        for (std::size_t d = 0; d < table.dirs.size(); ++d) {
          const auto& e = table.dirs[d];
          if (i + e[0] < 0 || i + e[0] >= shape.nx || j + e[1] < 0 || j + e[1] >= shape.ny || k + e[2] >= shape.nz)
            continue;
          if (table.rest[d][i + shape.nx * (j + static_cast<long>(shape.ny) * k)] == 0.0) return report;
        }

  // The coarse lattice.
  const LatticeShape coarse_shape{shape.nx / 2 + 1, shape.ny / 2 + 1, shape.nz / 2 + 1, shape.model};
  const int size[3] = {shape.nx, shape.ny, shape.nz},
            coarse_size[3] = {coarse_shape.nx, coarse_shape.ny, coarse_shape.nz};
  std::vector<int> to_fine[3];
  for (int a = 0; a < 3; ++a)
    for (int c = 0; c < coarse_size[a]; ++c) to_fine[a].push_back(fine_index(c, size[a], coarse_size[a]));
  auto fine_point = [&](int i, int j, int k) {
    return to_fine[0][i] + shape.nx * (to_fine[1][j] + static_cast<long>(shape.ny) * to_fine[2][k]);
  };
  SpringSystem coarse;
  const long cn = static_cast<long>(coarse_shape.nx) * coarse_shape.ny * coarse_shape.nz;
  coarse.positions.resize(cn);
  coarse.fixed.resize(cn);
  coarse.mass.resize(cn);
  for (int k = 0; k < coarse_shape.nz; ++k)
    for (int j = 0; j < coarse_shape.ny; ++j)
      for (int i = 0; i < coarse_shape.nx; ++i) {
        const long c = i + coarse_shape.nx * (j + static_cast<long>(coarse_shape.ny) * k), f = fine_point(i, j, k);
        coarse.positions[c] = system.positions[f];
        coarse.fixed[c] = system.fixed[f];
        coarse.mass[c] = system.mass.empty() ? 1.0 : system.mass[f];
      }
  for (int k = 0; k < coarse_shape.nz; ++k)
    for (int j = 0; j < coarse_shape.ny; ++j)
      for (int i = 0; i < coarse_shape.nx; ++i)
        for (const auto& d : table.dirs) {
          const int i2 = i + d[0], j2 = j + d[1], k2 = k + d[2];
          if (i2 < 0 || j2 < 0 || k2 < 0 || i2 >= coarse_shape.nx || j2 >= coarse_shape.ny || k2 >= coarse_shape.nz)
            continue;
          int from[3] = {to_fine[0][i], to_fine[1][j], to_fine[2][k]};
          int left[3] = {to_fine[0][i2] - from[0], to_fine[1][j2] - from[1], to_fine[2][k2] - from[2]};
          double rest = 0.0;
          // A span that is a multiple of one fine direction (steps of 2, or of 1, on every axis it
          // spans) is a chain of that direction's springs: the sum of their rest lengths. A mixed
          // span (a step of 1 on one axis and 2 on another, at the end of an even axis) is not:
          // its rest length comes from the rest metric at its first point, recovered from the
          // fine springs there (|u + v|^2 = |u|^2 + |v|^2 + 2 u.v for the axis springs u, v and
          // the diagonal u + v; exact on any affine lattice).
          int steps = 0;
          bool mixed = false;
          for (int a = 0; a < 3; ++a)
            if (left[a] != 0) {
              if (steps != 0 && std::abs(left[a]) != steps) mixed = true;
              steps = std::abs(left[a]);
            }
          if (mixed) {
            const long p = from[0] + shape.nx * (from[1] + static_cast<long>(shape.ny) * from[2]);
            std::array<int, 3> u[3];
            double length[3] = {0.0, 0.0, 0.0};
            for (int a = 0; a < 3; ++a) {
              u[a] = {0, 0, 0};
              u[a][a] = (left[a] > 0) - (left[a] < 0);
              if (left[a] != 0 && !((length[a] = table.of(p, u[a], shape)) > 0.0)) return report;
            }
            double square = 0.0;
            for (int a = 0; a < 3; ++a) {
              square += static_cast<double>(left[a]) * left[a] * length[a] * length[a];
              for (int b = a + 1; b < 3; ++b) {
                if (left[a] == 0 || left[b] == 0) continue;
                const std::array<int, 3> diagonal = {u[a][0] + u[b][0], u[a][1] + u[b][1], u[a][2] + u[b][2]};
                const double across = table.of(p, diagonal, shape);
                if (!(across > 0.0)) return report;
                // (u_a . u_b) for the signed unit steps; |left| t_a t_b times it, twice
                square += 2.0 * std::abs(left[a]) * std::abs(left[b]) * 0.5 *
                          (across * across - length[a] * length[a] - length[b] * length[b]);
              }
            }
            if (!(square > 0.0)) return report;
            rest = std::sqrt(square);
            left[0] = left[1] = left[2] = 0;  // done
          }
          while (left[0] != 0 || left[1] != 0 || left[2] != 0) {
            const std::array<int, 3> e = {(left[0] > 0) - (left[0] < 0), (left[1] > 0) - (left[1] < 0),
                                          (left[2] > 0) - (left[2] < 0)};
            const double r = table.of(from[0] + shape.nx * (from[1] + static_cast<long>(shape.ny) * from[2]), e, shape);
            if (!(r > 0.0)) return report;  // a spring the path needs is missing (model-6 diagonal)
            rest += r;
            for (int a = 0; a < 3; ++a) {
              from[a] += e[a];
              left[a] -= e[a];
            }
          }
          Spring s;
          s.a = static_cast<int>(i + coarse_shape.nx * (j + static_cast<long>(coarse_shape.ny) * k));
          s.b = static_cast<int>(i2 + coarse_shape.nx * (j2 + static_cast<long>(coarse_shape.ny) * k2));
          s.rest = rest;
          s.stiffness = 1.0 / rest;
          coarse.springs.push_back(s);
        }

  // Settle it: first its own coarse start, then the momentum method.
  SettleOptions coarse_options = options;
  coarse_options.solver = SolverKind::static_equilibrium;
  coarse_options.static_method = StaticMethod::momentum;
  coarse_options.tolerance = std::max(options.tolerance, options.coarse_start_tolerance);
  CoarseStartReport inner;
  SettleReport settled;
  try {
    inner = coarse_start(coarse, coarse_shape, coarse_options);
    coarse_options.coarse_start_points = 0;  // done above
    settled = settle(coarse, coarse_options, &coarse_shape);
  } catch (const SolverError&) {
    // A coarse lattice without a fixed point in some part, or one that diverged: the start is
    // only a shortcut, the fine solve runs from the given positions.
    return report;
  }
  report.levels = inner.levels + 1;
  report.iterations = inner.iterations + settled.iterations;

  // Interpolate: per fine index, the coarse cell below it and the weight of its upper corner.
  std::vector<int> cell[3];
  std::vector<double> weight[3];
  for (int a = 0; a < 3; ++a) {
    int c = 0;
    for (int f = 0; f < size[a]; ++f) {
      while (c + 2 < coarse_size[a] && to_fine[a][c + 1] <= f) ++c;
      cell[a].push_back(c);
      weight[a].push_back(static_cast<double>(f - to_fine[a][c]) / (to_fine[a][c + 1] - to_fine[a][c]));
    }
  }
  for (int k = 0; k < shape.nz; ++k)
    for (int j = 0; j < shape.ny; ++j)
      for (int i = 0; i < shape.nx; ++i) {
        const long p = i + shape.nx * (j + static_cast<long>(shape.ny) * k);
        if (system.fixed[p]) continue;
        Vec3 sum = Vec3::Zero();
        for (int corner = 0; corner < 8; ++corner) {
          const int ci = cell[0][i] + (corner & 1), cj = cell[1][j] + ((corner >> 1) & 1),
                    ck = cell[2][k] + (corner >> 2);
          const double w = ((corner & 1) ? weight[0][i] : 1.0 - weight[0][i]) *
                           (((corner >> 1) & 1) ? weight[1][j] : 1.0 - weight[1][j]) *
                           ((corner >> 2) ? weight[2][k] : 1.0 - weight[2][k]);
          if (w != 0.0)
            sum += w * coarse.positions[ci + coarse_shape.nx * (cj + static_cast<long>(coarse_shape.ny) * ck)];
        }
        system.positions[p] = sum;
      }
  // The start's perturbation (SettleOptions::coarse_start_perturbation), model-6 only: a fixed
  // offset per free point, a share of the mean rest length of the springs along the axes.
  if (shape.model == SpringModel::model6 && options.coarse_start_perturbation > 0.0) {
    double rest_sum = 0.0;
    long rest_count = 0;
    for (const auto& rests : table.rest)  // model-6: every direction is an axis
      for (double r : rests)
        if (r > 0.0) {
          rest_sum += r;
          ++rest_count;
        }
    const double amplitude = rest_count > 0 ? options.coarse_start_perturbation * rest_sum / rest_count : 0.0;
    for (long p = 0; p < n; ++p)
      if (!system.fixed[p])
        for (int c = 0; c < 3; ++c)
          system.positions[p][c] += amplitude * (splitmix64_unit(3 * static_cast<std::uint64_t>(p) + c) - 0.5);
  }
  report.seconds = std::chrono::duration<double>(clock::now() - t0).count();
  return report;
}

namespace detail {

namespace {
// The solver of a coarse-started system: the momentum solver, plus what the start did.
class CoarseStarted final : public SpringSolver {
 public:
  CoarseStarted(std::unique_ptr<SpringSolver> inner, const CoarseStartReport& start)
      : inner_(std::move(inner)), start_(start) {}
  double step() override { return inner_->step(); }
  double residual() override { return inner_->residual(); }
  double energy() override { return inner_->energy(); }
  std::vector<Vec3> positions() const override { return inner_->positions(); }
  std::string backend() const override { return inner_->backend(); }
  int inner_iterations() const override { return inner_->inner_iterations(); }
  bool stalled() const override { return inner_->stalled(); }
  int start_levels() const override { return start_.levels; }
  int start_iterations() const override { return start_.iterations; }

 private:
  std::unique_ptr<SpringSolver> inner_;
  CoarseStartReport start_;
};
}  // namespace

std::unique_ptr<SpringSolver> make_coarse_started_momentum(const SpringSystem& system, const SettleOptions& options,
                                                           const LatticeShape& shape) {
  const long n = static_cast<long>(shape.nx) * shape.ny * shape.nz;
  if (options.coarse_start_points <= 0 || n <= options.coarse_start_points) return nullptr;
  SpringSystem start = system;
  const CoarseStartReport report = coarse_start(start, shape, options);
  if (report.levels == 0) return nullptr;
  auto solver = make_structured_verlet(start, options, shape, true);
  if (!solver) return nullptr;
  return std::make_unique<CoarseStarted>(std::move(solver), report);
}

}  // namespace detail
}  // namespace fascicle::springs
