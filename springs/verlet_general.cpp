// Verlet (Zeleny 2011, formula 3.8) on the general data path: any spring list, stored as
// compressed rows (each point lists its springs), forces gathered per point into a separate
// array, then one integration pass. Both passes are TBB-parallel over fixed blocks of points,
// so results do not depend on the thread count. A system of one block (up to kBlock points, as
// a decomposition's lattice) evaluates each spring once instead, with the gather's bits, in two
// halves of the points side by side (each half's springs in the system's order: a spring
// between the halves is evaluated by both, each adding to its own end), so every point's force
// is still summed in the same order, whatever the threads. The momentum's power (only its sign
// is used: a restart where it turns negative) is the sum of the two halves' sums, the same
// whatever the threads, though rounded differently from one sum over all points (harmless: only
// the sign decides).

#include "geometry/errors.h"
#include "springs/solvers_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace fascicle::springs::detail {

SpringRows spring_rows(const SpringSystem& system) {
  const int n = static_cast<int>(system.positions.size());
  SpringRows rows;
  rows.row.assign(n + 1, 0);
  for (const Spring& s : system.springs) {
    ++rows.row[s.a + 1];
    ++rows.row[s.b + 1];
  }
  for (int i = 0; i < n; ++i) rows.row[i + 1] += rows.row[i];
  const std::size_t entries = static_cast<std::size_t>(rows.row[n]);
  rows.neighbour.resize(entries);
  rows.stiffness.resize(entries);
  rows.rest.resize(entries);
  std::vector<int> fill(rows.row.begin(), rows.row.end() - 1);
  for (const Spring& s : system.springs)
    for (int end = 0; end < 2; ++end) {
      const int p = end ? s.b : s.a, q = end ? s.a : s.b;
      const int slot = fill[p]++;
      rows.neighbour[slot] = q;
      rows.stiffness[slot] = s.stiffness;
      rows.rest[slot] = s.rest;
    }
  return rows;
}
namespace {

constexpr int kBlock = 4096;  // points per parallel block (fixed: deterministic reductions)
std::atomic<bool> spring_once_enabled{true};

// One half of the spring-once loop: the springs with an end among points [begin, end), in the
// system's order; `ends` bit 0: add the force to the first end, bit 1: subtract it from the second.
struct SpringHalf {
  int begin = 0, end = 0;
  std::vector<Spring> springs;
  std::vector<unsigned char> ends;
};

class GeneralVerlet final : public SpringSolver {
 public:
  GeneralVerlet(const SpringSystem& system, const SettleOptions& options, bool momentum)
      : options_(options),
        coefficients_(momentum ? momentum_coefficients(system) : verlet_coefficients(system, options)),
        momentum_(momentum) {
    n_ = static_cast<int>(system.positions.size());
    fixed_ = system.fixed;
    SpringRows rows = spring_rows(system);
    row_ = std::move(rows.row);
    neighbour_ = std::move(rows.neighbour);
    stiffness_ = std::move(rows.stiffness);
    rest_ = std::move(rows.rest);
    x_.resize(3 * static_cast<std::size_t>(n_));
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < 3; ++c) x_[3 * i + c] = system.positions[i][c];
    prev_ = x_;
    force_.assign(x_.size(), 0.0);
    blocks_ = (n_ + kBlock - 1) / kBlock;
    if (blocks_ == 1 && spring_once_enabled) {  // forces_once_half, in two halves
      const int middle = n_ / 2;
      halves_[0].end = halves_[1].begin = middle;
      halves_[1].end = n_;
      for (SpringHalf& h : halves_) {
        for (const Spring& sp : system.springs) {
          const unsigned char ends = static_cast<unsigned char>((sp.a >= h.begin && sp.a < h.end ? 1 : 0) |
                                                                (sp.b >= h.begin && sp.b < h.end ? 2 : 0));
          if (!ends) continue;
          h.springs.push_back(sp);
          h.ends.push_back(ends);
        }
      }
      once_ = true;
    }
    partial_.assign(std::max(blocks_, 1), 0.0);
    scale_ = residual_force_scale(system);
    watch_ = DivergenceWatch(system, options, energy());
  }

