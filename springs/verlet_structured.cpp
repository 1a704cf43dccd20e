// Verlet (Zeleny 2011, formula 3.8) on the structured lattice path.
//
// Data: struct of arrays (x, y, z; previous x, y, z), one stiffness array per half direction
// (3 for model-6, 13 for model-26; stiffness 1 / rest length, so the rest length is 1 / k and
// the force of a spring is (k - 1 / |l|) l), per-point coefficients a = dt^2 / m and
// b = 1 - c dt / m, fixed flags. Every array stores its rows padded to a multiple of 8 points
// from a 64-byte boundary (so every vector of 8 points lies in one cache line); padding points
// are fixed, without springs, and never read into a result. Neighbours are implicit: the spring
// from p in half direction d ends at p + offset[d].
//
// Every spring is evaluated once, from its first end, and its force pushed to both ends: +f to
// the first, -f to the other. The half directions only point forward in the row order (row =
// (j, k), rows in index order), to the same row, the next one and the three rows around it in
// the next plane, so once a row's own springs are evaluated its force is complete: the row is
// integrated at once (forces of the current positions, new positions written over the previous
// ones, which nothing else reads). The pushes go to per-task accumulators of two planes (the
// current and the next). Tasks take tiles: slabs of planes x strips of rows (so a task's data
// stays in the second-level cache). A tile first evaluates the rows around it that push into
// it (the plane before the slab, forward directions only; the rows on both sides of the strip
// in each plane), in the order one pass over the whole lattice makes them, so every point's
// force is summed in the same order whatever the tiles: the result does not depend on the
// thread count or the grain (tested bitwise). Compared with gathering (each point evaluating
// all its springs) this halves the inverse square roots, which bound the model-26 iteration.
// On model-26 lattices the three springs of a row into one target row (dx = -1, 0, +1) are
// summed in registers before the push, so each target row gets one aligned read-modify-write
// per vector instead of three overlapping unaligned ones (which stall store forwarding); the
// dx = -1 springs are evaluated in the lane of their target, so only their force on the source
// is shifted between lanes, once for the four groups. The rows of a tile with every spring run
// their vectors without masks, and software prefetch brings the positions of the next plane's
// rows and the previous positions ahead of the loads. The rows of a plane of a tile that are
// alike (all but the strip's first and last) run as one call, their set-up made once.
//
// This path needs a vector loop written with intrinsics: a row is one loop (own springs summed
// in registers, integration in the same pass), written once (springs/fused_rows_kernel.h) and
// compiled for AVX-512, 8 points a vector (springs/fused_rows_avx512.cpp: 1 / sqrt from VRSQRT14PD
// and a third-order step, relative error below about 6e-13), and for AVX2 with FMA, 4 points a
// vector (springs/fused_rows_avx2.cpp: VRSQRTPS and a fourth-order step). Elsewhere (or after set_structured_simd(false)) the portable gather path
// runs: every spring evaluated from both ends with a square root and a division, vectorised by
// the compiler (sweep_gather). All are deterministic; they differ from each other by rounding. When
// every direction's springs share one stiffness and every point the same coefficients, the rows
// read scalars instead of those arrays (detect_uniform). The same kernels run the momentum
// static solver (per-step b, gradient restarts).

#include "geometry/errors.h"
#include "springs/fused_row.h"
#include "springs/solvers_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define FASCICLE_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define FASCICLE_CLONES
#endif

