#pragma once
/// \file fibre_check.h
/// The fibre quality check (issue 6, "Check"): figures that say whether a set of fibres is a
/// faithful decomposition of a muscle, computed from the fibres and the muscle surface alone, so
/// fibres from any tool (this program's decomposition, a slicing method, a harmonic-field
/// method) are checked the same way.
///
/// Criteria and their default thresholds (CheckOptions), each judged, each named in `failed`:
/// - inside: every interior fibre point strictly inside the muscle by the exact test (CGAL
///   Side_of_triangle_mesh through morph/surface_query.h); end points may also lie on the surface
///   within `end_tolerance`. Pass when inside_fraction >= min_inside_fraction (1.0).
/// - inverted_cells (lattice fibres only, see fibres/fibre_grid.h): each hexahedral cell between
///   fibres (r,s), (r+1,s), (r,s+1), (r+1,s+1) and points k, k+1 is split into six tetrahedra
///   around its diagonal (r,s,k)-(r+1,s+1,k+1); a cell is inverted when one of its tetrahedra has
///   the sign opposite to the lattice's reference orientation (the sign of the sum of all
///   tetrahedra volumes) or a (numerically) zero volume. Pass when inverted_cells <=
///   max_inverted_cells (0). Folded lattices are exactly the ones whose fibres cross.
/// - coverage: samples uniform in the muscle volume; distance from each to the nearest fibre
///   segment, divided by the ideal spacing sqrt(V / (F L)) (V muscle volume, F fibre count, L mean
///   fibre length). Pass when the 95th percentile <= max_coverage_p95 (2.0).
/// - attachment: distance of each fibre's first point to the nearest origin-area point and of
///   its last point to the nearest insertion-area point, divided by the muscle length (extent of
///   the muscle's vertices along their principal axis, as morph/attachments.cpp defines the
///   automatic areas). Pass when the largest of both is <= max_attachment (0.02).
/// - segments (polylines inside): a fibre is a polyline, and a modeller draws its segments. A
///   segment "touches" the surface when the surface cuts it (a ray test from its midpoint towards
///   both ends, Moeller-Trumbore through the query's hierarchy; hits within `end_tolerance` of a
///   fibre end do not count, as that point lies on the surface) or when one of its points failed
///   the inside test; each touching segment is sampled at `excursion_samples` points between its
///   ends with the exact inside test, and the largest distance to the surface of the samples
///   outside is its excursion. It "crosses" when the excursion exceeds segment_tolerance of the
///   bounding-box diagonal (0.5 %). Pass when crossing_segments <= max_crossing_segments (0).
/// - smooth: the turning angle at each joint (the angle between consecutive segments); pass when
///   the largest is <= max_turning_angle_deg (45). Reported with where it is and the joints over
///   30 and over 45 degrees (TurningFigures).
/// - ends: the fibre ends must spread over their areas, not gather into a point. Each area's
///   surface (the surface within end_region_radius of the muscle length of an area point, and
///   every triangle whose three corners are; or the area's own patch, AttachmentArea::patch, for
///   an area inside the muscle) is sampled evenly; the ideal end spacing is
///   sqrt(area / F); the area's share is the fraction of its samples within one ideal end
///   spacing of a fibre end there. Pass when both shares are >= min_end_coverage (0.25): a grid
///   of F ends over the area covers all of it, ends over its middle half (by radius) about a
///   quarter plus a rim, ends gathered into a point about pi / F.
/// Length spread and the point spacing along the fibres (StepFigures) are reported, not judged.

#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/surface_query.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace fascicle {

