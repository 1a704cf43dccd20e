#pragma once
/// \file check_cells.h
/// The quality check's cells (between the interior lattice lines, fibres/fibre_check.cpp) and
/// their Kuhn tetrahedra, judged by the check's rule, for the steps that move fibre points after
/// the settle and must not fold a cell (fibres/contain_segments.h, fibres/align_ends.h).
#include "fibres/fibre_grid.h"
#include "springs/lattice.h"

#include <array>
#include <vector>

namespace fascicle {

/// Tetrahedra (ci, cj, ck, t) of the check's cells: cell (ci, cj, ck) spans lattice points
/// (ci..ci+1, cj..cj+1, ck..ck+1), t indexes kuhn_tetrahedra(). Good when the volume, oriented
/// like the whole lattice at construction, is above 1e-12 of the volume its edges could span.
class CheckCells {
 public:
  /// `x` (the lattice positions) is read at each query, so moves show at once.
  CheckCells(const springs::Lattice& lattice, const std::vector<Vec3>& x) : lattice_(lattice), x_(x) {
    double total = 0.0;
    for (int ck = 0; ck + 1 < lattice.nz; ++ck)
      for (int cj = 1; cj + 2 < lattice.ny; ++cj)
        for (int ci = 1; ci + 2 < lattice.nx; ++ci)
          for (int t = 0; t < 6; ++t) total += volume({ci, cj, ck, t}).volume;
    reference_ = total >= 0.0 ? 1.0 : -1.0;
  }

  /// The tetrahedra of the cells that have lattice point (i, j, k) as a corner.
  std::vector<std::array<int, 4>> around(int i, int j, int k) const {
    std::vector<std::array<int, 4>> out;
    for (int ck = k - 1; ck <= k; ++ck)
      for (int cj = j - 1; cj <= j; ++cj)
        for (int ci = i - 1; ci <= i; ++ci) {
          if (ck < 0 || ck + 1 >= lattice_.nz || cj < 1 || cj + 2 >= lattice_.ny || ci < 1 || ci + 2 >= lattice_.nx)
            continue;
          for (int t = 0; t < 6; ++t) out.push_back({ci, cj, ck, t});
        }
    return out;
  }

  bool good(const std::array<int, 4>& tet) const { return volume(tet).good(reference_); }

 private:
  TetVolume volume(const std::array<int, 4>& tet) const {
    const auto& local = kuhn_tetrahedra()[static_cast<std::size_t>(tet[3])];
    auto corner = [&](int q) -> const Vec3& {
      const int a = q & 1, b = (q >> 1) & 1, c = (q >> 2) & 1;
      return x_[static_cast<std::size_t>(lattice_.index(tet[0] + a, tet[1] + b, tet[2] + c))];
    };
    return tet_volume(corner(local[0]), corner(local[1]), corner(local[2]), corner(local[3]));
  }

  const springs::Lattice& lattice_;
  const std::vector<Vec3>& x_;
  double reference_ = 1.0;
};

}  // namespace fascicle
