#pragma once
/// \file sphere_map.h
/// Mapping a closed genus-0 muscle surface onto the unit sphere, one point per vertex, such that
/// the map is a bijection: every spherical triangle keeps the mesh's orientation,
/// det(v0, v1, v2) = (v0 x v1) . v2 > 0, none is degenerate, and together they cover the sphere
/// once (the spherical areas add up to 4 pi). Pipeline step 3 of ../shared/docs/METHOD.md.
///
/// Two methods, selectable so they can be compared on the same mesh:
///  - `tutte` (default): an initial bijective map, then flip-free area balancing. Starts:
///    * tube (long muscles, elongation > `tube_elongation`): the mesh cut along a shortest path
///      between its two far ends, the disk embedded by Tutte's method (Floater 2003, "One-to-one
///      piecewise linear mappings over triangulations": positive weights + convex boundary give a
///      one-to-one planar map) in a convex hexagon whose sides are the cut's two banks, the
///      hexagon folded onto a capped prism (each piece affinely) and projected centrally;
///      Lambert's cylindrical equal-area projection is the second fold. Orientation is kept
///      exactly inside each piece; triangles across a fold or near the poles may flip, and do
///      where flat planar slivers span much of the circumference next to an end: every lift
///      that bends planar lines into latitude circles turns them over;
///    * progressive (round muscles first, and the fallback of long ones): progressive-mesh
///      embedding (Shapiro and Tal 1998, "Polyhedron realization for shape transformation";
///      Praun and Hoppe 2003, "Spherical parametrization and remeshing"): half-edge collapses
///      that keep a closed genus-0 manifold down to a tetrahedron, then vertex splits in reverse
///      order, each new vertex placed inside the kernel of its ring and its neighbourhood relaxed
///      by flip-free moves towards the areas the faces stand for. Bijective by construction;
///    * stereographic (last resort, or forced): one triangle cut out, the disk Tutte-embedded in
///      an equilateral triangle, lifted by inverse stereographic projection with an origin and
///      scale that keep every geodesic triangle's orientation (a power-of-a-point condition,
///      checked), then Moebius-centred. Bijective in exact arithmetic, but a long shape crowds
///      towards its ends by exp(-2 pi length/circumference), beyond double precision.
///    Every Tutte start is checked, locally untangled (smoothing, then Tutte re-embedding of bad
///    clusters in a gnomonic chart) and the next start is tried while bad triangles remain. A tube
///    start is then re-embedded with edge weights scaled by the area ratios (each round again a
///    Tutte embedding), and the areas are balanced by a Gauss-Seidel Newton relaxation of
///    sum_t a_t^2 / det_t that refuses (halves) every step that would make a triangle flip or
///    degenerate. The report states which starts were tried and whether the result is a
///    bijection; `fascicle bench sphere` measures this on the corpus (docs/BENCHMARKS.md).
///  - `relax`: the thesis's method (Zeleny 2011, ch. 6.3, after Alexa 2000): Ritter bounding
///    sphere, centre moved inside by an exact inside test, projection by normalisation, random
///    tetrahedron anchors, centroid relaxation with renormalisation, collapse check, orientation
///    check. It may fail (flipped triangles); the report then says how.

#include "geometry/mesh.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace fascicle {

/// Sphere-map method.
enum class SphereMethod {
  tutte,  ///< Tutte embedding (stereographic or tube start) + flip-free relaxation (default)
  relax,  ///< the thesis's normalise-and-relax method (may fail)
};

/// Initial map of the `tutte` method.
enum class SphereStart {
  automatic,      ///< long shapes: tube, then progressive; round ones: progressive first (default)
  tube,           ///< only the tube map (prism fold, then Lambert fold)
  progressive,    ///< only the progressive-mesh start (collapse to a tetrahedron, split back)
  stereographic,  ///< only the stereographic Tutte lift
};

/// "tutte" or "relax".
const char* to_string(SphereMethod method);
/// "automatic", "tube", "progressive" or "stereographic".
const char* to_string(SphereStart start);
/// Parses the names of to_string(SphereStart); throws OptionError naming `--sphere-start` otherwise.
SphereStart sphere_start_from_string(const std::string& name);
/// Parses "tutte" / "relax"; throws OptionError naming `--sphere-method` otherwise.
SphereMethod sphere_method_from_string(const std::string& name);

/// Options of the sphere map.
struct SphereMapOptions {
  /// Method (default tutte).
  SphereMethod method = SphereMethod::tutte;

  // --- tutte ---
  /// Initial map (default automatic: elongated shapes try the tube map, then progressive; round ones
  /// progressive; stereographic last); the tube start with reweighting balances long muscles better.
  SphereStart start = SphereStart::automatic;
  /// Progressive start: largest valence a collapse may give the vertex it keeps, raised when no edge
  /// can collapse (default 12: low valences keep coarse levels free of fans of thin triangles).
  int progressive_max_valence = 12;
  /// Progressive start: flip-free relaxation rounds round each split, 4x as many global sweeps per
  /// doubling (default 2: balances areas much better than 0, which leaves vertices where split off).
  int progressive_relax_rounds = 2;
  /// Raise Tutte weights along the local long direction by k^2, k about length / circumference
  /// (default true: keeps long muscles from crowding exponentially towards their ends).
  bool anisotropic = true;
  /// Elongation ((end-to-end edge distance)^2 / area; sphere 0.8, 50:1 capsule 16) above which the
  /// tube start comes first (default 1.0: below it the tube start balances areas worse).
  double tube_elongation = 1.0;
  /// Tutte reweighting rounds after a tube start, edge weights times the faces' (area ratio)^exponent,
  /// kept while the mean |log area ratio| falls (default 8).
  int reweight_rounds = 8;
  double reweight_exponent = 1.0;  ///< area-ratio exponent in the reweighting (default 1, a full step)
  double reweight_target = 0.05;   ///< reweighting stops below this mean |log area ratio| (default 0.05)
  int untangle_sweeps = 50;        ///< local untangling sweeps on a start with flipped triangles (default 50)
  int mobius_steps = 60;           ///< largest number of Moebius centring steps (default 60)
  double mobius_tolerance = 1e-3;  ///< stop centring at this area-centroid offset (default 1e-3)
  /// Largest number of area-balancing sweeps, 0 disables (default 60: tube starts converge well within
  /// it; the cap bounds slowly improving stereographic starts; raise it when quality matters more).
  int balance_sweeps = 60;
  double balance_tolerance = 1e-4;  ///< stop balancing when a sweep lowers the energy by less (default 1e-4)

