#include "geometry/cross_section.h"

#include "geometry/mesh_stats.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>

namespace fascicle {

namespace {

// Area, first and second moments of a plane region from its boundary (Green's theorem), summed
// over directed boundary segments in any order.
struct AreaMoments {
  double a = 0, sx = 0, sy = 0, ixx = 0, iyy = 0, ixy = 0;
  void add(const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
    const double c = p.x() * q.y() - q.x() * p.y();
    a += c / 2.0;
    sx += (p.x() + q.x()) * c / 6.0;
    sy += (p.y() + q.y()) * c / 6.0;
    ixx += (p.x() * p.x() + p.x() * q.x() + q.x() * q.x()) * c / 12.0;
    iyy += (p.y() * p.y() + p.y() * q.y() + q.y() * q.y()) * c / 12.0;
    ixy += (p.x() * q.y() + 2.0 * p.x() * p.y() + 2.0 * q.x() * q.y() + q.x() * p.y()) * c / 24.0;
  }
};

}  // namespace

CrossSectionShape cross_section_shape(const TriangleMesh& mesh, const CrossSectionOptions& options) {
  CrossSectionShape shape;
  if (mesh.positions.empty() || mesh.triangles.empty() || options.slices < 1) return shape;
  const PrincipalAxes axes = principal_axes(mesh.positions);
  const Vec3 axis = axes.major(), u = axes.axes.col(1), v = axes.axes.col(0);
  const Vec3 w = u.cross(v);  // (u, v, w) right-handed: w is +-axis
  double lo = INFINITY, hi = -INFINITY;
  for (const Vec3& p : mesh.positions) {
    const double s = (p - axes.mean).dot(axis);
    lo = std::min(lo, s);
    hi = std::max(hi, s);
  }
  for (int k = 0; k < options.slices; ++k) {
    const double f = options.slices == 1 ? 0.5 * (options.from + options.to)
                                         : options.from + (options.to - options.from) * k / (options.slices - 1);
    const double level = lo + f * (hi - lo);
    AreaMoments m;
    for (const Triangle& t : mesh.triangles) {
      std::array<Vec3, 3> p;
      std::array<double, 3> d;
      for (int c = 0; c < 3; ++c) {
        p[c] = mesh.positions[t[c]] - axes.mean;
        d[c] = p[c].dot(axis) - level;
      }
      // The cut: the points where the edges change side (a vertex on the plane counts above).
      std::array<Vec3, 2> cut;
      int n = 0;
      for (int c = 0; c < 3 && n < 2; ++c) {
        const int e = (c + 1) % 3;
        if ((d[c] < 0.0) != (d[e] < 0.0)) cut[n++] = p[c] + (p[e] - p[c]) * (d[c] / (d[c] - d[e]));
      }
      if (n != 2) continue;
      // Directed along w x normal: anticlockwise in (u, v) round the region of an outward mesh
      // (an inward one flips every moment, which leaves the aspect as it is).
      const Vec3 normal = (p[1] - p[0]).cross(p[2] - p[0]);
      if ((cut[1] - cut[0]).dot(w.cross(normal)) < 0.0) std::swap(cut[0], cut[1]);
      m.add({cut[0].dot(u), cut[0].dot(v)}, {cut[1].dot(u), cut[1].dot(v)});
    }
    if (m.a == 0.0 || !std::isfinite(m.a)) continue;
    const double cx = m.sx / m.a, cy = m.sy / m.a;
    Eigen::Matrix2d c;
    c << m.ixx / m.a - cx * cx, m.ixy / m.a - cx * cy, m.ixy / m.a - cx * cy, m.iyy / m.a - cy * cy;
    const Eigen::Vector2d e = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(c, Eigen::EigenvaluesOnly).eigenvalues();
    if (!(e[0] > 0.0) || !(e[1] > 0.0)) continue;
    shape.aspects.push_back(std::sqrt(e[1] / e[0]));
  }
  if (!shape.aspects.empty()) {
    std::vector<double> sorted = shape.aspects;
    std::sort(sorted.begin(), sorted.end());
    const std::size_t n = sorted.size();
    shape.median_aspect = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  }
  return shape;
}

}  // namespace fascicle
