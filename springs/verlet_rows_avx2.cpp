// The AVX2 spring loop of the structured Verlet path (springs/fused_row.h), for processors with
// AVX2 and FMA but without AVX-512 (AMD before Zen 4, most desktop Intel processors, and virtual
// machines that hide AVX-512). It is the AVX-512 loop of springs/verlet_structured.cpp (read its
// comments for the method: own springs summed in registers, pushes into the target rows, lane
// shifts for the springs along x and, on model-26 lattices, for the dx = -1 springs and the
// groups of one target row) with 4 points a vector; the springs and pushes are the same. It
// differs in four places:
// - Model-26 order: a group's three springs are made one after another, each added into the
//   point's own sum and the group's push at once, and the dx = -1 sum starts from minus the
//   along-x force. The AVX-512 loop holds the group's three springs at once and sums in another
//   order; with AVX2's 16 vector registers that spilled (measured by `fascicle bench springs`,
//   docs/BENCHMARKS.md). The sums differ from the AVX-512 loop's by rounding.
// - 1 / |l|: AVX2 has no double-precision estimate of the inverse square root. The estimate is
//   VRSQRTPS of l2 rounded to single precision (relative error below 1.5 * 2^-12), refined in
//   double by one fourth-order step y = y0 (1 + e/2 + 3/8 e^2 + 5/16 e^3), e = 1 - l2 y0^2
//   computed from the double l2 (Householder's method for x^-1/2; relative error about
//   35/128 e^4 < 1e-13, plus rounding; the AVX-512 loop's third-order step from 14 bits gives
//   about 6e-13). Single precision bounds l2: a spring longer than about 1.8e19 length units gets
//   1 / |l| = 0 (off by less than 6e-20), one shorter than about 1e-19 a NaN force, which stops
//   the solve with the divergence error (the exact force of such a collapsed spring is finite).
// - Masks: lane bits, turned into vector masks for VMASKMOVPD loads and stores and for ANDs.
// - The largest squared force of a row: signed 64-bit comparisons of its bits with the sign bit
//   cleared (a sum of squares has none; a NaN stays above +Inf, which stays above every finite
//   value).
// Deterministic like the AVX-512 loop: the result does not depend on the threads or the tiles
// (tests/springs_solver_test.cpp compares them bitwise); it differs from the other loops by
// rounding.

#include "springs/fused_row.h"

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

#include <algorithm>
#include <cstring>
#include <type_traits>

namespace fascicle::springs::detail {

bool avx2_rows_supported() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }

