#include "morph/inside_grid.h"

#include <algorithm>
#include <cmath>

namespace fascicle {

UniformGrid UniformGrid::over(const BoundingBox& box, double pad, double target) {
  UniformGrid g;
  g.origin = box.min - Vec3::Constant(pad);
  const Vec3 extent = (box.max - box.min) + Vec3::Constant(2 * pad);
  g.h = std::cbrt(extent.prod() / std::max(1.0, target));
  // A flat box (zero extent on an axis) gives h = 0: fall back to the largest extent.
  if (!(g.h > 0.0) || !std::isfinite(g.h)) g.h = std::max(extent.maxCoeff() / std::cbrt(target), 1e-300);
  g.h = std::max(g.h, extent.maxCoeff() / 4096.0);
  for (int a = 0; a < 3; ++a) g.n[a] = std::max(1, std::min(4096, static_cast<int>(std::ceil(extent[a] / g.h))));
  return g;
}

int UniformGrid::coordinate(double x, int axis) const {
  const double c = std::floor((x - origin[axis]) / h);
  return static_cast<int>(std::clamp(c, -1.0, static_cast<double>(n[axis])));
}

InsideGrid::InsideGrid(const TriangleMesh& mesh, const std::function<bool(const Vec3&)>& exact_inside,
                       double target_cells) {
  const BoundingBox box = bounding_box(mesh.positions);
  const double diagonal = box.diagonal();
  grid_ = UniformGrid::over(box, 0.01 * diagonal, target_cells);
  bounds_ = box;
  const double eps = 1e-9 * diagonal;
  state_.assign(static_cast<std::size_t>(grid_.cells()), kFree);
  for (const Triangle& t : mesh.triangles) {
    const Vec3& p0 = mesh.positions[static_cast<std::size_t>(t[0])];
    const Vec3& p1 = mesh.positions[static_cast<std::size_t>(t[1])];
    const Vec3& p2 = mesh.positions[static_cast<std::size_t>(t[2])];
    const Vec3 tmin = p0.cwiseMin(p1).cwiseMin(p2), tmax = p0.cwiseMax(p1).cwiseMax(p2);
    std::array<int, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, grid_.coordinate(tmin[a] - eps, a));
      hi[a] = std::min(grid_.n[a] - 1, grid_.coordinate(tmax[a] + eps, a));
    }
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) state_[static_cast<std::size_t>(grid_.index(i, j, k))] = kNear;
  }
  // Flood fill the free regions (6-neighbourhood); one exact test per region.
  std::vector<long> stack;
  for (int k = 0; k < grid_.n[2]; ++k)
    for (int j = 0; j < grid_.n[1]; ++j)
      for (int i = 0; i < grid_.n[0]; ++i) {
        const long start = grid_.index(i, j, k);
        if (state_[static_cast<std::size_t>(start)] != kFree) continue;
        const char mark = exact_inside(grid_.centre(i, j, k)) ? kInside : kOutside;
        state_[static_cast<std::size_t>(start)] = mark;
        stack.push_back(start);
        while (!stack.empty()) {
          const long c = stack.back();
          stack.pop_back();
          const int ci = static_cast<int>(c % grid_.n[0]);
          const int cj = static_cast<int>((c / grid_.n[0]) % grid_.n[1]);
          const int ck = static_cast<int>(c / (static_cast<long>(grid_.n[0]) * grid_.n[1]));
          const int nb[6][3] = {{ci - 1, cj, ck}, {ci + 1, cj, ck}, {ci, cj - 1, ck},
                                {ci, cj + 1, ck}, {ci, cj, ck - 1}, {ci, cj, ck + 1}};
          for (const auto& q : nb) {
            if (q[0] < 0 || q[1] < 0 || q[2] < 0 || q[0] >= grid_.n[0] || q[1] >= grid_.n[1] || q[2] >= grid_.n[2])
              continue;
            const long qi = grid_.index(q[0], q[1], q[2]);
            if (state_[static_cast<std::size_t>(qi)] != kFree) continue;
            state_[static_cast<std::size_t>(qi)] = mark;
            stack.push_back(qi);
          }
        }
        ++regions_;
      }
}

InsideGrid::Known InsideGrid::classify(const Vec3& p) const {
  for (int a = 0; a < 3; ++a)
    if (!(p[a] >= bounds_.min[a] && p[a] <= bounds_.max[a])) return p.allFinite() ? Known::outside : Known::unknown;
  std::array<int, 3> c{};
  for (int a = 0; a < 3; ++a) {
    c[a] = grid_.coordinate(p[a], a);
    if (c[a] < 0 || c[a] >= grid_.n[a]) return Known::unknown;  // cannot happen inside bounds_
  }
  const char s = state_[static_cast<std::size_t>(grid_.index(c[0], c[1], c[2]))];
  if (s == kInside) return Known::inside;
  if (s == kOutside) return Known::outside;
  return Known::unknown;
}

std::vector<long> InsideGrid::candidate_cells() const {
  std::vector<long> cells;
  for (long c = 0; c < grid_.cells(); ++c)
    if (state_[static_cast<std::size_t>(c)] == kInside || state_[static_cast<std::size_t>(c)] == kNear)
      cells.push_back(c);
  return cells;
}

Vec3 InsideGrid::cell_corner(long c) const {
  const long i = c % grid_.n[0], j = (c / grid_.n[0]) % grid_.n[1],
             k = c / (static_cast<long>(grid_.n[0]) * grid_.n[1]);
  return grid_.origin + grid_.h * Vec3(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
}

}  // namespace fascicle
