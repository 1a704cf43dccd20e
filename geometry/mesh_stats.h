#pragma once
/// \file mesh_stats.h
/// Cheap measures on plain meshes: bounds, area, signed volume, Euler characteristic.

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

/// Total area of the triangles, units squared.
double surface_area(const TriangleMesh& mesh);

/// Signed volume enclosed by the triangles (divergence theorem), units cubed. Positive for a
/// closed mesh with outward (counter-clockwise) orientation; meaningless for an open mesh.
double signed_volume(const TriangleMesh& mesh);

/// Euler characteristic V - E + F counting only vertices referenced by a triangle.
long euler_characteristic(const TriangleMesh& mesh);

}  // namespace fascicle
