#pragma once
/// \file smooth_fibres.h
/// Each fibre's sharp joints smoothed along it (docs/decompose.md, step 12; the thesis's filter:
/// a number of steps and a weight). The settled lattice's lines zigzag where a cell was left
/// sheared and bend at the joints next to their cast ends; the check judges the largest turning
/// angle between consecutive segments. In each step, every inner point of an interior lattice
/// line (not its two ends, on the attachment areas) whose joint turns by more than
/// `max_turning_deg` moves `weight` of the way to the midpoint of its two neighbours on the line
/// (half, a quarter of that where the guards refuse); where the muscle's wall is in the way (the
/// joint bends round it), its inner neighbours move the same share towards the straight
/// continuation of the other segment instead. A move is made only where it keeps the point strictly
/// inside the muscle, starts no segment of its line leaving the surface (the check's rule,
/// fibres/fibre_check.h), takes none that leaves deeper out (its deepest of 16 samples) and turns no good tetrahedron of the check's cells round it
/// (fibres/check_cells.h) folded or flat. Joints under the threshold are left as they are: a
/// 15-point fibre is too coarse for a filter of all its points, which flattens the muscle's own
/// bends and draws the outer fibres off the surface (coverage). Steps end when one moves nothing.
/// Serial, in lattice order: deterministic.
#include "morph/surface_query.h"
#include "springs/lattice.h"
#include "springs/spring_system.h"

#include <nlohmann/json_fwd.hpp>

#include <vector>

namespace fascicle {

/// Options of smooth_fibres().
struct FibreSmoothingOptions {
  int steps = 10;       ///< sweeps over every fibre, 0..10000 (default 10; 0: no smoothing)
  double weight = 0.5;  ///< share of the way to the neighbours' midpoint a point moves, (0, 1] (default 0.5)
  /// Only joints turning by more than this are smoothed, degrees, [0, 180) (default 30, the check's
  /// goal below its 45 degree limit; 0: every joint).
  double max_turning_deg = 30.0;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// What smooth_fibres() did.
struct FibreSmoothingReport {
  long moved = 0;             ///< point moves made (over all steps)
  long refused_outside = 0;   ///< moves not made: the point would leave the muscle
  long refused_segments = 0;  ///< moves not made: a segment of its line would start to leave, or leave deeper
  long refused_cells = 0;     ///< moves not made: a cell round the point would fold
  double above_deg = 0.0;     ///< joints turning by more than this were smoothed (the options' max_turning_deg)
  double max_turning_before_deg = 0.0, max_turning_after_deg = 0.0;  ///< largest joint angle of the fibres
  /// Fibre segments leaving the muscle on return (the rule of fibres/contain_segments.h; the moves
  /// start none, and can end some).
  long crossing_after = 0;
  double seconds = 0.0;
  nlohmann::json to_json() const;
};

/// Joints of the interior lattice lines at `positions` that turn by more than `max_deg` degrees
/// (turning_angle_deg() of fibres/fibre_check.h).
long sharp_joints(const springs::Lattice& lattice, const std::vector<Vec3>& positions, double max_deg);

/// Smooths the interior lattice lines of `system` (the first lattice.point_count() positions) as
/// described above; `end_tolerance` (mesh units) is the distance within which a fibre end's
/// segment may touch the surface, as in the check. Throws OptionError for bad options.
FibreSmoothingReport smooth_fibres(const springs::Lattice& lattice, springs::SpringSystem& system,
                                   const SurfaceQuery& query, double end_tolerance,
                                   const FibreSmoothingOptions& options = {});

}  // namespace fascicle
