// The untangling energy's tetrahedron terms in vectors (fibres/untangle_terms.h): AVX2 (four
// tetrahedra) and AVX-512 (eight), one body (fibres/untangle_terms_body.inc) compiled for each
// width. The order of every operation is the scalar code's in fibres/untangle.cpp
// (Energy::evaluate and its helpers), as Eigen 3.4 evaluates it there:
// - J = D R (3 x 3 product): rows 0 and 1 of each column sum (d0 r0 + d1 r1) + d2 r2, row 2
//   d0 r0 + (d1 r1 + d2 r2) (Eigen's two-row packet and its scalar tail);
// - det J: h(0,1,2) - h(1,0,2) + h(2,0,1), h(a,b,c) = J0a (J1b J2c - J1c J2b);
// - |J|^2: ((q0 + q2) + (q4 + q6)) + ((q1 + q3) + (q5 + q7)), then + q8 (q = squared entries,
//   column-major: the two lanes of Eigen's packet sums);
// - the gradient (w dJ) R^T, summed like J.
// No FMA (this file is built with -ffp-contract=off, and the AVX-512 width would otherwise let the
// compiler fuse products and sums): each product and sum is rounded as in the scalar code.
// tests/fibres_untangle_test.cpp checks the untangling gives the same positions, bit for bit,
// with each width and without.

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
std::atomic<bool> g_untangle_avx512{true};
}  // namespace

void set_untangle_simd(bool enabled) { g_untangle_simd = enabled; }
void set_untangle_avx512(bool enabled) { g_untangle_avx512 = enabled; }

#if defined(__GNUC__) && defined(__x86_64__)

#pragma GCC push_options
#pragma GCC target("avx2")
// GCC 12's intrinsic headers pass an uninitialised vector through (the unmasked gather and the
// AVX-512 forms) and then warn about it: a false positive.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
namespace avx2 {
using V = __m256d;
constexpr int kLanes = 4;
inline V add(V a, V b) { return _mm256_add_pd(a, b); }
inline V sub(V a, V b) { return _mm256_sub_pd(a, b); }
inline V mul(V a, V b) { return _mm256_mul_pd(a, b); }
inline V div(V a, V b) { return _mm256_div_pd(a, b); }
inline V sqrt_v(V a) { return _mm256_sqrt_pd(a); }
inline V max_v(V a, V b) { return _mm256_max_pd(a, b); }
inline V set(double v) { return _mm256_set1_pd(v); }
inline V loadu(const double* p) { return _mm256_loadu_pd(p); }
inline void storeu(double* p, V v) { _mm256_storeu_pd(p, v); }
inline V load(const double* p) { return _mm256_load_pd(p); }
inline void store(double* p, V v) { _mm256_store_pd(p, v); }
inline V gather(const double* base, const int* index) {
  return _mm256_i32gather_pd(base, _mm_loadu_si128(reinterpret_cast<const __m128i*>(index)), 8);
}
inline bool all_in_range(V c) {
  const V in = _mm256_and_pd(_mm256_cmp_pd(c, set(1e-200), _CMP_GT_OQ), _mm256_cmp_pd(c, set(1e200), _CMP_LT_OQ));
  return _mm256_movemask_pd(in) == 0xF;
}
// magic - bits(c) / 3 in each lane, the unsigned 64-bit division exact, in registers (the
// derivation: two_thirds_power_v in untangle_terms_body.inc).
inline V magic_minus_third(V c, std::uint64_t magic) {
  const __m256i x = _mm256_castpd_si256(c);
  const __m256i low32 = _mm256_set1_epi64x(0xFFFFFFFFll);
  const __m256i m3 = _mm256_set1_epi64x(0xAAAAAAABll);  // ceil(2^33 / 3): floor(v / 3) = v m3 >> 33, v < 2^32
  const __m256i hi = _mm256_srli_epi64(x, 32), lo = _mm256_and_si256(x, low32);
  const __m256i qh = _mm256_srli_epi64(_mm256_mul_epu32(hi, m3), 33);
  const __m256i ql = _mm256_srli_epi64(_mm256_mul_epu32(lo, m3), 33);
  const __m256i rh = _mm256_sub_epi64(hi, _mm256_add_epi64(qh, _mm256_add_epi64(qh, qh)));
  const __m256i rl = _mm256_sub_epi64(lo, _mm256_add_epi64(ql, _mm256_add_epi64(ql, ql)));
  __m256i q = _mm256_add_epi64(_mm256_slli_epi64(qh, 32), _mm256_mul_epu32(rh, _mm256_set1_epi64x(1431655765ll)));
  q = _mm256_add_epi64(q, ql);
  // + 1 where rh + rl >= 3 (the compare gives -1 there)
  q = _mm256_sub_epi64(q, _mm256_cmpgt_epi64(_mm256_add_epi64(rh, rl), _mm256_set1_epi64x(2)));
  return _mm256_castsi256_pd(_mm256_sub_epi64(_mm256_set1_epi64x(static_cast<long long>(magic)), q));
}
#include "fibres/untangle_terms_body.inc"
}  // namespace avx2
#pragma GCC diagnostic pop
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx512f")
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
namespace avx512 {
using V = __m512d;
constexpr int kLanes = 8;
inline V add(V a, V b) { return _mm512_add_pd(a, b); }
inline V sub(V a, V b) { return _mm512_sub_pd(a, b); }
inline V mul(V a, V b) { return _mm512_mul_pd(a, b); }
inline V div(V a, V b) { return _mm512_div_pd(a, b); }
inline V sqrt_v(V a) { return _mm512_sqrt_pd(a); }
inline V max_v(V a, V b) { return _mm512_max_pd(a, b); }
inline V set(double v) { return _mm512_set1_pd(v); }
inline V loadu(const double* p) { return _mm512_loadu_pd(p); }
inline void storeu(double* p, V v) { _mm512_storeu_pd(p, v); }
inline V load(const double* p) { return _mm512_load_pd(p); }
inline void store(double* p, V v) { _mm512_store_pd(p, v); }
inline V gather(const double* base, const int* index) {
  return _mm512_i32gather_pd(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(index)), base, 8);
}
inline bool all_in_range(V c) {
  const __mmask8 in = _mm512_cmp_pd_mask(c, set(1e-200), _CMP_GT_OQ) & _mm512_cmp_pd_mask(c, set(1e200), _CMP_LT_OQ);
  return in == 0xFF;
}
// magic - bits(c) / 3 in each lane, as the AVX2 one.
inline V magic_minus_third(V c, std::uint64_t magic) {
  const __m512i x = _mm512_castpd_si512(c);
  const __m512i low32 = _mm512_set1_epi64(0xFFFFFFFFll);
  const __m512i m3 = _mm512_set1_epi64(0xAAAAAAABll);
  const __m512i hi = _mm512_srli_epi64(x, 32), lo = _mm512_and_si512(x, low32);
  const __m512i qh = _mm512_srli_epi64(_mm512_mul_epu32(hi, m3), 33);
  const __m512i ql = _mm512_srli_epi64(_mm512_mul_epu32(lo, m3), 33);
  const __m512i rh = _mm512_sub_epi64(hi, _mm512_add_epi64(qh, _mm512_add_epi64(qh, qh)));
  const __m512i rl = _mm512_sub_epi64(lo, _mm512_add_epi64(ql, _mm512_add_epi64(ql, ql)));
  __m512i q = _mm512_add_epi64(_mm512_slli_epi64(qh, 32), _mm512_mul_epu32(rh, _mm512_set1_epi64(1431655765ll)));
  q = _mm512_add_epi64(q, ql);
  const __mmask8 carry = _mm512_cmpgt_epu64_mask(_mm512_add_epi64(rh, rl), _mm512_set1_epi64(2));
  q = _mm512_mask_add_epi64(q, carry, q, _mm512_set1_epi64(1));
  return _mm512_castsi512_pd(_mm512_sub_epi64(_mm512_set1_epi64(static_cast<long long>(magic)), q));
}
#include "fibres/untangle_terms_body.inc"
}  // namespace avx512
#pragma GCC diagnostic pop
#pragma GCC pop_options

