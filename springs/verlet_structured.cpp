// Verlet (Zeleny 2011, formula 3.8) on the structured lattice path.
//
// Data: struct of arrays (x, y, z; previous x, y, z), one stiffness array per half direction
// (3 for model-6, 13 for model-26; stiffness 1 / rest length, so the rest length is 1 / k and
// the force of a spring is (k - 1 / |l|) l), per-point coefficients a = dt^2 / m and
// b = 1 - c dt / m, fixed flags. Neighbours are implicit: the spring from p in direction d ends
// at p + offset[d] and the one from p - offset[d] ends at p.
//
// Each point gathers its spring forces from the current positions only (every spring is
// evaluated from both ends) and its new position is written over its previous one: the forces
// of a step are a function of the current array, so the result does not depend on traversal
// order or thread count, exactly as accumulating them into a separate array (the general path)
// would; fusing the two passes halves the memory traffic. Rows of interior points without a
// fixed point run through a branch-free loop the compiler vectorises (compiled for AVX-512,
// AVX2 and baseline x86-64, picked at run time); points on the boundary of the index box take
// a checked scalar path. When every direction's springs share one stiffness and every point
// the same coefficients, the rows read scalars instead of those arrays (detect_uniform). The
// same kernels run the momentum static solver (per-step b, gradient restarts).

#include "geometry/errors.h"
#include "springs/solvers_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <utility>

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define FASCICLE_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define FASCICLE_CLONES
#endif

