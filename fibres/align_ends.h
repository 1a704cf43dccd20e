#pragma once
/// \file align_ends.h
/// Fibre ends continued along their fibres (docs/decompose.md, step 10). The cast (step 6) puts
/// a face's ends under a shrunk copy of the layer next to them, along one axis for the whole
/// face, so an outer fibre that reaches its area obliquely bends at its last inner point: a hook.
/// Here each fibre's end moves to where its last inner segment, continued, first meets the
/// surface, so its end joint does not turn; where that does not fit, along the direction halfway
/// between that segment and the one to its cast end (half the turn left), then three quarters of
/// the way to the cast end (three quarters left), else the cast end stays. A cast is used only
/// when it lands within `radius` of an attachment-area point within `max_extension` times the
/// longer of the fibre's two segments there. A face's ends move together (one at a time, a spread
/// end would cross its neighbours still shrunk); where a tetrahedron of the check's end cells
/// (fibres/check_cells.h) that was good turns folded or flat, the moves at that cell's end
/// corners are taken back, until none does. The segment to the first hit lies inside the muscle,
/// so no segment starts to leave. Serial, in lattice order: deterministic.
#include "morph/attachments.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"
#include "springs/spring_system.h"

#include <nlohmann/json_fwd.hpp>

namespace fascicle {

/// Options of align_ends().
struct EndAlignmentOptions {
  /// Longest new end segment, in the longer of the fibre's end segment and the one before it
  /// (default 2: a longer reach runs along the side wall, not to the area).
  double max_extension = 2.0;
  /// Throws OptionError unless max_extension > 0.
  void validate() const;
};

/// What align_ends() did, per face and in all.
struct EndAlignmentReport {
  long moved = 0;    ///< ends moved onto their fibre's line continued
  long halfway = 0;  ///< ends moved along the halfway direction (half the cast's turn left)
  long three_quarters = 0;  ///< ends moved three quarters of the way to the cast (3/4 of its turn left)
  long kept = 0;     ///< ends left at their cast places (off the area, out of reach, or folding)
  nlohmann::json to_json() const;
};

/// Moves the interior lattice lines' end points (k = 0 and nz - 1) of `system` as described
/// above; `areas` are the attachment areas the ends belong to (origin at k = 0), `radius` the
/// largest distance of an end from its area's points (mesh units).
EndAlignmentReport align_ends(const springs::Lattice& lattice, springs::SpringSystem& system,
                              const SurfaceQuery& query, const Attachments& areas, double radius,
                              const EndAlignmentOptions& options = {});

}  // namespace fascicle
