#pragma once
/// \file primitives.h
/// Small closed test meshes built in code: the shapes every module's tests start from.
///
/// Every TriangleMesh returned here is closed (each edge shared by exactly two triangles),
/// consistently oriented counter-clockwise seen from outside (positive signed volume), free of
/// duplicate points and degenerate triangles. Units are whatever the caller passes (tests use
/// millimetres). Genus is 0 except for the torus (genus 1). The one deliberately broken shape,
/// two tetrahedra sharing a vertex, is returned as a PolygonSoup.

#include "geometry/mesh.h"

#include <vector>

namespace fascicle {

/// Corner tetrahedron with vertices (0,0,0), (s,0,0), (0,s,0), (0,0,s), s = `size`.
/// 4 vertices, 4 triangles, volume s^3/6. Throws OptionError when size <= 0 or is not finite.
TriangleMesh make_tetrahedron(double size = 1.0);

/// Axis-aligned cube of edge `size` centred at the origin, each face an n x n grid of squares
/// split into two triangles (n = `per_edge`). 6n^2 + 2 vertices, 12n^2 triangles, volume size^3
/// exactly. Throws OptionError when size <= 0 or per_edge < 1 or per_edge > 4096.
TriangleMesh make_cube(double size = 1.0, int per_edge = 1);

/// Sphere of `radius` centred at the origin: the regular icosahedron subdivided `subdivisions`
/// times (each triangle split into four at its edge midpoints, new points projected on the sphere).
/// 10*4^k + 2 vertices, 20*4^k triangles; all vertices lie on the sphere, so the volume is slightly
/// below 4/3 pi r^3 (within 1% for k >= 3). Throws OptionError when radius <= 0 or k not in [0, 8].
TriangleMesh make_icosphere(int subdivisions, double radius = 1.0);

/// Capsule (a cylinder with hemispherical ends) along the x axis, centred at the origin.
/// `length` is tip to tip (>= 2 radius), `radius` of the cylinder; `segments` points per ring.
/// Each hemisphere has max(2, segments/4) rings; the cylinder gets rings spaced about one ring
/// edge length apart, so long thin capsules (aspect 50:1) keep near-square quads. No texture
/// coordinates. Volume tends to pi r^2 (L - 2r) + 4/3 pi r^3 from below as segments grows.
/// Throws OptionError when radius <= 0, length < 2 radius, segments < 3, or the ring count
/// would exceed 1e6.
TriangleMesh make_capsule(double length, double radius, int segments = 24);

/// A tube of radius `tube_radius` whose axis is a circular arc of radius `bend_radius` in the xy
/// plane (centre at the origin) from angle 0 to `angle` radians, closed at both ends by flat
/// caps (a fan to the cap centre). Genus 0. `segments` points per ring; `rings` rings along the
/// arc (0: about one ring edge length apart, at least 2). Volume tends to pi r^2 R angle (Pappus).
/// Throws OptionError unless 0 < tube_radius < bend_radius, 0 < angle < 2 pi, segments >= 3,
/// rings >= 0 (and not above 1e6).
TriangleMesh make_bent_tube(double bend_radius, double tube_radius, double angle, int segments = 24, int rings = 0);

/// Torus around the z axis: centre circle radius `major_radius`, tube radius `minor_radius`,
/// `major_segments` x `minor_segments` quads split in two. Genus 1 (Euler characteristic 0), for
/// negative tests of stages that need genus 0. Volume tends to 2 pi^2 R r^2.
/// Throws OptionError unless 0 < minor_radius < major_radius and both segment counts >= 3.
TriangleMesh make_torus(double major_radius, double minor_radius, int major_segments = 48, int minor_segments = 24);

/// Two unit corner tetrahedra that touch at the origin only (the second is the first mirrored
/// through the origin): 7 points, 8 triangles, each tetrahedron outward. Vertex 0 is a
/// non-manifold vertex (its faces form two fans); every edge is shared by exactly two faces.
PolygonSoup make_two_tetrahedra_sharing_vertex();

/// Closes a sequence of rings into one genus-0 mesh: `rings` is a list of R >= 1 rings of the same
/// M >= 3 points each (ring i point j); consecutive rings are joined by quads split into two
/// triangles, and the first and last rings are joined by fans to `first_pole` and `last_pole`.
/// Vertex order: first_pole, ring 0, ring 1, ..., last_pole. The triangle orientation is chosen so
/// that the signed volume is positive (outward), whichever way the rings wind.
/// Used by the capsule, bent tube and the sample muscle. The caller keeps the rings from crossing.
/// Throws OptionError when rings is empty, a ring has fewer than 3 points or sizes differ.
TriangleMesh make_closed_tube(const std::vector<std::vector<Vec3>>& rings, const Vec3& first_pole,
                              const Vec3& last_pole);

}  // namespace fascicle
