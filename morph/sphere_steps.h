#pragma once
/// \file sphere_steps.h
/// Internal steps of the sphere map (morph/ only; not part of the public interface).

#include "geometry/mesh.h"
#include "morph/mesh_adjacency.h"
#include "morph/sphere_map.h"

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace fascicle::detail {

/// det(a, b, c) = (a x b) . c written as ((b - a) x (c - a)) . a, which keeps its relative
/// accuracy for tiny triangles (the differences are exact when the points are close).
inline double sphere_det(const Vec3& a, const Vec3& b, const Vec3& c) { return (b - a).cross(c - a).dot(a); }

/// Signed area of the geodesic triangle (a, b, c) on the unit sphere (Van Oosterom and
/// Strackee 1983): 2 atan2(det, 1 + a.b + b.c + c.a). Negative when the triangle is flipped.
inline double sphere_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  return 2.0 * std::atan2(sphere_det(a, b, c), 1.0 + a.dot(b) + b.dot(c) + c.dot(a));
}

/// Smallest det a relaxation step may leave on a triangle: 4 x degenerate_area (det is about
/// twice the area for small triangles), so every accepted state counts no degenerate triangle.
constexpr double min_step_det = 4.0 * degenerate_area;

/// Surface area share of every triangle (area / total), faces of zero area get 1e-12 of the mean
/// so ratios stay finite.
std::vector<double> area_shares(const TriangleMesh& mesh);

/// Graph distances along edges (mesh units) from `source` by Dijkstra; `previous`, when given,
/// receives each vertex's predecessor on a shortest path (-1 for the source).
std::vector<double> edge_distances(const TriangleMesh& mesh, const MeshAdjacency& adjacency, int source,
                                   std::vector<int>* previous = nullptr);

/// Elongation of a closed mesh: (end-to-end edge distance)^2 / area, about length over
/// circumference for a tube (0.8 for a sphere, 16 for a 50:1 capsule). `ends` receives the far
/// pair of a double Dijkstra sweep.
double elongation(const TriangleMesh& mesh, const MeshAdjacency& adjacency, std::array<int, 2>& ends);

/// Result of the Tutte embedding and stereographic lift.
struct TutteLift {
  std::vector<Vec3> sphere;  ///< #V unit vectors
  int cut_face = -1;
  double margin = 0.0;  ///< power ratio (> 1: every geodesic triangle keeps its orientation)
  std::string kind;     ///< "stereographic" or "tube"
};

/// Tutte embedding of the mesh minus one triangle into an equilateral triangle, lifted to the
/// sphere by inverse stereographic projection (see sphere_map.h). Throws SolverError when the
/// factorisation fails.
TutteLift tutte_lift(const TriangleMesh& mesh, const MeshAdjacency& adjacency, bool anisotropic);

/// Tube map for long shapes: the mesh is cut along a shortest path between its two ends, the
/// disk embedded by Tutte's method into a convex hexagon whose two long sides are the two banks of
/// the cut (placed by arc length), and the hexagon carried to the sphere (TubeFold). The banks
/// both become the date line. Triangles near the poles (where the hexagon's apex angle is opened
/// to a full turn) may come out flipped; the caller checks, untangles, tries the other fold. Built once (cut, weights, symbolic
/// factorisation); lift() solves again for new weight factors.
/// How the tube map's hexagon is carried to the sphere.
enum class TubeFold {
  prism,    ///< folded onto a capped prism and projected centrally (keeps orientation per piece)
  lambert,  ///< Lambert cylindrical equal-area (longitude x, z linear in y)
};