namespace fascicle::springs::detail {
namespace {

constexpr int kMaxDirections = 13;

struct Kernel {
  const double* x;
  const double* y;
  const double* z;
  double* px;  // previous positions, overwritten with the new ones
  double* py;
  double* pz;
  const double* k[kMaxDirections];
  long offset[kMaxDirections];
  const double* a;
  const double* b;
  const std::uint8_t* fixed;
  // Uniform lattices: one stiffness per direction, one a and one b for every point.
  double k_uniform[kMaxDirections];
  double a_uniform, b_uniform;
};

// Largest of non-negative doubles or NaN, as unsigned bit patterns: every NaN (either sign) is
// above +Inf, which is above every finite value, so the maximum is order-independent and a NaN
// anywhere survives the reduction. Integer max vectorises without -ffast-math.
inline std::uint64_t bits_of(double v) {
  std::uint64_t u;
  std::memcpy(&u, &v, sizeof u);
  return u;
}
inline double double_of(std::uint64_t u) {
  double v;
  std::memcpy(&v, &u, sizeof v);
  return v;
}

// Adds the two springs of half direction d (towards p + off and from p - off) to f; their
// stiffnesses are k[p] and k[p - off], or `uniform` for every spring when Uniform.
template <bool Uniform>
inline __attribute__((always_inline)) void add_direction(const double* __restrict x, const double* __restrict y,
                                                         const double* __restrict z, const double* __restrict k,
                                                         double uniform, long off, long p, double xp, double yp,
                                                         double zp, double& fx, double& fy, double& fz) {
  {
    const long q = p + off;
    const double lx = x[q] - xp, ly = y[q] - yp, lz = z[q] - zp;
    const double w = (Uniform ? uniform : k[p]) - 1.0 / std::sqrt(lx * lx + ly * ly + lz * lz);
    fx += w * lx;
    fy += w * ly;
    fz += w * lz;
  }
  {
    const long q = p - off;
    const double lx = x[q] - xp, ly = y[q] - yp, lz = z[q] - zp;
    const double w = (Uniform ? uniform : k[q]) - 1.0 / std::sqrt(lx * lx + ly * ly + lz * lz);
    fx += w * lx;
    fy += w * ly;
    fz += w * lz;
  }
}

// One row of interior points. Returns the largest squared force (as bits, see bits_of) and adds
// sum f . (x - x_previous) to `power` (the momentum solver's restart test).
template <bool Write, bool UniformK, bool UniformAB, std::size_t... Ds>
inline __attribute__((always_inline)) std::uint64_t row_body(const Kernel& g, long p0, long p1, double* power,
                                                             std::index_sequence<Ds...>) {
  const double* __restrict x = g.x;
  const double* __restrict y = g.y;
  const double* __restrict z = g.z;
  double* __restrict px = g.px;
  double* __restrict py = g.py;
  double* __restrict pz = g.pz;
  const double* __restrict a = g.a;
  const double* __restrict b = g.b;
  const double* const k[sizeof...(Ds)] = {g.k[Ds]...};
  const long off[sizeof...(Ds)] = {g.offset[Ds]...};
  const double ku[sizeof...(Ds)] = {g.k_uniform[Ds]...};
  const double au = g.a_uniform, bu = g.b_uniform;
  std::uint64_t largest = 0;
  double fv = 0.0;
  // Point p writes only px/py/pz[p], which no other iteration reads: no loop-carried dependence
  // (GCC's restrict on locals is too weak to prove it with three output streams). The simd
  // reductions are deterministic for a given machine (lane order is fixed).
#pragma omp simd reduction(max : largest) reduction(+ : fv)
  for (long p = p0; p < p1; ++p) {
    const double xp = x[p], yp = y[p], zp = z[p];
    double fx = 0.0, fy = 0.0, fz = 0.0;
    (add_direction<UniformK>(x, y, z, k[Ds], ku[Ds], off[Ds], p, xp, yp, zp, fx, fy, fz), ...);
    const std::uint64_t bits = bits_of(fx * fx + fy * fy + fz * fz);
    largest = bits > largest ? bits : largest;
    const double vx = xp - px[p], vy = yp - py[p], vz = zp - pz[p];
    fv += fx * vx + fy * vy + fz * vz;
    if (Write) {
      const double ap = UniformAB ? au : a[p], bp = UniformAB ? bu : b[p];
      px[p] = xp + bp * vx + ap * fx;
      py[p] = yp + bp * vy + ap * fy;
      pz[p] = zp + bp * vz + ap * fz;
    }
  }
  *power += fv;
  return largest;
}


using RowFunction = std::uint64_t (*)(const Kernel&, long, long, double*);
#define FASCICLE_ROW(name, write, uk, uab, d)                                                   \
  FASCICLE_CLONES std::uint64_t name(const Kernel& g, long p0, long p1, double* power) {     \
    return row_body<write, uk, uab>(g, p0, p1, power, std::make_index_sequence<d>());         \
  }
FASCICLE_ROW(force6, false, false, false, 3)
FASCICLE_ROW(force26, false, false, false, 13)
FASCICLE_ROW(force6_k, false, true, false, 3)
FASCICLE_ROW(force26_k, false, true, false, 13)
FASCICLE_ROW(step6, true, false, false, 3)
FASCICLE_ROW(step26, true, false, false, 13)
FASCICLE_ROW(step6_ab, true, false, true, 3)
FASCICLE_ROW(step26_ab, true, false, true, 13)
FASCICLE_ROW(step6_k, true, true, false, 3)
FASCICLE_ROW(step26_k, true, true, false, 13)
FASCICLE_ROW(step6_kab, true, true, true, 3)
FASCICLE_ROW(step26_kab, true, true, true, 13)
#undef FASCICLE_ROW

// kRows[write][uniform stiffness][uniform a, b][model-26]; forces alone ignore a, b.
const RowFunction kRows[2][2][2][2] = {
    {{{force6, force26}, {force6, force26}}, {{force6_k, force26_k}, {force6_k, force26_k}}},
    {{{step6, step26}, {step6_ab, step26_ab}}, {{step6_k, step26_k}, {step6_kab, step26_kab}}}};

class StructuredVerlet final : public SpringSolver {
 public:
  StructuredVerlet(const SpringSystem& system, const SettleOptions& options, const LatticeShape& shape,
                   std::vector<std::vector<double>> stiffness, bool momentum)
      : options_(options),
        coefficients_(momentum ? momentum_coefficients(system) : verlet_coefficients(system, options)),
        shape_(shape), stiffness_(std::move(stiffness)), momentum_(momentum) {
    n_ = static_cast<long>(system.positions.size());
    const auto& dirs = half_offsets(shape.model);
    directions_ = static_cast<int>(dirs.size());
    for (int d = 0; d < directions_; ++d) {
      dir_[d] = dirs[d];
      offset_[d] = dirs[d][0] + static_cast<long>(shape.nx) * (dirs[d][1] + static_cast<long>(shape.ny) * dirs[d][2]);
    }
    for (int c = 0; c < 3; ++c) {
      x_[c].resize(n_);
      p_[c].resize(n_);
      for (long i = 0; i < n_; ++i) x_[c][i] = p_[c][i] = system.positions[i][c];
    }
    fixed_.resize(n_);
    for (long i = 0; i < n_; ++i) fixed_[i] = system.fixed[i] ? 1 : 0;
    rows_ = static_cast<long>(shape.ny) * shape.nz;
    // At least ~8192 points a task: small lattices run as one task (TBB's overhead per task
    // is larger than a small lattice's iteration); results do not depend on the grain.
    grain_ = std::max(1L, 8192L / std::max(1, shape.nx));
    row_largest_.assign(rows_, 0);
    row_power_.assign(rows_, 0.0);
    // The vectorised loop has no fixed-point logic: a row with a fixed interior point takes the
    // checked path (template lattices fix only the index box's boundary, so none does).
    row_has_fixed_.assign(rows_, 0);
    for (long row = 0; row < rows_; ++row)
      for (int i = 1; i + 1 < shape.nx; ++i)
        if (fixed_[row * shape.nx + i]) row_has_fixed_[row] = 1;
    row_energy_.assign(rows_, 0.0);
    detect_uniform();
    if (momentum_) uniform_ab_ = true;  // one a for every point, b set each step
    scale_ = residual_force_scale(system);
    floor_ = energy_floor(system);
    initial_energy_ = std::max(energy(), floor_);
  }

