#pragma once
/// \file decompose.h
/// The whole job (../shared/docs/METHOD.md, "The job" and "The pipeline"): a raw muscle surface
/// in, muscle fibres out, checked.
///
///  1. repair (repair/repair.h) into a closed genus-0 manifold: decompose() of
///     fibres/decompose_mesh.h, which then calls decompose_repaired() below with the repaired mesh
///     (plain data: this header does not depend on the repair stage);
///  2. attachment areas: from landmark files, or automatic (morph/attachments.h);
///  3. sphere map of the muscle (morph/sphere_map.h), bijective, and a locator on it (of a copy
///     simplified to map_faces triangles where the muscle is finer: repair/simplify_mesh.h);
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
///     first, with the fibre ends free (soft pins) and then held, with containment; then, where a
///     fibre segment leaves the muscle, an attempt whose contact rounds pin the segments too
///     (contact_segments; the lattices with and without it are finished, and the one failing fewer
///     of the segments and smoothness criteria is kept); see docs/decompose.md step 8;
///  8. the fibre ends continued along their fibres onto the surface (no hook at the end joint),
///     where that stays on the area and folds no cell (fibres/align_ends.h);
///  9. fibre segments that cut the surface between their points are shifted back inside where
///     that folds no cell and takes no other segment out (fibres/contain_segments.h; undone when
///     the result then fails the check and would pass without it);
/// 10. each fibre's joints that turn by more than 30 degrees smoothed along it, under the check's
///     guards (fibres/smooth_fibres.h);
/// 11. the fibres are the interior lattice lines (the surface ring lies on the surface and is not
///     output), checked with fibres/fibre_check.h: all points inside, no inverted cell, coverage,
///     attachment distances (and the segments that leave the muscle, reported).
/// With a crossing template (unipennate, bipennate) the lattice is the parallel one and step 11's
/// fibres are drawn through it instead (fibres/pennate_fibres.h, which smooths them itself), checked against the areas they
/// span, the lattice judged as a map (no folded cell, every point inside).
/// At most two tries (fibres/try_policy.h): a first with the options as given, and a second,
/// with second_try()'s options, only where the first shows a failure mode that the second's
/// change addresses; the better result is kept (better_result()).
#include "fibres/align_ends.h"
#include "fibres/architecture.h"
#include "fibres/contain_segments.h"
#include "fibres/fibre_check.h"
#include "fibres/landmark_strip.h"
#include "fibres/pennate_fibres.h"
#include "fibres/smooth_fibres.h"
#include "fibres/template_placement.h"
#include "fibres/try_policy.h"
#include "fibres/untangle_lattice.h"
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/sphere_map.h"
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
  zero,       ///< rest length 0: the settle is the discrete harmonic map (one linear solve)
  tension,    ///< the template's, stretched to the muscle, then scaled down until every spring
              ///< starts in tension (no spring pushes, so none buckles)
  template_,  ///< the template's, stretched by the best linear fit to the muscle
};
/// "zero", "tension", "template".
const char* rest_shape_name(RestShape shape);
/// Parses a rest-shape name; throws OptionError naming `--rest` and the valid names.
RestShape parse_rest_shape(const std::string& name);

