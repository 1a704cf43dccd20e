#pragma once
/// \file repair.h
/// The repair stage: any polygon soup in, one closed, outward-oriented, self-intersection-free,
/// genus-0 triangle mesh out (or a clear refusal). A staged pipeline on CGAL Polygon Mesh
/// Processing (CGAL 5.5); each step reports how many elements it changed:
///
///  1. weld duplicate and near-duplicate vertices (tolerance relative to the bounding-box
///     diagonal), triangulate polygons, drop degenerate and duplicate faces;
///  2. orient the soup (PMP::orient_polygon_soup) and build the mesh, splitting non-manifold
///     vertices and edges;
///  3. stitch borders, keep the largest connected component (or all, see options);
///  4. remove geometrically degenerate faces, fill holes with refined, faired patches;
///  5. remove self-intersections; orient outward;
///  6. verify: one component, closed, 2-manifold, no self-intersection, Euler characteristic 2,
///     positive volume.
/// Where local repair cannot reach that (handles, overlapping shells, a mesh in pieces), the
/// fallback is CGAL 3D Alpha Wrapping with alpha and offset relative to the mesh size, coarsened
/// until the wrap is genus 0; the report says why it was used.
///
/// Only this module includes CGAL headers; its interface is plain data (geometry/mesh.h).

#include "geometry/mesh.h"

#include <nlohmann/json_fwd.hpp>

#include <optional>
#include <string>
#include <vector>