class TubeEmbedder {
 public:
  TubeEmbedder(const TriangleMesh& mesh, const MeshAdjacency& adjacency, const std::array<int, 2>& ends);
  ~TubeEmbedder();
  /// False when the ends are adjacent (no tube to cut).
  bool valid() const;
  /// Planar positions (hexagon) of the cut mesh's vertices (#V originals, then the copies).
  /// `face_scale` (optional, #F positive factors) multiplies each edge's weight by the geometric
  /// mean of its two faces' factors: the reweighting rounds use it to let crowded regions grow.
  /// Throws SolverError when the factorisation fails.
  std::vector<Eigen::Vector2d> solve(const std::vector<double>* face_scale = nullptr);
  /// Mean |log(planar area share / surface share)| of a solve; `ratio` receives each face's.
  double planar_log_ratio(const std::vector<Eigen::Vector2d>& uv, const std::vector<double>& shares,
                          std::vector<double>& ratio) const;
  /// The sphere positions of a solve.
  TutteLift lift(const std::vector<Eigen::Vector2d>& uv, TubeFold fold) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Local untangling: every vertex of a flipped or degenerate triangle is moved to the normalised
/// centroid of its neighbours when that raises the smallest det of its triangles; up to
/// `max_sweeps` sweeps. Returns the number of non-positive triangles left.
long untangle(const TriangleMesh& mesh, const MeshAdjacency& adjacency, std::vector<Vec3>& sphere, int max_sweeps);

/// Re-embeds each cluster of flipped or degenerate triangles: the cluster grown by 1..max_rings
/// rings is mapped to the gnomonic chart at its centre (great circles are straight lines there,
/// so planar and geodesic orientation agree), its inner vertices are placed by a Tutte solve
/// with the region's outer vertices fixed, and the result is kept when every touched triangle is
/// valid. Returns the number of bad triangles left.
long reembed_patches(const TriangleMesh& mesh, const MeshAdjacency& adjacency, std::vector<Vec3>& sphere,
                     int max_rings);

/// Half-edge collapses that take a closed genus-0 mesh down to a tetrahedron, in order. Collapse
/// i removes vertex removed[i] into kept[i] (which stays where it is), deletes the two faces
/// dead[i] of the edge, and rewrites the removed corner of faces moved[moved_start[i] ..
/// moved_start[i+1]) to kept[i]. Face ids are the mesh's own.
struct CollapseSequence {
  std::vector<int> removed, kept;
  std::vector<std::array<int, 2>> dead;
  std::vector<int> moved_start, moved;  ///< CSR: faces that changed corner in each collapse
  /// Faces that take over the area of each collapse's dead faces: dead[i][k] gives half of its
  /// area to receivers[i][2k] (across its edge removed-o) and half to receivers[i][2k+1] (across kept-o).
  std::vector<std::array<int, 4>> receivers;
  std::array<int, 4> base{};        ///< the tetrahedron's vertices
  std::array<int, 4> base_faces{};  ///< and its faces
};

/// Simplifies `mesh` (closed, genus 0, checked by check_sphere_topology) by half-edge collapses,
/// shortest edge first, each kept only when the link condition holds (the edge's ends share
/// exactly the two opposite corners as neighbours), no vertex drops below valence 3, and the kept
/// vertex's valence stays <= max_valence (raised when no edge is left under it). Every
/// intermediate mesh is then a closed genus-0 manifold. Throws TopologyError when no edge can be
/// collapsed before the tetrahedron (not a sphere).
CollapseSequence collapse_to_tetrahedron(const TriangleMesh& mesh, const MeshAdjacency& adjacency, int max_valence);

/// The mesh after the first `collapses` collapses of `sequence`, compacted (removed vertices
/// dropped, indices renumbered): for checking that every level is a manifold.
TriangleMesh collapsed_mesh(const TriangleMesh& mesh, const CollapseSequence& sequence, std::size_t collapses);

/// Result of progressive_embedding.
struct ProgressiveResult {
  std::vector<Vec3> sphere;  ///< #V unit vectors
  long collapses = 0;        ///< vertex splits done (= #V - 4)
  long failed_splits = 0;    ///< splits whose new vertex found no valid place (0 unless precision ran out)
};

/// Progressive-mesh sphere embedding (Shapiro and Tal 1998; Praun and Hoppe 2003): collapse to a
/// tetrahedron (collapse_to_tetrahedron), place it regular on the sphere, split the vertices back
/// in reverse order, each new vertex a small step from the vertex it was collapsed into, inside
/// the wedge of the faces it takes over (step halved until every new triangle is robustly
/// positive), then `relax_rounds` rounds of flip-free local Newton moves of sum w_f^2 / det_f on
/// the new vertex, its partner and their ring (w_f: the surface area face f stands for at that
/// level, its own plus what the collapses' dead faces handed to it), and 4 x relax_rounds sweeps
/// over all vertices whenever the vertex count doubles, so that no triangle is crowded towards
/// degeneracy and areas are roughly balanced from the coarse levels on.
/// Every accepted state is a bijection (det is linear in the unnormalised point, so a move whose
/// end keeps every det positive keeps it positive all the way).
ProgressiveResult progressive_embedding(const TriangleMesh& mesh, const MeshAdjacency& adjacency, int max_valence,
                                        int relax_rounds);

/// Moebius centring: repeatedly applies the sphere automorphism that moves the area centroid
/// c = sum_t share_t * centroid_t towards the centre, x -> (1 - |c|^2)(x - c) / |x - c|^2 - c,
/// halving c whenever a triangle would degenerate or shrink by more than half of what a conformal
/// map with that centre can do, less 10 % (slivers bending over). Returns the number of steps taken;
/// `residual` receives the final |c|.
int mobius_center(const TriangleMesh& mesh, const std::vector<double>& shares, std::vector<Vec3>& sphere, int max_steps,
                  double tolerance, double& residual);

/// Flip-free area balancing (see sphere_map.h). Returns sweeps done; counts refused moves.
int balance_areas(const TriangleMesh& mesh, const MeshAdjacency& adjacency, const std::vector<double>& shares,
                  std::vector<Vec3>& sphere, int max_sweeps, double tolerance, int& rejected);

/// The thesis's method; fills the relax fields of `report` and returns the sphere positions.
std::vector<Vec3> thesis_relax(const TriangleMesh& mesh, const MeshAdjacency& adjacency,
                               const SphereMapOptions& options, SphereMapReport& report);

}  // namespace fascicle::detail
