#include "repair/weld_vertices.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <unordered_map>

namespace fascicle {

namespace {

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int a) {
    while (parent[a] != a) {
      parent[a] = parent[parent[a]];
      a = parent[a];
    }
    return a;
  }
  void unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (a < b)
      parent[b] = a;
    else
      parent[a] = b;  // lowest index represents the group
  }
};

struct CellHash {
  std::size_t operator()(const std::array<std::int64_t, 3>& c) const {
    std::uint64_t h = static_cast<std::uint64_t>(c[0]) * 0x9E3779B97F4A7C15ULL;
    h ^= static_cast<std::uint64_t>(c[1]) * 0xC2B2AE3D27D4EB4FULL + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(c[2]) * 0x165667B19E3779F9ULL + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};

}  // namespace

WeldResult weld_vertices(const std::vector<Vec3>& points, double tolerance) {
  const std::size_t n = points.size();
  UnionFind groups(n);
  using Cell = std::array<std::int64_t, 3>;

  // Exact copies (an STL file repeats each corner in every face round it) are united first, by
  // sorting (+0.0 and -0.0 alike, NaN last and never united); with a tolerance only one point of
  // each copy group then enters the grid: the groups come out the same, with a fraction of the
  // grid lookups.
  auto compare = [](double a, double b) {
    const bool na = std::isnan(a), nb = std::isnan(b);
    if (na || nb) return static_cast<int>(na) - static_cast<int>(nb);
    return a < b ? -1 : (b < a ? 1 : 0);
  };
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    for (int k = 0; k < 3; ++k)
      if (const int c = compare(points[a][k], points[b][k])) return c < 0;
    return a < b;
  });
  std::vector<int> distinct;
  distinct.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0 && points[order[k]] == points[order[k - 1]])
      groups.unite(order[k - 1], order[k]);
    else
      distinct.push_back(order[k]);
  }
  if (tolerance > 0.0) {
    const double inv = 1.0 / tolerance;
    const double tol2 = tolerance * tolerance;
    std::unordered_map<Cell, std::vector<int>, CellHash> grid;
    grid.reserve(distinct.size());
    auto cell_of = [&](const Vec3& p) {
      return Cell{static_cast<std::int64_t>(std::floor(p[0] * inv)), static_cast<std::int64_t>(std::floor(p[1] * inv)),
                  static_cast<std::int64_t>(std::floor(p[2] * inv))};
    };
    for (const int i : distinct) {
      const Cell c = cell_of(points[i]);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            auto it = grid.find(Cell{c[0] + dx, c[1] + dy, c[2] + dz});
            if (it == grid.end()) continue;
            for (int j : it->second)
              if ((points[j] - points[i]).squaredNorm() <= tol2) groups.unite(j, i);
          }
      grid[c].push_back(i);
    }
  }

  WeldResult result;
  result.representative.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    result.representative[i] = groups.find(static_cast<int>(i));
    if (result.representative[i] != static_cast<int>(i)) ++result.merged;
  }
  return result;
}

}  // namespace fascicle