/// Options of a decomposition. Defaults are those of `fascicle decompose`.
struct DecomposeOptions {
  SphereMapOptions sphere;        ///< muscle sphere map (default tutte)
  AttachmentOptions attachments;  ///< landmark tolerance, automatic end fraction
  /// Landmark areas joined into gapless strips before the placement, the cast and the check
  /// (fibres/landmark_strip.h; default on, longest join 0.1 of the length).
  StripOptions strip;
  PlacementOptions placement;                                    ///< regions and alignment on the sphere
  springs::TemplateKind kind = springs::TemplateKind::parallel;  ///< template (default parallel)
  /// Crossing templates (unipennate, bipennate): the pennation their fibres are drawn with through
  /// the settled lattice (fibres/pennate_fibres.h; default 13.2 degrees).
  PennateOptions pennate;
  int fibres = 100;                                           ///< fibres output, >= 4, split near-square (default 100)
  int resolution = 15;                                        ///< points per fibre, >= 2 (default 15)
  springs::SpringModel model = springs::SpringModel::model6;  ///< springs (default model-6)
  RestShape rest = RestShape::tension;                        ///< spring rest lengths in the settle (default tension)
  /// Largest lattice whose first (harmonic) settle is one sparse Cholesky solve, >= 0 (default 8192);
  /// larger ones use multigrid (springs/multigrid.h): the factor's fill grows about as points^2.
  long harmonic_direct_points = 8192;
  /// Largest surface the sphere map and the placement (steps 3-4) work on, triangles, >= 1000
  /// (default 100000): a finer muscle is simplified for them (repair/simplify_mesh.h) and the placed
  /// points moved to its closest points; the map's factorisations grow faster than the surface,
  /// and 15 x 100 fibres need far fewer triangles. Every other step works on the muscle itself.
  long map_faces = 100000;
  /// Settle of the interior (default: static solver, relative residual 1e-6, at most 20000 iterations).
  springs::SettleOptions settle = default_settle();
  /// Settle backend (default cpu): "cpu", "gl" (float32 compute shaders, finished on the CPU in double
  /// when short of the tolerance) or "auto" (the CPU: a decomposition's lattice is too small for the GPU).
  std::string backend = "cpu";
  int cast_rounds = 2;  ///< rounds of "cast the fibre ends under the next layer, settle again"
                        ///< (step 6), >= 0 (default 2; 0: ends stay where the sphere maps put them)
  /// Cast each attachment face's rim (surface-ring points) with its fibre ends (default true;
  /// false: the rim stays where placed, which next to a narrow end can lie inside the cast ends).
  bool cast_rim = true;
  /// Shrink the cast's starting layer by one factor per azimuth round the cast axis (true,
  /// fibres/azimuth_cast.h) or by one factor for the whole face (false) (default true: a side of
  /// the area narrow seen from the layer's centre then shrinks only its own side of the face).
  bool cast_by_azimuth = true;
  int soft_contact_rounds = 3;  ///< first containment rounds that anchor outside points by springs
                                ///< (4x stiffer each round) instead of fixing them, >= 0 (default 3)
  int contact_rounds = 6;       ///< containment rounds per settle (step 6), >= 0 (default 6)
  double contact_depth = 0.3;   ///< contact target depth, in local spacings, (0, 1) (default 0.3)
  bool untangle_cells = true;  ///< unfold the cells the settle leaves inverted (step 7) (default true)
  /// The untangling: solver, iteration budget, fibre-end pins, containment (defaults:
  /// fibres/untangle_lattice.h).
  LatticeUntangleOptions untangle;
  /// After the untangling's attempts, one more from the kept result whose containment rounds also pin
  /// the fibre segments that leave the muscle between their points back inside (step 7; default true;
  /// not with a crossing template, whose fibres do not run along the lattice lines).
  bool contact_segments = true;
  /// Each fibre's sharp joints smoothed along it after the segment moves, under the check's guards
  /// (fibres/smooth_fibres.h; default 10 steps, weight 0.5, joints over 30 degrees; steps 0: none).
  FibreSmoothingOptions smoothing;
  /// Move the fibre segments that leave the muscle back inside (step 11, fibres/contain_segments.h)
  /// (default true).
  bool contain_segments = true;
  /// Those moves: sweeps, margin, samples, largest shift (defaults: fibres/contain_segments.h).
  SegmentContainmentOptions segments;
  /// Continue each fibre's end along its last inner segment onto the surface where that stays on
  /// the area and folds no cell (fibres/align_ends.h; default true).
  bool align_ends = true;
  /// Units and specific tension of the architecture figures (fibres/architecture.h; default mm,
  /// 61 N/cm^2).
  ArchitectureOptions architecture;
  /// The final check (default_check()): the criteria of fibres/fibre_check.h with the segments,
  /// turning and ends figures reported but not judged.
  CheckOptions check = default_check();
  /// Automatic areas only: share of attachments.end_fraction the lattice ends are placed on, (0, 1]
  /// (default 1); the check still uses the full areas, so `fascicle check` passes the same result.
  double placement_end_share = 1.0;
  /// Width of the cells between the surface ring and the outermost fibres, in fibre spacings, (0, 1]
  /// (default 1; 0.5, the second try for a coverage gap, brings the outermost fibres half a spacing
  /// from the surface but folds more muscles).
  double edge_cell = 1.0;
  /// When the decomposition is tried a second time (fibres/try_policy.h; default: once more where
  /// the first shows folds, uneven layers or a coverage gap).
  TryPolicy tries;
  /// Not a setting: called with each stage's short description as it starts ("repair", "try 2:
  /// settle") for progress; empty: nothing is called (default).
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
  std::string status;   ///< "ok" or "failed" (the quality check failed)
  std::string failure;  ///< why, when failed
  nlohmann::json repair, sphere, attachments, placement, lattice, settle, containment, untangle;
  /// The repaired muscle's cross-sections (geometry/cross_section.h: median_aspect, aspects) and
  /// whether they made the first try put the corners on the edges (`flat`, PlacementOptions::flat_section_aspect).
  nlohmann::json cross_section;
  /// Crossing templates only (else null): how the pennate fibres were drawn (PennateReport) and the
  /// check of the lattice they were drawn through (`map`: inverted_cells, inside_fraction).
  nlohmann::json pennate;
  CheckReport quality;
  Architecture architecture;  ///< of the fibres returned (fibres/architecture.h)
  /// One entry per whole decomposition tried (what it changed, status, failed criteria, failure
  /// modes, figures, seconds), in order (at most two, fibres/try_policy.h), and which was kept.
  nlohmann::json attempts = nlohmann::json::array();
  int kept_attempt = 0;  ///< index into `attempts` of the result returned
  std::string renderer;  ///< OpenGL renderer when the GPU settled, else empty
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

/// The second try after a first whose check shows `modes` (failure_modes(), fibres/try_policy.h):
/// `first` with the rings placed by meridian for "folds" and "uneven_layers" (with band_by_length,
/// where the first placed them by levels); for "coverage" the lattice's corners on the thin edges
/// (the corner twist for the areas, PlacementOptions::twist_for(), set to 45 degrees) where the
/// first's were not there, else edge cells of 0.5 (where the first's were wider); and for the
/// whole check's modes (whole_check_modes(): "gathered_ends", "hooked_ends", "segments_out")
/// faces as deep as the first ring (placement.max_face_depth 1). Except: "gathered_ends" alone
/// where the areas are landmark strips (`landmarks`, with first.strip.join: landmark areas joined
/// into strips along the muscle, fibres/landmark_strip.h), as deeper faces do not spread the ends
/// over such a strip; and "sharp_joints" (the largest joint inside the fibres), which the end
/// layers do not reach. `change` names what changed ("meridian_rings", "corners_on_edges",
/// "narrow_edge_cells", "deep_faces", joined by "+"), empty when nothing applies: then there is
/// no second try.
struct SecondTry {
  std::string change;
  DecomposeOptions options;
};
SecondTry second_try(const DecomposeOptions& first, const std::vector<std::string>& modes,
                     bool landmarks = false);

/// Whether check result `a` is better than `b`: passing first, then fewer failed criteria, fewer
/// inverted cells, a larger inside fraction, a lower coverage p95 (the first of equals is kept).
bool better_result(const CheckReport& a, const CheckReport& b);

/// Handedness of a settled lattice: +1 or -1 as its layers' (r, s) normals (the normals of their
/// best affine fits over the index grid, inner points) point along or against the direction of
/// growing t (from the layer before to the layer after), summed over the inner layers; 0 for a
/// lattice of fewer than three layers or a sum of 0. The fibre ends are cast so that their faces
/// turn this way (step 6).
int lattice_handedness(const springs::SpringSystem& system, const springs::Lattice& lattice);

/// Decomposes an already repaired muscle (closed genus 0, outward): steps 2-11, then, where the
/// first result shows a failure mode of fibres/try_policy.h, once more with second_try()'s options,
/// keeping the better result: by better_result() after a first that failed decompose's check;
/// after one that passed it, the second only where it passes too and fails fewer of the whole
/// check's criteria, or as many and is evener (uneven layers); the report's `attempts` lists both
/// tries with the failure modes, `kept_attempt` the one returned. Throws InputError(landmarks) for far landmarks or coinciding areas, OptionError for
/// bad options, SolverError when the sphere map is not a bijection or the first settle diverges,
/// Error(gpu) for GPU failures; an exception in the second try is recorded in `attempts` and the
/// first result returned.
Decomposition decompose_repaired(const TriangleMesh& muscle, const Landmarks& landmarks,
                                 const DecomposeOptions& options = {});

}  // namespace fascicle
