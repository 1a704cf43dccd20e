// Template lattices (Zeleny 2011, ch. 5.2, 6.2): regular (r, s, t) sampling, model-6/26 springs.

#include "springs/lattice.h"

#include "geometry/errors.h"

#include <cmath>
#include <string>

namespace fascicle::springs {
namespace {

// Volume of the hexahedral cell (i, j, k)-(i+1, j+1, k+1) as six tetrahedra around the diagonal
// 0-7 (absolute values: the templates may be left- or right-handed in (r, s, t)).
double cell_volume(const Lattice& lattice, int i, int j, int k) {
  const auto& p = lattice.system.positions;
  auto at = [&](int di, int dj, int dk) -> const Vec3& { return p[lattice.index(i + di, j + dj, k + dk)]; };
  const Vec3& a = at(0, 0, 0);
  const Vec3& h = at(1, 1, 1);
  const Vec3 ring[6] = {at(1, 0, 0), at(1, 1, 0), at(0, 1, 0), at(0, 1, 1), at(0, 0, 1), at(1, 0, 1)};
  double volume = 0.0;
  for (int q = 0; q < 6; ++q) {
    const Vec3& b = ring[q];
    const Vec3& c = ring[(q + 1) % 6];
    volume += std::abs((b - a).cross(c - a).dot(h - a)) / 6.0;
  }
  return volume;
}

void add_surface(Lattice& lattice) {
  const int nx = lattice.nx, ny = lattice.ny, nz = lattice.nz;
  auto quad = [&](int a, int b, int c, int d) {
    lattice.surface.push_back({a, b, c});
    lattice.surface.push_back({a, c, d});
  };
  // Faces of the index box, each wound so its normal points out of the box in index space.
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      quad(lattice.index(i, j, 0), lattice.index(i, j + 1, 0), lattice.index(i + 1, j + 1, 0),
           lattice.index(i + 1, j, 0));
      const int k = nz - 1;
      quad(lattice.index(i, j, k), lattice.index(i + 1, j, k), lattice.index(i + 1, j + 1, k),
           lattice.index(i, j + 1, k));
    }
  for (int k = 0; k + 1 < nz; ++k)
    for (int i = 0; i + 1 < nx; ++i) {
      quad(lattice.index(i, 0, k), lattice.index(i + 1, 0, k), lattice.index(i + 1, 0, k + 1),
           lattice.index(i, 0, k + 1));
      const int j = ny - 1;
      quad(lattice.index(i, j, k), lattice.index(i, j, k + 1), lattice.index(i + 1, j, k + 1),
           lattice.index(i + 1, j, k));
    }
  for (int k = 0; k + 1 < nz; ++k)
    for (int j = 0; j + 1 < ny; ++j) {
      quad(lattice.index(0, j, k), lattice.index(0, j, k + 1), lattice.index(0, j + 1, k + 1),
           lattice.index(0, j + 1, k));
      const int i = nx - 1;
      quad(lattice.index(i, j, k), lattice.index(i, j + 1, k), lattice.index(i, j + 1, k + 1),
           lattice.index(i, j, k + 1));
    }
  // The template map may reverse orientation: make the signed volume positive (outward).
  const auto& p = lattice.system.positions;
  double signed_volume = 0.0;
  for (const Triangle& t : lattice.surface) signed_volume += p[t[0]].dot(p[t[1]].cross(p[t[2]]));
  if (signed_volume < 0.0)
    for (Triangle& t : lattice.surface) std::swap(t[1], t[2]);
}

void add_springs(Lattice& lattice) {
  const auto& offsets = half_offsets(lattice.model);
  auto& system = lattice.system;
  system.springs.reserve(static_cast<std::size_t>(lattice.point_count()) * offsets.size());
  for (int k = 0; k < lattice.nz; ++k)
    for (int j = 0; j < lattice.ny; ++j)
      for (int i = 0; i < lattice.nx; ++i)
        for (const auto& o : offsets) {
          const int i2 = i + o[0], j2 = j + o[1], k2 = k + o[2];
          if (i2 < 0 || j2 < 0 || k2 < 0 || i2 >= lattice.nx || j2 >= lattice.ny || k2 >= lattice.nz) continue;
          Spring s;
          s.a = lattice.index(i, j, k);
          s.b = lattice.index(i2, j2, k2);
          s.rest = (system.positions[s.a] - system.positions[s.b]).norm();
          if (!(s.rest > 0.0))
            throw OptionError("lattice: points " + std::to_string(s.a) + " and " + std::to_string(s.b) +
                              " coincide; use fewer fibres or points");
          s.stiffness = 1.0 / s.rest;
          system.springs.push_back(s);
        }
}

void finish(Lattice& lattice, double mass) {
  const int n = lattice.point_count();
  auto& system = lattice.system;
  system.fixed.assign(n, 0);
  for (int k = 0; k < lattice.nz; ++k)
    for (int j = 0; j < lattice.ny; ++j)
      for (int i = 0; i < lattice.nx; ++i)
        if (i == 0 || j == 0 || k == 0 || i == lattice.nx - 1 || j == lattice.ny - 1 || k == lattice.nz - 1)
          system.fixed[lattice.index(i, j, k)] = 1;
  system.mass.assign(n, mass);
  for (int j = 0; j < lattice.ny; ++j)
    for (int i = 0; i < lattice.nx; ++i) {
      lattice.origin.push_back(lattice.index(i, j, 0));
      lattice.insertion.push_back(lattice.index(i, j, lattice.nz - 1));
    }
  add_springs(lattice);
  add_surface(lattice);
}

}  // namespace