  double step() override {
    if (momentum_) {
      // Nesterov's momentum schedule k / (k + 3) with the gradient restart of O'Donoghue and
      // Candes 2015: when the last step moved against the force (f . v < 0), drop the velocity.
      if (since_restart_ > 0 && power_ < 0.0) {
        for (int c = 0; c < 3; ++c) p_[c] = x_[c];
        since_restart_ = 0;
        ++restarts_;
      }
      coefficients_.b.assign(1, static_cast<double>(since_restart_) / (since_restart_ + 3));
      ++since_restart_;
    }
    const double r2 = sweep(true);
    if (!std::isfinite(r2)) throw_verlet_divergence(iteration_ + 1, NAN, initial_energy_, coefficients_, options_);
    for (int c = 0; c < 3; ++c) std::swap(x_[c], p_[c]);
    ++iteration_;
    if (iteration_ % options_.energy_interval == 0) {
      const double e = energy();
      if (!std::isfinite(e) || e > options_.energy_growth_bound * initial_energy_)
        throw_verlet_divergence(iteration_, e, initial_energy_, coefficients_, options_);
    }
    return std::sqrt(r2) / scale_;
  }

  double residual() override { return std::sqrt(sweep(false)) / scale_; }

  double energy() override {
    const double dt2 = coefficients_.dt * coefficients_.dt;
    const int nx = shape_.nx;
    tbb::parallel_for(tbb::blocked_range<long>(0, rows_, grain_), [&](const tbb::blocked_range<long>& range) {
      for (long row = range.begin(); row != range.end(); ++row) {
        double e = 0.0;
        for (int i = 0; i < nx; ++i) {
          const long p = row * nx + i;
          double v2 = 0.0;
          for (int c = 0; c < 3; ++c) v2 += (x_[c][p] - p_[c][p]) * (x_[c][p] - p_[c][p]);
          e += 0.5 * coefficients_.mass[p] * v2 / dt2;
          for (int d = 0; d < directions_; ++d) {
            const double k = stiffness_[d][p];
            if (k == 0.0) continue;  // no spring: the neighbour is outside the lattice
            const long q = p + offset_[d];
            double l2 = 0.0;
            for (int c = 0; c < 3; ++c) l2 += (x_[c][q] - x_[c][p]) * (x_[c][q] - x_[c][p]);
            const double stretch = k * std::sqrt(l2) - 1.0;  // k (|l| - rest)
            e += 0.5 * stretch * stretch / k;
          }
        }
        row_energy_[row] = e;
      }
    }, tbb::simple_partitioner());
    double total = 0.0;
    for (long row = 0; row < rows_; ++row) total += row_energy_[row];
    return total;
  }

  std::vector<Vec3> positions() const override {
    std::vector<Vec3> out(n_);
    for (long i = 0; i < n_; ++i) out[i] = Vec3(x_[0][i], x_[1][i], x_[2][i]);
    return out;
  }
  std::string backend() const override {
    return std::string(momentum_ ? "momentum-" : "") + (uniform_k_ ? "structured-uniform" : "structured");
  }
  double time_step() const override { return coefficients_.dt; }
  double mean_damping() const override { return coefficients_.mean_damping; }

 private:
  Kernel kernel() {
    Kernel g;
    g.x = x_[0].data();
    g.y = x_[1].data();
    g.z = x_[2].data();
    g.px = p_[0].data();
    g.py = p_[1].data();
    g.pz = p_[2].data();
    for (int d = 0; d < kMaxDirections; ++d) {
      g.k[d] = d < directions_ ? stiffness_[d].data() : nullptr;
      g.offset[d] = d < directions_ ? offset_[d] : 0;
    }
    g.a = coefficients_.a.data();
    g.b = coefficients_.b.data();
    g.fixed = fixed_.data();
    for (int d = 0; d < kMaxDirections; ++d) g.k_uniform[d] = d < directions_ ? k_uniform_[d] : 0.0;
    g.a_uniform = coefficients_.a.empty() ? 0.0 : coefficients_.a[0];
    g.b_uniform = coefficients_.b.empty() ? 0.0 : coefficients_.b[0];  // momentum: b holds one value
    return g;
  }