/// Options of the fibre check: sampling, tolerances and pass thresholds.
struct CheckOptions {
  /// Uniform volume samples for the coverage figures (default 20000).
  int coverage_samples = 20000;
  /// Seed of the sample generator: the same seed gives the same report (default 1).
  std::uint64_t seed = 1;
  /// Fibre end points (first and last point) count as inside when they are within this fraction
  /// of the muscle's bounding-box diagonal of the surface, on either side (default 1e-4):
  /// fibres of a decomposition end on the attachment areas, i.e. on the surface.
  double end_tolerance = 1e-4;
  /// Pass threshold: smallest acceptable inside_fraction (default 1.0: every point inside).
  double min_inside_fraction = 1.0;
  /// Pass threshold: largest acceptable number of inverted lattice cells (default 0).
  long max_inverted_cells = 0;
  /// Pass threshold: largest acceptable coverage 95th percentile, in ideal spacings (default 2.0).
  double max_coverage_p95 = 2.0;
  /// Pass threshold: largest acceptable attachment distance, as a fraction of the muscle length
  /// (default 0.02).
  double max_attachment = 0.02;
  /// A segment crosses the surface when a sample of it lies outside by more than this fraction
  /// of the muscle's bounding-box diagonal (default 0.005).
  double segment_tolerance = 0.005;
  /// Pass threshold: largest acceptable number of crossing segments (default 0); -1 reports them
  /// without judging.
  long max_crossing_segments = 0;
  /// Points sampled between the ends of each segment the surface cuts, for the exact inside
  /// test that measures how far it goes out, in [1, 10000] (default 32).
  int excursion_samples = 32;
  /// Pass threshold: largest acceptable turning angle between consecutive segments, degrees, in
  /// (0, 180] (default 45).
  double max_turning_angle_deg = 45.0;
  /// The surface of an attachment area for the ends criterion: within this fraction of the muscle
  /// length of an area point, (0, 1] (default 0.01).
  double end_region_radius = 0.01;
  /// Even samples on each attachment area's surface for the ends criterion (default 4000).
  int end_samples = 4000;
  /// Pass threshold: smallest acceptable share of each area within one ideal end spacing of a
  /// fibre end, [0, 1] (default 0.25).
  double min_end_coverage = 0.25;
  /// How many outside points (and inverted cells, crossing segments) the report lists (default
  /// 10); the counts cover all of them.
  int outside_listed = 10;

  /// Throws OptionError naming the first field out of range (coverage_samples not in [1, 1e8],
  /// end_tolerance < 0, min_inside_fraction outside [0, 1], max_inverted_cells < 0,
  /// max_coverage_p95 or max_attachment <= 0 or not finite, max_crossing_segments < -1,
  /// segment_tolerance < 0, excursion_samples not in [1, 10000],
  /// max_turning_angle_deg not in (0, 180], end_region_radius not in (0, 1], end_samples not in
  /// [1, 10000000], min_end_coverage not in [0, 1], outside_listed < 0).
  void validate() const;
};

/// A fibre point that failed the inside test.
struct OutsidePoint {
  int fibre = 0;                 ///< line index in the Polylines
  int point = 0;                 ///< point index along the fibre
  Vec3 position = Vec3::Zero();  ///< mesh units
  double distance = 0.0;         ///< distance to the surface, mesh units
};

/// A fibre segment (points `segment` and `segment + 1`) that leaves the muscle.
struct CrossingSegment {
  int fibre = 0;           ///< line index in the Polylines
  int segment = 0;         ///< index of its first point along the fibre
  double excursion = 0.0;  ///< largest sampled distance outside the surface, mesh units (0 when
                           ///< no sample fell outside: the segment only grazes the surface)
};

/// Where the poorly covered volume is: the samples farther than `threshold` ideal spacings from
/// every fibre ("far" samples), counted by position along the muscle and by depth below its
/// surface, so that a failed coverage criterion says whether the ends, the flanks (just under
/// the surface) or the inside are thin.
struct FarSamples {
  static constexpr int kAlongBins = 10;  ///< tenths of the muscle's length
  static constexpr int kDepthBins = 4;   ///< depth below the surface, see depth_edges
  /// Upper depth edges of the depth bins, in ideal spacings: [0,1), [1,2), [2,4), [4,inf).
  static constexpr double depth_edges[kDepthBins] = {1.0, 2.0, 4.0, 1e300};
  double threshold = 0.0;  ///< distance in ideal spacings beyond which a sample is far (the
                           ///< check's max_coverage_p95)
  double fraction = 0.0;   ///< share of all samples that are far
  /// Samples and far samples in each tenth along the principal axis of the muscle's vertices
  /// (the axis of muscle_length), bin 0 at the origin end (the end nearer the origin area's
  /// centroid).
  std::array<int, kAlongBins> along_samples{}, along_far{};
  /// Samples and far samples by depth (distance to the surface) in ideal spacings; measured only
  /// when the coverage criterion fails (depth_measured; else all zero): a closest-point query per
  /// sample, and only a failure needs explaining.
  bool depth_measured = false;
  std::array<int, kDepthBins> depth_samples{}, depth_far{};
};

/// Coverage figures: sample-to-nearest-fibre distances in ideal spacings.
struct CoverageFigures {
  double mean = 0.0;           ///< mean distance / ideal_spacing
  double p95 = 0.0;            ///< 95th percentile distance / ideal_spacing
  double max = 0.0;            ///< largest distance / ideal_spacing
  double ideal_spacing = 0.0;  ///< sqrt(V / (F L)), mesh units
  double volume = 0.0;         ///< muscle volume V, mesh units cubed
  int samples = 0;             ///< samples drawn inside the muscle
  FarSamples far;              ///< where the samples beyond the threshold lie
};