SpringModel parse_spring_model(int value) {
  if (value == 6) return SpringModel::model6;
  if (value == 26) return SpringModel::model26;
  throw OptionError("model: must be 6 or 26, got " + std::to_string(value));
}

const std::vector<std::array<int, 3>>& half_offsets(SpringModel model) {
  static const std::vector<std::array<int, 3>> six = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  static const std::vector<std::array<int, 3>> twenty_six = [] {
    std::vector<std::array<int, 3>> offsets;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          // Lexicographically positive in (dz, dy, dx): the linear index offset is positive.
          const bool positive = dz > 0 || (dz == 0 && (dy > 0 || (dy == 0 && dx > 0)));
          if (positive) offsets.push_back({dx, dy, dz});
        }
    return offsets;
  }();
  return model == SpringModel::model6 ? six : twenty_six;
}

void LatticeOptions::validate() const {
  if (nr > 0 || ns > 0) {
    if (nr < 2 || ns < 2 || nr > 100'000 || ns > 100'000)
      throw OptionError("lattice split: nr and ns must both be in 2..100000, got " + std::to_string(nr) + " x " +
                        std::to_string(ns));
    if (static_cast<double>(nr) * ns * resolution > 2e8)
      throw OptionError("nr x ns x resolution: above the limit of 2e8 points");
  } else if (fibres < 4)
    throw OptionError("fibres: must be >= 4 (a 2 x 2 lattice), got " + std::to_string(fibres));
  if (fibres > 4'000'000) throw OptionError("fibres: at most 4000000, got " + std::to_string(fibres));
  if (!(edge_cell > 0.0 && edge_cell <= 1.0))
    throw OptionError("edge_cell: must be in (0, 1], got " + std::to_string(edge_cell));
  if (resolution < 2 || resolution > 100'000)
    throw OptionError("resolution: must be in 2..100000 points per fibre, got " + std::to_string(resolution));
  if (static_cast<double>(fibres) * resolution > 2e8)
    throw OptionError("fibres x resolution: " + std::to_string(static_cast<double>(fibres) * resolution) +
                      " points is above the limit of 2e8");
  if (!(density > 0.0) || !std::isfinite(density))
    throw OptionError("density: must be > 0, got " + std::to_string(density));
}

std::array<int, 2> near_square_split(int fibres) {
  if (fibres < 4) throw OptionError("fibres: must be >= 4, got " + std::to_string(fibres));
  int best = 1;
  for (int d = 1; static_cast<long long>(d) * d <= fibres; ++d)
    if (fibres % d == 0) best = d;
  if (fibres / best <= 2 * best) return {best, fibres / best};
  const int nr = static_cast<int>(std::lround(std::sqrt(static_cast<double>(fibres))));
  return {nr, (fibres + nr - 1) / nr};
}

double lattice_line_position(int i, int n, double edge_cell) {
  if (edge_cell == 1.0 || i == 0) return static_cast<double>(i);
  if (i == n - 1) return 2.0 * edge_cell + static_cast<double>(n - 3);
  return edge_cell + static_cast<double>(i - 1);
}

Vec3 lattice_coordinates(const Lattice& lattice, int q) {
  const int i = q % lattice.nx;
  const int j = (q / lattice.nx) % lattice.ny;
  const int k = q / (lattice.nx * lattice.ny);
  return Vec3(lattice_line_position(i, lattice.nx, lattice.edge_cell) /
                  lattice_line_position(lattice.nx - 1, lattice.nx, lattice.edge_cell),
              lattice_line_position(j, lattice.ny, lattice.edge_cell) /
                  lattice_line_position(lattice.ny - 1, lattice.ny, lattice.edge_cell),
              static_cast<double>(k) / (lattice.nz - 1));
}

Lattice build_lattice(const LatticeOptions& options) {
  options.validate();
  const auto split = (options.nr > 0 && options.ns > 0) ? std::array<int, 2>{options.nr, options.ns}
                                                        : near_square_split(options.fibres);
  Lattice lattice;
  lattice.nx = split[0];
  lattice.ny = split[1];
  lattice.nz = options.resolution;
  lattice.model = options.model;
  lattice.kind = options.kind;
  // Edge cells narrower than the others need a line between the boundary lines.
  lattice.edge_cell = lattice.nx > 2 && lattice.ny > 2 ? options.edge_cell : 1.0;
  const int n = lattice.point_count();
  lattice.system.positions.resize(n);
  // A crossing family's lattice is the parallel one: the map of the cube its fibres are drawn through.
  const TemplateKind shape = crosses_lattice(options.kind) ? TemplateKind::parallel : options.kind;
  for (int q = 0; q < n; ++q) {
    const Vec3 c = lattice_coordinates(lattice, q);
    lattice.system.positions[static_cast<std::size_t>(q)] = template_point(shape, c.x(), c.y(), c.z());
  }
  double volume = 0.0;
  for (int k = 0; k + 1 < lattice.nz; ++k)
    for (int j = 0; j + 1 < lattice.ny; ++j)
      for (int i = 0; i + 1 < lattice.nx; ++i) volume += cell_volume(lattice, i, j, k);
  finish(lattice, options.density * volume / n);
  return lattice;
}

Lattice regular_lattice(int n, SpringModel model, double spacing, double mass, bool fix_boundary) {
  if (n < 2) throw OptionError("lattice size: must be >= 2, got " + std::to_string(n));
  if (!(spacing > 0.0)) throw OptionError("spacing: must be > 0, got " + std::to_string(spacing));
  if (!(mass > 0.0)) throw OptionError("mass: must be > 0, got " + std::to_string(mass));
  Lattice lattice;
  lattice.nx = lattice.ny = lattice.nz = n;
  lattice.model = model;
  lattice.kind = TemplateKind::parallel;
  lattice.system.positions.resize(static_cast<std::size_t>(n) * n * n);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) lattice.system.positions[lattice.index(i, j, k)] = Vec3(i, j, k) * spacing;
  finish(lattice, mass);
  if (!fix_boundary) std::fill(lattice.system.fixed.begin(), lattice.system.fixed.end(), 0);
  return lattice;
}