  // A lattice is uniform when every direction's springs share one stiffness to 1e-12 relative
  // (regular lattices: the rest lengths differ only by rounding); a, b are uniform when every
  // point has the same. Interior rows then read scalars instead of 3 or 13 stiffness arrays and
  // 2 coefficient arrays, which is most of the memory traffic. The stiffness used is the direction's mean: a
  // change of at most 1e-12 relative, far below any solver tolerance.
  void detect_uniform() {
    uniform_ab_ = n_ > 0;
    for (long i = 1; i < n_ && uniform_ab_; ++i)
      uniform_ab_ = coefficients_.a[i] == coefficients_.a[0] && coefficients_.b[i] == coefficients_.b[0];
    uniform_k_ = n_ > 0;
    for (int d = 0; d < directions_ && uniform_k_; ++d) {
      double lo = std::numeric_limits<double>::infinity(), hi = 0.0, sum = 0.0;
      long count = 0;
      for (long i = 0; i < n_; ++i) {
        const double k = stiffness_[d][i];
        if (k == 0.0) continue;  // no spring (neighbour outside)
        lo = std::min(lo, k);
        hi = std::max(hi, k);
        sum += k;
        ++count;
      }
      if (count == 0 || hi - lo > 1e-12 * hi) uniform_k_ = false;
      else k_uniform_[d] = sum / count;
    }
    if (!uniform_k_) return;
    // The checked boundary path reads the arrays: give them the same values.
    for (int d = 0; d < directions_; ++d)
      for (long i = 0; i < n_; ++i)
        if (stiffness_[d][i] != 0.0) stiffness_[d][i] = k_uniform_[d];
  }

