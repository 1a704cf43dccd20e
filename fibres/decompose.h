#pragma once
/// \file decompose.h
/// The whole job (../shared/docs/METHOD.md, "The job" and "The pipeline"): a raw muscle surface
/// in, muscle fibres out, checked.
///
///  1. repair (repair/repair.h) into a closed genus-0 manifold;
///  2. attachment areas: from landmark files, or automatic (morph/attachments.h);
///  3. sphere map of the muscle (morph/sphere_map.h), bijective, and a locator on it;
///  4. the template lattice (springs/lattice.h) with a ring of surface lines around the requested
///     fibres: (nr + 2) x (ns + 2) lines of `resolution` points; its surface points are placed on
///     the muscle (fibres/template_placement.h: template sphere, pole-frame alignment of both
///     attachment areas, location in the muscle's sphere map);
///  5. settle of the interior with the surface points fixed: first the zero-rest-length
///     equilibrium (one sparse linear solve; a discrete harmonic map of the surface positions),
///     then the springs' rest lengths taken from the template, stretched by the best-fitting
///     linear map of template onto that first equilibrium, and the chosen solver run from it;
///  6. containment: a free point the settle leaves outside the muscle (exact inside test) gets a
///     zero-length spring to an anchor at the closest surface point, `contact_depth` of its local
///     spacing further in (4x stiffer each round, `soft_contact_rounds` rounds), then is fixed at
///     its anchor, the settle repeated each time (at most `contact_rounds` rounds) - a contact
///     constraint of the solve, reported, never a silent clip of the output; after the first
///     settle the fibre ends are cast onto the surface under the layer next to them (under its
///     best affine fit over the index grid where that layer is folded seen along the end axis,
///     so that the ends are never a copy of a fold) and the interior settled again
///     (`cast_rounds` times), with the same containment;
///  7. untangling (fibres/untangle_lattice.h): the cells the settle left inverted are unfolded by
///     a barrier energy (Garanzha et al. 2021) relative to each cell's settled shape, locally
///     first, with the fibre ends free (soft pins) and then held, with containment; see
///     docs/decompose.md step 8;
///  8. optional smoothing along the fibres (free points only);
///  9. fibre segments that cut the surface between their points are shifted back inside where
///     that folds no cell and takes no other segment out (fibres/contain_segments.h; undone when
///     the result then fails the check and would pass without it);
/// 10. the fibres are the interior lattice lines (the surface ring lies on the surface and is not
///     output), checked with fibres/fibre_check.h: all points inside, no inverted cell, coverage,
///     attachment distances (and the segments that leave the muscle, reported).
/// A result that fails the check is made again with the options of retry_plan() (the alternative
/// placement; with landmark areas other corner twists) and the best kept (better_result()).
#include "fibres/architecture.h"
#include "fibres/contain_segments.h"
#include "fibres/fibre_check.h"
#include "fibres/landmark_strip.h"
#include "fibres/template_placement.h"
#include "fibres/untangle_lattice.h"
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/sphere_map.h"
#include "repair/repair.h"
#include "springs/lattice.h"
#include "springs/settle.h"

#include <nlohmann/json.hpp>
#include <functional>
#include <string>
#include <vector>
#include <utility>