/// Attachment figures: fibre end to area distances as fractions of the muscle length.
struct AttachmentFigures {
  double origin_max = 0.0, origin_mean = 0.0;        ///< first points to the origin area
  double insertion_max = 0.0, insertion_mean = 0.0;  ///< last points to the insertion area
  double muscle_length = 0.0;                        ///< principal-axis extent, mesh units
  long origin_points = 0, insertion_points = 0;      ///< points of the areas measured against
};

/// Fibre length figures (polyline lengths, mesh units; cv = standard deviation / mean).
struct LengthFigures {
  double mean = 0.0, min = 0.0, max = 0.0, cv = 0.0;
};

/// How evenly the points are spaced along the fibres (segment lengths, mesh units). A fibre with
/// one segment several times its others is sampled coarsely there: a curved muscle's surface can
/// cut such a segment although both its points are inside (as round a hooked tendon end).
struct StepFigures {
  double mean = 0.0;  ///< mean segment length over all segments
  /// Per fibre, its longest segment divided by its mean segment: the largest over the fibres,
  /// and the median.
  double max_ratio = 0.0, median_ratio = 0.0;
  int worst_fibre = -1;    ///< the fibre with max_ratio (line index), -1 when there is none
  int worst_segment = -1;  ///< its longest segment (index of its first point)
  /// When every fibre has the same number of points: the mean length of segment k over the
  /// fibres, k = 0 .. points - 2 (the lattice's layer steps), and the longest of them divided
  /// by their median (layer_ratio); empty and 0 otherwise.
  std::vector<double> layers;
  double layer_ratio = 0.0;
};

/// Turning angles between consecutive segments (degrees).
struct TurningFigures {
  double max_deg = 0.0;           ///< largest turning angle
  int fibre = -1;                 ///< where: line index, -1 when no fibre has a joint
  int joint = -1;                 ///< the joint's point index along the fibre (1 .. points - 2)
  long joints = 0;                ///< joints measured (interior points whose both segments have a length)
  long over_30 = 0, over_45 = 0;  ///< joints turning by more than 30 and 45 degrees
  long end_joints_over_45 = 0;    ///< of those over 45, the first or last joint of a fibre
  bool max_at_end = false;        ///< the largest is the first or last joint of its fibre (a hooked end)
};

/// How the fibre ends cover one attachment area (the ends criterion).
struct EndCoverage {
  double share = 0.0;    ///< fraction of the area's samples within one ideal spacing of an end
  double spacing = 0.0;  ///< ideal end spacing sqrt(area / F), mesh units
  double area = 0.0;     ///< the area's surface, mesh units squared (estimated from the samples)
  int samples = 0;       ///< samples drawn on it
};

/// Result of check_fibres. `pass` is true when no criterion failed; `failed` names the failed
/// ones ("inside", "inverted_cells", "coverage", "attachment", "segments", "smooth", "ends").
struct CheckReport {
  long fibres = 0;                             ///< fibre count F
  long points = 0;                             ///< fibre points in all
  long inside_points = 0;                      ///< points that passed the inside test
  double inside_fraction = 0.0;                ///< inside_points / points
  long outside = 0;                            ///< points - inside_points
  std::vector<OutsidePoint> outside_examples;  ///< the first options.outside_listed of them
  long segments = 0;                           ///< segments in all (points - fibres)
  long crossing_segments = 0;                  ///< segments out by more than the tolerance (judged)
  long touching_segments = 0;                  ///< segments the surface cuts at all (reported)
  double segment_inside_fraction = 0.0;        ///< 1 - crossing_segments / segments
  /// Largest excursion of a segment outside the surface (mesh units, sampled), the same as a
  /// fraction of the muscle length (attachment.muscle_length) and of the bounding-box diagonal
  /// (the criterion's measure).
  double max_segment_excursion = 0.0, max_segment_excursion_relative = 0.0, max_segment_excursion_diagonal = 0.0;
  std::vector<CrossingSegment> crossing_examples;  ///< the first options.outside_listed of them
  bool lattice = false;                            ///< the fibres carry a lattice (fibre_r, fibre_s)
  int lattice_nr = 0, lattice_ns = 0;              ///< lattice index ranges (0 when not a lattice)
  long cells = 0;                                  ///< lattice cells checked (0 when not a lattice)
  long inverted_cells = 0;                         ///< cells with an inverted or flat tetrahedron
  /// (r, s, k) of the first options.outside_listed inverted cells: the cell between fibres
  /// (r..r+1, s..s+1) and points k, k+1.
  std::vector<std::array<int, 3>> inverted_examples;
  CoverageFigures coverage;
  AttachmentFigures attachment;
  LengthFigures length;
  StepFigures steps;                        ///< point spacing along the fibres (reported, not judged)
  double max_turning_angle_deg = 0.0;       ///< largest angle between consecutive segments
  TurningFigures turning;                   ///< the turning angles in detail (smooth criterion)
  EndCoverage origin_ends, insertion_ends;  ///< the ends criterion, per area
  CheckOptions thresholds;                  ///< the options the check ran with
  bool pass = false;
  std::vector<std::string> failed;  ///< names of the failed criteria, in the order above
  double seconds = 0.0;             ///< wall time of the check