  // --- relax (thesis) ---
  double relax_threshold = 1e-5;      ///< stop below this largest vertex move, sphere units (default 1e-5)
  int relax_max_iterations = 10000;   ///< iterations of one relaxation (default 10000, the thesis's cap)
  int relax_restarts = 5;             ///< new random tetrahedra tried after a failed collapse check (default 5)
  int relax_threshold_lowerings = 3;  ///< threshold divided by 10 after a failed orientation check (default 3)
  unsigned seed = 1;                  ///< seed of the random tetrahedron rotation (default 1)

  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// Quality of a sphere map against its surface.
/// Area ratio of triangle t: (spherical area / 4 pi) / (surface area / total surface area).
struct SphereQuality {
  long triangles = 0;
  long flipped = 0;                                   ///< exact orientation det(v0, v1, v2) < 0 (CGAL exact predicate)
  long degenerate = 0;                                ///< exact det = 0, or spherical area below `degenerate_area`
  double area_sum = 0.0;                              ///< sum of signed spherical areas; 4 pi for a bijection
  double area_ratio_min = 0.0, area_ratio_max = 0.0;  ///< over triangles of positive surface area
  double area_log_mean = 0.0;                         ///< mean over those triangles of |log(area ratio)|
  double angle_error_mean_deg = 0.0;                  ///< mean |spherical angle - surface angle| per corner, degrees
  double angle_error_max_deg = 0.0;                   ///< largest of those, degrees
  /// True when flipped = degenerate = 0 and |area_sum - 4 pi| < 1e-6.
  bool bijective() const;
};

/// Spherical triangles smaller than this (unit sphere, steradians) count as degenerate: 1e-12 of
/// the sphere, far below anything a map of a million triangles needs.
constexpr double degenerate_area = 1e-12 * 4.0 * 3.14159265358979323846;

/// What the map did.
struct SphereMapReport {
  std::string method;   ///< "tutte" or "relax"
  std::string status;   ///< "ok" or "failed"
  std::string failure;  ///< how it failed, empty when ok
  SphereQuality quality;
  std::string initial_map;  ///< tutte: "stereographic" (one triangle cut), "tube" (cut end to end) or "progressive"
  std::vector<std::string>
      starts_tried;  ///< tutte: starts computed, in order ("tube-prism", "tube-lambert", "stereographic", "progressive")
  double elongation = 0.0;           ///< tutte: (end-to-end edge distance)^2 / area
  int reweight_rounds = 0;           ///< tutte: reweighting rounds kept after the lift
  int cut_face = -1;                 ///< tutte: the triangle cut out (it covers the north pole)
  double lift_margin = 0.0;          ///< tutte: power ratio of the lift (> 1 guarantees orientation)
  int mobius_steps = 0;              ///< tutte: Moebius centring steps taken
  double mobius_residual = 0.0;      ///< tutte: |area centroid| after centring
  int iterations = 0;                ///< balancing sweeps (tutte) or relaxation iterations (relax)
  int rejected_moves = 0;            ///< tutte: vertex moves refused because a triangle would flip
  int restarts = 0;                  ///< relax: new tetrahedra after failed collapse checks
  int threshold_lowerings = 0;       ///< relax: threshold lowerings after failed orientation checks
  bool center_moved_inside = false;  ///< relax: Ritter centre was outside and moved in
  double seconds = 0.0;              ///< wall time of the whole map
  double solve_seconds = 0.0;        ///< tutte: weights + factorisation + solve
  nlohmann::json to_json() const;
};

/// A sphere map: `positions[v]` is vertex v's image on the unit sphere; same triangles.
struct SphereMap {
  std::vector<Vec3> positions;
  SphereMapReport report;
};

/// Maps `mesh` (closed, oriented outward, genus 0; #V positions in any units) to the unit sphere.
/// The result's positions have norm 1; mesh.triangles index them unchanged.
/// Method and sources: see the file comment. The result is checked with exact predicates; when it
/// is not a bijection the report says so (status "failed", `failure` says how many triangles are
/// flipped or degenerate) and the positions are still returned for inspection.
/// Throws TopologyError when the mesh is not closed genus 0 (see check_sphere_topology),
/// OptionError for bad options, SolverError when the linear solve fails.
SphereMap map_to_sphere(const TriangleMesh& mesh, const SphereMapOptions& options = {});

/// Measures a sphere map (`sphere`: #V unit vectors for mesh.positions) against its surface:
/// exact orientation of every spherical triangle, area ratios and angle errors.
SphereQuality measure_sphere_map(const TriangleMesh& mesh, const std::vector<Vec3>& sphere);

/// JSON of a quality record (the "quality" object of the report).
nlohmann::json to_json(const SphereQuality& quality);

}  // namespace fascicle
