#include "fibres/fibre_grid.h"

#include "springs/lattice.h"

#include <cmath>
#include <utility>
#include <stdexcept>

namespace fascicle {

namespace {

const CellArray* find_array(const Polylines& fibres, const char* name) {
  for (const CellArray& array : fibres.cell_data) {
    if (array.name == name && array.values.size() == fibres.lines.size()) return &array;
  }
  return nullptr;
}

bool as_index(double value, int& index) {
  if (!std::isfinite(value) || value < 0.0 || value > 1e8 || std::floor(value) != value) return false;
  index = static_cast<int>(value);
  return true;
}

}  // namespace

FibreGrid fibre_grid(const Polylines& fibres) {
  const CellArray* r_array = find_array(fibres, fibre_r_array);
  const CellArray* s_array = find_array(fibres, fibre_s_array);
  if (r_array == nullptr || s_array == nullptr || fibres.lines.empty()) return {};
  const size_t points = fibres.lines.front().size();
  if (points < 2) return {};
  int nr = 0, ns = 0;
  std::vector<int> r(fibres.lines.size()), s(fibres.lines.size());
  for (size_t line = 0; line < fibres.lines.size(); ++line) {
    if (fibres.lines[line].size() != points) return {};
    if (!as_index(r_array->values[line], r[line]) || !as_index(s_array->values[line], s[line])) return {};
    nr = std::max(nr, r[line] + 1);
    ns = std::max(ns, s[line] + 1);
  }
  // A sparse index range (a few fibres with huge indices) is not a lattice worth a dense table.
  if (static_cast<double>(nr) * ns > 4.0 * static_cast<double>(fibres.lines.size()) + 16.0) return {};
  FibreGrid grid;
  grid.nr = nr;
  grid.ns = ns;
  grid.points = static_cast<int>(points);
  grid.line_of.assign(static_cast<size_t>(nr) * static_cast<size_t>(ns), -1);
  for (size_t line = 0; line < fibres.lines.size(); ++line) {
    int& slot = grid.line_of[static_cast<size_t>(r[line] + nr * s[line])];
    if (slot != -1) return {};
    slot = static_cast<int>(line);
  }
  return grid;
}

TetVolume tet_volume(const Vec3& v0, const Vec3& v1, const Vec3& v2, const Vec3& v3) {
  const Vec3 a = v1 - v0, b = v2 - v0, c = v3 - v0;
  return {a.dot(b.cross(c)) / 6.0, a.norm() * b.norm() * c.norm() / 6.0};
}

const std::array<std::array<int, 4>, 6>& kuhn_tetrahedra() {
  // Axis orders (0 = r, 1 = s, 2 = fibre); the last three are odd permutations, whose
  // tetrahedra have their two last corners swapped to be positive.
  static const std::array<std::array<int, 4>, 6> tets = [] {
    static const int orders[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
    std::array<std::array<int, 4>, 6> out{};
    for (int t = 0; t < 6; ++t) {
      int corner = 0;
      out[static_cast<size_t>(t)][0] = 0;
      for (int step = 0; step < 3; ++step) {
        corner |= 1 << orders[t][step];
        out[static_cast<size_t>(t)][static_cast<size_t>(step) + 1] = corner;
      }
      if (t >= 3) std::swap(out[static_cast<size_t>(t)][2], out[static_cast<size_t>(t)][3]);
    }
    return out;
  }();
  return tets;
}

Polylines lattice_fibres(std::vector<std::vector<Vec3>> lines, const std::vector<int>& r, const std::vector<int>& s) {
  if (r.size() != lines.size() || s.size() != lines.size()) {
    throw std::invalid_argument("lattice_fibres: index arrays do not match the fibre count");
  }
  Polylines fibres;
  fibres.lines = std::move(lines);
  fibres.cell_data.push_back({fibre_r_array, std::vector<double>(r.begin(), r.end())});
  fibres.cell_data.push_back({fibre_s_array, std::vector<double>(s.begin(), s.end())});
  return fibres;
}

Polylines lattice_interior_fibres(const springs::Lattice& lattice, const std::vector<Vec3>& positions) {
  std::vector<std::vector<Vec3>> lines;
  std::vector<int> rs, ss;
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i) {
      std::vector<Vec3> line(static_cast<std::size_t>(lattice.nz));
      for (int k = 0; k < lattice.nz; ++k)
        line[static_cast<std::size_t>(k)] = positions[static_cast<std::size_t>(lattice.index(i, j, k))];
      lines.push_back(std::move(line));
      rs.push_back(i - 1);
      ss.push_back(j - 1);
    }
  return lattice_fibres(std::move(lines), rs, ss);
}

}  // namespace fascicle
