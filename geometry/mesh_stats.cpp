#include "geometry/mesh_stats.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <unordered_set>

namespace fascicle {

double BoundingBox::diagonal() const {
  if (!(min.array() <= max.array()).all()) return 0.0;
  return (max - min).norm();
}

BoundingBox bounding_box(const std::vector<Vec3>& points) {
  BoundingBox box;
  for (const Vec3& p : points) {
    box.min = box.min.cwiseMin(p);
    box.max = box.max.cwiseMax(p);
  }
  return box;
}

PrincipalAxes principal_axes(const std::vector<Vec3>& points) {
  PrincipalAxes out;
  if (points.empty()) return out;
  for (const Vec3& p : points) out.mean += p;
  out.mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Vec3& p : points) scatter += (p - out.mean) * (p - out.mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  out.axes = eig.eigenvectors();
  out.variances = eig.eigenvalues() / static_cast<double>(points.size());
  return out;
}

double surface_area(const TriangleMesh& mesh) {
  double area = 0.0;
  for (const Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.positions[t[0]];
    area += 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
  }
  return area;
}

double signed_volume(const TriangleMesh& mesh) {
  // Translate to the box centre first: for CT coordinates (offsets of 1e7) the plain formula
  // loses every significant digit.
  const Vec3 c = bounding_box(mesh.positions).center();
  double volume = 0.0;
  for (const Triangle& t : mesh.triangles) {
    const Vec3 a = mesh.positions[t[0]] - c, b = mesh.positions[t[1]] - c, d = mesh.positions[t[2]] - c;
    volume += a.dot(b.cross(d));
  }
  return volume / 6.0;
}

long euler_characteristic(const TriangleMesh& mesh) {
  std::unordered_set<long long> edges;
  std::vector<char> used(mesh.positions.size(), 0);
  for (const Triangle& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      used[t[k]] = 1;
      const long long a = std::min(t[k], t[(k + 1) % 3]), b = std::max(t[k], t[(k + 1) % 3]);
      edges.insert(a * (1LL << 31) + b);
    }
  }
  const long v = static_cast<long>(std::count(used.begin(), used.end(), 1));
  return v - static_cast<long>(edges.size()) + static_cast<long>(mesh.triangles.size());
}

PolygonSoup to_soup(const TriangleMesh& mesh) {
  PolygonSoup soup;
  soup.points = mesh.positions;
  soup.polygons.reserve(mesh.triangles.size());
  for (const Triangle& t : mesh.triangles) soup.polygons.push_back({t[0], t[1], t[2]});
  return soup;
}

}  // namespace fascicle
