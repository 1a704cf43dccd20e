#pragma once
/// \file fused_rows_kernel.h
/// Private to springs/fused_rows_avx512.cpp and springs/fused_rows_avx2.cpp: the one vector spring
/// loop of the structured Verlet path (springs/fused_row.h), written once over a vector type
/// `Ops` (lanes doubles a vector and the few operations whose instructions differ between the
/// instruction sets: masked loads and stores, the lane shift, the inverse square root estimate,
/// the free-lane mask and the reductions). Include it after `#pragma GCC target(...)` and after
/// every standard header, so that only this loop and its Ops are compiled for that instruction set.
///
/// The method (springs/verlet_structured.cpp has the whole picture): a point's own springs are
/// summed in registers; springs to other rows are pushed into the ring (-f at the target); the
/// springs along x (same row, i -> i + 1) are pushed within registers by shifting f one lane up
/// and carrying the last lane into the next vector; the point is then integrated at once. On
/// model-26 lattices the three springs of a row into one target row (dx = -1, 0, +1) are summed in
/// registers and pushed with one read-modify-write a vector (pushing them one by one makes
/// overlapping unaligned stores and loads of the same lines, which the processor cannot forward);
/// the dx = -1 springs are evaluated from the sources one point on, in the lane of their target,
/// so only their force on the source is shifted. A group's springs are made one after another,
/// each added into the point's sum and the group's push at once: fewer values live at a time,
/// which keeps AVX2's 16 vector registers from spilling and costs AVX-512 nothing (measured by
/// `fascicle bench springs --spring-loop`). Rows with every spring and push run their vectors
/// but the last without masks or per-direction tests (the same operations, so the same bits:
/// which copy runs depends on the tile, the result must not).

namespace fascicle::springs::detail {

// `rows` consecutive rows of one plane (r the first) whose springs, targets and pushes are alike
// (every pointer of the next row one stride on), so the set-up is made once for the run. Row t's
// largest squared force (bits, see verlet_structured.cpp) and power go to largest_out[t] and
// power_out[t].
template <class Ops, int Directions>
void fused_rows_t(const FusedRow& given, long rows, std::uint64_t* largest_out, double* power_out) {
  using V = typename Ops::V;
  constexpr long L = Ops::kLanes;
  constexpr unsigned kFull = (1u << L) - 1u;
  // A local copy: vector stores may alias anything, so fields read through a reference would be
  // reloaded after every store.
  FusedRow r = given;
  const long nx = r.nx;
  const double* x[3] = {r.x[0], r.x[1], r.x[2]};
  V carry[3], minus_carry[3], group_carry[4][3];
  typename Ops::Bits largest;
  V fv;
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
    // Model-6: full when every direction exists and (but along x) pushes within the lane.
    for (int d = 0; d < Directions; ++d) {
      full = full && r.valid[d] && (d == r.along_x || r.push[d][0]) && (d == r.along_x || r.dx[d] == 0);
      arrays = arrays || r.k[d];
    }
  }
  // Software prefetch, one line per array and 8 points: the positions two rows on from the
  // farthest target row (the next rows' targets in the next plane, read here from memory for
  // the first time in the iteration) and the next row's previous positions. The hardware
  // prefetcher alone left the 100^3 model-26 row waiting for memory about a fifth of its time.
  long ahead = 0;
  for (int d = 0; d < r.directions; ++d) ahead = std::max(ahead, r.offset[d]);
  ahead += 2 * r.stride;
  const long along_offset = r.along_x >= 0 ? r.offset[r.along_x] : 0;
  const double* along_k = r.along_x >= 0 ? r.k[r.along_x] : nullptr;
  const double along_ku = r.along_x >= 0 ? r.ku[r.along_x] : 0.0;

