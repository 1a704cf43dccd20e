#include "morph/signed_distance_grid.h"

#include "geometry/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace fascicle {

SignedDistanceGrid::SignedDistanceGrid(const SurfaceQuery& query, const Vec3& low, const Vec3& high, double cell,
                                       long max_nodes)
    : query_(query), low_(low), cell_(cell) {
  if (!(cell > 0.0) || !low.allFinite() || !high.allFinite() || !(high.array() > low.array()).all())
    throw Error(ErrorCode::internal, "SignedDistanceGrid: empty box or cell " + std::to_string(cell));
  const Vec3 size = high - low;
  for (;;) {
    long nodes = 1;
    for (int c = 0; c < 3; ++c) {
      n_[c] = static_cast<int>(std::ceil(size[c] / cell_)) + 1;
      nodes *= n_[c];
    }
    if (nodes <= std::max(8L, max_nodes)) break;
    cell_ *= 1.25;
  }
  values_.assign(static_cast<std::size_t>(n_[0]) * static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(n_[2]),
                 std::numeric_limits<double>::quiet_NaN());
}

double SignedDistanceGrid::exact(const Vec3& p) const {
  const double d = query_.closest_point(p).distance;
  return query_.side(p) == Side::inside ? -d : d;
}

double SignedDistanceGrid::node(int i, int j, int k) {
  double& v =
      values_[static_cast<std::size_t>(i) +
              static_cast<std::size_t>(n_[0]) *
                  (static_cast<std::size_t>(j) + static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(k))];
  if (std::isnan(v)) {
    v = exact(low_ + cell_ * Vec3(i, j, k));
    ++computed_;
  }
  return v;
}

double SignedDistanceGrid::operator()(const Vec3& p, Vec3* gradient) {
  const Vec3 u = (p - low_) / cell_;
  int base[3];
  double f[3];
  for (int c = 0; c < 3; ++c) {
    const double fl = std::floor(u[c]);
    if (!(fl >= 0.0 && fl + 1.0 < n_[c])) {
      // Outside the grid: the exact value, its gradient along the offset from the surface.
      const SurfacePoint s = query_.closest_point(p);
      const bool inside = query_.side(p) == Side::inside;
      if (gradient) {
        const Vec3 off = p - s.position;
        *gradient = off.norm() > 0.0 ? Vec3((inside ? -1.0 : 1.0) * off.normalized()) : Vec3::Zero();
      }
      return inside ? -s.distance : s.distance;
    }
    base[c] = static_cast<int>(fl);
    f[c] = u[c] - fl;
  }
  double v[2][2][2];
  for (int c = 0; c < 2; ++c)
    for (int b = 0; b < 2; ++b)
      for (int a = 0; a < 2; ++a) v[c][b][a] = node(base[0] + a, base[1] + b, base[2] + c);
  // Along x, then y, then z.
  double vx[2][2], dx[2][2];
  for (int c = 0; c < 2; ++c)
    for (int b = 0; b < 2; ++b) {
      vx[c][b] = v[c][b][0] + f[0] * (v[c][b][1] - v[c][b][0]);
      dx[c][b] = v[c][b][1] - v[c][b][0];
    }
  double vy[2], dxy[2], dy[2];
  for (int c = 0; c < 2; ++c) {
    vy[c] = vx[c][0] + f[1] * (vx[c][1] - vx[c][0]);
    dxy[c] = dx[c][0] + f[1] * (dx[c][1] - dx[c][0]);
    dy[c] = vx[c][1] - vx[c][0];
  }
  const double value = vy[0] + f[2] * (vy[1] - vy[0]);
  if (gradient)
    *gradient = Vec3(dxy[0] + f[2] * (dxy[1] - dxy[0]), dy[0] + f[2] * (dy[1] - dy[0]), vy[1] - vy[0]) / cell_;
  return value;
}

}  // namespace fascicle
