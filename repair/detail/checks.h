#pragma once
// Private: checks shared by the repair pipeline's translation units. Plain data in and out;
// the CGAL types stay inside mesh_checks.cpp.

#include "geometry/mesh.h"
#include "repair/repair.h"

#include <cstdint>

namespace fascicle::detail {

/// Census of a triangle soup or mesh (counts only referenced vertices). Self-intersections are
/// pairs of triangles that meet anywhere but in their common corners or edge (exact predicates);
/// with `count_intersections` false (a mesh already verified) they are set to 0 uncounted.
MeshCensus census_of_triangles(const TriangleMesh& mesh, bool count_intersections = true);

/// Two-sided approximate Hausdorff distance (absolute units): the larger of the two one-sided
/// distances, each the maximum over all vertices and `samples` area-weighted random points of
/// one mesh of the distance to the other (CGAL AABB tree). Seeded, so reproducible.
double hausdorff_distance(const TriangleMesh& a, const TriangleMesh& b, int samples, std::uint64_t seed = 1);

/// One-sided version: the largest distance from a sample point of `from` (vertices and
/// `samples` area-weighted points) to the surface `to`, absolute units.
double one_sided_distance(const TriangleMesh& from, const TriangleMesh& to, int samples, std::uint64_t seed = 1);

}  // namespace fascicle::detail