namespace fascicle {

/// What to do with several connected components.
enum class ComponentPolicy {
  largest,  ///< keep the largest (by volume when closed, else area); the rest are dropped
  merge,    ///< keep everything: wrap all pieces into one surface (alpha wrap)
};

/// Options of the repair stage. Every length is relative to the input's bounding-box diagonal.
struct RepairOptions {
  /// Vertices closer than this (relative to the diagonal) are welded. Default 1e-6: merges
  /// exporter round-off, never distinct vertices of a real scan (spacing ~1e-3 of the diagonal).
  double weld_tolerance = 1e-6;
  /// Component policy (default: keep the largest).
  ComponentPolicy components = ComponentPolicy::largest;
  /// Keep-largest is faithful only when the largest component holds at least this share of the
  /// total area (default 0.75); below it the mesh is in pieces and is wrapped instead.
  double min_largest_share = 0.75;
  /// Self-intersections are smoothed apart only if no vertex moves farther than this share of the
  /// diagonal (default 0.01); otherwise the region is cut out and refilled.
  double untangle_limit = 0.01;
  /// Fill holes with refined and faired patches (default true; false: plain triangulation).
  bool fair_holes = true;
  /// Allow the alpha-wrap fallback (default true; false: a mesh local repair cannot fix is refused).
  bool allow_wrap = true;
  /// Finest wrap alpha, share of the diagonal (default 1/100); wraps run coarse to fine (finest x 2^k),
  /// the finest genus-0 one kept, coarser alphas up to half the diagonal tried if none is.
  double wrap_alpha = 0.01;
  /// Wrap offset as a fraction of alpha (default 1/30).
  double wrap_offset_ratio = 1.0 / 30.0;
  /// Largest distance of a wrap from the input, share of the diagonal (default 0.02: a coarse wrap
  /// that bridges a real hole or handle is not a repair; a faithful one lies about alpha / 30 away).
  /// The same limit holds the refill of self-intersecting regions: a refill the surface before it
  /// lies farther from than this has replaced the surface, and the mesh is wrapped instead.
  double wrap_max_distance = 0.02;
  /// Alpha levels from coarse to fine (default 5: 16, 8, 4, 2 and 1 times wrap_alpha).
  int wrap_levels = 5;
  /// Largest wrap output accepted, faces; a finer wrap estimated above it is skipped (default 500 000).
  long max_wrap_faces = 500'000;
  /// Time budget of all wrap attempts, seconds (default 40); each runs in a child process stopped
  /// when the budget is spent, and the finest genus-0 wrap found by then is kept.
  double wrap_seconds = 40.0;
  // The program that runs each wrap attempt (`fascicle-wrap-worker`) is found as
  // detail::find_wrap_worker describes: the environment variable FASCICLE_WRAP_WORKER, else beside
  // the running program, else in the build folder; a wrap with no worker is InputError(file_missing).
  /// Address-space limit of the wrap worker, MiB (default 0: only the process's own limits); a wrap
  /// that needs more ends the repair with ErrorCode::repair_failed.
  long wrap_memory_mb = 0;
  /// Sample points per side for the two-sided Hausdorff estimate (default 20000).
  int hausdorff_samples = 20000;

  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// Topological and geometric census of a mesh or soup. Soups are counted after exact
/// duplicate points are merged (an STL file stores each triangle's corners separately).
struct MeshCensus {
  long vertices = 0;               ///< referenced vertices
  long faces = 0;                  ///< faces (polygons)
  long components = 0;             ///< connected components (through shared vertices)
  long boundary_edges = 0;         ///< edges with one incident face
  long non_manifold_edges = 0;     ///< edges with more than two incident faces
  long non_manifold_vertices = 0;  ///< vertices whose faces do not form one fan (closed mesh only)
  std::optional<long> genus;       ///< (2C - chi) / 2 when closed and manifold, else unknown
  long euler = 0;                  ///< V - E + F
  long self_intersections = 0;     ///< intersecting pairs of non-adjacent triangles
  double volume = 0.0;             ///< signed volume (meaningful when closed)
  double area = 0.0;               ///< total area
};

/// One pipeline step's effect.
struct RepairStep {
  std::string name;  ///< e.g. "weld_vertices"
  long changed = 0;  ///< elements changed (merged, removed, added, flipped...)
  double seconds = 0.0;
  std::string note;  ///< optional detail
};

/// What the repair did; `to_json` gives the report file's content.
struct RepairReport {
  std::string status;  ///< "repaired", "unchanged" (already valid) or "failed"
  MeshCensus input, output;
  std::vector<RepairStep> steps;
  bool fallback_used = false;                  ///< the alpha-wrap fallback produced the output
  std::string fallback_reason;                 ///< why local repair was not enough
  double wrap_alpha = 0.0, wrap_offset = 0.0;  ///< absolute, when wrapped
  std::string wrap_worker;                     ///< the alpha-wrap worker program that ran, when wrapped
  /// Two-sided approximate Hausdorff distance between the output and the input faces it stands
  /// for (the input less the faces dropped with smaller components), relative to the input's
  /// bounding-box diagonal. With the wrap fallback: the whole input.
  double hausdorff = 0.0;
  /// The same against the whole input, dropped components included.
  double hausdorff_whole_input = 0.0;
  double kept_area_share = 1.0;  ///< area of the output / area of the input
  double seconds = 0.0;
  nlohmann::json to_json() const;
};

/// A repaired mesh with its report.
struct RepairResult {
  TriangleMesh mesh;
  RepairReport report;
};

/// Repairs a soup into a closed, outward-oriented, self-intersection-free genus-0 manifold.
/// The result always passes `verify_genus0` (on success).
/// Throws TopologyError(repair_failed) when no option reaches genus 0 (the message says which
/// check failed), OptionError for bad options, InputError(file_empty) for an empty soup.
RepairResult repair_mesh(const PolygonSoup& soup, const RepairOptions& options = {});

/// Census of a soup (counts after exact duplicate points are merged).
MeshCensus census_of(const PolygonSoup& soup);

/// Checks the guarantee the repair stage gives: one component, closed, 2-manifold, no
/// self-intersection, Euler characteristic 2, positive volume. Returns an empty string when the
/// mesh passes, else the first failed check in words.
std::string verify_genus0(const TriangleMesh& mesh);

}  // namespace fascicle