namespace fascicle::springs::detail {

namespace {
std::atomic<bool> g_simd_enabled{true};
std::atomic<bool> g_avx512_enabled{true};
}  // namespace

void set_structured_simd(bool enabled) { g_simd_enabled = enabled; }
void set_structured_avx512(bool enabled) { g_avx512_enabled = enabled; }

namespace {
// The vector loop a structured solver built now would take: 2 AVX-512, 1 AVX2, 0 none.
int simd_level() {
  if (!g_simd_enabled) return 0;
  if (g_avx512_enabled && avx512_rows_supported()) return 2;
  return avx2_rows_supported() ? 1 : 0;
}
}  // namespace

bool structured_simd_active() { return simd_level() > 0; }

const char* structured_simd_name() {
  static const char* const names[] = {"plain", "avx2", "avx512"};
  return names[simd_level()];
}

namespace {

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

// The portable path (processors without AVX2, or set_structured_simd(false)): the gather
// formulation. Each point sums its springs from both ends at the current positions and its new
// position is written over its previous one; rows of interior points without a fixed point run
// through a branch-free loop the compiler vectorises (compiled for AVX-512, AVX2 and baseline
// x86-64, picked at run time); points on the boundary of the index box take a checked scalar
// path. Every point's force is a function of the current positions alone, so the result does
// not depend on the traversal order either.
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
// sum f . (x - x_previous) to `power` (the momentum solver's restart test), summed in point order
// from `terms` (room for p1 - p0 values): a vector reduction would group the sum by the clone's
// vector width, and the result must not depend on the processor (SettleOptions::portable_loop).
template <bool Write, bool UniformK, bool UniformAB, std::size_t... Ds>
inline __attribute__((always_inline)) std::uint64_t row_body(const Kernel& g, long p0, long p1, double* power,
                                                             double* __restrict terms, std::index_sequence<Ds...>) {
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
  // Point p writes only px/py/pz[p] and terms[p - p0], which no other iteration reads: no
  // loop-carried dependence (GCC's restrict on locals is too weak to prove it with three output
  // streams). The maximum does not depend on the order.
#pragma omp simd reduction(max : largest)
  for (long p = p0; p < p1; ++p) {
    const double xp = x[p], yp = y[p], zp = z[p];
    double fx = 0.0, fy = 0.0, fz = 0.0;
    (add_direction<UniformK>(x, y, z, k[Ds], ku[Ds], off[Ds], p, xp, yp, zp, fx, fy, fz), ...);
    const std::uint64_t bits = bits_of(fx * fx + fy * fy + fz * fz);
    largest = bits > largest ? bits : largest;
    const double vx = xp - px[p], vy = yp - py[p], vz = zp - pz[p];
    terms[p - p0] = fx * vx + fy * vy + fz * vz;
    if (Write) {
      const double ap = UniformAB ? au : a[p], bp = UniformAB ? bu : b[p];
      px[p] = xp + bp * vx + ap * fx;
      py[p] = yp + bp * vy + ap * fy;
      pz[p] = zp + bp * vz + ap * fz;
    }
  }
  double fv = 0.0;
  for (long i = 0; i < p1 - p0; ++i) fv += terms[i];
  *power += fv;
  return largest;
}

using RowFunction = std::uint64_t (*)(const Kernel&, long, long, double*, double*);
#define FASCICLE_ROW(name, write, uk, uab, d)                                                           \
  FASCICLE_CLONES std::uint64_t name(const Kernel& g, long p0, long p1, double* power, double* terms) { \
    return row_body<write, uk, uab>(g, p0, p1, power, terms, std::make_index_sequence<d>());            \
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

// Allocations on 64-byte boundaries (a cache line, one 512-bit vector): with rows of a multiple
// of 8 points every vector load and store of the AVX-512 path then stays within one line.
template <class T>
struct LineAligned {
  using value_type = T;
  LineAligned() = default;
  template <class U>
  LineAligned(const LineAligned<U>&) {}
  T* allocate(std::size_t n) {
    void* p = std::aligned_alloc(64, (n * sizeof(T) + 63) / 64 * 64);
    if (!p) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t) { std::free(p); }
  template <class U>
  bool operator==(const LineAligned<U>&) const {
    return true;
  }
  template <class U>
  bool operator!=(const LineAligned<U>&) const {
    return false;
  }
};
using AlignedDoubles = std::vector<double, LineAligned<double>>;

// Accumulators of one task: two planes of ny rows of nx forces per coordinate (plane k and
// k + 1, alternating; nx here the padded row length); a task touches only the rows of its strip.
// The first push into a row overwrites it, rows without one are zeroed (zero; see sweep).
struct Ring {
  AlignedDoubles f[3];
  long ny = 0, nx = 0;
  void reset(long rows_per_plane, long row_length) {
    if (ny != rows_per_plane || nx != row_length) {
      ny = rows_per_plane;
      nx = row_length;
      for (auto& v : f) v.assign(static_cast<std::size_t>(2 * ny * nx), 0.0);
    }
  }
  // Where row (j, k) starts in each f (no division: fused_row asks for about 40 a row).
  long start(long j, long k) const { return ((k & 1) * ny + j) * nx; }
  // Row j + ny k of the lattice.
  void zero(long r) {
    for (int c = 0; c < 3; ++c)
      std::memset(f[c].data() + start(r % ny, r / ny), 0, sizeof(double) * static_cast<std::size_t>(nx));
  }
};

// A task's part of the lattice: planes [k0, k1) x rows [j0, j1) of each plane.
struct Tile {
  long k0, k1, j0, j1;
  // Whether row (j, k) is pushed into by this task: inside the tile.
  bool holds(long j, long k) const { return j >= j0 && j < j1 && k >= k0 && k < k1; }
};

class StructuredVerlet final : public SpringSolver {
 public:
  StructuredVerlet(const SpringSystem& system, const SettleOptions& options, const LatticeShape& shape,
                   std::vector<std::vector<double>> stiffness, bool momentum)
      : options_(options),
        coefficients_(momentum ? momentum_coefficients(system) : verlet_coefficients(system, options)),
        shape_(shape),
        stiffness_(std::move(stiffness)),
        momentum_(momentum) {
    n_ = static_cast<long>(system.positions.size());
    rows_ = static_cast<long>(shape.ny) * shape.nz;
    // Rows padded to a multiple of 8 points: with the 64-byte aligned arrays every row, and so
    // every vector of the AVX-512 path, starts on a cache line (a vector split over two lines
    // costs two accesses). The padding points are never read into a result: the vector loads
    // past a row's end are masked, the other loops stop at nx.
    stride_ = (static_cast<long>(shape.nx) + 7) / 8 * 8;
    padded_n_ = stride_ * rows_;
    const auto& dirs = half_offsets(shape.model);
    directions_ = static_cast<int>(dirs.size());
    for (int d = 0; d < directions_; ++d) {
      dir_[d] = dirs[d];
      offset_[d] = dirs[d][0] + stride_ * (dirs[d][1] + static_cast<long>(shape.ny) * dirs[d][2]);
    }
    if (directions_ == kMaxDirections) {
      // Model-26: the 12 directions off the row in groups of one target row (dy, dz), slots by
      // dx + 1 (fused_row).
      int groups = 0;
      long key[4];
      for (int d = 0; d < directions_; ++d) {
        const int dx = dir_[d][0], dy = dir_[d][1], dz = dir_[d][2];
        if (dy == 0 && dz == 0) continue;  // along x
        const long kd = dy + 3L * dz;
        int g = 0;
        while (g < groups && key[g] != kd) ++g;
        if (g == groups) key[groups++] = kd;
        group_[g][dx + 1] = d;
      }
      if (groups != 4 || key[kFirstPushGroup] != 1 + 3L * 1)
        throw std::logic_error("structured Verlet: unexpected order of the model-26 directions");
    } else if (dir_[kModel6FirstPush] != std::array<int, 3>{0, 0, 1}) {
      throw std::logic_error("structured Verlet: unexpected order of the model-6 directions");
    }
    for (int c = 0; c < 3; ++c) {
      x_[c].assign(padded_n_, 0.0);
      p_[c].assign(padded_n_, 0.0);
      for (long i = 0; i < n_; ++i) x_[c][padded(i)] = p_[c][padded(i)] = system.positions[i][c];
    }
    fixed_.assign(padded_n_, 1);  // padding: fixed
    for (long i = 0; i < n_; ++i) fixed_[padded(i)] = system.fixed[i] ? 1 : 0;
    for (auto& k : stiffness_) k = padded_copy(k, 0.0);  // padding: no spring
    // Per-point coefficients (momentum: b may hold one value); padding takes the row's first
    // point's value, so uniform coefficients stay uniform.
    for (std::vector<double>* v : {&coefficients_.a, &coefficients_.b, &coefficients_.mass})
      if (static_cast<long>(v->size()) == n_ && n_ > 0) *v = padded_copy(*v, NAN);
    // Tiles of whole rows: slabs of planes (a slab re-evaluates the forward springs of the plane
    // before it: 9 of the 13 model-26 directions, one plane a slab) x strips of at most 25 rows
    // (a strip re-evaluates the pushes of the rows on both sides: 9 springs a plane), 2 slabs per
    // thread. Strips keep a task's positions and accumulators in the second-level cache; wider
    // strips evaluate fewer springs twice (at 100^3 on 2 threads 4 x 4 tiles of 25 x 25 rows,
    // about 5.8 % of the springs). The result does not depend on the tiles.
    const long threads = std::max(1, tbb::this_task_arena::max_concurrency());
    slab_ = std::max(2L, (shape.nz + 2 * threads - 1) / (2 * threads));
    strip_ = shape.ny;
    if (shape.ny > 32) strip_ = (shape.ny + (shape.ny + 24) / 25 - 1) / ((shape.ny + 24) / 25);
    // Small lattices run as one task: TBB's overhead per task is larger than their iteration.
    if (n_ < 32768) {
      slab_ = shape.nz;
      strip_ = shape.ny;
    }
    slabs_ = (shape.nz + slab_ - 1) / slab_;
    strips_ = (shape.ny + strip_ - 1) / strip_;
    row_largest_.assign(rows_, 0);
    row_power_.assign(rows_, 0.0);
    simd_ = structured_simd_active() && !options.portable_loop;
    avx512_ = simd_level() == 2;
    // The portable path's vectorised rows have no fixed-point logic: a row with a fixed interior
    // point takes the checked path.
    row_has_fixed_.assign(rows_, 0);
    for (long row = 0; row < rows_; ++row)
      for (int i = 1; i + 1 < shape.nx; ++i)
        if (fixed_[row * stride_ + i]) row_has_fixed_[row] = 1;
    row_energy_.assign(rows_, 0.0);
    detect_uniform();
    if (momentum_) uniform_ab_ = true;  // one a for every point, b set each step
    scale_ = residual_force_scale(system);
    watch_ = DivergenceWatch(system, options, energy());
  }

  double step() override {
    if (momentum_) {
      // Gradient restart: the last step moved against the force (f . v < 0).
      if (schedule_.restart(power_ < 0.0))
        for (int c = 0; c < 3; ++c) p_[c] = x_[c];
      coefficients_.b.assign(1, schedule_.next());
    }
    const double r2 = sweep(true);
    watch_.check_force(iteration_ + 1, r2, coefficients_, options_);
    for (int c = 0; c < 3; ++c) std::swap(x_[c], p_[c]);
    ++iteration_;
    if (watch_.due(iteration_)) watch_.check(iteration_, energy(), coefficients_, options_);
    return std::sqrt(r2) / scale_;
  }

  double residual() override { return std::sqrt(sweep(false)) / scale_; }

  double energy() override {
    const double dt2 = coefficients_.dt * coefficients_.dt;
    const long nx = shape_.nx, ny = shape_.ny, nz = shape_.nz;
    tbb::parallel_for(
        tbb::blocked_range<long>(0, rows_, grain_),
        [&](const tbb::blocked_range<long>& range) {
          for (long row = range.begin(); row != range.end(); ++row) {
            const long base = row * stride_, j = row % ny, k = row / ny;
            const double* __restrict x = x_[0].data() + base;
            const double* __restrict y = x_[1].data() + base;
            const double* __restrict z = x_[2].data() + base;
            const double* __restrict px = p_[0].data() + base;
            const double* __restrict py = p_[1].data() + base;
            const double* __restrict pz = p_[2].data() + base;
            const double* __restrict mass = coefficients_.mass.data() + base;
            double e = 0.0;
#pragma omp simd reduction(+ : e)
            for (long i = 0; i < nx; ++i) {
              const double vx = x[i] - px[i], vy = y[i] - py[i], vz = z[i] - pz[i];
              e += 0.5 * mass[i] * (vx * vx + vy * vy + vz * vz) / dt2;
            }
            for (int d = 0; d < directions_; ++d) {
              if (j + dir_[d][1] < 0 || j + dir_[d][1] >= ny || k + dir_[d][2] >= nz) continue;
              const long i0 = dir_[d][0] < 0 ? 1 : 0, i1 = dir_[d][0] > 0 ? nx - 1 : nx;
              const double* __restrict ks = stiffness_[d].data() + base;
              const double* __restrict qx = x + offset_[d];
              const double* __restrict qy = y + offset_[d];
              const double* __restrict qz = z + offset_[d];
#pragma omp simd reduction(+ : e)
              for (long i = i0; i < i1; ++i) {
                const double lx = qx[i] - x[i], ly = qy[i] - y[i], lz = qz[i] - z[i];
                const double stretch = ks[i] * std::sqrt(lx * lx + ly * ly + lz * lz) - 1.0;  // k (|l| - rest)
                e += 0.5 * stretch * stretch / ks[i];
              }
            }
            row_energy_[row] = e;
          }
        },
        tbb::simple_partitioner());
    double total = 0.0;
    for (long row = 0; row < rows_; ++row) total += row_energy_[row];
    return total;
  }

  std::vector<Vec3> positions() const override {
    std::vector<Vec3> out(n_);
    for (long i = 0; i < n_; ++i) {
      const long q = padded(i);
      out[i] = Vec3(x_[0][q], x_[1][q], x_[2][q]);
    }
    return out;
  }
  std::string backend() const override {
    return std::string(momentum_ ? "momentum-" : "") + (uniform_k_ ? "structured-uniform" : "structured");
  }
  double time_step() const override { return coefficients_.dt; }
  double mean_damping() const override { return coefficients_.mean_damping; }

 private:
  // Index of lattice point i (build_lattice order) in the padded arrays.
  long padded(long i) const { return i % shape_.nx + stride_ * (i / shape_.nx); }
  // A per-point array in the padded layout; padding points get `pad` (NaN: the row's first value).
  std::vector<double> padded_copy(const std::vector<double>& v, double pad) const {
    std::vector<double> out(static_cast<std::size_t>(padded_n_), pad);
    for (long row = 0; row < rows_; ++row)
      for (long i = 0; i < stride_; ++i)
        out[row * stride_ + i] = i < shape_.nx ? v[row * shape_.nx + i] : std::isnan(pad) ? v[row * shape_.nx] : pad;
    return out;
  }

  // A lattice is uniform when every direction's springs share one stiffness to 1e-12 relative
  // (regular lattices: the rest lengths differ only by rounding); a, b are uniform when every
  // point has the same. Interior rows then read scalars instead of 3 or 13 stiffness arrays and
  // 2 coefficient arrays, which is most of the memory traffic. The stiffness used is the direction's mean: a
  // change of at most 1e-12 relative, far below any solver tolerance.
  void detect_uniform() {
    uniform_ab_ = n_ > 0;
    for (long i = 1; i < padded_n_ && uniform_ab_; ++i)
      uniform_ab_ = coefficients_.a[i] == coefficients_.a[0] && coefficients_.b[i] == coefficients_.b[0];
    uniform_k_ = n_ > 0;
    for (int d = 0; d < directions_ && uniform_k_; ++d) {
      double lo = std::numeric_limits<double>::infinity(), hi = 0.0, sum = 0.0;
      long count = 0;
      for (long i = 0; i < padded_n_; ++i) {
        const double k = stiffness_[d][i];
        if (k == 0.0) continue;  // no spring (neighbour outside)
        lo = std::min(lo, k);
        hi = std::max(hi, k);
        sum += k;
        ++count;
      }
      if (count == 0 || hi - lo > 1e-12 * hi)
        uniform_k_ = false;
      else
        k_uniform_[d] = sum / count;
    }
    if (!uniform_k_) return;
    // The checked boundary path reads the arrays: give them the same values.
    for (int d = 0; d < directions_; ++d)
      for (long i = 0; i < padded_n_; ++i)
        if (stiffness_[d][i] != 0.0) stiffness_[d][i] = k_uniform_[d];
  }

  // The vector loops' row `r`: pushes into the rows the tile holds; `integrate` false for the rows
  // around the tile (only pushes; `forward_only`: only the directions into the next plane).
  FusedRow fused_row(Ring& ring, long r, const Tile& tile, bool integrate, bool forward_only, bool write) {
    const long nx = shape_.nx, ny = shape_.ny, nz = shape_.nz;
    const long j = r % ny, k = r / ny, base = r * stride_;
    FusedRow f;
    for (int c = 0; c < 3; ++c) {
      f.x[c] = x_[c].data() + base;
      f.p[c] = p_[c].data() + base;
      f.ring[c] = ring.f[c].data() + ring.start(j, k);
    }
    f.directions = directions_;
    f.along_x = -1;
    for (int d = 0; d < directions_; ++d) {
      const int dx = dir_[d][0], dy = dir_[d][1], dz = dir_[d][2];
      f.valid[d] = j + dy >= 0 && j + dy < ny && k + dz < nz && nx > (dx != 0 ? 1 : 0) && (!forward_only || dz == 1);
      f.dx[d] = dx;
      f.offset[d] = offset_[d];
      f.k[d] = uniform_k_ ? nullptr : stiffness_[d].data() + base;
      f.ku[d] = k_uniform_[d];
      const bool along_x = dx == 1 && dy == 0 && dz == 0;
      if (along_x && f.valid[d] && integrate) f.along_x = d;
      const bool push = f.valid[d] && !along_x && tile.holds(j + dy, k + dz);
      const long target = push ? ring.start(j + dy, k + dz) : 0;
      for (int c = 0; c < 3; ++c) f.push[d][c] = push ? ring.f[c].data() + target : nullptr;
    }
    if (directions_ == kMaxDirections) {
      std::memcpy(f.group, group_, sizeof group_);
      for (int g = 0; g < 4; ++g)  // the push of dx = 0 (dx = +-1 are not valid in a row of one point)
        for (int c = 0; c < 3; ++c) f.group_push[g][c] = f.push[group_[g][1]][c];
    }
    f.a = uniform_ab_ ? nullptr : coefficients_.a.data() + base;
    f.b = uniform_ab_ ? nullptr : coefficients_.b.data() + base;
    f.au = coefficients_.a.empty() ? 0.0 : coefficients_.a[0];
    f.bu = coefficients_.b.empty() ? 0.0 : coefficients_.b[0];  // momentum: b holds one value
    f.fixed = fixed_.data() + base;
    f.nx = nx;
    f.stride = stride_;
    f.integrate = integrate;
    f.write = write;
    f.power = momentum_;  // only the momentum solver reads power_
    return f;
  }

  // Rows r .. r + count - 1 of one plane on a vector path (AVX-512 or AVX2), alike in their springs
  // and pushes (springs/fused_rows_kernel.h). `integrate`: rows of the tile (own springs, then each row is complete
  // and integrated); else rows around it (pushes into the tile only).
  void process_rows(Ring& ring, long r, long count, const Tile& tile, bool integrate, bool forward_only, bool write) {
    const FusedRow row = fused_row(ring, r, tile, integrate, forward_only, write);
    if (avx512_)
      fused_rows_avx512(row, count, row_largest_.data() + r, row_power_.data() + r);
    else
      fused_rows_avx2(row, count, row_largest_.data() + r, row_power_.data() + r);
  }

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

  // The portable pass (gather).
  double sweep_gather(bool write) {
    const Kernel g = kernel();
    const int nx = shape_.nx, ny = shape_.ny, nz = shape_.nz;
    const bool model6 = directions_ == 3;
    tbb::parallel_for(
        tbb::blocked_range<long>(0, rows_, grain_),
        [&](const tbb::blocked_range<long>& range) {
          std::vector<double> terms(static_cast<std::size_t>(nx));  // a row's power terms (row_body)
          for (long row = range.begin(); row != range.end(); ++row) {
            const int j = static_cast<int>(row % ny), k = static_cast<int>(row / ny);
            const long base = row * stride_;
            std::uint64_t largest = 0;
            double power = 0.0;
            auto take = [&largest](std::uint64_t v) { largest = v > largest ? v : largest; };
            if (j == 0 || k == 0 || j == ny - 1 || k == nz - 1 || nx < 3 || row_has_fixed_[row]) {
              for (int i = 0; i < nx; ++i) take(boundary_point(g, base + i, i, j, k, write, &power));
            } else {
              take(boundary_point(g, base, 0, j, k, write, &power));
              const long p0 = base + 1, p1 = base + nx - 1;
              take(kRows[write][uniform_k_][uniform_ab_][model6 ? 0 : 1](g, p0, p1, &power, terms.data()));
              take(boundary_point(g, base + nx - 1, nx - 1, j, k, write, &power));
            }
            row_largest_[row] = largest;
            row_power_[row] = power;
          }
        },
        tbb::simple_partitioner());
    std::uint64_t largest = 0;
    power_ = 0.0;
    for (long row = 0; row < rows_; ++row) {
      largest = std::max(largest, row_largest_[row]);
      power_ += row_power_[row];
    }
    return double_of(largest);
  }

  // One pass over the lattice: forces at the current positions, new positions into p_ when
  // `write`. Returns the largest squared force at a free point (NaN when any is NaN).
  //
  // Tasks take tiles: slabs of planes x strips of rows. Rows are visited in index order: for
  // each plane of the slab, the row before the strip (its pushes into the strip), the strip's
  // rows (own springs, pushes, integration), the row after it (its pushes into the strip); a
  // slab starts with the same for the plane before it, directions into the next plane only.
  // Every row that pushes into a point does so in the same order as in one pass over the whole
  // lattice, so each point's force is summed in the same order whatever the tiles.
  double sweep(bool write) {
    if (!simd_) return sweep_gather(write);
    const long ny = shape_.ny;
    tbb::parallel_for(
        tbb::blocked_range<long>(0, slabs_ * strips_, 1),
        [&](const tbb::blocked_range<long>& range) {
          Ring& ring = rings_.local();
          ring.reset(ny, stride_);
          for (long task = range.begin(); task != range.end(); ++task) {
            Tile tile;
            tile.k0 = (task / strips_) * slab_;
            tile.k1 = std::min<long>(shape_.nz, tile.k0 + slab_);
            tile.j0 = (task % strips_) * strip_;
            tile.j1 = std::min<long>(ny, tile.j0 + strip_);
            // The strip's rows but its first and last are alike (their targets j - 1 .. j + 1 are
            // all in the strip and the lattice): one run. The first and last row push into one row
            // fewer each.
            auto plane = [&](long k, bool integrate, bool forward_only) {
              const long r0 = ny * k;
              if (tile.j0 > 0) process_rows(ring, r0 + tile.j0 - 1, 1, tile, false, forward_only, write);
              process_rows(ring, r0 + tile.j0, 1, tile, integrate, forward_only, write);
              if (tile.j1 - tile.j0 > 2)
                process_rows(ring, r0 + tile.j0 + 1, tile.j1 - tile.j0 - 2, tile, integrate, forward_only, write);
              if (tile.j1 - tile.j0 > 1) process_rows(ring, r0 + tile.j1 - 1, 1, tile, integrate, forward_only, write);
              if (tile.j1 < ny) process_rows(ring, r0 + tile.j1, 1, tile, false, forward_only, write);
            };
            // The first push into row (j, k + 1) stores instead of adding: model-6 the one of row
            // (j, k) in direction (0, 0, 1), model-26 the one of row (j - 1, k) in group (1, 1) (rows
            // go in index order, the row before the strip included, and nothing pushes into k + 1
            // from plane k - 1). Only rows without such a push are zeroed: the first plane of the
            // lattice (no plane before it) and, model-26, row 0 of each plane.
            const bool model26 = directions_ == kMaxDirections;
            if (tile.k0 == 0)
              for (long j = tile.j0; j < tile.j1; ++j) ring.zero(j);
            else if (model26 && tile.j0 == 0)
              ring.zero(ny * tile.k0);
            if (tile.k0 > 0) plane(tile.k0 - 1, false, true);
            for (long k = tile.k0; k < tile.k1; ++k) {
              if (model26 && tile.j0 == 0 && k + 1 < tile.k1) ring.zero(ny * (k + 1));
              plane(k, true, false);
            }
          }
        },
        tbb::simple_partitioner());
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
  long n_ = 0, stride_ = 1, padded_n_ = 0, rows_ = 0, grain_ = 1, slab_ = 1, slabs_ = 1, strip_ = 1, strips_ = 1;
  bool simd_ = false;    // a vector loop (structured_simd_active at construction), else gather
  bool avx512_ = false;  // that loop is the AVX-512 one, else the AVX2 one
  std::vector<char> row_has_fixed_;
  tbb::enumerable_thread_specific<Ring> rings_;
  int directions_ = 0, iteration_ = 0;
  std::array<int, 3> dir_[kMaxDirections];
  long offset_[kMaxDirections] = {};
  int group_[4][3] = {};  // model-26: FusedRow::group
  double k_uniform_[kMaxDirections] = {};
  bool uniform_k_ = false, uniform_ab_ = false;
  AlignedDoubles x_[3], p_[3];
  std::vector<std::uint8_t> fixed_;
  std::vector<std::uint64_t> row_largest_;
  std::vector<double> row_power_;
  double power_ = 0.0;  // sum over free points of f . (x - x_previous), last sweep
  bool momentum_ = false;
  MomentumSchedule schedule_;
  DivergenceWatch watch_;
  std::vector<double> row_energy_;
  double scale_ = 1.0;
};

}  // namespace

std::unique_ptr<SpringSolver> make_structured_verlet(const SpringSystem& system, const SettleOptions& options,
                                                     const LatticeShape& shape, bool momentum) {
  const long n = static_cast<long>(shape.nx) * shape.ny * shape.nz;
  if (shape.nx < 1 || shape.ny < 1 || shape.nz < 1 || n != static_cast<long>(system.positions.size())) return nullptr;
  const auto& dirs = half_offsets(shape.model);
  std::vector<std::vector<double>> stiffness(dirs.size(), std::vector<double>(n, 0.0));
  for (const Spring& s : system.springs) {
    const int ia = s.a % shape.nx, ja = (s.a / shape.nx) % shape.ny, ka = s.a / (shape.nx * shape.ny);
    const int ib = s.b % shape.nx, jb = (s.b / shape.nx) % shape.ny, kb = s.b / (shape.nx * shape.ny);
    const std::array<int, 3> delta = {ib - ia, jb - ja, kb - ka};
    int found = -1;
    for (std::size_t d = 0; d < dirs.size(); ++d)
      if (dirs[d] == delta) found = static_cast<int>(d);
    if (found < 0) return nullptr;                                         // not a neighbour of this model
    if (stiffness[found][s.a] != 0.0) return nullptr;                      // duplicate spring
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