namespace fascicle {

/// Rest lengths of the lattice's springs in the settle (step 5).
enum class RestShape {
  zero,      ///< rest length 0: the settle is the discrete harmonic map (one linear solve)
  tension,   ///< the template's, stretched to the muscle, then scaled down until every spring
             ///< starts in tension (no spring pushes, so none buckles)
  template_, ///< the template's, stretched by the best linear fit to the muscle
};
/// "zero", "tension", "template".
const char* rest_shape_name(RestShape shape);
/// Parses a rest-shape name; throws OptionError naming `--rest` and the valid names.
RestShape parse_rest_shape(const std::string& name);

/// Options of a decomposition. Defaults are those of `fascicle decompose`.
struct DecomposeOptions {
  RepairOptions repair;             ///< repair stage (defaults: repair/repair.h)
  SphereMapOptions sphere;          ///< muscle sphere map (default tutte)
  AttachmentOptions attachments;    ///< landmark tolerance, automatic end fraction
  /// Landmark areas joined into gapless strips along their spanning tree before the placement,
  /// the cast and the check (fibres/landmark_strip.h; default on, longest join 0.1 of the length).
  StripOptions strip;
  PlacementOptions placement;       ///< regions and alignment on the sphere
  springs::TemplateKind kind = springs::TemplateKind::parallel;  ///< template (default parallel)
  int fibres = 100;                 ///< fibres output, >= 4, split near-square (default 100)
  int resolution = 15;              ///< points per fibre, >= 2 (default 15)
  springs::SpringModel model = springs::SpringModel::model6;  ///< springs (default model-6)
  RestShape rest = RestShape::tension;  ///< spring rest lengths in the settle (default tension)
  /// The first settle (zero rest lengths: the harmonic interpolation of the placed surface) is
  /// one sparse Cholesky solve on lattices of at most this many points, and a geometric-multigrid
  /// solve (springs/multigrid.h) on larger ones, >= 0 (default 8192). The factor's fill grows
  /// about as the square of a 3D lattice's points: 4 ms at the default 2160 points, 4.1 s at
  /// 1000 fibres x 30 points (34 020), while the multigrid's cost grows linearly
  /// (docs/BENCHMARKS.md, "Decompose", eighteenth session).
  long harmonic_direct_points = 8192;
  /// Settle of the interior (default: static solver, relative residual 1e-6, at most 20000
  /// iterations).
  springs::SettleOptions settle = default_settle();
  /// Compute backend of the settles: "cpu", "gl" (OpenGL compute shaders in float32: Verlet, or
  /// the static solver as its momentum method; a solve that float32 stops short of its
  /// tolerance is finished on the CPU in double, shaders::GpuSettleOptions::polish, always on
  /// here) or "auto" (the CPU: a decomposition's lattice is too small for the GPU to pay off,
  /// docs/decompose.md step 5) (default cpu).
  std::string backend = "cpu";
  int cast_rounds = 2;          ///< rounds of "fibre ends cast onto the surface under the layer
                                ///< next to them, settle again" (step 6b), >= 0 (default 2;
                                ///< 0: the ends stay where the sphere maps place them)
  /// Cast the rim of each attachment face (its surface-ring points) with its fibre ends, from
  /// the same layer or fit one index step beyond them (default true; false: the rim stays where
  /// the placement put it, which next to a narrow end can lie inside the cast ends).
  bool cast_rim = true;
  int soft_contact_rounds = 3;  ///< of the containment rounds, the first ones anchor outside points
                                ///< by zero-length springs to targets just inside (4x stiffer each
                                ///< round) instead of fixing them, >= 0 (default 3)
  int contact_rounds = 6;       ///< containment rounds per settle (step 6), >= 0 (default 6)
  double contact_depth = 0.3;   ///< depth of a contact point below the surface, in local lattice
                                ///< spacings, (0, 1) (default 0.3)
  /// A point only just outside goes only this deep (three times its distance outside, clamped to
  /// [contact_depth_min, contact_depth]), in local spacings, (0, contact_depth] (default 0.3 =
  /// contact_depth: always contact_depth; the second try of a failed decomposition uses 0.05,
  /// retry_alternative: a deep target for a point a hair outside can push it past its
  /// neighbours and fold cells: LHDL gluteus maximus with an even perimeter, 24 folded cells
  /// before the untangling with 0.3, 11 with 0.05).
  double contact_depth_min = 0.3;
  /// Unfold the cells the settle leaves inverted (step 7, fibres/untangle_lattice.h) (default true).
  bool untangle_cells = true;
  /// The untangling: solver, iteration budget, fibre-end pins, containment (defaults:
  /// fibres/untangle_lattice.h).
  LatticeUntangleOptions untangle;
  /// When the fibres fail the check, decompose once more with alternative_placement() (first in
  /// retry_plan()) and keep the better result (better_result()) (default true: the folds a placement
  /// leaves depend on its free choices, and a muscle that folds with one often does not with
  /// the other; docs/BENCHMARKS.md, "Decompose").
  bool retry_alternative = true;
  /// The alternative placement and the rims left (retry_plan()) are skipped when the first
  /// result has more inverted cells than this, >= 0 (default 50: on the 47 corpus muscles no first
  /// result with more folded cells (72, 135, 204, 311) passed on the second try, and those tries
  /// took 40 s of the batch's 233 s of processor time; results with 2-47 were retried and two of
  /// them then passed; docs/BENCHMARKS.md, "Decompose". The rims left, gated too since
  /// 2026-11-22: after first results with 136, 196 and 313 folded cells they gave 134, 203 and
  /// 311 for 40 s of processor time; the one muscle they rescue had 3). Skipped too, whatever
  /// this value, when the first result's folds outlasted the untangling with the surface ring
  /// free (LatticeUntangleReport::free_ring_tried; LHDL psoas: 29 cells, retries 70 and 65).
  long retry_max_inverted_cells = 50;
  /// Move the fibre segments that leave the muscle between their points back inside (step 10,
  /// fibres/contain_segments.h) (default true).
  bool contain_segments = true;
  /// Those moves: sweeps, margin, samples, largest shift (defaults: fibres/contain_segments.h).
  SegmentContainmentOptions segments;
  int smooth_steps = 0;         ///< Laplacian smoothing passes along the fibres, >= 0 (default 0)
  double smooth_weight = 0.5;   ///< weight of each pass, (0, 1] (default 0.5)
  /// Units and specific tension of the architecture figures (fibres/architecture.h; default mm,
  /// 61 N/cm^2).
  ArchitectureOptions architecture;
  /// The final check (default_check()): the criteria of fibres/fibre_check.h with the segments,
  /// turning and ends figures reported but not judged.
  CheckOptions check = default_check();
  /// Corner twists (degrees, each in [-180, 180]) tried in turn, each a whole decomposition with
  /// placement.corner_twist_deg replaced, when the attachment areas come from landmarks and the
  /// decomposition with placement.corner_twist_deg (and the alternative placement) fails the
  /// check; the first that passes is kept, else the best by better_result(). Default
  /// {0, 67.5, 22.5}: with the square cross-section the twist has a period of 90 degrees, and
  /// these split it in steps of 22.5 with 45. Why: with landmark areas the poles of
  /// the placement lie on the muscle's side, where the twist's reference (the muscle's second
  /// principal axis seen from each level) is unreliable, and coverage p95 swings with the twist
  /// (LHDL gluteus maximus, parallel template: 2.34 at 45, 2.56 at 0, 2.97 at 22.5, 1.83 at 67.5;
  /// iliacus: 3.02 at 45, 1.85 at 0; docs/BENCHMARKS.md, "Decompose"). Automatic areas never
  /// retry: their poles are the muscle's ends, where 45 was measured on the whole corpus. Empty:
  /// no retry.
  std::vector<double> landmark_twists_deg = {0.0, 67.5, 22.5};
  /// Automatic areas only: the areas the lattice's ends are placed on, cast onto and held near
  /// while untangling are this share of attachments.end_fraction at each end, (0, 1] (default 1).
  /// The check still measures the fibre ends against the full areas (attachments.end_fraction),
  /// which contain the smaller ones, so a result passes `fascicle check` with the same
  /// end fraction.
  double placement_end_share = 1.0;
  /// Automatic areas only: when the decomposition (and the retries before this one in
  /// retry_plan()) fails the check, decompose once more with placement_end_share multiplied by
  /// this, and keep the better result; (0, 1), or 0 for no such retry (default 0.8: the LHDL psoas,
  /// whose insertion end hooks, folds 2 cells with the full areas and none with 0.8 of them,
  /// coverage p95 1.98; 0.6 of them folded 6, and shares 0.6-1.4 left the opendihu left biceps
  /// at 6-119 folded cells; docs/BENCHMARKS.md, "Decompose", fifteenth session). Not gated by
  /// retry_max_inverted_cells: a different area changes the whole placement.
  double end_share_retry = 0.8;
  /// When the kept result's longest layer of fibre segments is more than this many times the
  /// median layer (the check's steps.layer_ratio: the rings skipped a stretch of the muscle),
  /// decompose once more with the lateral rings placed by meridian
  /// (PlacementOptions::meridian_rings): the first try's options, then, unless that result is
  /// kept and passes, the kept try's options. A result is kept when it is better
  /// (better_result()), or when both pass and it has the lower layer ratio and no deeper segment
  /// excursion. >= 1, or 0 for no such try (default 2.5: on the corpus only the LHDL psoas, 4.08,
  /// is retried, and keeps its first meridian try, 1.56; the opendihu biceps, 2.10-2.17, fold
  /// with meridian rings; docs/BENCHMARKS.md, "Decompose", twenty-second session).
  double even_layers_ratio = 2.5;
  /// Width of the lattice cells between the surface ring and the outermost fibres, in fibre
  /// spacings (springs::LatticeOptions::edge_cell; default 1: the ring spaced like the fibres;
  /// 0.5 puts each fibre at the centre of its share of the cross-section, so that the outermost
  /// fibres lie half a spacing from the surface instead of a whole one, but costs the settle
  /// about 60 ms on the LHDL gluteus maximus).
  /// Measured on the corpus (docs/BENCHMARKS.md, "Decompose", twenty-third session): median
  /// coverage p95 1.47 with 1, 1.03 with 0.5; but 0.5 folds two muscles that pass with 1, so
  /// see edge_cell_fallback. In (0, 1].
  double edge_cell = 1.0;
  /// With edge_cell < 1: when the first try fails the check (or its layer ratio is above
  /// even_layers_ratio), decompose again with edge cells of 1 and the whole retry plan, and keep
  /// the better result (default true). The first try then leaves out the untangling's free-ring
  /// attempts (untangle.free_ring), which take most of a failing try's time. With false, every
  /// try uses edge_cell.
  bool edge_cell_fallback = true;
  /// Landmark areas only: when the whole plan (edge cells as edge_cell, level or meridian rings,
  /// every retry) fails the check, run it once more with meridian rings and edge cells of 0.5
  /// (no fallback, no layer-ratio try) and keep the better result (default true; no effect when
  /// edge_cell is already below 1 or meridian rings are asked for). A result that passes before
  /// this stage is never changed by it. Why: with its landmark files the LHDL psoas, whose origin
  /// strip runs down its side and whose tendon hooks, failed every earlier try with the parallel
  /// template and this stage passed (coverage p95 1.992, 0 folded cells; docs/BENCHMARKS.md,
  /// "Decompose", twenty-fifth session). Since the untangling's depths are measured across the
  /// fibres (LatticeUntangleOptions::across_spacing) that pair passes on its first try (twenty-sixth
  /// session); the psoas with the curved, fanned and rectus templates passes only on this stage
  /// (twenty-seventh session).
  bool landmark_narrow_retry = true;
  /// Not a setting: called with a short description of each stage as it starts ("repair",
  /// "try 2: settle", ...) so that a caller can show progress; empty: nothing is called (default).
  std::function<void(const std::string& stage)> progress;
  /// Throws OptionError naming the first bad field.
  void validate() const;
  static springs::SettleOptions default_settle();
  /// CheckOptions with max_crossing_segments -1, max_turning_angle_deg 180 and min_end_coverage
  /// 0: the decomposition is judged on inside, inverted cells, coverage and attachment; its
  /// fibres do not yet meet the segments, smoothness and ends criteria on every muscle
  /// (docs/decompose.md, "Where it stands"), which `fascicle check` judges.
  static CheckOptions default_check();
};

/// Speed against accuracy as one choice: a documented set of fibre count, points per fibre, the
/// settle's tolerance and the check's coverage samples.
///   draft:    36 fibres x 9 points, tolerance 1e-4, 5000 coverage samples
///   standard: 100 fibres x 15 points, tolerance 1e-6, 20000 coverage samples (the defaults)
///   fine:     144 fibres x 19 points, tolerance 1e-7, 40000 coverage samples
enum class Quality { draft, standard, fine };
/// "draft", "standard", "fine".
const char* quality_name(Quality quality);
/// Parses a level's name; throws OptionError naming `--quality` and the valid names.
Quality parse_quality(const std::string& name);
/// `options` with the level's fibres, resolution, settle.tolerance and check.coverage_samples.
DecomposeOptions with_quality(DecomposeOptions options, Quality quality);

/// Landmark files of the attachment areas (both or neither).
struct Landmarks {
  std::vector<Vec3> origin, insertion;
  std::string origin_source, insertion_source;  ///< file names, for messages
  bool given() const { return !origin.empty() || !insertion.empty(); }
};

/// What a decomposition did: every stage's figures and seconds.
struct DecomposeReport {
  std::string status;       ///< "ok" or "failed" (the quality check failed)
  std::string failure;      ///< why, when failed
  nlohmann::json repair, sphere, attachments, placement, lattice, settle, containment, untangle, smoothing;
  CheckReport quality;
  Architecture architecture;  ///< of the fibres returned (fibres/architecture.h)
  /// One entry per whole decomposition tried (corner twist, status, failed criteria, figures,
  /// seconds), in order, and which was kept (DecomposeOptions::landmark_twists_deg).
  nlohmann::json attempts = nlohmann::json::array();
  int kept_attempt = 0;     ///< index into `attempts` of the result returned
  std::string renderer;     ///< OpenGL renderer when the GPU settled, else empty
  /// Seconds per stage; query_seconds: building the surface's point-location and inside-test
  /// trees, sphere_seconds: the muscle's sphere map and its locator, each once for all attempts
  /// and side by side (they overlap); seconds: the total wall time, every attempt included.
  double repair_seconds = 0, query_seconds = 0, sphere_seconds = 0, placement_seconds = 0, settle_seconds = 0,
         check_seconds = 0, seconds = 0;
  nlohmann::json to_json() const;
};

/// The repaired muscle, its fibres (interior lattice lines, origin to insertion, with the
/// `fibre_r`, `fibre_s` arrays of fibres/fibre_grid.h) and the report.
struct Decomposition {
  TriangleMesh muscle;
  Polylines fibres;
  DecomposeReport report;
};

/// The options of the second try of a failed decomposition: `options` with the placement's
/// even_perimeter switched, contact_depth_min switched between 0.05 (or contact_depth, if
/// smaller) and contact_depth (shallow contact targets on or off), and no further retry.
DecomposeOptions alternative_placement(const DecomposeOptions& options);

/// The retries of a decomposition that fails the check, in order, each with what it changes:
/// "alternative_placement" (alternative_placement(), when options.retry_alternative), then
/// "rim_left" (options with cast_rim false, when options.retry_alternative and cast_rim), then with
/// landmark areas one "corner_twist" per options.landmark_twists_deg entry, with automatic areas
/// "end_share" (placement_end_share times options.end_share_retry, when that is not 0); then, with landmark
/// areas joined into strips and options.strip.disk_fallback, "landmark_disks" (the first try with
/// the strips off) and the same plan again with the strips off, each change prefixed
/// "landmark_disks_". Retries do not retry. (After the plan, decompose may add "meridian_rings"
/// tries, DecomposeOptions::even_layers_ratio, and with landmark areas that failed every try the
/// whole plan again from "landmark_narrow", DecomposeOptions::landmark_narrow_retry.)
struct RetryStep {
  std::string change;        ///< what the step changes (the names above), for the report
  DecomposeOptions options;  ///< the options of the whole decomposition tried
  /// Skipped when the first try of its sequence (the first try, or "landmark_disks") has more
  /// inverted cells than DecomposeOptions::retry_max_inverted_cells (the alternative placements
  /// and the rims left; the corner twists are not: they change the lattice's whole turn).
  bool gated = false;
  /// Its result is the first try of a new sequence (the landmark disks' first try).
  bool starts_sequence = false;
};
std::vector<RetryStep> retry_plan(const DecomposeOptions& options, bool landmarks_given);

/// Whether check result `a` is better than `b`: passing first, then fewer failed criteria, fewer
/// inverted cells, a larger inside fraction, a lower coverage p95 (the first of equals is kept).
bool better_result(const CheckReport& a, const CheckReport& b);

/// Handedness of a settled lattice: +1 or -1 as its layers' (r, s) normals (the normals of their
/// best affine fits over the index grid, inner points) point along or against the direction of
/// growing t (from the layer before to the layer after), summed over the inner layers; 0 for a
/// lattice of fewer than three layers or a sum of 0. The fibre ends are cast so that their faces
/// turn this way (step 6).
int lattice_handedness(const springs::SpringSystem& system, const springs::Lattice& lattice);

/// Decomposes the raw muscle `soup` (any units) into fibres. Method: see the file comment.
/// The result's report says "failed" when the final check fails (the fibres are still returned
/// for inspection; the command line then writes no fibre file). Throws TopologyError
/// (repair_failed) when the mesh cannot be repaired, InputError(landmarks) for far landmarks or
/// coinciding areas, OptionError for bad options, SolverError when the sphere map is not a
/// bijection or the settle diverges, Error(gpu) for GPU failures.
Decomposition decompose(const PolygonSoup& soup, const Landmarks& landmarks, const DecomposeOptions& options = {});

/// Decomposes an already repaired muscle (closed genus 0, outward): steps 2-9; while the result
/// fails the check, again with each of retry_plan()'s options in turn (the alternative placement,
/// the face rims left, then, with landmark areas, the corner twists of options.landmark_twists_deg), keeping the best
/// result by better_result() (the report's `attempts` lists every try, `kept_attempt` the one
/// returned). Throws as decompose(); an exception in a retry (not the first attempt) is recorded
/// in `attempts` and that retry skipped.
Decomposition decompose_repaired(const TriangleMesh& muscle, const Landmarks& landmarks,
                                 const DecomposeOptions& options = {});

}  // namespace fascicle
