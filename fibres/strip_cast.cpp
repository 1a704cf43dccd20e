#include "fibres/strip_cast.h"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace fascicle {

StripCast cast_strip_face(const Vec3& centre, const std::vector<Vec3>& offsets, const Vec3& axis,
                          const std::vector<Vec3>& area_points,
                          const std::function<bool(const Vec3&, const Vec3&, Vec3&)>& hit,
                          const std::function<bool(const Vec3&)>& near, int steps) {
  StripCast out;
  if (offsets.empty() || steps < 1) return out;
  const Vec3 n = axis.normalized();
  // The strip's direction seen along the axis.
  Vec3 along = Vec3::Zero();
  if (area_points.size() >= 2) {
    Vec3 mean = Vec3::Zero();
    for (const Vec3& p : area_points) mean += p;
    mean /= static_cast<double>(area_points.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const Vec3& p : area_points) {
      const Vec3 d = (p - mean) - (p - mean).dot(n) * n;
      cov += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    if (eig.info() == Eigen::Success && eig.eigenvalues()(2) > 0.0) along = eig.eigenvectors().col(2);
  }
  if (!(along.norm() > 0.5)) {
    for (const Vec3& o : offsets) {
      const Vec3 d = o - o.dot(n) * n;
      if (d.norm() > 0.0) {
        along = d.normalized();
        break;
      }
    }
  }
  if (!(along.norm() > 0.5)) along = n.unitOrthogonal();
  along = (along - along.dot(n) * n).normalized();

  std::vector<double> factor(static_cast<std::size_t>(steps));
  factor[0] = 1.0;
  for (int s = 1; s < steps; ++s) factor[static_cast<std::size_t>(s)] = 0.8 * factor[static_cast<std::size_t>(s - 1)];
  std::vector<Vec3> ends;
  auto try_pair = [&](double a, double c) {
    ends.clear();
    for (const Vec3& o : offsets) {
      const double l = o.dot(along);
      const Vec3 start = centre + a * l * along + c * (o - l * along);
      Vec3 end;
      if (!hit(start, n, end) || !near(end)) return false;
      ends.push_back(end);
    }
    return true;
  };
  double best = 0.0;
  for (double a : factor) {
    if (a <= best) break;  // even c = 1 cannot keep a larger face
    for (double c : factor) {
      if (a * c <= best) break;
      if (try_pair(a, c)) {
        best = a * c;
        out.placed = true;
        out.lambda_long = a;
        out.lambda_cross = c;
        out.ends = ends;
        break;
      }
    }
  }
  return out;
}

}  // namespace fascicle
