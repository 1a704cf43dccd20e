#pragma once
/// \file inject_defects.h
/// Puts known defects into good meshes, reproducibly, so that repair and every later stage can be
/// tested against each failure a real segmentation shows (the approach of Manifold's tests: one
/// test per error status that corrupts a good mesh).
///
/// Randomness: std::mt19937_64 seeded with the caller's seed, mapped to integers and doubles by
/// our own arithmetic (not std::uniform_*_distribution, whose output differs between standard
/// libraries), and no iteration over hash containers, so a seed gives the same soup bit for bit
/// with any standard library on the same platform.
///
/// Geometry helpers stay plain (no CGAL): adjacency is by shared point indices, so after
/// duplicate_vertices the copies count as different vertices, as they would for a reader.

#include "geometry/mesh.h"

#include <cstdint>
#include <string>
#include <vector>

namespace fascicle {

/// Every defect the injector can make. The order is the order inject_random_combination applies
/// them in: topology changes first, then vertex copies, then coordinate changes.
enum class DefectKind {
  holes,                    ///< remove connected patches of faces -> boundary loops
  flipped_patch,            ///< reverse the orientation of a connected patch
  pinched_vertex,           ///< glue two vertices across a thin part at their midpoint -> a vertex with two face fans
  non_manifold_edge,        ///< a fin triangle on an existing edge -> an edge with three faces
  handle,                   ///< a straight tunnel through the body between two vertex stars -> genus + 1
  self_intersection_fold,   ///< push one vertex through the opposite side -> intersecting faces
  stray_component,          ///< a small closed sphere outside the mesh
  inner_shell,              ///< a small closed outward sphere inside the mesh
  outer_shell,              ///< a closed outward sphere enclosing the whole mesh
  slivers,                  ///< split triangles into needle and cap slivers (same surface, closed)
  zero_area_faces,          ///< split triangles so one part is collinear (zero area, still closed)
  duplicate_vertices,       ///< exact copies of vertices, re-referenced by some of their faces
  near_duplicate_vertices,  ///< copies moved by near_distance * diagonal, re-referenced likewise
  scale,                    ///< multiply every coordinate by scale_factor (unit mistakes)
  offset,                   ///< translate every point by `offset` (CT scanner coordinates)
  nan_coordinates,          ///< set coordinates to NaN (for reader/writer tests; readers reject these)
};

/// Stable snake_case name of a kind, as in the enum ("pinched_vertex"); used on the command line
/// and in reports.
const char* defect_name(DefectKind kind);

/// Kind for a name from defect_name(). Throws OptionError listing the valid names otherwise.
DefectKind defect_kind_from_name(const std::string& name);

/// Every kind, in enum order.
std::vector<DefectKind> all_defect_kinds();

/// How much of a defect to make. Fields a kind does not use are ignored.
struct DefectParams {
  int count = 1;           ///< instances: holes, patches, pinches, fins, handles, folds, shells, NaN coordinates
  int patch_faces = 12;    ///< faces per patch for holes and flipped_patch (capped at a quarter of the faces)
  double fraction = 0.02;  ///< share of vertices (duplicates) or triangles (slivers, zero-area) affected; at least one
  double near_distance = 1e-7;        ///< near-duplicate displacement as a fraction of the bounding-box diagonal
  double scale_factor = 1e-3;         ///< factor for `scale` (1e-3: millimetres read as metres)
  Vec3 offset = Vec3::Constant(1e7);  ///< translation for `offset`, file units

  /// Throws OptionError naming the field: count in [1, 1e6], patch_faces in [1, 1e7],
  /// fraction in (0, 1], near_distance in (0, 1e-2], scale_factor finite and > 0, offset finite.
  void validate() const;
};

/// One applied defect: its kind, how many instances (holes, vertices copied, triangles split...)
/// and a one-line human note with the details (face counts, vertex indices, distances).
struct DefectRecord {
  DefectKind kind;
  int count = 0;
  std::string note;
};

/// What an injection did, in order.
struct DefectLog {
  std::vector<DefectRecord> records;
};

/// Applies `params.count` (or `fraction`) instances of one defect kind to a copy of `mesh` and
/// returns the result. `seed` fixes every random choice. Points left unreferenced by removed faces
/// are dropped (indices compacted), except by duplicate kinds, which keep every original point.
/// The input is not required to be clean, but patch, star and ray based kinds look for places
/// where the surface is locally a disc: each edge in two faces, consistently oriented.
/// Appends one record to `log` (may be null).
/// Throws OptionError from params.validate(), TopologyError when the mesh has no place for the
/// defect (no faces, too few faces, no vertex with a disc-shaped star, no interior for an inner
/// shell).
PolygonSoup inject(const PolygonSoup& mesh, DefectKind kind, std::uint64_t seed, const DefectParams& params = {},
                   DefectLog* log = nullptr);

/// Same as above for a triangle mesh (converted with to_soup first).
PolygonSoup inject(const TriangleMesh& mesh, DefectKind kind, std::uint64_t seed, const DefectParams& params = {},
                   DefectLog* log = nullptr);

/// Injects `count` distinct kinds drawn by `seed` from all kinds except nan_coordinates, applied in
/// enum order with default params, each from derive_seed(seed, 1 + its position). count in [0, 15];
/// throws OptionError otherwise, and whatever inject throws.
PolygonSoup inject_random_combination(const PolygonSoup& mesh, std::uint64_t seed, int count, DefectLog* log = nullptr);

/// Same as above for a triangle mesh (converted with to_soup first).
PolygonSoup inject_random_combination(const TriangleMesh& mesh, std::uint64_t seed, int count,
                                      DefectLog* log = nullptr);

/// An independent seed for sub-step `step` of a run seeded with `seed` (SplitMix64 of both), so
/// that chained injections do not share random streams.
std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t step);

/// Converts a soup whose polygons are all triangles back to a TriangleMesh (same points, same
/// order). Throws TopologyError naming the first polygon that is not a triangle.
TriangleMesh soup_triangles(const PolygonSoup& soup);

}  // namespace fascicle
