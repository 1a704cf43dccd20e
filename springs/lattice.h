#pragma once
/// \file lattice.h
/// Sampling a fibre template into a regular (r, s, t) lattice of points joined by springs
/// (Zeleny 2011, ch. 5.2 and 6.2): fibres = nr x ns lattice lines along t, `resolution` points
/// per fibre; points on the boundary of the index box are the template surface (fixed);
/// springs join model-6 (face) or model-26 (face, edge and corner) neighbours, with the rest
/// length measured on the template and stiffness 1 / rest length.

#include "geometry/thesis_format.h"
#include "springs/fibre_template.h"
#include "springs/spring_system.h"

#include <array>
#include <vector>

namespace fascicle::springs {

/// Neighbour connectivity of a lattice.
enum class SpringModel {
  model6 = 6,    ///< the 6 face neighbours (3 springs per point)
  model26 = 26,  ///< all 26 neighbours (13 springs per point)
};

/// Parses 6 or 26. Throws OptionError naming the value.
SpringModel parse_spring_model(int value);

/// The half-set of neighbour offsets (dx, dy, dz) of a model: 3 for model-6, 13 for model-26,
/// each lexicographically positive, so every spring is listed once.
const std::vector<std::array<int, 3>>& half_offsets(SpringModel model);

/// Options for build_lattice.
struct LatticeOptions {
  TemplateKind kind = TemplateKind::parallel;  ///< template family (default parallel)
  int fibres = 100;                            ///< fibre count N, split nr x ns near-square (default 100)
  /// Explicit split: when both are > 0 (each >= 2) the lattice has nr x ns lines and `fibres` is
  /// ignored (default 0, 0: the near-square split of `fibres`).
  int nr = 0, ns = 0;
  int resolution = 20;                      ///< points per fibre, >= 2 (default 20)
  SpringModel model = SpringModel::model6;  ///< connectivity (default model-6)
  double density = 1.1;                     ///< mass per unit template volume; mass per point = density V / #points
                                            ///< (default 1.1: muscle tissue in the thesis's units, ch. 7.1.3)
  /// Width of the cells between the boundary lines and the first inner lines along r and s, in
  /// inner spacings (default 1: evenly spaced lines). 0.5 puts each inner line at the centre of
  /// its share of the cross-section, as when the boundary lines are a surface ring round the
  /// fibres (the decomposition). In (0, 1].
  double edge_cell = 1.0;
  /// Throws OptionError naming the bad field and value.
  void validate() const;
};

/// Near-square split of `fibres` (>= 4): the divisor pair nr <= ns of N closest to square if its
/// ratio ns / nr is at most 2, else nr = round(sqrt N), ns = ceil(N / nr) (then nr ns >= N).
std::array<int, 2> near_square_split(int fibres);

/// A template lattice: nx = nr points along r, ny = ns along s, nz = resolution along t.
/// Point (i, j, k) has index i + nx (j + ny k). `system` holds positions (template units),
/// fixed flags (boundary of the index box), masses and springs (model order: for each point in
/// index order, its half offsets in half_offsets() order).
struct Lattice {
  int nx = 0, ny = 0, nz = 0;
  double edge_cell = 1.0;  ///< LatticeOptions::edge_cell
  SpringModel model = SpringModel::model6;
  TemplateKind kind = TemplateKind::parallel;
  SpringSystem system;
  std::vector<Triangle> surface;  ///< triangles of the index box's boundary, outward
  std::vector<int> origin;        ///< indices of the points at t = 0
  std::vector<int> insertion;     ///< indices of the points at t = 1
  int index(int i, int j, int k) const { return i + nx * (j + ny * k); }
  int point_count() const { return nx * ny * nz; }
};

/// Position of line i of n along r or s in inner spacings: 0, a, a + 1, ..., a + n - 3, 2 a + n - 3
/// for edge cells of width a (exactly i when a = 1).
double lattice_line_position(int i, int n, double edge_cell);

/// Template coordinates (r, s, t) in [0, 1]^3 of lattice point q.
Vec3 lattice_coordinates(const Lattice& lattice, int q);

/// Samples a template into a lattice. Throws OptionError for bad options.
Lattice build_lattice(const LatticeOptions& options);

/// A regular lattice of n x n x n points with spacing `spacing` (the thesis's test lattices,
/// tables 7.1-7.6): the `parallel` template scaled by spacing (n - 1). Boundary points fixed
/// when `fix_boundary`. Mass per point `mass`.
Lattice regular_lattice(int n, SpringModel model, double spacing, double mass, bool fix_boundary);

/// The lattice in the thesis text format: points ('m' = surface), surface triangles, springs
/// with stiffness, one fibre per lattice line (first point, last point), origin and insertion
/// areas. Positions are `positions` when given (#N), else the lattice's own.
ThesisModel to_thesis_model(const Lattice& lattice, const std::vector<Vec3>* positions = nullptr);

/// The polylines of the fibres (each lattice line along t) at `positions` (#N).
Polylines fibre_polylines(const Lattice& lattice, const std::vector<Vec3>& positions);

}  // namespace fascicle::springs