  // The springs from the points s (lanes) to the points at index q of the position arrays: sets
  // l = x[q] - s and returns w = k - 1 / |l| (the force is w l). With Masked, lanes outside the
  // lane bits m get l = 0 and w = 0: no force (a full m takes the unmasked instructions).
  // Lanes with l2 = 0 give NaN (as 1 / sqrt(0) * 0 does on the plain path).
  auto spring_weight = [&](auto masked, unsigned m, long q, const V s[3], V k, V l[3]) __attribute__((always_inline)) {
    const bool use_mask = decltype(masked)::value && m != kFull;
    for (int c = 0; c < 3; ++c)
      l[c] = use_mask ? Ops::sub_where(m, Ops::load(m, x[c] + q), s[c]) : Ops::sub(Ops::loadu(x[c] + q), s[c]);
    const V l2 = Ops::fmadd(l[2], l[2], Ops::fmadd(l[1], l[1], Ops::mul(l[0], l[0])));
    return use_mask ? Ops::weight_where(m, l2, k) : Ops::weight(l2, k);
  };
  using Masked = std::integral_constant<bool, true>;
  using Unmasked = std::integral_constant<bool, false>;

  // One vector of L points from i. Kind: 0 the checked body, 1 a vector of a full row with
  // uniform stiffness, 2 the same with per-point stiffness.
  auto vector = [&](long i, auto kind) __attribute__((always_inline)) {
    constexpr int Kind = decltype(kind)::value;
    const long left = nx - i;
    const unsigned row_mask = Kind != 0 || left >= L ? kFull : (1u << left) - 1u;
    const V s[3] = {Ops::load(row_mask, x[0] + i), Ops::load(row_mask, x[1] + i), Ops::load(row_mask, x[2] + i)};
    if ((i & 7) == 0)
      for (int c = 0; c < 3; ++c) {
        _mm_prefetch(reinterpret_cast<const char*>(x[c] + i + ahead), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(r.p[c] + i + r.stride), _MM_HINT_T0);
      }
    V own[3] = {Ops::zero(), Ops::zero(), Ops::zero()};
    V along[3] = {Ops::zero(), Ops::zero(), Ops::zero()};
    // Model-26: the springs of direction d from the source points at i + shift (0 or 1) in the
    // lanes where `valid` and their target exists. Sets l, returns w. Kind 0 numbers the
    // directions as FusedRow does, the other kinds by 4 g + slot (15: along x).
    auto spring = [&](int d, bool valid, long shift, const V from[3], V l[3]) __attribute__((always_inline)) {
      if constexpr (Kind == 0) {
        // Lanes whose source (i + shift + lane) and target (one more for dx = +1, one less for
        // dx = -1) exist.
        const long source_left = left - shift;
        unsigned m = source_left >= L ? kFull : source_left > 0 ? (1u << source_left) - 1u : 0u;
        if (r.dx[d] > 0 && source_left <= L) m &= m >> 1;
        if (r.dx[d] < 0 && i + shift == 0) m &= kFull - 1u;
        if (!valid) m = 0;
        const V k = r.k[d] ? Ops::load(m, r.k[d] + i + shift) : Ops::set1(r.ku[d]);
        return spring_weight(Masked(), m, i + shift + r.offset[d], from, k, l);
      } else {
        (void)valid;
        const int g = d >> 2, slot = d & 3;
        const long offset = d == 15 ? along_offset : group_offset[g][slot];
        const double* ka = d == 15 ? along_k : group_k[g][slot];
        const double ku = d == 15 ? along_ku : group_ku[g][slot];
        const V k = Kind == 2 ? Ops::loadu(ka + i + shift) : Ops::set1(ku);
        return spring_weight(Unmasked(), kFull, i + shift + offset, from, k, l);
      }
    };
    if constexpr (Directions == kMaxDirections) {
      const unsigned next_mask = Kind == 0 && left <= L ? row_mask >> 1 : kFull;
      V next[3];  // the sources of the dx = -1 springs
      for (int c = 0; c < 3; ++c) next[c] = Kind == 0 ? Ops::load(next_mask, x[c] + i + 1) : Ops::loadu(x[c] + i + 1);
      // The dx = -1 springs' force on their sources (one lane on), less the along-x springs'
      // force on theirs: shifted up once at the end.
      V minus[3] = {Ops::zero(), Ops::zero(), Ops::zero()};
      if (Kind != 0 || r.along_x >= 0) {
        V l[3];
        const V w = spring(Kind == 0 ? r.along_x : 15, true, 0, s, l);
        for (int c = 0; c < 3; ++c) {
          along[c] = Ops::mul(w, l[c]);
          own[c] = Ops::add(own[c], along[c]);
          minus[c] = Ops::sub(minus[c], along[c]);
        }
      }
#pragma GCC unroll 4
      for (int g = 0; g < 4; ++g) {
        if (Kind == 0 && !r.integrate && !r.group_push[g][0]) continue;
        const int dm = Kind == 0 ? r.group[g][0] : 4 * g;
        const int d0 = Kind == 0 ? r.group[g][1] : 4 * g + 1;
        const int dp = Kind == 0 ? r.group[g][2] : 4 * g + 2;
        const bool push = Kind != 0 || r.group_push[g][0];
        V sum[3], l[3];
        V w = spring(dp, Kind != 0 || r.valid[dp], 0, s, l);
        for (int c = 0; c < 3; ++c) {
          const V fp = Ops::mul(w, l[c]);
          own[c] = Ops::add(own[c], fp);
          if (!push) continue;
          sum[c] = Ops::shift_up(fp, group_carry[g][c]);
          group_carry[g][c] = fp;
        }
        w = spring(d0, Kind != 0 || r.valid[d0], 0, s, l);
        for (int c = 0; c < 3; ++c) {
          own[c] = Ops::fmadd(w, l[c], own[c]);
          if (push) sum[c] = Ops::fmadd(w, l[c], sum[c]);
        }
        w = spring(dm, Kind != 0 || r.valid[dm], 1, next, l);
        for (int c = 0; c < 3; ++c) {
          minus[c] = Ops::fmadd(w, l[c], minus[c]);
          if (!push) continue;
          sum[c] = Ops::fmadd(w, l[c], sum[c]);
          // The group (dy, dz) = (1, 1) makes the first push into its target row (see sweep):
          // 0 - sum is stored without reading the row (the same bits as a zeroed row's).
          double* target = r.group_push[g][c] + i;
          const bool first = g == kFirstPushGroup;
          if (Kind == 0)
            Ops::store(row_mask, target, Ops::sub(first ? Ops::zero() : Ops::load(row_mask, target), sum[c]));
          else
            Ops::storeu(target, Ops::sub(first ? Ops::zero() : Ops::loadu(target), sum[c]));
        }
      }
      for (int c = 0; c < 3; ++c) {
        const V back_up = Ops::shift_up(minus[c], minus_carry[c]);
        minus_carry[c] = minus[c];
        own[c] = Ops::add(own[c], back_up);
      }
    } else {
#pragma GCC unroll 13
      for (int d = 0; d < Directions; ++d) {
        unsigned m = row_mask;  // lanes whose target exists: i + dx in [0, nx)
        if constexpr (Kind == 0) {
          if (!r.valid[d]) continue;
          if (r.dx[d] > 0 && left <= L) m &= row_mask >> 1;
          if (r.dx[d] < 0 && i == 0) m &= kFull - 1u;
        }
        const V k = Kind == 2   ? Ops::loadu(r.k[d] + i)
                    : Kind == 1 ? Ops::set1(r.ku[d])
                    : r.k[d]    ? Ops::load(m, r.k[d] + i)
                                : Ops::set1(r.ku[d]);
        V l[3];
        const V w = spring_weight(std::integral_constant<bool, Kind == 0>(), m, i + r.offset[d], s, k, l);
        if (d == r.along_x) {
          for (int c = 0; c < 3; ++c) {
            along[c] = Ops::mul(w, l[c]);
            own[c] = Ops::add(own[c], along[c]);
          }
        } else {
          // f = w l fused into the sums: +f to the own point, -f to the target
          for (int c = 0; c < 3; ++c) own[c] = Ops::fmadd(w, l[c], own[c]);
          if (Kind != 0 || r.push[d][0]) {
            for (int c = 0; c < 3; ++c) {
              // The direction (0, 0, 1) makes the only push from plane k into row (j, k + 1), the
              // first (see sweep): stored without reading the row (the same bits as a zeroed row's).
              double* target = r.push[d][c] + i + (Kind == 0 ? r.dx[d] : 0);
              const V before = d == kModel6FirstPush ? Ops::zero() : Ops::load(m, target);
              Ops::store(m, target, Ops::fnmadd(w, l[c], before));
            }
          }
        }
      }
    }
    if (!r.integrate) return;
    // f(i) = pushes + own - along(i - 1): `along` shifted one lane up, the previous vector's last
    // lane coming in at lane 0 (model-26: already in own, above).
    V force[3];
    for (int c = 0; c < 3; ++c) {
      const V pushed = Ops::load(row_mask, r.ring[c] + i);
      if constexpr (Directions == kMaxDirections) {
        force[c] = Ops::add(pushed, own[c]);
      } else {
        const V shifted = Ops::shift_up(along[c], carry[c]);
        carry[c] = along[c];
        force[c] = Ops::sub(Ops::add(pushed, own[c]), shifted);
      }
    }
    std::uint64_t packed = 0;    // the fixed flags, a byte a lane (fewer at the row's end)
    if (Kind != 0 || left >= L)  // a fixed-size copy is one load; a variable one, a loop
      std::memcpy(&packed, r.fixed + i, L);
    else
      std::memcpy(&packed, r.fixed + i, static_cast<std::size_t>(left));
    const typename Ops::Free is_free = Ops::free_lanes(packed, row_mask);
    const V f2 = Ops::fmadd(force[2], force[2], Ops::fmadd(force[1], force[1], Ops::mul(force[0], force[0])));
    largest = Ops::max_bits(largest, is_free, f2);
    V v[3];
    for (int c = 0; c < 3; ++c) v[c] = Ops::sub(s[c], Ops::load(row_mask, r.p[c] + i));
    if (r.power) {
      const V pv = Ops::fmadd(force[2], v[2], Ops::fmadd(force[1], v[1], Ops::mul(force[0], v[0])));
      fv = Ops::add_where(is_free, fv, pv);
    }
    if (!r.write) return;
    const V a = r.a ? Ops::load(row_mask, r.a + i) : Ops::set1(r.au);
    const V b = r.b ? Ops::load(row_mask, r.b + i) : Ops::set1(r.bu);
    for (int c = 0; c < 3; ++c) {
      // fixed points: x_new = x; free: x + b v + a f
      const V moved = Ops::fmadd(a, force[c], Ops::fmadd(b, v[c], s[c]));
      Ops::store(row_mask, r.p[c] + i, Ops::select(is_free, moved, s[c]));
    }
  };
  // The next row's pointers: one stride further on (null ones stay null).
  const long stride = r.stride;
  auto advance = [stride](auto*& pointer) {
    if (pointer) pointer += stride;
  };
  for (long row = 0; row < rows; ++row) {
    for (int c = 0; c < 3; ++c) {
      carry[c] = minus_carry[c] = Ops::zero();
      for (int g = 0; g < 4; ++g) group_carry[g][c] = Ops::zero();
    }
    largest = Ops::zero_bits();
    fv = Ops::zero();
    for (long i = 0; i < nx; i += L) {
      if (full && i + L < nx) {
        if (arrays)
          vector(i, std::integral_constant<int, 2>());
        else
          vector(i, std::integral_constant<int, 1>());
        continue;
      }
      vector(i, std::integral_constant<int, 0>());
    }
    if (r.integrate) {
      double lanes[L];  // the lanes summed and compared in lane order
      Ops::storeu(lanes, fv);
      double sum = 0.0;
      for (double value : lanes) sum += value;
      power_out[row] = sum;
      std::uint64_t big[L];
      Ops::storeu_bits(big, largest);
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
    for (int d = 0; d < Directions; ++d) advance(r.k[d]);  // (the checked body's stiffness)
    advance(r.a);
    advance(r.b);
    advance(r.fixed);
  }
}

template <class Ops>
void fused_rows(const FusedRow& r, long rows, std::uint64_t* largest_out, double* power_out) {
  if (r.directions == 3)
    fused_rows_t<Ops, 3>(r, rows, largest_out, power_out);
  else
    fused_rows_t<Ops, kMaxDirections>(r, rows, largest_out, power_out);
}

}  // namespace fascicle::springs::detail
