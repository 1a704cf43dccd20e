#pragma once
/// \file sphere_locator.h
/// Point location in a sphere map (pipeline step 5 of ../shared/docs/METHOD.md): which spherical
/// triangle holds a direction, with which barycentric coordinates, and where that is on the
/// muscle. The thesis tested every triangle (O(N T)). Here a query walks from a start face stored
/// per cube-map cell across the edges whose plane through the centre has the point on its
/// negative side (a visibility walk with exact orientation predicates, a few steps); an empty
/// cell starts where a walk from a neighbouring cell reaches its centre. A CGAL AABB tree over the
/// chord triangles, queried with the ray from the centre, resolves points exactly on edges and
/// vertices and is the fallback should a walk not finish; it is built on first use.

#include "geometry/mesh.h"
#include "morph/surface_query.h"

#include <memory>
#include <vector>

namespace fascicle {

/// Locates directions in a bijective sphere map. Build once, query many times (thread-safe).
class SphereLocator {
 public:
  /// `sphere`: #V unit vectors; `triangles`: #F triangles indexing them, positively oriented
  /// (a bijective map from map_to_sphere). Both are copied. Throws TopologyError when empty.
  SphereLocator(const std::vector<Vec3>& sphere, const std::vector<Triangle>& triangles);
  ~SphereLocator();
  SphereLocator(const SphereLocator&) = delete;
  SphereLocator& operator=(const SphereLocator&) = delete;

  /// The spherical triangle holding direction `p` (any non-zero vector; only its direction
  /// counts): face index and barycentric coordinates of the point where the ray from the centre
  /// through p meets the face's chord triangle (non-negative, sum 1; `position` is that point).
  /// Containment is decided exactly: (a x b).p >= 0, (b x c).p >= 0, (c x a).p >= 0 (thesis
  /// test 2.3) with CGAL's exact orientation predicate. A direction on an edge or a vertex lies
  /// in several faces; the one with the smallest index is returned, so the answer does not depend
  /// on the tree's traversal order. Throws std::invalid_argument for a zero or non-finite p.
  SurfacePoint locate(const Vec3& p) const;

  /// locate() for many directions, in parallel (TBB).
  std::vector<SurfacePoint> locate_all(const std::vector<Vec3>& directions) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The point of `mesh` with the same face and barycentric coordinates as `located`
/// (sphere -> muscle).
Vec3 point_on_mesh(const TriangleMesh& mesh, const SurfacePoint& located);

/// The sphere point of a surface point (muscle -> sphere): the normalised barycentric
/// combination of the face's sphere corners; exact inverse of SphereLocator::locate.
Vec3 point_on_sphere(const std::vector<Vec3>& sphere, const std::vector<Triangle>& triangles,
                     const SurfacePoint& surface_point);

}  // namespace fascicle
