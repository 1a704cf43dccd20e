#pragma once
/// \file fused_row.h
/// Private to the structured Verlet path (springs/verlet_structured.cpp): one row of the lattice as
/// the vector spring loop sees it (FusedRow), and that loop. One source (springs/fused_rows_kernel.h)
/// compiled for two instruction sets: AVX-512, 8 points a vector (springs/fused_rows_avx512.cpp),
/// and AVX2 with FMA, 4 points a vector (springs/fused_rows_avx2.cpp), picked at run time by what
/// the processor has.

#include <cstdint>

namespace fascicle::springs::detail {

constexpr int kMaxDirections = 13;
// Model-26: the group of the springs into the row (j + 1, k + 1) (FusedRow::group; the order of
// half_offsets puts it last, checked at construction).
constexpr int kFirstPushGroup = 3;
// Model-6: the direction (0, 0, 1) (half_offsets order, checked at construction).
constexpr int kModel6FirstPush = 2;

// One row on a vector path. A point's own springs are summed in registers
// (+f for each direction in order); springs to other rows are pushed into the ring (-f at the
// target); the springs along x (same row, i -> i + 1) are pushed within registers by shifting
// f one lane up and carrying the last lane into the next vector. The force of a point is then
// ring (pushes of earlier rows) + own - shifted, and the point is integrated at once. (Model-26
// shifts the along-x force together with the dx = -1 springs' forces on their sources.)
// Without `integrate` (a slab's prologue) only the pushes are made.
struct FusedRow {
  const double* x[3];     // the row's positions (index i = point i of the row)
  double* p[3];           // the row's previous positions, overwritten with the new ones
  const double* ring[3];  // the row's accumulated pushes
  int directions;
  bool valid[kMaxDirections];  // the direction's target row exists (and is used)
  int dx[kMaxDirections];
  long offset[kMaxDirections];      // index offset of the target point
  const double* k[kMaxDirections];  // per-point stiffness at the source (null: ku)
  double ku[kMaxDirections];
  double* push[kMaxDirections][3];  // the target row's accumulators at point 0 (null: not pushed)
  int along_x;                      // the direction (1, 0, 0), -1 when not valid
  // Model-26: the 12 other directions in 4 groups of one target row each, (dx = -1, 0, +1).
  int group[4][3];
  double* group_push[4][3];  // the group's target row (null: not pushed)
  const double* a;           // per-point a, b (null: au, bu)
  const double* b;
  double au, bu;
  const std::uint8_t* fixed;
  long nx;
  long stride;  // from one row to the next in every array (nx rounded up to a multiple of 8)
  bool integrate, write;
  bool power;  // sum f . v (the momentum solver's restart test); else the power is left 0
};

/// `rows` rows of one plane from `r` (every pointer of the next row one stride on); row t's
/// largest squared force (bits, see verlet_structured.cpp) and power go to largest_out[t] and
/// power_out[t]. Call only where the processor has the instruction set (the *_supported below).
void fused_rows_avx512(const FusedRow& r, long rows, std::uint64_t* largest_out, double* power_out);
void fused_rows_avx2(const FusedRow& r, long rows, std::uint64_t* largest_out, double* power_out);

/// Whether the processor runs fused_rows_avx512 (AVX-512F), fused_rows_avx2 (AVX2 and FMA).
bool avx512_rows_supported();
bool avx2_rows_supported();

}  // namespace fascicle::springs::detail
