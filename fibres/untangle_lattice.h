#pragma once
/// \file untangle_lattice.h
/// Step 8 of the decomposition (docs/decompose.md): the cells of a settled fibre lattice that are
/// folded are unfolded, with every lattice point kept inside the muscle.
///
/// The lattice's cells are split as the quality check splits them (kuhn_tetrahedra(),
/// fibres/fibre_grid.h) and handed to the barrier untangling of fibres/untangle.h (Garanzha et al.
/// 2021), each tetrahedron measured against its own settled shape where that shape is good, else
/// against its layer's mean cell. The work is local first (the points within 2, then 6 lattice
/// steps of a folded cell move), then the whole lattice; a wider region that frees no more points
/// is skipped. The first attempt holds the fibre ends and starts from the settled lattice (enough
/// where the folds are local, and cheap); while cells stay folded, a second starts again from the
/// settled lattice with the ends free (each end free within a ball round the nearest point of its
/// attachment area, end_area_margin, or without areas held by a soft pin at its cast place, at
/// most `end_shift` of the muscle length from it), and a third goes on from there with the ends
/// held. While cells still stay folded, the last two run again with the surface ring free too
/// (free_ring: each ring point held on a plane just under the surface, sliding along it; the ring
/// is freed only after the attempts with it held, since a freed ring changes the coverage of
/// muscles the held ring already unfolds; in these attempts the containment is also part of the
/// untangling's energy, containment_energy; when they still leave folds they run once more with
/// that switched, containment_retry). Containment is part of every attempt: a point moved
/// outside gets a soft pin under the tangent plane at its closest surface point (stronger each
/// round, sliding_contact); an attempt stops when a round does not fold fewer cells than the
/// rounds before it (or, when asked, after `contact_stall_rounds` rounds in a row that did not
/// leave fewer points outside). Each attempt is then finished: a point still outside is fixed just
/// inside (at the shallowest depth that folds none of its cells, pin_search) and the cells around
/// it are untangled again with it fixed (`pin_rounds`; undone when that does not fold fewer
/// cells), so that no step after the untangling moves a lattice point and the pins do not fold
/// cells behind the untangling's back. The attempt with the fewest folded cells after its pins
/// stays. Depths are in local spacings across the fibres (across_spacing).
#include "fibres/untangle.h"
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fascicle {

/// Options of untangle_lattice().
struct LatticeUntangleOptions {
  UntangleOptions solver;        ///< the barrier solver (defaults: fibres/untangle.h)
  /// L-BFGS iterations each of the (at most three) attempts may spend, all its rounds together,
  /// >= 0 (default 8000: a lattice that cannot be unfolded costs seconds, not minutes; an
  /// iteration count, not a time, so that the result does not depend on the machine).
  int iterations = 8000;
  /// Weight of the soft pins that hold the fibre ends at their cast places when the first attempt
  /// lets them move, per squared local spacing (energy units of one well-shaped tetrahedron are
  /// about 3), > 0 (default 30; stiffer pins make the untangling fail more often).
  double end_anchor_weight = 30.0;
  /// Farthest a fibre end may move from its cast place, as a share of the muscle length, [0, 1)
  /// (default 0.0095: with the cast ends within 0.01 of an area point, the ends stay within 0.02
  /// of their areas, the check's limit).
  double end_shift = 0.0095;
  /// When the attempts with the surface ring held (the lattice lines round the fibres, which the
  /// placement put on the surface) leave folds, the free-ends attempt and the held-ends one after
  /// it run again with the ring free: each ring point is held by a soft pin on a plane just
  /// under the surface (see ring_depth) and may slide along it, so that the rings next to a hooked
  /// end can turn with the layers inside them (true); or the ring stays where the settle put it
  /// (false) (default true: with it the opendihu biceps tracer unfolds, docs/BENCHMARKS.md "Folds
  /// next to hooked ends").
  bool free_ring = true;
  /// Depth of a free ring point's plane under its closest surface point, in local lattice
  /// spacings, [0, 1) (default 0.1: with 0 more interior points were pushed out; with 0.3 the
  /// coverage p95 of the three bent muscles rose to 2.0-2.5).
  double ring_depth = 0.1;
  /// Weight of a free ring point's plane pin, per squared local spacing, > 0 (default 120).
  double ring_weight = 120.0;
  /// With attachment areas given: how far a fibre end may lie from the nearest point of its area,
  /// as a share of the muscle length, [0, 1); while the ends are free they move without cost
  /// within 0.8 of it (a ball round the nearest area point, renewed each round) and are put back
  /// onto it at the end, instead of within `end_shift` of their cast places; 0 = the cast-place
  /// rule (default 0.015: under the check's 0.02, so that an end the clamp leaves at the limit
  /// still passes; next to a hooked tendon end the unfolded end layer needs its ends farther from
  /// their cast places than end_shift allows, docs/BENCHMARKS.md "Folds next to hooked ends").
  double end_area_margin = 0.015;
  /// Weight of the first soft pin of a point moved outside, per squared local spacing (4x each
  /// round), > 0 (default 30).
  double contact_weight = 30.0;
  /// Containment pins as half-spaces (the point is pushed under the tangent plane at its closest
  /// surface point, `contact_depth` deep, and may slide along it) (true) or as zero-length springs
  /// to that point (false) (default true).
  bool sliding_contact = true;
  /// The pins at the end put a point still outside at the shallowest of a few depths under the
  /// closest surface point (0.02 to `contact_depth` local spacings) that folds none of its cells,
  /// else at the one that folds the fewest (true), or always `contact_depth` deep (false)
  /// (default true).
  bool pin_search = true;
  /// Containment rounds of an attempt (soft pins, untangle again), 0..100 (default 16). Each
  /// round takes in some of the points left outside; those still outside after the last are
  /// pinned just inside, and many pins close together pinch the cells between them. With 6 the
  /// LHDL psoas with its landmark files failed with the fanned and rectus templates (6 and 16
  /// folded cells): every try ended with hundreds of points outside and still falling; with 16
  /// both pass (0 folded, coverage p95 1.918 and 1.870), and the corpus stays at 47 of 47
  /// (docs/BENCHMARKS.md, "Decompose", twenty-seventh session).
  int contact_rounds = 16;
  /// An attempt's containment rounds stop after this many rounds in a row that did not leave
  /// fewer points outside than the best round of the attempt before them (the pins at the end take
  /// the points still outside), 0..100, 0 = never (default 0: 2 halved the untangling's iterations
  /// on the LHDL gluteus maximus, whose soft pins of rounds 3 to 6 pushed points out as fast as
  /// they pulled others in, but the more points the pins at the end then took folded the LHDL
  /// iliacus (98 cells) and the VHF tensor fasciae latae (1) in the corpus, docs/BENCHMARKS.md).
  int contact_stall_rounds = 0;
  /// A containment round that leaves cells folded and folds no fewer than the best round before
  /// stops the attempt's rounds ("fold_stalled") only when it also leaves no fewer points outside
  /// than the best round before (true), or whatever the points outside did (false, the rule
  /// before 2026-11-29) (default true). On the LHDL psoas with its landmark files and the curved
  /// template the attempt with the surface ring free stopped after one round with 1 folded
  /// tetrahedron and 375 points outside, which the pins at the end then took; every try failed
  /// (9 folded cells at best). Going on while points come in, the narrow stage's untwisted try
  /// ends with none outside and passes (coverage p95 1.794); the corpus and the other 19 LHDL pairs
  /// are unchanged (docs/BENCHMARKS.md, "Decompose", twenty-seventh session).
  bool fold_stall_needs_outside_stall = true;
  /// Rounds of "fix the points still outside just inside, untangle again with them fixed" at the
  /// end, >= 0 (default 3; the pins of the last round stay even if they fold a cell, which the
  /// report then counts).
  int pin_rounds = 3;
  /// Depth of a contact point below the surface, in local lattice spacings, (0, 1) (default 0.3).
  double contact_depth = 0.3;
  /// Containment inside the untangling's energy (UntangleContainment, fibres/untangle.h) in the
  /// attempts with the surface ring free: each free interior lattice point (not the ring, held by
  /// its plane pins, nor the fibre ends, held by their area pins) within `containment_band` local
  /// spacings h of the surface, or outside it, pays
  /// contact_weight / h^2 * max(0, d + containment_margin h)^2 on its signed distance d to the
  /// surface (a signed-distance grid of the muscle, morph/signed_distance_grid.h), the weight raised
  /// 4x a stage while a point is outside, so that the unfolded lattice is already inside and the
  /// pins at the end have few points to move; the soft pins of the rounds stay as they are (true);
  /// or only the soft pins (false) (default false: in the corpus it took the LHDL psoas from 33 to
  /// 2 folded cells and the opendihu left biceps from 123 to 14 (coverage p95 1.63), but folded
  /// 16 cells of the biceps tracer, which passes without it: 44 of 47 pass instead of 45,
  /// docs/BENCHMARKS.md "Containment inside the untangling energy").
  bool containment_energy = false;
  /// The same in every attempt, not only those with the ring free (default false).
  bool containment_energy_everywhere = false;
  /// Depth the containment energy pushes a point to, in local spacings, [0, 1) (default 0.15:
  /// above the error of the grid's interpolation, whose cells are a quarter of the smaller
  /// spacings). (Variants measured and removed, each worse on the LHDL psoas and the opendihu left
  /// biceps: the freed fibre ends in the containment energy with a ball round their areas, the
  /// freed ring in it, a scale raised only after stages that fold no fewer cells, a larger
  /// budget; docs/BENCHMARKS.md, "Fibre ends in the containment energy" and the s10a section.)
  double containment_margin = 0.15;
  /// When the free-ring attempts leave folds, they run once more with the containment energy
  /// switched (on when containment_energy is false, off when it is true), from the settled lattice;
  /// the result with the fewest folded cells after its pins stays (the earlier on a tie), so that
  /// muscles the first setting unfolds never pay for the second (default true: the LHDL psoas and
  /// the opendihu left biceps, the only corpus muscles whose free-ring attempts leave folds, keep
  /// the contained result, the others are untouched; docs/BENCHMARKS.md).
  bool containment_retry = true;
  /// Points farther inside than this many local spacings are left out of the containment energy
  /// (they cannot reach the surface in one run), > 0 (default 3).
  double containment_band = 3.0;
  /// The local spacing h that the depths (ring_depth, contact_depth, the pins' search,
  /// containment_margin, containment_band) are measured in: the mean length of a point's springs
  /// within its layer, across the fibres (lattice_across_spacing()) (true); or of all its springs,
  /// the springs along the fibres included (lattice_local_spacing()) (false). The weights stay per
  /// squared lattice_local_spacing(). Along a long, thin
  /// muscle the springs along the fibres are many times longer than those across (LHDL psoas,
  /// 15 points a fibre: about 23 mm against 1.7 mm), so a depth of 0.3 h over all springs put
  /// points one and a half fibre spacings under the surface (default true: the corpus passes, 47
  /// of 47, in less time, the LHDL psoas with its landmark files and the parallel template on its
  /// first try; docs/BENCHMARKS.md, twenty-sixth session).
  bool across_spacing = true;
  /// Throws OptionError naming the first bad field.
  void validate() const;
};

/// What untangle_lattice() did.
struct LatticeUntangleReport {
  /// One entry per untangle() run (its report, radius, round...), and after each attempt one with
  /// its name (`attempt`) and the folded tetrahedra left after its pins (`finished`).
  nlohmann::json runs = nlohmann::json::array();
  long inverted_before = 0;   ///< counted folded tetrahedra of the settled lattice
  long inverted_left = 0;     ///< and at the end
  int budget_left = 0;        ///< iterations left to the last attempt
  long pinned = 0;            ///< points fixed just inside at the end of the kept attempt
  std::string kept;           ///< the attempt kept: held_ends, free_ends, free_then_held_ends, free_ring or free_ring_then_held_ends
  /// Whether the attempts with the surface ring free ran (the attempts with it held left folds).
  bool free_ring_tried = false;
  /// Why the attempts' containment rounds ended, with how often: contained (no point outside),
  /// rounds (contact_rounds done), budget (iterations spent), outside_stalled
  /// (contact_stall_rounds), fold_stalled (a round that did not fold fewer cells, nor, with
  /// fold_stall_needs_outside_stall, leave fewer points outside).
  nlohmann::json stops = nlohmann::json::object();
  long iterations = 0;        ///< L-BFGS iterations of all runs
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
LatticeUntangleReport untangle_lattice(const springs::Lattice& lattice, springs::SpringSystem& system,
                                       const SurfaceQuery& query, double muscle_length,
                                       const LatticeUntangleOptions& options = {}, const Attachments* areas = nullptr);

}  // namespace fascicle