  double step() override {
    double momentum = 0.0;
    if (momentum_) {
      // Gradient restart: the last step moved against the force (f . v < 0).
      if (schedule_.restart(power_ < 0.0)) prev_ = x_;
      momentum = schedule_.next();
    }
    double r2 = 0.0;
    if (once_) {
      // Each half's forces, then its integration, side by side; x_ is only read until the swap.
      double largest[2] = {0.0, 0.0}, power[2] = {0.0, 0.0};
      auto half = [&](int h) {
        largest[h] = forces_once_half(x_, halves_[h]);
        power[h] = integrate(halves_[h].begin, halves_[h].end, momentum);
      };
      tbb::parallel_invoke([&] { half(0); }, [&] { half(1); });
      r2 = larger(largest[0], largest[1]);
      watch_.check_force(iteration_ + 1, r2, coefficients_, options_);
      power_ = power[0] + power[1];
    } else {
      r2 = compute_forces(x_);
      watch_.check_force(iteration_ + 1, r2, coefficients_, options_);
      tbb::parallel_for(tbb::blocked_range<int>(0, blocks_, 1), [&](const tbb::blocked_range<int>& range) {
        for (int blk = range.begin(); blk != range.end(); ++blk)
          partial_[blk] = integrate(blk * kBlock, std::min(n_, (blk + 1) * kBlock), momentum);
      });
      power_ = 0.0;
      for (int blk = 0; blk < blocks_; ++blk) power_ += partial_[blk];
    }
    std::swap(x_, prev_);
    ++iteration_;
    if (watch_.due(iteration_)) watch_.check(iteration_, energy(), coefficients_, options_);
    return std::sqrt(r2) / scale_;
  }

  double residual() override { return std::sqrt(compute_forces(x_)) / scale_; }

  double energy() override {
    // One block: one sum in the points' order (every 16th step; the divergence bound and the
    // energy history keep their bits).
    if (once_) return energy_of(0, n_);
    tbb::parallel_for(tbb::blocked_range<int>(0, blocks_, 1), [&](const tbb::blocked_range<int>& range) {
      for (int blk = range.begin(); blk != range.end(); ++blk)
        partial_[blk] = energy_of(blk * kBlock, std::min(n_, (blk + 1) * kBlock));
    });
    double total = 0.0;
    for (int blk = 0; blk < blocks_; ++blk) total += partial_[blk];
    return total;
  }

  std::vector<Vec3> positions() const override {
    std::vector<Vec3> out(n_);
    for (int i = 0; i < n_; ++i) out[i] = Vec3(x_[3 * i], x_[3 * i + 1], x_[3 * i + 2]);
    return out;
  }
  std::string backend() const override { return momentum_ ? "momentum-general" : "general"; }
  double time_step() const override { return coefficients_.dt; }
  double mean_damping() const override { return coefficients_.mean_damping; }

 private:
  // Gathers spring forces at `x` into force_; returns the largest squared force at a free point
  // (NaN/Inf when any force is not finite).
  double compute_forces(const std::vector<double>& x) {
    if (once_) {
      double largest[2] = {0.0, 0.0};
      tbb::parallel_invoke([&] { largest[0] = forces_once_half(x, halves_[0]); },
                           [&] { largest[1] = forces_once_half(x, halves_[1]); });
      return larger(largest[0], largest[1]);
    }
    tbb::parallel_for(tbb::blocked_range<int>(0, blocks_, 1), [&](const tbb::blocked_range<int>& range) {
      for (int blk = range.begin(); blk != range.end(); ++blk) {
        double largest = 0.0;
        const int end = std::min(n_, (blk + 1) * kBlock);
        for (int i = blk * kBlock; i < end; ++i) {
          double f[3] = {0.0, 0.0, 0.0};
          for (int s = row_[i]; s < row_[i + 1]; ++s) {
            const int q = neighbour_[s];
            const double l[3] = {x[3 * q] - x[3 * i], x[3 * q + 1] - x[3 * i + 1], x[3 * q + 2] - x[3 * i + 2]};
            const double len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
            if (len == 0.0) continue;
            const double w = stiffness_[s] * (len - rest_[s]) / len;
            for (int c = 0; c < 3; ++c) f[c] += w * l[c];
          }
          for (int c = 0; c < 3; ++c) force_[3 * i + c] = f[c];
          const double f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
          if (!fixed_[i] && (f2 > largest || std::isnan(f2))) largest = f2;  // NaN sticks
        }
        partial_[blk] = largest;
      }
    });
    double largest = 0.0;
    for (int blk = 0; blk < blocks_; ++blk)
      if (partial_[blk] > largest || std::isnan(partial_[blk])) largest = partial_[blk];
    return largest;
  }