  /// The report as JSON: every field above (thresholds under "thresholds").
  nlohmann::json to_json() const;
  /// A human-readable table, one criterion per line with its value, threshold and verdict.
  std::string to_table() const;
  /// One line: pass or FAIL, then each criterion with its value, threshold and verdict.
  std::string summary() const;
};

/// The point spacing figures of `fibres` (StepFigures; fibres with fewer than 2 points are
/// skipped).
StepFigures step_figures(const Polylines& fibres);

/// The angle between directions u and v, degrees (0 when either is zero): how far a fibre turns at
/// the joint where a segment along u meets one along v. The check's rule.
double turning_angle_deg(const Vec3& u, const Vec3& v);

/// Muscle length used to scale attachment distances: the extent of the vertices along their
/// principal axis (largest eigenvector of their covariance), mesh units. 0 for an empty mesh.
double muscle_length(const TriangleMesh& muscle);

/// Whether the segment [a, b] leaves the closed surface of `query`: a ray from its midpoint
/// towards each end hits the surface before that end, where hits within `margin_a` of a (and
/// `margin_b` of b) do not count (a fibre end lies on the surface). Does not test a and b
/// themselves.
bool segment_leaves(const SurfaceQuery& query, const Vec3& a, const Vec3& b, double margin_a, double margin_b);

/// segment_leaves() for segment k (points k, k + 1) of a fibre of `segments` segments: the
/// fibre's ends (point 0, point `segments`) lie on the surface by design, so hits within
/// `end_tolerance` (mesh units) of them do not count. The check's rule and step 11's.
bool fibre_segment_leaves(const SurfaceQuery& query, const Vec3& a, const Vec3& b, int k, int segments,
                          double end_tolerance);

/// The deepest of `samples` points spaced evenly inside [a, b] (ends excluded) that is outside
/// the surface: its distance to the surface (0 when none is outside); its parameter along the
/// segment into `t` and its closest surface point into `closest` when given and one is outside.
double segment_excursion(const SurfaceQuery& query, const Vec3& a, const Vec3& b, int samples, double* t = nullptr,
                         Vec3* closest = nullptr);

/// Checks `fibres` against the closed muscle surface `muscle` and its attachment `areas`.
/// - fibres: polylines in mesh units, each ordered from origin to insertion; with the cell
///   arrays fibre_r / fibre_s when they come from a lattice (then cells are checked).
/// - muscle: closed, outward-oriented triangle mesh (repair it first: repair/repair.h).
/// - areas: origin and insertion areas on `muscle` (morph/attachments.h).
/// Method: see the file comment. The inside test classifies a uniform grid over the muscle's
/// box once (cells touched by no triangle's box share one side, found by one exact test per
/// connected region) and runs the exact test only in cells near the surface; coverage samples
/// are drawn uniformly from the cells that can hold inside points and kept when inside;
/// nearest-fibre distances come from a bounding-volume hierarchy over the segments (exact, no
/// brute force). Independent of the thread count; the same seed gives the same figures.
/// Throws OptionError for bad options; InputError(file_empty) when there is no fibre,
/// InputError(malformed) when a fibre has fewer than 2 points, InputError(bad_number) when a
/// point is not finite;
/// TopologyError when the muscle has no triangles, is not an oriented 2-manifold or has a
/// non-positive volume; InputError(landmarks) when an area has no point.
CheckReport check_fibres(const Polylines& fibres, const TriangleMesh& muscle, const Attachments& areas,
                         const CheckOptions& options = {});

/// The same with a SurfaceQuery already built on `muscle` (saves building its trees again when
/// the caller has one, as the decomposition does). `query` must have been built on `muscle`.
CheckReport check_fibres(const Polylines& fibres, const TriangleMesh& muscle, const SurfaceQuery& query,
                         const Attachments& areas, const CheckOptions& options = {});

/// The criteria a report's figures fail under the thresholds of `options`, in the order of
/// CheckReport::failed (the check's own verdict): a report measured once judged again, as the
/// decomposition judges its candidates against the whole check's defaults.
std::vector<std::string> failed_criteria(const CheckReport& report, const CheckOptions& options);

}  // namespace fascicle