  // Checked scalar path for a point on the boundary of the index box.
  std::uint64_t boundary_point(const Kernel& g, long p, int i, int j, int k, bool write, double* power) const {
    const double xp = g.x[p], yp = g.y[p], zp = g.z[p];
    double f[3] = {0.0, 0.0, 0.0};
    for (int d = 0; d < directions_; ++d) {
      for (int sign = 1; sign >= -1; sign -= 2) {
        const int i2 = i + sign * dir_[d][0], j2 = j + sign * dir_[d][1], k2 = k + sign * dir_[d][2];
        if (i2 < 0 || j2 < 0 || k2 < 0 || i2 >= shape_.nx || j2 >= shape_.ny || k2 >= shape_.nz) continue;
        const long q = p + sign * offset_[d];
        const double l[3] = {g.x[q] - xp, g.y[q] - yp, g.z[q] - zp};
        const double w = g.k[d][sign > 0 ? p : q] - 1.0 / std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
        for (int c = 0; c < 3; ++c) f[c] += w * l[c];
      }
    }
    const bool is_fixed = g.fixed[p] != 0;
    if (is_fixed) {
      if (write) {
        g.px[p] = xp;
        g.py[p] = yp;
        g.pz[p] = zp;
      }
      return 0;
    }
    const double v[3] = {xp - g.px[p], yp - g.py[p], zp - g.pz[p]};
    *power += f[0] * v[0] + f[1] * v[1] + f[2] * v[2];
    if (write) {
      const double a = uniform_ab_ ? g.a_uniform : g.a[p], b = uniform_ab_ ? g.b_uniform : g.b[p];
      g.px[p] = xp + b * v[0] + a * f[0];
      g.py[p] = yp + b * v[1] + a * f[1];
      g.pz[p] = zp + b * v[2] + a * f[2];
    }
    return bits_of(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  }

  // One pass over the lattice: forces at the current positions, new positions into p_ when
  // `write`. Returns the largest squared force at a free point (NaN when any is NaN).
  double sweep(bool write) {
    const Kernel g = kernel();
    const int nx = shape_.nx, ny = shape_.ny, nz = shape_.nz;
    const bool model6 = directions_ == 3;
    tbb::parallel_for(tbb::blocked_range<long>(0, rows_, grain_), [&](const tbb::blocked_range<long>& range) {
      for (long row = range.begin(); row != range.end(); ++row) {
        const int j = static_cast<int>(row % ny), k = static_cast<int>(row / ny);
        const long base = row * nx;
        std::uint64_t largest = 0;
        double power = 0.0;
        auto take = [&largest](std::uint64_t v) { largest = v > largest ? v : largest; };
        if (j == 0 || k == 0 || j == ny - 1 || k == nz - 1 || nx < 3 || row_has_fixed_[row]) {
          for (int i = 0; i < nx; ++i) take(boundary_point(g, base + i, i, j, k, write, &power));
        } else {
          take(boundary_point(g, base, 0, j, k, write, &power));
          const long p0 = base + 1, p1 = base + nx - 1;
          take(kRows[write][uniform_k_][uniform_ab_][model6 ? 0 : 1](g, p0, p1, &power));
          take(boundary_point(g, base + nx - 1, nx - 1, j, k, write, &power));
        }
        row_largest_[row] = largest;
        row_power_[row] = power;
      }
    }, tbb::simple_partitioner());
    std::uint64_t largest = 0;
    power_ = 0.0;
    for (long row = 0; row < rows_; ++row) {
      largest = std::max(largest, row_largest_[row]);
      power_ += row_power_[row];
    }
    return double_of(largest);
  }

  SettleOptions options_;
  VerletCoefficients coefficients_;
  LatticeShape shape_;
  std::vector<std::vector<double>> stiffness_;  // [direction][point]; 0 where no spring
  long n_ = 0, rows_ = 0, grain_ = 1;
  int directions_ = 0, iteration_ = 0;
  std::array<int, 3> dir_[kMaxDirections];
  long offset_[kMaxDirections] = {};
  double k_uniform_[kMaxDirections] = {};
  bool uniform_k_ = false, uniform_ab_ = false;
  std::vector<double> x_[3], p_[3];
  std::vector<std::uint8_t> fixed_;
  std::vector<std::uint64_t> row_largest_;
  std::vector<double> row_power_;
  double power_ = 0.0;  // sum over free points of f . (x - x_previous), last sweep
  bool momentum_ = false;
  int since_restart_ = 0;
  int restarts_ = 0;
  std::vector<char> row_has_fixed_;
  std::vector<double> row_energy_;
  double scale_ = 1.0, floor_ = 0.0, initial_energy_ = 0.0;
};

}  // namespace

std::unique_ptr<SpringSolver> make_structured_verlet(const SpringSystem& system, const SettleOptions& options,
                                                     const LatticeShape& shape, bool momentum) {
  const long n = static_cast<long>(shape.nx) * shape.ny * shape.nz;
  if (shape.nx < 1 || shape.ny < 1 || shape.nz < 1 || n != static_cast<long>(system.positions.size()))
    return nullptr;
  const auto& dirs = half_offsets(shape.model);
  std::vector<std::vector<double>> stiffness(dirs.size(), std::vector<double>(n, 0.0));
  for (const Spring& s : system.springs) {
    const int ia = s.a % shape.nx, ja = (s.a / shape.nx) % shape.ny, ka = s.a / (shape.nx * shape.ny);
    const int ib = s.b % shape.nx, jb = (s.b / shape.nx) % shape.ny, kb = s.b / (shape.nx * shape.ny);
    const std::array<int, 3> delta = {ib - ia, jb - ja, kb - ka};
    int found = -1;
    for (std::size_t d = 0; d < dirs.size(); ++d)
      if (dirs[d] == delta) found = static_cast<int>(d);
    if (found < 0) return nullptr;                       // not a neighbour of this model
    if (stiffness[found][s.a] != 0.0) return nullptr;    // duplicate spring
    if (!(std::abs(s.stiffness * s.rest - 1.0) <= 1e-12)) return nullptr;  // k != 1 / rest
    stiffness[found][s.a] = s.stiffness;
  }
  // Every in-lattice neighbour pair must carry a spring: the vectorised rows assume it.
  for (int k = 0; k < shape.nz; ++k)
    for (int j = 0; j < shape.ny; ++j)
      for (int i = 0; i < shape.nx; ++i)
        for (std::size_t d = 0; d < dirs.size(); ++d) {
          const int i2 = i + dirs[d][0], j2 = j + dirs[d][1], k2 = k + dirs[d][2];
          if (i2 < 0 || j2 < 0 || k2 < 0 || i2 >= shape.nx || j2 >= shape.ny || k2 >= shape.nz) continue;
          if (stiffness[d][i + static_cast<long>(shape.nx) * (j + static_cast<long>(shape.ny) * k)] == 0.0)
            return nullptr;
        }
  return std::make_unique<StructuredVerlet>(system, options, shape, std::move(stiffness), momentum);
}

}  // namespace fascicle::springs::detail