namespace {

#define FASCICLE_AVX2 __attribute__((target("avx2,fma"), always_inline)) inline

constexpr long kLanes = 4;
constexpr unsigned kFull = 0xF;

// The vector mask of the lane bits m (bit l: lane l): all ones in those lanes.
FASCICLE_AVX2 __m256i lanes_of(unsigned m) {
  const __m256i bit = _mm256_setr_epi64x(1, 2, 4, 8);
  return _mm256_cmpeq_epi64(_mm256_and_si256(_mm256_set1_epi64x(static_cast<long long>(m)), bit), bit);
}
// Loads and stores of 4 doubles under lane bits; a full mask takes the plain instruction.
FASCICLE_AVX2 __m256d load4(unsigned m, const double* p) {
  return m == kFull ? _mm256_loadu_pd(p) : _mm256_maskload_pd(p, lanes_of(m));
}
FASCICLE_AVX2 void store4(unsigned m, double* p, __m256d v) {
  if (m == kFull)
    _mm256_storeu_pd(p, v);
  else
    _mm256_maskstore_pd(p, lanes_of(m), v);
}
// (carry[3], v[0], v[1], v[2]): v one lane up, the previous vector's last lane coming in at 0.
FASCICLE_AVX2 __m256d shift_up(__m256d v, __m256d carry) {
  return _mm256_shuffle_pd(_mm256_permute2f128_pd(carry, v, 0x21), v, 0x5);
}

// The springs from the 4 points s (lanes) to the points at index q of the position arrays x: sets
// l = x[q] - s and returns w = k - 1 / |l| (the force is w l). With Masked, lanes outside the lane
// bits m get l = 0 and w = 0: no force (a full m takes the unmasked instructions).
template <bool Masked>
FASCICLE_AVX2 __m256d spring_weight(unsigned m, const double* const x[3], long q, const __m256d s[3], __m256d k,
                                    __m256d l[3]) {
  const bool masked = Masked && m != kFull;
  const __m256i mask = masked ? lanes_of(m) : _mm256_setzero_si256();
  for (int c = 0; c < 3; ++c)
    l[c] = masked ? _mm256_and_pd(_mm256_sub_pd(_mm256_maskload_pd(x[c] + q, mask), s[c]), _mm256_castsi256_pd(mask))
                  : _mm256_sub_pd(_mm256_loadu_pd(x[c] + q), s[c]);
  const __m256d l2 = _mm256_fmadd_pd(l[2], l[2], _mm256_fmadd_pd(l[1], l[1], _mm256_mul_pd(l[0], l[0])));
  const __m256d y0 = _mm256_cvtps_pd(_mm_rsqrt_ps(_mm256_cvtpd_ps(l2)));
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d e = _mm256_fnmadd_pd(l2, _mm256_mul_pd(y0, y0), one);
  __m256d g = _mm256_fmadd_pd(e, _mm256_set1_pd(0.3125), _mm256_set1_pd(0.375));
  g = _mm256_fmadd_pd(e, g, _mm256_set1_pd(0.5));
  const __m256d u = _mm256_fmadd_pd(e, g, one);
  const __m256d w = _mm256_fnmadd_pd(y0, u, k);  // k - 1 / |l|
  return masked ? _mm256_and_pd(w, _mm256_castsi256_pd(mask)) : w;
}

template <int Directions>
__attribute__((target("avx2,fma"))) void fused_rows_avx2_t(const FusedRow& given, long rows, std::uint64_t* largest_out,
                                                           double* power_out) {
  FusedRow r = given;  // a local copy (vector stores may alias anything)
  const long nx = r.nx;
  const double* x[3] = {r.x[0], r.x[1], r.x[2]};
  __m256d carry[3], minus_carry[3], group_carry[4][3];
  __m256i largest;
  __m256d fv;
  // Full rows (see the AVX-512 loop): every vector but the last runs without masks.
  bool full = r.integrate && r.along_x >= 0;
  bool arrays = false;  // per-point stiffness
  long group_offset[4][3] = {};
  const double* group_k[4][3] = {};
  double group_ku[4][3] = {};
  if constexpr (Directions == kMaxDirections) {
    for (int g = 0; g < 4; ++g) {
      full = full && r.group_push[g][0];
      for (int s = 0; s < 3; ++s) {
        const int d = r.group[g][s];
        full = full && r.valid[d];
        arrays = arrays || r.k[d];
        group_offset[g][s] = r.offset[d];
        group_k[g][s] = r.k[d];
        group_ku[g][s] = r.ku[d];
      }
    }
    if (r.along_x >= 0) arrays = arrays || r.k[r.along_x];
  } else {
    // Model-6: a row whose directions all exist and push (not the last row of a tile's strip,
    // nor a row at a face) runs its vectors but the last without lane checks.
    for (int d = 0; d < Directions; ++d) {
      full = full && r.valid[d] && (d == r.along_x || r.push[d][0]) && (d == r.along_x || r.dx[d] == 0);
      arrays = arrays || r.k[d];
    }
  }
  long ahead = 0;  // software prefetch distance (see the AVX-512 loop)
  for (int d = 0; d < r.directions; ++d) ahead = std::max(ahead, r.offset[d]);
  ahead += 2 * r.stride;
  const long along_offset = r.along_x >= 0 ? r.offset[r.along_x] : 0;
  const double* along_k = r.along_x >= 0 ? r.k[r.along_x] : nullptr;
  const double along_ku = r.along_x >= 0 ? r.ku[r.along_x] : 0.0;
  const __m256i no_sign = _mm256_set1_epi64x(0x7FFFFFFFFFFFFFFFLL);
  // One vector of 4 points from i. Kind: 0 the checked body, 1 a vector of a full row with
  // uniform stiffness, 2 the same with per-point stiffness.
  auto vector = [&](long i, auto kind) __attribute__((target("avx2,fma"), always_inline)) {
    constexpr int Kind = decltype(kind)::value;
    const long left = nx - i;
    const unsigned row_mask = Kind != 0 || left >= kLanes ? kFull : (1u << left) - 1u;
    const __m256d s[3] = {load4(row_mask, x[0] + i), load4(row_mask, x[1] + i), load4(row_mask, x[2] + i)};
    if ((i & 7) == 0)  // one line per array and 8 points
      for (int c = 0; c < 3; ++c) {
        _mm_prefetch(reinterpret_cast<const char*>(x[c] + i + ahead), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(r.p[c] + i + r.stride), _MM_HINT_T0);
      }
    __m256d own[3] = {_mm256_setzero_pd(), _mm256_setzero_pd(), _mm256_setzero_pd()};
    __m256d along[3] = {_mm256_setzero_pd(), _mm256_setzero_pd(), _mm256_setzero_pd()};
    // Model-26: the springs of direction d from the source points at i + shift (0 or 1) in the
    // lanes where `valid` and their target exists. Sets l, returns w.
    auto spring = [&](int d, bool valid, long shift, const __m256d from[3], __m256d l[3])
        __attribute__((target("avx2,fma"), always_inline)) {
      if constexpr (Kind == 0) {
        const long source_left = left - shift;
        unsigned m = source_left >= kLanes ? kFull : source_left > 0 ? (1u << source_left) - 1u : 0u;
        if (r.dx[d] > 0 && source_left <= kLanes) m &= m >> 1;
        if (r.dx[d] < 0 && i + shift == 0) m &= 0xEu;
        if (!valid) m = 0;
        const __m256d k = r.k[d] ? load4(m, r.k[d] + i + shift) : _mm256_set1_pd(r.ku[d]);
        return spring_weight<true>(m, x, i + shift + r.offset[d], from, k, l);
      } else {
        (void)valid;
        const int g = d >> 2, slot = d & 3;  // d: 4 g + slot, 15 the along-x direction
        const long offset = d == 15 ? along_offset : group_offset[g][slot];
        const double* ka = d == 15 ? along_k : group_k[g][slot];
        const double ku = d == 15 ? along_ku : group_ku[g][slot];
        const __m256d k = Kind == 2 ? _mm256_loadu_pd(ka + i + shift) : _mm256_set1_pd(ku);
        return spring_weight<false>(kFull, x, i + shift + offset, from, k, l);
      }
    };
    if constexpr (Directions == kMaxDirections) {
      // Model-26: the three directions of a group (dx = -1, 0, +1) summed in registers and pushed
      // into their target row with one read-modify-write a vector (see the AVX-512 loop).
      const unsigned next_mask = Kind == 0 && left <= kLanes ? row_mask >> 1 : kFull;
      __m256d next[3];  // the sources of the dx = -1 springs
      for (int c = 0; c < 3; ++c) next[c] = Kind == 0 ? load4(next_mask, x[c] + i + 1) : _mm256_loadu_pd(x[c] + i + 1);
      // dx = -1 springs: the force on their sources (one lane on), less the along-x springs' force
      // on theirs (see back_up below).
      __m256d minus[3] = {_mm256_setzero_pd(), _mm256_setzero_pd(), _mm256_setzero_pd()};
      if (Kind != 0 || r.along_x >= 0) {
        __m256d l[3];
        const __m256d w = spring(Kind == 0 ? r.along_x : 15, true, 0, s, l);
        for (int c = 0; c < 3; ++c) {
          along[c] = _mm256_mul_pd(w, l[c]);
          own[c] = _mm256_add_pd(own[c], along[c]);
          minus[c] = _mm256_sub_pd(minus[c], along[c]);
        }
      }
      // A group's springs one after another, each added into the group's push (`sum`) at once:
      // with 16 vector registers, fewer values live at a time (own, minus, sum, one spring).
#pragma GCC unroll 4
      for (int g = 0; g < 4; ++g) {
        if (Kind == 0 && !r.integrate && !r.group_push[g][0]) continue;
        const int dm = Kind == 0 ? r.group[g][0] : 4 * g;
        const int d0 = Kind == 0 ? r.group[g][1] : 4 * g + 1;
        const int dp = Kind == 0 ? r.group[g][2] : 4 * g + 2;
        const bool push = Kind != 0 || r.group_push[g][0];
        __m256d sum[3], l[3];
        __m256d w = spring(dp, Kind != 0 || r.valid[dp], 0, s, l);
        for (int c = 0; c < 3; ++c) {
          const __m256d fp = _mm256_mul_pd(w, l[c]);
          own[c] = _mm256_add_pd(own[c], fp);
          if (!push) continue;
          sum[c] = shift_up(fp, group_carry[g][c]);
          group_carry[g][c] = fp;
        }
        w = spring(d0, Kind != 0 || r.valid[d0], 0, s, l);
        for (int c = 0; c < 3; ++c) {
          own[c] = _mm256_fmadd_pd(w, l[c], own[c]);
          if (push) sum[c] = _mm256_fmadd_pd(w, l[c], sum[c]);
        }
        w = spring(dm, Kind != 0 || r.valid[dm], 1, next, l);
        for (int c = 0; c < 3; ++c) {
          minus[c] = _mm256_fmadd_pd(w, l[c], minus[c]);
          if (!push) continue;
          sum[c] = _mm256_fmadd_pd(w, l[c], sum[c]);
          double* target = r.group_push[g][c] + i;
          const bool first = g == kFirstPushGroup;  // stored without reading the row
          if (Kind == 0)
            store4(row_mask, target, _mm256_sub_pd(first ? _mm256_setzero_pd() : load4(row_mask, target), sum[c]));
          else
            _mm256_storeu_pd(target, _mm256_sub_pd(first ? _mm256_setzero_pd() : _mm256_loadu_pd(target), sum[c]));
        }
      }
      for (int c = 0; c < 3; ++c) {
        const __m256d back_up = shift_up(minus[c], minus_carry[c]);
        minus_carry[c] = minus[c];
        own[c] = _mm256_add_pd(own[c], back_up);
      }
    } else {
      // Model-6. A vector of a full row (Kind 1 and 2: every direction valid and pushed, every
      // lane's target in the row, row_mask full) skips the checks: the same operations in the
      // same order.
#pragma GCC unroll 13
      for (int d = 0; d < Directions; ++d) {
        unsigned m = row_mask;  // lanes whose target exists: i + dx in [0, nx)
        if constexpr (Kind == 0) {
          if (!r.valid[d]) continue;
          if (r.dx[d] > 0 && left <= kLanes) m &= row_mask >> 1;
          if (r.dx[d] < 0 && i == 0) m &= 0xEu;
        }
        const __m256d k = Kind == 2   ? _mm256_loadu_pd(r.k[d] + i)
                          : Kind == 1 ? _mm256_set1_pd(r.ku[d])
                          : r.k[d]    ? load4(m, r.k[d] + i)
                                      : _mm256_set1_pd(r.ku[d]);
        __m256d l[3];
        const __m256d w = spring_weight<Kind == 0>(m, x, i + r.offset[d], s, k, l);
        if (d == r.along_x) {
          for (int c = 0; c < 3; ++c) {
            along[c] = _mm256_mul_pd(w, l[c]);
            own[c] = _mm256_add_pd(own[c], along[c]);
          }
        } else {
          for (int c = 0; c < 3; ++c) own[c] = _mm256_fmadd_pd(w, l[c], own[c]);
          if (Kind != 0 || r.push[d][0]) {
            for (int c = 0; c < 3; ++c) {
              double* target = r.push[d][c] + i + (Kind == 0 ? r.dx[d] : 0);
              const __m256d before = d == kModel6FirstPush ? _mm256_setzero_pd() : load4(m, target);
              store4(m, target, _mm256_fnmadd_pd(w, l[c], before));
            }
          }
        }
      }
    }
    if (!r.integrate) return;
    __m256d force[3];
    for (int c = 0; c < 3; ++c) {
      const __m256d pushed = load4(row_mask, r.ring[c] + i);
      if constexpr (Directions == kMaxDirections) {
        force[c] = _mm256_add_pd(pushed, own[c]);
      } else {
        const __m256d shifted = shift_up(along[c], carry[c]);
        carry[c] = along[c];
        force[c] = _mm256_sub_pd(_mm256_add_pd(pushed, own[c]), shifted);
      }
    }
    std::uint32_t packed = 0;         // the 4 fixed flags (fewer at the row's end)
    if (Kind != 0 || left >= kLanes)  // a fixed-size copy is one load; a variable one, a loop
      std::memcpy(&packed, r.fixed + i, kLanes);
    else
      std::memcpy(&packed, r.fixed + i, static_cast<std::size_t>(left));
    const __m256i flags = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(static_cast<int>(packed)));
    const __m256i is_free = _mm256_and_si256(_mm256_cmpeq_epi64(flags, _mm256_setzero_si256()), lanes_of(row_mask));
    const __m256d f2 =
        _mm256_fmadd_pd(force[2], force[2], _mm256_fmadd_pd(force[1], force[1], _mm256_mul_pd(force[0], force[0])));
    const __m256i bits = _mm256_and_si256(_mm256_castpd_si256(f2), no_sign);
    largest = _mm256_blendv_epi8(largest, bits, _mm256_and_si256(is_free, _mm256_cmpgt_epi64(bits, largest)));
    __m256d v[3];
    for (int c = 0; c < 3; ++c) v[c] = _mm256_sub_pd(s[c], load4(row_mask, r.p[c] + i));
    if (r.power) {
      const __m256d pv =
          _mm256_fmadd_pd(force[2], v[2], _mm256_fmadd_pd(force[1], v[1], _mm256_mul_pd(force[0], v[0])));
      fv = _mm256_add_pd(fv, _mm256_and_pd(pv, _mm256_castsi256_pd(is_free)));
    }
    if (!r.write) return;
    const __m256d a = r.a ? load4(row_mask, r.a + i) : _mm256_set1_pd(r.au);
    const __m256d b = r.b ? load4(row_mask, r.b + i) : _mm256_set1_pd(r.bu);
    for (int c = 0; c < 3; ++c) {
      // fixed points: x_new = x; free: x + b v + a f
      const __m256d moved = _mm256_fmadd_pd(a, force[c], _mm256_fmadd_pd(b, v[c], s[c]));
      store4(row_mask, r.p[c] + i, _mm256_blendv_pd(s[c], moved, _mm256_castsi256_pd(is_free)));
    }
  };
  const long stride = r.stride;
  auto advance = [stride](auto*& pointer) {
    if (pointer) pointer += stride;
  };
  for (long row = 0; row < rows; ++row) {
    for (int c = 0; c < 3; ++c) {
      carry[c] = minus_carry[c] = _mm256_setzero_pd();
      for (int g = 0; g < 4; ++g) group_carry[g][c] = _mm256_setzero_pd();
    }
    largest = _mm256_setzero_si256();
    fv = _mm256_setzero_pd();
    for (long i = 0; i < nx; i += kLanes) {
      {
        if (full && i + kLanes < nx) {
          if (arrays)
            vector(i, std::integral_constant<int, 2>());
          else
            vector(i, std::integral_constant<int, 1>());
          continue;
        }
      }
      vector(i, std::integral_constant<int, 0>());
    }
    if (r.integrate) {
      alignas(32) double lanes[kLanes];
      _mm256_store_pd(lanes, fv);
      double sum = 0.0;
      for (double value : lanes) sum += value;
      power_out[row] = sum;
      alignas(32) std::uint64_t big[kLanes];
      _mm256_store_si256(reinterpret_cast<__m256i*>(big), largest);
      std::uint64_t out = 0;
      for (std::uint64_t value : big) out = value > out ? value : out;
      largest_out[row] = out;
    }
    if (row + 1 == rows) break;
    for (int c = 0; c < 3; ++c) {
      x[c] += stride;
      advance(r.p[c]);
      advance(r.ring[c]);
    }
    if constexpr (Directions == kMaxDirections) {
      for (int g = 0; g < 4; ++g)
        for (int c = 0; c < 3; ++c) {
          advance(r.group_push[g][c]);
          advance(group_k[g][c]);
        }
      advance(along_k);
    } else {
      for (int d = 0; d < Directions; ++d)
        for (int c = 0; c < 3; ++c) advance(r.push[d][c]);
    }
    for (int d = 0; d < Directions; ++d) advance(r.k[d]);
    advance(r.a);
    advance(r.b);
    advance(r.fixed);
  }
}

#undef FASCICLE_AVX2

}  // namespace

void fused_rows_avx2(const FusedRow& r, long rows, std::uint64_t* largest_out, double* power_out) {
  if (r.directions == 3)
    fused_rows_avx2_t<3>(r, rows, largest_out, power_out);
  else
    fused_rows_avx2_t<kMaxDirections>(r, rows, largest_out, power_out);
}

}  // namespace fascicle::springs::detail

#else

namespace fascicle::springs::detail {
bool avx2_rows_supported() { return false; }
void fused_rows_avx2(const FusedRow&, long, std::uint64_t*, double*) {}
}  // namespace fascicle::springs::detail

#endif
