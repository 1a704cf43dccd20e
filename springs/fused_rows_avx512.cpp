// The structured Verlet path's spring loop with AVX-512: 8 points a vector (springs/fused_row.h;
// the loop itself is springs/fused_rows_kernel.h). What this instruction set sets:
// - 1 / |l|: y0 = VRSQRT14PD(l2) (relative error e0 below 2^-14) refined by one third-order step
//   y = y0 (1 + e/2 + 3 e^2 / 8), e = 1 - l2 y0^2 (Householder's method for x^-1/2): relative
//   error below 5/16 e0^3, about 6e-13, plus rounding; folded into w = k - y0 (1 + e (1/2 + 3/8 e)).
// - Masks are lane bits (k registers); a full mask takes the plain load or store (masked ones are
//   slower on some processors).
// - The largest squared force of a row: unsigned 64-bit maximum of its bits.

#include "springs/fused_row.h"

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <type_traits>

// GCC 12's intrinsic headers pass an uninitialised vector through (the unmasked forms) and then
// warn about it: a false positive.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC push_options
#pragma GCC target("avx512f")

namespace fascicle::springs::detail {
namespace {

#define FASCICLE_OP __attribute__((always_inline)) static inline

struct Avx512 {
  using V = __m512d;
  using Bits = __m512i;
  using Free = __mmask8;
  static constexpr long kLanes = 8;
  FASCICLE_OP __mmask8 mask(unsigned m) { return static_cast<__mmask8>(m); }
  FASCICLE_OP V zero() { return _mm512_setzero_pd(); }
  FASCICLE_OP V set1(double v) { return _mm512_set1_pd(v); }
  FASCICLE_OP V loadu(const double* p) { return _mm512_loadu_pd(p); }
  FASCICLE_OP void storeu(double* p, V v) { _mm512_storeu_pd(p, v); }
  // Lanes outside m read as 0 and are not written.
  FASCICLE_OP V load(unsigned m, const double* p) {
    return m == 0xFF ? _mm512_loadu_pd(p) : _mm512_maskz_loadu_pd(mask(m), p);
  }
  FASCICLE_OP void store(unsigned m, double* p, V v) {
    if (m == 0xFF)
      _mm512_storeu_pd(p, v);
    else
      _mm512_mask_storeu_pd(p, mask(m), v);
  }
  FASCICLE_OP V add(V a, V b) { return _mm512_add_pd(a, b); }
  FASCICLE_OP V sub(V a, V b) { return _mm512_sub_pd(a, b); }
  FASCICLE_OP V mul(V a, V b) { return _mm512_mul_pd(a, b); }
  FASCICLE_OP V fmadd(V a, V b, V c) { return _mm512_fmadd_pd(a, b, c); }
  FASCICLE_OP V fnmadd(V a, V b, V c) { return _mm512_fnmadd_pd(a, b, c); }
  FASCICLE_OP V sub_where(unsigned m, V a, V b) { return _mm512_maskz_sub_pd(mask(m), a, b); }
  // (carry[7], v[0], ..., v[6]): v one lane up, the previous vector's last lane coming in at 0.
  FASCICLE_OP V shift_up(V v, V carry) {
    return _mm512_castsi512_pd(_mm512_alignr_epi64(_mm512_castpd_si512(v), _mm512_castpd_si512(carry), 7));
  }
  // The refinement of 1 / sqrt(l2): returns y0 and u with 1 / sqrt(l2) ~ y0 u.
  FASCICLE_OP V refined(V l2, V& y0) {
    // (maskz form: GCC 12 warns about the undefined pass-through of the plain form)
    y0 = _mm512_maskz_rsqrt14_pd(static_cast<__mmask8>(0xFF), l2);
    const V e = _mm512_fnmadd_pd(l2, _mm512_mul_pd(y0, y0), _mm512_set1_pd(1.0));
    const V g = _mm512_fmadd_pd(e, _mm512_set1_pd(0.375), _mm512_set1_pd(0.5));
    return _mm512_fmadd_pd(e, g, _mm512_set1_pd(1.0));
  }
  // w = k - 1 / sqrt(l2); weight_where: 0 outside m.
  FASCICLE_OP V weight(V l2, V k) {
    V y0;
    const V u = refined(l2, y0);
    return _mm512_fnmadd_pd(y0, u, k);
  }
  FASCICLE_OP V weight_where(unsigned m, V l2, V k) {
    V y0;
    const V u = refined(l2, y0);
    return _mm512_maskz_fnmadd_pd(mask(m), y0, u, k);
  }
  // The free lanes: in m and with a zero fixed byte (`packed`: one byte a lane).
  FASCICLE_OP Free free_lanes(std::uint64_t packed, unsigned m) {
    const __m128i bytes = _mm_cvtsi64_si128(static_cast<long long>(packed));
    const __mmask8 fixed = _mm512_test_epi64_mask(_mm512_cvtepu8_epi64(bytes), _mm512_set1_epi64(0xFF));
    return static_cast<__mmask8>(mask(m) & ~fixed);
  }
  FASCICLE_OP Bits zero_bits() { return _mm512_setzero_si512(); }
  // The largest bits of non-negative doubles (or NaN) in the free lanes.
  FASCICLE_OP Bits max_bits(Bits largest, Free free, V f2) {
    return _mm512_mask_max_epu64(largest, free, largest, _mm512_castpd_si512(f2));
  }
  FASCICLE_OP V add_where(Free free, V sum, V v) { return _mm512_mask_add_pd(sum, free, sum, v); }
  FASCICLE_OP V select(Free free, V if_free, V otherwise) { return _mm512_mask_blend_pd(free, otherwise, if_free); }
  FASCICLE_OP void storeu_bits(std::uint64_t* p, Bits v) { _mm512_storeu_si512(p, v); }
};

#undef FASCICLE_OP

}  // namespace
}  // namespace fascicle::springs::detail

#include "springs/fused_rows_kernel.h"

namespace fascicle::springs::detail {
void fused_rows_avx512(const FusedRow& r, long rows, std::uint64_t* largest_out, double* power_out) {
  fused_rows<Avx512>(r, rows, largest_out, power_out);
}
}  // namespace fascicle::springs::detail

#pragma GCC pop_options
#pragma GCC diagnostic pop

namespace fascicle::springs::detail {
bool avx512_rows_supported() { return __builtin_cpu_supports("avx512f"); }
}  // namespace fascicle::springs::detail

#else

namespace fascicle::springs::detail {
bool avx512_rows_supported() { return false; }
void fused_rows_avx512(const FusedRow&, long, std::uint64_t*, double*) {}
}  // namespace fascicle::springs::detail

#endif
