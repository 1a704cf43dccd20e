#pragma once
/// \file surface_query.h
/// Queries on a closed muscle surface: closest surface point (face + barycentric coordinates),
/// the exact inside test and the first hit of a ray. CGAL AABB tree and Side_of_triangle_mesh
/// behind a plain interface.

#include "geometry/mesh.h"

#include <memory>

namespace fascicle {

class InsideGrid;

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

/// Point queries on one triangle mesh. Build once (an AABB tree over the triangles, a bounding
/// volume hierarchy for rays, and for the inside test CGAL::Side_of_triangle_mesh, which counts
/// ray crossings with exact predicates), then query many times. closest_point and first_hit may
/// be called from several threads, and so may side(), which builds its tree and grid on first
/// use (once, whichever thread calls first).
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

  /// closest_point of every point, for many points at once (threads): the points are visited in
  /// the order of a space-filling curve, and each query starts from the previous one's closest
  /// point (a tight first bound, no search for a start). The closest point is the same as
  /// closest_point's wherever one triangle is closest; where several are equally close (a point
  /// nearest to an edge or a vertex), either may be returned, the position then differing only
  /// by rounding.
  std::vector<SurfacePoint> closest_points(const std::vector<Vec3>& points) const;

  /// Exact side of `p` with respect to the closed surface (precondition: the mesh is closed;
  /// on an open mesh the answer is meaningless). The inside grid (inside_grid()) answers for
  /// points away from the surface; the others get exact_side().
  Side side(const Vec3& p) const;

  /// The exact test alone, without the grid (the same answer as side()).
  Side exact_side(const Vec3& p) const;

  /// The classified grid side() consults (built with the exact test on first use of either).
  const InsideGrid& inside_grid() const;

  /// First hit of the ray p + t d (t > 0; d need not be unit) with the surface, among the
  /// triangles whose box meets the box of the segment t in [0, reach] (so only hits with
  /// t < reach): Moeller-Trumbore on each (ray_triangle_hit()), the triangles found through a
  /// bounding-volume hierarchy; the hit position into `hit`; false (hit untouched) when none.
  /// The same answer, to the bit, as that test on every triangle in turn.
  bool first_hit(const Vec3& p, const Vec3& d, double reach, Vec3& hit) const;

  /// side(p) == Side::inside.
  bool inside(const Vec3& p) const { return side(p) == Side::inside; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Moeller-Trumbore test of the ray p + t d against the triangle (a, b, c): its parameter t
/// (any sign) into `t`, false when the ray misses it (or is parallel to it, |det| < 1e-300).
bool ray_triangle_hit(const Vec3& p, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c, double& t);

/// Barycentric coordinates of `p` with respect to the triangle (a, b, c), computed on the
/// triangle's plane (p is projected first), clamped to the triangle and renormalised.
Vec3 triangle_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace fascicle