ThesisModel to_thesis_model(const Lattice& lattice, const std::vector<Vec3>* positions) {
  ThesisModel model;
  model.points = positions ? *positions : lattice.system.positions;
  FASCICLE_CHECK(model.points.size() == lattice.system.positions.size(), "position count");
  model.surface = lattice.system.fixed;
  model.triangles = lattice.surface;
  model.springs.reserve(lattice.system.springs.size());
  for (const Spring& s : lattice.system.springs) model.springs.push_back({s.a, s.b, s.stiffness});
  for (int j = 0; j < lattice.ny; ++j)
    for (int i = 0; i < lattice.nx; ++i)
      model.fibres.push_back({lattice.index(i, j, 0), lattice.index(i, j, lattice.nz - 1)});
  model.origin = lattice.origin;
  model.insertion = lattice.insertion;
  return model;
}

Polylines fibre_polylines(const Lattice& lattice, const std::vector<Vec3>& positions) {
  FASCICLE_CHECK(positions.size() == static_cast<std::size_t>(lattice.point_count()), "position count");
  Polylines out;
  for (int j = 0; j < lattice.ny; ++j)
    for (int i = 0; i < lattice.nx; ++i) {
      std::vector<Vec3> line;
      for (int k = 0; k < lattice.nz; ++k) line.push_back(positions[lattice.index(i, j, k)]);
      out.lines.push_back(std::move(line));
    }
  return out;
}

}  // namespace fascicle::springs