bool untangle_terms_avx2_supported() { return __builtin_cpu_supports("avx2"); }
bool untangle_terms_avx512_supported() { return __builtin_cpu_supports("avx512f"); }

void untangle_terms_simd(int lanes, const double* positions, const int* const corners[4], const double* const r[9],
                         const double* weight, const double* eps_floor, double eps, double lambda, double* term,
                         double* const* grad) {
  if (lanes == 8)
    avx512::terms(positions, corners, r, weight, eps_floor, eps, lambda, term, grad);
  else
    avx2::terms(positions, corners, r, weight, eps_floor, eps, lambda, term, grad);
}

namespace {
__attribute__((target("avx2"))) void third_bits_avx2(const double* c, std::uint64_t magic, std::uint64_t* out) {
  _mm256_storeu_pd(reinterpret_cast<double*>(out), avx2::magic_minus_third(_mm256_loadu_pd(c), magic));
}
__attribute__((target("avx512f"))) void third_bits_avx512(const double* c, std::uint64_t magic, std::uint64_t* out) {
  _mm512_storeu_pd(reinterpret_cast<double*>(out), avx512::magic_minus_third(_mm512_loadu_pd(c), magic));
}
}  // namespace

void untangle_third_bits_simd(int lanes, const double* c, std::uint64_t magic, std::uint64_t* out) {
  if (lanes == 8)
    third_bits_avx512(c, magic, out);
  else
    third_bits_avx2(c, magic, out);
}

#else

bool untangle_terms_avx2_supported() { return false; }
bool untangle_terms_avx512_supported() { return false; }
void untangle_terms_simd(int, const double*, const int* const[4], const double* const[9], const double*, const double*,
                         double, double, double*, double* const*) {}
void untangle_third_bits_simd(int, const double*, std::uint64_t, std::uint64_t*) {}

#endif

int untangle_simd_lanes() {
  if (!g_untangle_simd || !untangle_terms_avx2_supported()) return 0;
  return g_untangle_avx512 && untangle_terms_avx512_supported() ? 8 : 4;
}

}  // namespace fascicle::detail
