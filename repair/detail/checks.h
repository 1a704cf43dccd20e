#pragma once
// Private: checks shared by the repair pipeline's translation units. Plain data in and out;
// the CGAL types stay inside mesh_checks.cpp.

#include "geometry/mesh.h"
#include "repair/repair.h"

#include <array>
#include <cstdint>
#include <string>

namespace fascicle::detail {

/// Census of a triangle soup or mesh (counts only referenced vertices). Self-intersections are
/// pairs of triangles that meet anywhere but in their common corners or edge (exact predicates);
/// with `count_intersections` false (a mesh already verified) they are set to 0 uncounted.
MeshCensus census_of_triangles(const TriangleMesh& mesh, bool count_intersections = true);

/// Two-sided approximate Hausdorff distance (absolute units): the larger of the two one-sided
/// distances, each the maximum over all vertices and `samples` area-weighted random points of
/// one mesh of the distance to the other (CGAL AABB tree). Seeded, so reproducible.
double hausdorff_distance(const TriangleMesh& a, const TriangleMesh& b, int samples, std::uint64_t seed = 1);

/// verify_genus0() with the self-intersection test left out when `test_intersections` is false:
/// for a mesh whose faces were already tested by the caller and not moved since.
std::string verify_genus0(const TriangleMesh& mesh, bool test_intersections);

/// Whether a triangle soup already is what orienting it would make: every face with three
/// distinct corners, every edge in at most two faces, those two running it in opposite
/// directions, and the faces round each vertex one fan (the soup builds a halfedge mesh as it is).
bool is_oriented_manifold_soup(const TriangleMesh& soup);

/// A face's key: its three corner coordinates, sorted, as bytes (the same for either orientation).
std::string face_key(std::array<Vec3, 3> corners);

/// Whether `a` and `b` hold the same faces (each face's three corner coordinates, in any order
/// and orientation): then their Hausdorff distance is exactly 0 and need not be sampled.
bool same_faces(const TriangleMesh& a, const TriangleMesh& b);

/// One-sided version: the largest distance from a sample point of `from` (vertices and
/// `samples` area-weighted points) to the surface `to`, absolute units.
double one_sided_distance(const TriangleMesh& from, const TriangleMesh& to, int samples, std::uint64_t seed = 1);

}  // namespace fascicle::detail
