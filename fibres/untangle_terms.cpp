// The untangling energy's tetrahedron terms in AVX2 vectors (fibres/untangle_terms.h). The order
// of every operation below is the scalar code's in fibres/untangle.cpp (Energy::evaluate and its
// helpers), as Eigen 3.4 evaluates it there:
// - J = D R (3 x 3 product): rows 0 and 1 of each column sum (d0 r0 + d1 r1) + d2 r2, row 2
//   d0 r0 + (d1 r1 + d2 r2) (Eigen's two-row packet and its scalar tail);
// - det J: h(0,1,2) - h(1,0,2) + h(2,0,1), h(a,b,c) = J0a (J1b J2c - J1c J2b);
// - |J|^2: ((q0 + q2) + (q4 + q6)) + ((q1 + q3) + (q5 + q7)), then + q8 (q = squared entries,
//   column-major: the two lanes of Eigen's packet sums);
// - the gradient (w dJ) R^T, summed like J.
// No FMA: each product and sum is rounded as in the scalar code. tests/fibres_untangle_test.cpp
// checks the untangling gives the same positions, bit for bit, with and without this path.

#include "fibres/untangle_terms.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

namespace fascicle::detail {

namespace {
std::atomic<bool> g_untangle_simd{true};
}

void set_untangle_simd(bool enabled) { g_untangle_simd = enabled; }

#if defined(__GNUC__) && defined(__x86_64__)

bool untangle_terms_avx2_supported() { return __builtin_cpu_supports("avx2"); }

namespace {

#define FASCICLE_AVX2 __attribute__((target("avx2"), always_inline)) inline

FASCICLE_AVX2 __m256d add(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
FASCICLE_AVX2 __m256d sub(__m256d a, __m256d b) { return _mm256_sub_pd(a, b); }
FASCICLE_AVX2 __m256d mul(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
FASCICLE_AVX2 __m256d div(__m256d a, __m256d b) { return _mm256_div_pd(a, b); }
FASCICLE_AVX2 __m256d set(double v) { return _mm256_set1_pd(v); }

// c^(2/3) as two_thirds_power() in fibres/untangle.cpp: the exponent-bit estimate of c^(-1/3)
// (integer arithmetic, lane by lane: AVX2 has no 64-bit division), four Newton steps, c y; lanes
// outside (1e-200, 1e200) take std::cbrt(c * c).
FASCICLE_AVX2 __m256d two_thirds_power4(__m256d c) {
  alignas(32) double lanes[4];
  _mm256_store_pd(lanes, c);
  alignas(32) std::uint64_t bits[4];
  for (int l = 0; l < 4; ++l) {
    std::memcpy(&bits[l], &lanes[l], sizeof(double));
    bits[l] = 0x553ef0ff289dd796ull - bits[l] / 3;
  }
  __m256d y = _mm256_castsi256_pd(_mm256_load_si256(reinterpret_cast<const __m256i*>(bits)));
  const __m256d four = set(4.0), third = set(1.0 / 3.0);
  for (int step = 0; step < 4; ++step) y = mul(mul(y, sub(four, mul(mul(mul(c, y), y), y))), third);
  __m256d out = mul(c, y);
  const __m256d in_range = _mm256_and_pd(_mm256_cmp_pd(c, set(1e-200), _CMP_GT_OQ), _mm256_cmp_pd(c, set(1e200), _CMP_LT_OQ));
  if (_mm256_movemask_pd(in_range) != 0xF) {
    alignas(32) double result[4];
    _mm256_store_pd(result, out);
    for (int l = 0; l < 4; ++l)
      if (!(lanes[l] > 1e-200 && lanes[l] < 1e200)) result[l] = std::cbrt(lanes[l] * lanes[l]);
    out = _mm256_load_pd(result);
  }
  return out;
}

}  // namespace

__attribute__((target("avx2"))) void untangle_terms_avx2(const double p[12][4], const double* const r[9],
                                                         const double* weight, const double* eps_floor, double eps,
                                                         double lambda, double* term, double* const* grad) {
  // D: the edge vectors (columns), D(row, col) = p[col + 1][row] - p[0][row].
  __m256d d[9];
  for (int col = 0; col < 3; ++col)
    for (int row = 0; row < 3; ++row)
      d[row + 3 * col] = sub(_mm256_loadu_pd(p[3 * (col + 1) + row]), _mm256_loadu_pd(p[row]));
  __m256d rr[9];
  for (int k = 0; k < 9; ++k) rr[k] = _mm256_loadu_pd(r[k]);
  // J = D R
  __m256d j[9];
  for (int col = 0; col < 3; ++col)
    for (int row = 0; row < 3; ++row) {
      const __m256d a0 = mul(d[row], rr[3 * col]), a1 = mul(d[row + 3], rr[1 + 3 * col]),
                    a2 = mul(d[row + 6], rr[2 + 3 * col]);
      j[row + 3 * col] = row < 2 ? add(add(a0, a1), a2) : add(a0, add(a1, a2));
    }
  auto m = [&](int row, int col) __attribute__((target("avx2"), always_inline)) { return j[row + 3 * col]; };
  auto h = [&](int a, int b, int c) __attribute__((target("avx2"), always_inline)) {
    return mul(m(0, a), sub(mul(m(1, b), m(2, c)), mul(m(1, c), m(2, b))));
  };
  const __m256d det = add(sub(h(0, 1, 2), h(1, 0, 2)), h(2, 0, 1));
  // std::max(eps, floor): the floor where it is larger, else eps
  const __m256d e = _mm256_max_pd(_mm256_loadu_pd(eps_floor), set(eps));
  const __m256d root = _mm256_sqrt_pd(add(mul(e, e), mul(det, det)));
  const __m256d half = set(0.5), one = set(1.0);
  const __m256d c = mul(half, add(det, root));
  const __m256d c23 = two_thirds_power4(c);
  __m256d q[9];
  for (int k = 0; k < 9; ++k) q[k] = mul(j[k], j[k]);
  const __m256d frob = add(add(add(add(q[0], q[2]), add(q[4], q[6])), add(add(q[1], q[3]), add(q[5], q[7]))), q[8]);
  const __m256d shape = div(frob, c23);
  const __m256d det2p1 = add(mul(det, det), one);
  const __m256d volume = div(det2p1, c);
  const __m256d w = _mm256_loadu_pd(weight);
  const __m256d l1 = set(1.0 - lambda), lam = set(lambda);
  _mm256_storeu_pd(term, mul(w, add(mul(l1, shape), mul(lam, volume))));
  if (!grad) return;
  const __m256d dc = mul(half, add(one, div(det, root)));
  __m256d cof[9];
  auto cross = [&](int a, int b, int out) __attribute__((target("avx2"), always_inline)) {
    const __m256d* u = j + 3 * a;
    const __m256d* v = j + 3 * b;
    __m256d* o = cof + 3 * out;
    o[0] = sub(mul(u[1], v[2]), mul(u[2], v[1]));
    o[1] = sub(mul(u[2], v[0]), mul(u[0], v[2]));
    o[2] = sub(mul(u[0], v[1]), mul(u[1], v[0]));
  };
  cross(1, 2, 0);
  cross(2, 0, 1);
  cross(0, 1, 2);
  const __m256d s0 = div(set(2.0), c23);
  const __m256d s1 = mul(div(mul(set(2.0 / 3.0), shape), c), dc);
  const __m256d s2 = mul(lam, sub(div(mul(set(2.0), det), c), div(mul(det2p1, dc), mul(c, c))));
  __m256d wdj[9];
  for (int k = 0; k < 9; ++k) wdj[k] = mul(w, add(mul(l1, sub(mul(s0, j[k]), mul(s1, cof[k]))), mul(s2, cof[k])));
  // (w dJ) R^T: entry (row, col) = sum over k of (w dJ)(row, k) R(col, k).
  for (int col = 0; col < 3; ++col)
    for (int row = 0; row < 3; ++row) {
      const __m256d a0 = mul(wdj[row], rr[col]), a1 = mul(wdj[row + 3], rr[col + 3]), a2 = mul(wdj[row + 6], rr[col + 6]);
      _mm256_storeu_pd(grad[row + 3 * col], row < 2 ? add(add(a0, a1), a2) : add(a0, add(a1, a2)));
    }
}

#undef FASCICLE_AVX2

#else

bool untangle_terms_avx2_supported() { return false; }
void untangle_terms_avx2(const double[12][4], const double* const[9], const double*, const double*, double, double,
                         double*, double* const*) {}

#endif

bool untangle_simd_active() { return g_untangle_simd && untangle_terms_avx2_supported(); }

}  // namespace fascicle::detail
