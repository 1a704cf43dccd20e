// The structured Verlet path's spring loop with AVX2 and FMA: 4 points a vector
// (springs/fused_row.h; the loop itself is springs/fused_rows_kernel.h), for processors without
// AVX-512 (AMD before Zen 4, most desktop Intel processors, virtual machines that hide AVX-512).
// What this instruction set sets:
// - 1 / |l|: AVX2 has no double-precision estimate of the inverse square root. The estimate is
//   VRSQRTPS of l2 rounded to single precision (relative error below 1.5 * 2^-12), refined in
//   double by one fourth-order step y = y0 (1 + e/2 + 3/8 e^2 + 5/16 e^3), e = 1 - l2 y0^2
//   (Householder's method for x^-1/2; relative error about 35/128 e^4 < 1e-13, plus rounding).
//   Single precision bounds l2: a spring longer than about 1.8e19 length units gets 1 / |l| = 0
//   (off by less than 6e-20), one shorter than about 1e-19 a NaN force, which stops the solve
//   with the divergence error (the exact force of such a collapsed spring is finite).
// - Masks: lane bits, turned into vector masks for VMASKMOVPD loads and stores and for ANDs.
// - The largest squared force of a row: signed 64-bit comparisons of its bits with the sign bit
//   cleared (a sum of squares has none; a NaN stays above +Inf, which stays above every finite
//   value).

#include "springs/fused_row.h"

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <type_traits>

#pragma GCC push_options
#pragma GCC target("avx2,fma")

namespace fascicle::springs::detail {
namespace {

#define FASCICLE_OP __attribute__((always_inline)) static inline

struct Avx2 {
  using V = __m256d;
  using Bits = __m256i;
  using Free = __m256i;  // all ones in the free lanes
  static constexpr long kLanes = 4;
  static constexpr unsigned kFull = 0xF;
  // The vector mask of the lane bits m (bit l: lane l): all ones in those lanes.
  FASCICLE_OP __m256i lanes_of(unsigned m) {
    const __m256i bit = _mm256_setr_epi64x(1, 2, 4, 8);
    return _mm256_cmpeq_epi64(_mm256_and_si256(_mm256_set1_epi64x(static_cast<long long>(m)), bit), bit);
  }
  FASCICLE_OP V zero() { return _mm256_setzero_pd(); }
  FASCICLE_OP V set1(double v) { return _mm256_set1_pd(v); }
  FASCICLE_OP V loadu(const double* p) { return _mm256_loadu_pd(p); }
  FASCICLE_OP void storeu(double* p, V v) { _mm256_storeu_pd(p, v); }
  // Lanes outside m read as 0 and are not written.
  FASCICLE_OP V load(unsigned m, const double* p) {
    return m == kFull ? _mm256_loadu_pd(p) : _mm256_maskload_pd(p, lanes_of(m));
  }
  FASCICLE_OP void store(unsigned m, double* p, V v) {
    if (m == kFull)
      _mm256_storeu_pd(p, v);
    else
      _mm256_maskstore_pd(p, lanes_of(m), v);
  }
  FASCICLE_OP V add(V a, V b) { return _mm256_add_pd(a, b); }
  FASCICLE_OP V sub(V a, V b) { return _mm256_sub_pd(a, b); }
  FASCICLE_OP V mul(V a, V b) { return _mm256_mul_pd(a, b); }
  FASCICLE_OP V fmadd(V a, V b, V c) { return _mm256_fmadd_pd(a, b, c); }
  FASCICLE_OP V fnmadd(V a, V b, V c) { return _mm256_fnmadd_pd(a, b, c); }
  FASCICLE_OP V sub_where(unsigned m, V a, V b) {
    return _mm256_and_pd(_mm256_sub_pd(a, b), _mm256_castsi256_pd(lanes_of(m)));
  }
  // (carry[3], v[0], v[1], v[2]): v one lane up, the previous vector's last lane coming in at 0.
  FASCICLE_OP V shift_up(V v, V carry) { return _mm256_shuffle_pd(_mm256_permute2f128_pd(carry, v, 0x21), v, 0x5); }
  // w = k - 1 / sqrt(l2); weight_where: 0 outside m.
  FASCICLE_OP V weight(V l2, V k) {
    const V y0 = _mm256_cvtps_pd(_mm_rsqrt_ps(_mm256_cvtpd_ps(l2)));
    const V one = _mm256_set1_pd(1.0);
    const V e = _mm256_fnmadd_pd(l2, _mm256_mul_pd(y0, y0), one);
    V g = _mm256_fmadd_pd(e, _mm256_set1_pd(0.3125), _mm256_set1_pd(0.375));
    g = _mm256_fmadd_pd(e, g, _mm256_set1_pd(0.5));
    const V u = _mm256_fmadd_pd(e, g, one);
    return _mm256_fnmadd_pd(y0, u, k);
  }
  FASCICLE_OP V weight_where(unsigned m, V l2, V k) {
    return _mm256_and_pd(weight(l2, k), _mm256_castsi256_pd(lanes_of(m)));
  }
  // The free lanes: in m and with a zero fixed byte (`packed`: one byte a lane).
  FASCICLE_OP Free free_lanes(std::uint64_t packed, unsigned m) {
    const __m256i flags = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(static_cast<int>(packed)));
    return _mm256_and_si256(_mm256_cmpeq_epi64(flags, _mm256_setzero_si256()), lanes_of(m));
  }
  FASCICLE_OP Bits zero_bits() { return _mm256_setzero_si256(); }
  // The largest bits of non-negative doubles (or NaN) in the free lanes.
  FASCICLE_OP Bits max_bits(Bits largest, Free free, V f2) {
    const __m256i bits = _mm256_and_si256(_mm256_castpd_si256(f2), _mm256_set1_epi64x(0x7FFFFFFFFFFFFFFFLL));
    return _mm256_blendv_epi8(largest, bits, _mm256_and_si256(free, _mm256_cmpgt_epi64(bits, largest)));
  }
  FASCICLE_OP V add_where(Free free, V sum, V v) {
    return _mm256_add_pd(sum, _mm256_and_pd(v, _mm256_castsi256_pd(free)));
  }
  FASCICLE_OP V select(Free free, V if_free, V otherwise) {
    return _mm256_blendv_pd(otherwise, if_free, _mm256_castsi256_pd(free));
  }
  FASCICLE_OP void storeu_bits(std::uint64_t* p, Bits v) { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), v); }
};

#undef FASCICLE_OP

}  // namespace
}  // namespace fascicle::springs::detail

#include "springs/fused_rows_kernel.h"

namespace fascicle::springs::detail {
void fused_rows_avx2(const FusedRow& r, long rows, std::uint64_t* largest_out, double* power_out) {
  fused_rows<Avx2>(r, rows, largest_out, power_out);
}
}  // namespace fascicle::springs::detail

#pragma GCC pop_options

namespace fascicle::springs::detail {
bool avx2_rows_supported() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }
}  // namespace fascicle::springs::detail

#else

namespace fascicle::springs::detail {
bool avx2_rows_supported() { return false; }
void fused_rows_avx2(const FusedRow&, long, std::uint64_t*, double*) {}
}  // namespace fascicle::springs::detail

#endif
