#pragma once
/// \file pennate_fibres.h
/// Pennate fibres drawn through a settled lattice (Blemker & Delp 2005: fibres defined in a unit
/// cube, mapped into the muscle by the cube's volumetric map). The decomposition's parallel
/// lattice, settled in the muscle, is that map: the trilinear interpolation of its points over
/// its index cells, the surface ring on the muscle's surface and the layers t = 0 and t = 1 on
/// its two end areas. A crossing family (springs::crosses_lattice) is drawn through it:
///
/// - Cross-section. The template's x runs across the muscle's thickness and y across its width:
///   a lattice cross-section is a square whose corners lie, with the corner twist of 45 degrees
///   (fibres/template_placement.h), two on the muscle's thin edges and two in the middle of its
///   broad faces. The longer of the square's two diagonals in the muscle (measured on the middle
///   layer) joins the thin edges. The template's y = s picks a chord perpendicular to it (the
///   lattice coordinates X + Y = 2s, or (1 - X) + Y = 2s), and x runs along that chord from the
///   boundary on one side of the diagonal to the boundary on the other: the template's faces
///   x = 0 and x = 1 become the muscle's two broad faces (the aponeuroses), its sheet x = 1/2 the
///   diagonal's surface (a central aponeurosis), its faces y = 0 and y = 1 the thin edges.
/// - Pennation. The fibres of one chord (a sheet of fibres, fixed s) rise along the muscle by the
///   template's advance; the advance of each sheet is solved (bisection) so that the mean angle of
///   its fibres' chords (first point to last) to the line of action is the requested pennation.
///   The fibre length is then what the muscle's thickness gives: it is not chosen.
/// - Surface. In the cells next to the lattice's side faces a point moves by the offset that
///   takes its foot on the face onto the closest surface point (the ring lies on the surface at
///   its points only), weighted from 1 on the face to 0 one cell in. The template's z runs over
///   the lattice's inner layers (1 .. nz - 2): the cells next to the cast end faces are sheared on
///   a rounded end, and a fibre drawn through them can turn back. An end on the template's faces
///   goes where its fibre, continued straight from its last two inner points, leaves the muscle
///   (no hook), so the fibres cut by the end faces reach the ends straight. Ends on the central
///   sheet stay inside. An inner point the trilinear cells still put outside (they can bulge out
///   of a concave stretch of surface between their corners) is reflected in its closest surface
///   point. Then each fibre is smoothed along itself (PennateOptions::smoothing_steps), its ends
///   held and every point kept inside.
/// - Areas. The origin area is the set of all fibre starts (the aponeurosis and the part of the
///   origin end the cut fibres start on), sampled densely on an (r, s) grid and placed as the
///   fibres' ends are, the insertion area the set of all fibre ends; each carries that grid as its
///   own surface (AttachmentArea::patch: the central sheet lies inside the muscle), which the
///   check's ends criterion samples.
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"

#include <nlohmann/json_fwd.hpp>

#include <vector>

namespace fascicle {

/// Options of the pennate fibres.
struct PennateOptions {
  /// Mean angle of each sheet's fibres to the line of action, degrees, in (0, 90) (default 13.2: the
  /// mean over the 24 lower-limb muscles of Ward et al. 2009, Clin Orthop Relat Res 467).
  double pennation_deg = 13.2;
  /// Samples of each area along r and along s, per fibre spacing, >= 1 (default 8: area points a
  /// fraction of an end spacing apart, so that the check's distances to the areas are the ends' own).
  int area_density = 8;
  /// Smoothing along each fibre (the thesis's filter: steps and a weight), ends held, a move that
  /// would take a point out of the muscle not made, and a fibre whose segments it would take out
  /// smoothed with half the steps, again and again: the map's cells bend at their faces, and a
  /// crooked corner cell kinks the fibres through it. Steps >= 0 (default 10), weight in (0, 1]
  /// (default 0.5: each inner point moves half way to its neighbours' midpoint per step).
  int smoothing_steps = 10;
  double smoothing_weight = 0.5;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// What the drawing did.
struct PennateReport {
  double target_deg = 0.0;                       ///< requested pennation
  double mean_deg = 0.0;                         ///< mean pennation of all fibres' chords
  std::vector<double> advance;                   ///< per sheet (s), the template's rise per unit of x
  int unreached = 0;                             ///< sheets whose advance hit its bound before the target
  bool mirrored = false;                         ///< the long diagonal is X = 1 - Y (else X = Y)
  double diagonal_ratio = 0.0;                   ///< middle layer: short diagonal over long diagonal
  long fibres = 0, projected_ends = 0;           ///< fibres drawn, ends moved onto the surface
  long reflected_points = 0;                     ///< inner points found outside, reflected inside
  long smoothing_refused = 0;                    ///< smoothing moves not made (the point would leave the muscle)
  long smoothing_reduced = 0;                    ///< times a fibre's smoothing steps were halved (a segment left)
  long origin_points = 0, insertion_points = 0;  ///< area samples
  nlohmann::json to_json() const;
};

/// Fibres, the areas their ends lie on, and the report.
struct PennateFibres {
  Polylines fibres;
  Attachments areas;
  PennateReport report;
};

/// Draws `fibre_count` fibres (split nr x ns as the lattice's: springs::near_square_split) of
/// `resolution` points of the crossing family `kind` through `lattice` settled at `positions`
/// (the lattice points first, in its order, the muscle's units; further entries are ignored), with the pennation of `options` against the unit
/// `line_of_action`; ends on the surface of the muscle of `query`. Throws OptionError for a kind
/// that does not cross the lattice or bad options.
PennateFibres pennate_fibres(springs::TemplateKind kind, const springs::Lattice& lattice,
                             const std::vector<Vec3>& positions, int fibre_count, int resolution,
                             const Vec3& line_of_action, const SurfaceQuery& query, const PennateOptions& options = {});

}  // namespace fascicle
