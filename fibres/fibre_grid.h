#pragma once
/// \file fibre_grid.h
/// Fibres as a lattice: a decomposition's fibres are the lattice lines (r, s) of a template
/// lattice, all with the same number of points, and neighbouring fibres bound hexahedral cells.
/// In files the lattice indices travel as the per-fibre cell data arrays `fibre_r` and `fibre_s`
/// (geometry/mesh.h, Polylines::cell_data); fibres from other tools have none and are then
/// checked without cells.
#include "geometry/mesh.h"
#include <array>
#include <vector>

namespace fascicle {

namespace springs {
struct Lattice;
}

/// Name of the per-fibre array holding a fibre's first lattice index.
inline constexpr const char* fibre_r_array = "fibre_r";
/// Name of the per-fibre array holding a fibre's second lattice index.
inline constexpr const char* fibre_s_array = "fibre_s";

/// Lattice structure of a set of fibres.
struct FibreGrid {
  int nr = 0, ns = 0;        ///< index ranges r in [0, nr), s in [0, ns); 0 when not a lattice
  int points = 0;            ///< points per fibre (the same for every fibre)
  std::vector<int> line_of;  ///< nr * ns entries: the line at (r, s) is line_of[r + nr s], or -1
  /// True when the fibres form a lattice (nr, ns > 0).
  bool is_lattice() const { return nr > 0 && ns > 0; }
  /// The line index at (r, s), or -1 when out of range or absent.
  int at(int r, int s) const {
    return (r < 0 || s < 0 || r >= nr || s >= ns) ? -1 : line_of[static_cast<size_t>(r + nr * s)];
  }
};

/// The lattice structure of `fibres`: present when both arrays `fibre_r` and `fibre_s` exist,
/// hold non-negative integers, no (r, s) pair repeats and every line has the same number of
/// points (>= 2). Otherwise an empty grid (nr = ns = 0), which is not an error: such fibres are
/// checked without cells.
FibreGrid fibre_grid(const Polylines& fibres);

/// The Kuhn split of a lattice cell, the one split used wherever cells are measured (the quality
/// check's inverted cells, the untangling's tetrahedra). The corners of a hexahedral cell are
/// numbered a + 2b + 4c (a = 1: one step along r, b: along s, c: along the fibre); the cell splits
/// into six tetrahedra around its diagonal 0 - 7, one per order in which the three axes are
/// stepped. Each entry lists a tetrahedron's corners, the first one 0, ordered so that its signed
/// volume (v1 - v0) . ((v2 - v0) x (v3 - v0)) has the sign of the frame (r, s, fibre) when the cell
/// is not folded (for the unit cube: +1/6 each).
const std::array<std::array<int, 4>, 6>& kuhn_tetrahedra();

/// A tetrahedron as the quality check measures it: signed volume (v1 - v0) . ((v2 - v0) x
/// (v3 - v0)) / 6 and the volume its three edges from v0 could span, |v1 - v0| |v2 - v0| |v3 - v0| / 6.
struct TetVolume {
  double volume = 0.0, scale = 0.0;
  /// Good (not folded, not flat) when the volume, times the lattice's orientation `reference`
  /// (+1 or -1), is above 1e-12 of the scale (round-off level; zero edges are flat).
  bool good(double reference) const { return reference * volume > 1e-12 * scale; }
};
TetVolume tet_volume(const Vec3& v0, const Vec3& v1, const Vec3& v2, const Vec3& v3);

/// Fibres with their lattice indices as cell data arrays `fibre_r`, `fibre_s`.
/// `lines`, `r` and `s` have the same size (throws std::invalid_argument otherwise).
Polylines lattice_fibres(std::vector<std::vector<Vec3>> lines, const std::vector<int>& r, const std::vector<int>& s);

/// The fibres of a decomposition lattice: its interior lines (1 <= i <= nx - 2, 1 <= j <= ny - 2;
/// the surface ring is not output) at `positions` (one per lattice point), in lattice order,
/// origin (k = 0) to insertion, with r = i - 1 and s = j - 1.
Polylines lattice_interior_fibres(const springs::Lattice& lattice, const std::vector<Vec3>& positions);

}  // namespace fascicle
