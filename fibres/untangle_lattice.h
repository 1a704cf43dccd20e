#pragma once
/// \file untangle_lattice.h
/// Step 8 of the decomposition (docs/decompose.md): the cells of a settled fibre lattice that are
/// folded are unfolded, with every lattice point kept inside the muscle.
///
/// The lattice's cells are split as the quality check splits them (kuhn_tetrahedra(),
/// fibres/fibre_grid.h) and handed to the barrier untangling of fibres/untangle.h (Garanzha et al.
/// 2021), each tetrahedron measured against its own settled shape where that shape is good, else
/// against its layer's mean cell. The work is local first (the points within 2, then 6 lattice
/// steps of a folded cell move), then, once the surface ring has been freed (below), the whole
/// lattice; a wider region that frees no more points is skipped. The first attempt holds the
/// fibre ends and starts from the settled lattice (enough
/// where the folds are local, and cheap); while cells stay folded, a second starts again from the
/// settled lattice with the ends free (each end free within a ball round the nearest point of its
/// attachment area, end_area_margin, or without areas held by a soft pin at its cast place, at
/// most `end_shift` of the muscle length from it), and a third goes on from there with the ends
/// held (only where the second left fewer folded cells than the first: from a start no better,
/// the held ends stall on the same folds; likewise for each continuation below). While cells still stay folded, the last two run again with the surface ring free too
/// (free_ring: each ring point held on a plane just under the surface, sliding along it; the ring
/// is freed only after the attempts with it held, since a freed ring changes the coverage of
/// muscles the held ring already unfolds; with containment_energy the containment is also part of
/// the untangling's energy in these attempts). Containment is part of every attempt: a point moved
/// outside gets a soft pin under the tangent plane at its closest surface point (stronger each
/// round, sliding_contact); an attempt stops when a round does not fold fewer cells than the
/// rounds before it (or, when asked, after `contact_stall_rounds` rounds in a row that did not
/// leave fewer points outside). Each attempt is then finished: a point still outside is fixed just
/// inside (at the shallowest depth that folds none of its cells, pin_search) and the cells around
/// it are untangled again with it fixed (`pin_rounds`; undone when that does not fold fewer
/// cells), so that no step after the untangling moves a lattice point and the pins do not fold
/// cells behind the untangling's back. The attempt with the fewest folded cells after its pins
/// stays. Depths are in local spacings across the fibres (across_spacing).
#include "fibres/contain_segments.h"
#include "fibres/untangle.h"
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fascicle {

/// Options of untangle_lattice().
struct LatticeUntangleOptions {
  UntangleOptions solver;  ///< the barrier solver (defaults: fibres/untangle.h)
  /// L-BFGS iterations per attempt, all its rounds together, >= 0 (default 8000: a lattice that
  /// cannot be unfolded costs seconds; a count, not a time, so the result is machine-independent).
  int iterations = 8000;
  /// Weight of the soft pins holding free fibre ends at their cast places, per squared local spacing
  /// (a good tetrahedron's energy is about 3), > 0 (default 30; stiffer pins fail more often).
  double end_anchor_weight = 30.0;
  /// Farthest a fibre end may move from its cast place, share of the muscle length, [0, 1) (default
  /// 0.0095: cast ends lie within 0.01 of their area, so moved ends stay within the check's 0.02).
  double end_shift = 0.0095;
  /// Rerun the free-ends and held-ends attempts with the surface ring sliding on planes under the surface
  /// when the held ring leaves folds (default true: rings next to a hooked end must turn with the layers).
  bool free_ring = true;
  /// Depth of a free ring point's plane under the surface, local spacings, [0, 1) (default 0.1:
  /// shallower pushes interior points out, deeper raises the coverage p95 of bent muscles).
  double ring_depth = 0.1;
  double ring_weight = 120.0;  ///< free ring point's plane pin, per squared spacing, > 0 (default 120)
  /// With areas: how far a free fibre end may lie from its area, share of the muscle length, [0, 1),
  /// 0 = end_shift (default 0.015: under the check's 0.02; next to a hooked end, end_shift is too tight).
  double end_area_margin = 0.015;
  double contact_weight = 30.0;  ///< first pin of a point outside, per spacing^2, 4x a round, > 0 (default 30)
  /// Containment pins as half-spaces under the tangent plane at the closest surface point, free to
  /// slide (true), or as zero-length springs to that point (false) (default true).
  bool sliding_contact = true;
  /// Final pins at the shallowest of a few depths (0.02 to contact_depth) that folds none of the
  /// point's cells, else the fewest (true), or always contact_depth deep (false) (default true).
  bool pin_search = true;
  /// Containment rounds of an attempt, 0..100 (default 16: points still outside after the last round
  /// are pinned, and many pins close together pinch the cells between them).
  int contact_rounds = 16;
  /// Stop an attempt's rounds after this many in a row that leave no fewer points outside than the
  /// best, 0..100, 0 = never (default 0: stopping early saves time but leaves more pins, which fold cells).
  int contact_stall_rounds = 0;
  /// A round that folds no fewer cells than the best stops the rounds only if it also leaves no fewer
  /// points outside (true), or always (false) (default true: rounds still taking points in may unfold).
  bool fold_stall_needs_outside_stall = true;
  /// Rounds of "fix the points still outside just inside, untangle again" at the end, >= 0 (default
  /// 3; the last round's pins stay even if they fold a cell, which the report counts).
  int pin_rounds = 3;
  double contact_depth = 0.3;  ///< contact target depth, local spacings, (0, 1) (default 0.3)
  /// Free-ring attempts: containment also in the untangling's energy (UntangleContainment,
  /// fibres/untangle.h) (default false: it unfolds some muscles but folds others that pass without it).
  bool containment_energy = false;
  bool containment_energy_everywhere = false;  ///< the same in every attempt (default false)
  /// Depth the containment energy pushes a point to, local spacings, [0, 1) (default 0.15: above the
  /// error of the signed-distance grid's interpolation, whose cells are a quarter of the spacing).
  double containment_margin = 0.15;
  /// Points farther inside than this many local spacings are left out of the containment energy
  /// (they cannot reach the surface in one run), > 0 (default 3).
  double containment_band = 3.0;
  /// Depths in spacings across the fibres (lattice_across_spacing()) (true) or over all springs (false)
  /// (default true: on long thin muscles the springs along the fibres are far longer, so depths overshoot).
  bool across_spacing = true;
  /// Throws OptionError naming the first bad field.
  void validate() const;
};

/// What untangle_lattice() did.
struct LatticeUntangleReport {
  /// One entry per untangle() run (its report, radius, round...), and after each attempt one with
  /// its name (`attempt`) and the folded tetrahedra left after its pins (`finished`).
  nlohmann::json runs = nlohmann::json::array();
  long inverted_before = 0;  ///< counted folded tetrahedra of the settled lattice
  long inverted_left = 0;    ///< and at the end
  int budget_left = 0;       ///< iterations left to the last attempt
  long pinned = 0;           ///< points fixed just inside at the end of the kept attempt
  std::string
      kept;  ///< the attempt kept: held_ends, free_ends, free_then_held_ends, free_ring or free_ring_then_held_ends
  /// Whether the attempts with the surface ring free ran (the attempts with it held left folds).
  bool free_ring_tried = false;
  /// With segments: the free points of leaving fibre segments before and after the segment
  /// attempt, and whether that attempt was kept (`kept` then ends in "+segments").
  long leaving_before = 0, leaving_after = 0;
  long crossing_before = 0, crossing_after = 0;  ///< and the segments leaving by more than the check allows
  bool segments_kept = false;
  /// With segments and segments leaving: whether the caller's `segments_needed` asked for the
  /// segment attempt (false: the kept result needs nothing it could give, and it did not run).
  bool segments_needed = false;
  /// Why the attempts' containment rounds ended, with how often: contained (no point outside),
  /// rounds (contact_rounds done), budget (iterations spent), outside_stalled
  /// (contact_stall_rounds), fold_stalled (a round that did not fold fewer cells, nor, with
  /// fold_stall_needs_outside_stall, leave fewer points outside), unmoved (a segment round after
  /// the first that moved no lattice point).
  nlohmann::json stops = nlohmann::json::object();
  long iterations = 0;  ///< L-BFGS iterations of all runs
  nlohmann::json to_json() const;
};

/// The free points of `system` that are not strictly inside the surface of `query` (exact test),
/// in index order.
std::vector<int> outside_free_points(const springs::SpringSystem& system, const SurfaceQuery& query);

/// Mean length of the springs at each point of `system` (its local lattice spacing).
std::vector<double> lattice_local_spacing(const springs::SpringSystem& system);

/// Mean length of the springs at each lattice point of `system` that join it to points of its own
/// layer of `lattice` (the spacing across the fibres); a point without such springs, and every
/// point after the lattice's (anchors), keeps lattice_local_spacing()'s value.
std::vector<double> lattice_across_spacing(const springs::Lattice& lattice, const springs::SpringSystem& system);

/// A point just inside the muscle for the lattice point q (usually outside): the closest surface
/// point moved `depth` local spacings inwards (halved until it is inside); where the muscle is too
/// thin for that, a point between the closest surface point and a lattice neighbour that is inside
/// (`lattice_points`: how many of the system's points are lattice points, the rest are anchors).
/// May return a point that is not inside when nothing else is found.
Vec3 lattice_contact_point(const springs::SpringSystem& system, int lattice_points, const SurfaceQuery& query, int q,
                           double depth, const std::vector<double>& spacing);

/// The tetrahedra of all cells of `lattice` at positions `x` (kuhn_tetrahedra() of every cell),
/// oriented like the total volume of the interior cells. Counted: the cells between interior
/// lattice lines (the output fibres, which the check counts); the cells against the surface ring
/// are in the energy only, with eps never below 0.5 (a soft preference that keeps the interior
/// inside the ring without making a fold there a barrier). Reference of a tetrahedron: its own
/// shape at `x` where that is good (det J > 0.2 and distortion tr(J^T J) / (3 det^(2/3)) < 2
/// against the layer's box), else the box of its layer's mean edge lengths along r, s and t.
std::vector<UntangleTet> lattice_cell_tets(const springs::Lattice& lattice, const std::vector<Vec3>& x);

/// Counted tetrahedra of `tets` with det J <= 0 at `x`.
long inverted_tets(const std::vector<Vec3>& x, const std::vector<UntangleTet>& tets);

/// Unfolds the folded cells of the settled `lattice` whose points are `system` (positions, fixed
/// flags; the springs are used only to find a point's neighbours and local spacing; points after
/// lattice.point_count() are anchors and stay). The fibre ends (layers t = 0 and t = 1, interior
/// lines) are fixed on entry and on return. `query` is the muscle's surface, `muscle_length` its
/// length (fibres/fibre_check.h, muscle_length()), `areas` (may be null) the attachment areas the
/// fibre ends belong to (origin: layer t = 0, insertion: t = 1; see end_area_margin). Method: see
/// the file comment. On return the interior lattice points that were outside are fixed just
/// inside, and `inverted_left` counts the folded tetrahedra after those pins. Throws OptionError
/// for bad options.
/// With `segments` (may be null) and a fibre segment that leaves the surface by more than
/// segments->tolerance, one more attempt runs last, from the kept result with the ends and the
/// ring held, whose containment rounds also hold the segments in: the free points of an interior
/// line's segment that leaves (leaving_segment_shifts(); the fibre ends' segments may touch the
/// surface within segments->end_tolerance) get half-space pins where that segment comes back
/// inside, 4x stronger each round like the outside points', and the rounds go on while one
/// leaves and a round still moves a point. It is kept when it folds no more cells, leaves fewer points on leaving segments and no
/// more segments leaving by more than the tolerance; `unheld` (may be null) then receives the
/// system as it was before it (the coverage is not guarded: a caller whose check then fails can
/// fall back on it). `segments_needed` (may be empty: always) is asked first, with the kept result,
/// whether the attempt can help: a caller that finishes the lattice after the untangling and
/// prefers the result without the attempt on a tie skips a search that cannot change its choice.
LatticeUntangleReport untangle_lattice(
    const springs::Lattice& lattice, springs::SpringSystem& system, const SurfaceQuery& query, double muscle_length,
    const LatticeUntangleOptions& options = {}, const Attachments* areas = nullptr,
    const SegmentContact* segments = nullptr, springs::SpringSystem* unheld = nullptr,
    const std::function<bool(const springs::SpringSystem&)>& segments_needed = {});

}  // namespace fascicle