  // One block: each spring evaluated once, in the system's order, its force added to its first
  // end and subtracted from its second. A point's rows list its springs in that same order, and
  // the second end's gather would compute the negated difference, the same length and the same
  // factor, so every force is the gather's to the bit at half the square roots and divisions.
  // This is one half of the points (`h`): its forces, and the largest squared force at a free
  // point among them (NaN when one is not finite).
  double forces_once_half(const std::vector<double>& x, const SpringHalf& h) {
    std::fill(force_.begin() + 3 * static_cast<std::ptrdiff_t>(h.begin),
              force_.begin() + 3 * static_cast<std::ptrdiff_t>(h.end), 0.0);
    const std::size_t count = h.springs.size();
    for (std::size_t k = 0; k < count; ++k) {
      const Spring& s = h.springs[k];
      const std::size_t a = 3 * static_cast<std::size_t>(s.a), b = 3 * static_cast<std::size_t>(s.b);
      const double l[3] = {x[b] - x[a], x[b + 1] - x[a + 1], x[b + 2] - x[a + 2]};
      const double len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
      if (len == 0.0) continue;
      const double w = s.stiffness * (len - s.rest) / len;
      const unsigned char ends = h.ends[k];
      if (ends & 1)
        for (int c = 0; c < 3; ++c) force_[a + c] += w * l[c];
      if (ends & 2)
        for (int c = 0; c < 3; ++c) force_[b + c] -= w * l[c];
    }
    double largest = 0.0;
    for (int i = h.begin; i < h.end; ++i) {
      const double* f = &force_[3 * static_cast<std::size_t>(i)];
      const double f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
      if (!fixed_[i] && (f2 > largest || std::isnan(f2))) largest = f2;  // NaN sticks
    }
    return largest;
  }

  // One Verlet (or momentum) update of points [begin, end) from force_ into prev_ (the next
  // positions; fixed points keep theirs); returns their power, force . velocity over free points.
  double integrate(int begin, int end, double momentum) {
    const double* a = coefficients_.a.data();
    const double* b = coefficients_.b.data();
    double power = 0.0;
    for (int i = begin; i < end; ++i) {
      const double bi = momentum_ ? momentum : b[i];
      for (int c = 0; c < 3; ++c) {
        const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
        const double v = x_[k] - prev_[k];
        if (!fixed_[i]) power += force_[k] * v;
        prev_[k] = fixed_[i] ? x_[k] : x_[k] + bi * v + a[i] * force_[k];
      }
    }
    return power;
  }

  // The larger of two halves' largest squared forces; a NaN in either sticks, as in one loop.
  static double larger(double first, double second) { return first > second || std::isnan(first) ? first : second; }

  // Kinetic and spring energy of points [begin, end) (each spring seen from both ends).
  double energy_of(int begin, int end) const {
    const double dt2 = coefficients_.dt * coefficients_.dt;
    double e = 0.0;
    for (int i = begin; i < end; ++i) {
      double v2 = 0.0;
      for (int c = 0; c < 3; ++c) {
        const double v = x_[3 * i + c] - prev_[3 * i + c];
        v2 += v * v;
      }
      e += 0.5 * coefficients_.mass[i] * v2 / dt2;
      for (int s = row_[i]; s < row_[i + 1]; ++s) {
        const int q = neighbour_[s];
        double l2 = 0.0;
        for (int c = 0; c < 3; ++c) {
          const double l = x_[3 * q + c] - x_[3 * i + c];
          l2 += l * l;
        }
        const double stretch = std::sqrt(l2) - rest_[s];
        e += 0.25 * stiffness_[s] * stretch * stretch;
      }
    }
    return e;
  }

  SettleOptions options_;
  VerletCoefficients coefficients_;
  int n_ = 0, blocks_ = 0, iteration_ = 0;
  std::vector<char> fixed_;
  std::vector<int> row_, neighbour_;
  std::vector<double> stiffness_, rest_;
  bool once_ = false;  // a one-block system: each spring once, in two halves
  SpringHalf halves_[2];
  std::vector<double> x_, prev_, force_, partial_;
  double scale_ = 1.0;
  DivergenceWatch watch_;
  bool momentum_ = false;
  MomentumSchedule schedule_;
  double power_ = 0.0;
};

}  // namespace

void set_general_spring_once(bool enabled) { spring_once_enabled = enabled; }

std::unique_ptr<SpringSolver> make_general_verlet(const SpringSystem& system, const SettleOptions& options,
                                                  bool momentum) {
  return std::make_unique<GeneralVerlet>(system, options, momentum);
}

}  // namespace fascicle::springs::detail
