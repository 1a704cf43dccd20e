#pragma once
/// \file mesh_stats.h
/// Cheap measures on plain meshes: bounds, principal axes, area, signed volume, Euler
/// characteristic.

#include "geometry/mesh.h"

#include <limits>

namespace fascicle {

/// Axis-aligned bounding box. Empty input gives min = +inf, max = -inf.
struct BoundingBox {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 max = Vec3::Constant(-std::numeric_limits<double>::infinity());
  /// Length of the diagonal (0 for an empty or single-point box).
  double diagonal() const;
  Vec3 center() const { return 0.5 * (min + max); }
};

/// Bounding box of the points, in their units.
BoundingBox bounding_box(const std::vector<Vec3>& points);

/// Principal axes of a point set: its mean and the eigenvectors of its scatter matrix
/// sum_i (p_i - mean)(p_i - mean)^T.
struct PrincipalAxes {
  Vec3 mean = Vec3::Zero();  ///< centroid of the points (0 for no point)
  /// Unit eigenvectors as columns, by increasing variance: col(2) is the major (longest) axis,
  /// col(0) the minor one. Each column's sign is arbitrary (callers that need a direction choose
  /// it). Identity for no point.
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  /// Variance of the points along each column of `axes` (eigenvalues of the scatter matrix
  /// divided by the point count), increasing; units squared.
  Vec3 variances = Vec3::Zero();
  /// The major axis, axes.col(2).
  Vec3 major() const { return axes.col(2); }
};

/// Principal axes of `points` (Eigen's self-adjoint eigen solver on the 3x3 scatter matrix;
/// O(n), no CGAL). Empty input gives the defaults of PrincipalAxes.
PrincipalAxes principal_axes(const std::vector<Vec3>& points);

/// Total area of the triangles, units squared.
double surface_area(const TriangleMesh& mesh);

/// Signed volume enclosed by the triangles (divergence theorem), units cubed. Positive for a
/// closed mesh with outward (counter-clockwise) orientation; meaningless for an open mesh.
double signed_volume(const TriangleMesh& mesh);

/// Euler characteristic V - E + F counting only vertices referenced by a triangle.
long euler_characteristic(const TriangleMesh& mesh);

}  // namespace fascicle
