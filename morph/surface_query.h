#pragma once
/// \file surface_query.h
/// Queries on a closed muscle surface: closest surface point (face + barycentric coordinates)
/// and the exact inside test. CGAL AABB tree and Side_of_triangle_mesh behind a plain interface.

#include "geometry/mesh.h"

#include <memory>

namespace fascicle {

/// A point on a triangle mesh: face index, barycentric coordinates (non-negative, sum 1) with
/// respect to the face's corners in order, the position they give, and (for closest-point
/// queries) the distance from the query, in the mesh's units.
struct SurfacePoint {
  int face = -1;
  Vec3 barycentric = Vec3::Zero();
  Vec3 position = Vec3::Zero();
  double distance = 0.0;
};

/// Where a point lies with respect to a closed surface.
enum class Side { inside, boundary, outside };

/// Point queries on one triangle mesh. Build once (an AABB tree over the triangles, and for the
/// inside test CGAL::Side_of_triangle_mesh, which counts ray crossings with exact predicates),
/// then query many times. closest_point may be called from several threads; side() builds its
/// tree on first use and is not meant for concurrent first calls.
class SurfaceQuery {
 public:
  /// Builds the trees. `mesh` must outlive nothing: its data are copied. Throws TopologyError
  /// when the mesh has no triangles.
  explicit SurfaceQuery(const TriangleMesh& mesh);
  ~SurfaceQuery();
  SurfaceQuery(const SurfaceQuery&) = delete;
  SurfaceQuery& operator=(const SurfaceQuery&) = delete;

  /// Closest point of the surface to `p` (mesh units): face, barycentric coordinates, position,
  /// distance.
  SurfacePoint closest_point(const Vec3& p) const;

  /// Exact side of `p` with respect to the closed surface (precondition: the mesh is closed;
  /// on an open mesh the answer is meaningless).
  Side side(const Vec3& p) const;

  /// side(p) == Side::inside.
  bool inside(const Vec3& p) const { return side(p) == Side::inside; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Barycentric coordinates of `p` with respect to the triangle (a, b, c), computed on the
/// triangle's plane (p is projected first), clamped to the triangle and renormalised.
Vec3 triangle_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace fascicle
