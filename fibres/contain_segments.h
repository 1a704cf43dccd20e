#pragma once
/// \file contain_segments.h
/// Step 11 of the decomposition (docs/decompose.md): fibre segments that leave the muscle between
/// their two points are moved back inside.
///
/// The lattice points are inside after the settle and the untangling (their containment), but
/// a fibre is a polyline: where the surface curves between two of its points (the inner side of
/// a bend, a groove) the straight segment between them can cut through it (fibres/fibre_check.h,
/// crossing_segments; this step counts the segments that segment_leaves() finds, which is the
/// check's count when every fibre point is inside). For each such segment of an interior lattice
/// line (the output fibres), the deepest of `samples` samples outside the surface (8 x samples + 1
/// when the segment leaves between them) is found with its closest surface point; the segment's
/// free points are moved along that direction so that the sample lies `margin` times its depth
/// inside (both by the same shift when both are free; when one is a fixed fibre end, the other
/// takes the shift divided by its weight at the sample), and again from the moved segment while
/// it has a sample outside (a faceted wall), up to `steps` shifts. The move is tried on the
/// segment's own line, then on patches of lines round it (Chebyshev radius 1 ... patch_radius,
/// each line's two points shifted by 1 - distance / (radius + 1) of the move), the first that
/// passes is kept: every moved point strictly inside, the segment no longer leaves, no segment
/// of a moved line next to the moved points (layers k-1 to k+2) that did not leave now leaves,
/// and no tetrahedron of the check's cells round the moved points (kuhn_tetrahedra(), oriented
/// like the lattice) that was good turns inverted or flat; otherwise it is undone. So no segment
/// starts to leave and no cell folds; the coverage is not guarded (the decomposition keeps the
/// unmoved fibres when the moved ones fail the check and those pass). Sweeps repeat over the
/// segments that still leave until one keeps no move or `sweeps` are done. Deterministic (the
/// moves serial, in lattice order).
#include "morph/surface_query.h"
#include "springs/lattice.h"
#include "springs/spring_system.h"

#include <nlohmann/json_fwd.hpp>

#include <utility>
#include <vector>

namespace fascicle {

/// Options of contain_segments().
struct SegmentContainmentOptions {
  int sweeps = 4;  ///< passes over all fibres; a pass that keeps no move ends the work (default 4)
  /// How far inside the deepest sample is moved, as a share of how far outside it was (default 0.25:
  /// relative to the excursion, not the spacing, so shifted points do not cross their neighbours).
  double margin = 0.25;
  int samples = 16;  ///< samples along a segment for its deepest excursion (default 16)
  int steps = 4;     ///< shifts of one move, each from the deepest sample still outside (default 4)
  /// Longest shift tried, in local spacings (mean spring length at the segment's points) (default 3:
  /// a segment that needs more cuts a bend too deep for a local move).
  double max_shift = 3.0;
  int patch_radius = 3;  ///< patch of lines moved together, Chebyshev radius, 0 = alone (default 3)

  /// Throws OptionError naming the first field out of range (sweeps < 0, margin not in (0, 10],
  /// samples < 1, steps < 1, max_shift not > 0, patch_radius < 0).
  void validate() const;
};

/// What contain_segments() did.
struct SegmentContainmentReport {
  long crossing_before = 0;  ///< fibre segments leaving the muscle on entry
  long crossing_after = 0;   ///< and on return
  long moved = 0;            ///< moves kept
  /// Segments left as they were in a sweep: every move undone (a test above failed), or none
  /// tried (both points fixed, no sample outside, a shift over max_shift).
  long rejected = 0;
  int sweeps = 0;  ///< passes made
  double seconds = 0.0;
  nlohmann::json to_json() const;
};

/// The fibre segments a containment holds inside (fibres/untangle_lattice.h): where the fibre ends'
/// segments may touch the surface, and the shifts' options.
struct SegmentContact {
  double end_tolerance = 0.0;  ///< mesh units (the check's end tolerance times the muscle's diagonal)
  /// Excursion over which a segment fails the check, mesh units (its segment_tolerance times the diagonal).
  double tolerance = 0.0;
  int excursion_samples = 32;  ///< samples the check measures an excursion with
  SegmentContainmentOptions shifts;
};

/// The interior lattice lines' segments that leave the surface (fibre_segment_leaves()) by more
/// than contact.tolerance at one of contact.excursion_samples samples: the check's
/// crossing_segments for the lattice's fibres.
long crossing_segment_count(const springs::Lattice& lattice, const springs::SpringSystem& system,
                            const SurfaceQuery& query, const SegmentContact& contact);

/// The shifts that take segment k (points a, b) of a fibre of `segments` segments back inside:
/// the deepest sample outside moved `margin` times its depth inside, repeated from the moved
/// segment up to `steps` times; both points shifted alike when both are free (free0, free1),
/// else the free one by the shift over its weight at the sample. Into d0, d1 (zero when nothing
/// is outside or neither point is free). False when a shift exceeds max_shift x `spacing`.
bool segment_inward_shift(const SurfaceQuery& query, const Vec3& a, const Vec3& b, bool free0, bool free1, int k,
                          int segments, double end_tolerance, double spacing, const SegmentContainmentOptions& options,
                          Vec3* d0, Vec3* d1);

/// For every segment of the interior lattice lines that leaves the surface (the check's rule,
/// fibre_segment_leaves()), the segment_inward_shift() of its free points, each shortened to at
/// most max_shift local spacings; a point of two leaving segments takes the longer shift. As
/// (lattice point, shift) pairs in lattice order: the pins of the untangling's segment attempt
/// (fibres/untangle_lattice.h, docs/decompose.md step 8). Throws OptionError for bad options.
std::vector<std::pair<int, Vec3>> leaving_segment_shifts(const springs::Lattice& lattice,
                                                         const springs::SpringSystem& system, const SurfaceQuery& query,
                                                         double end_tolerance,
                                                         const SegmentContainmentOptions& options = {});

/// Moves the interior lattice lines' segments that leave the surface of `query` back inside (see
/// the file comment). `system` holds the lattice's positions and fixed flags (the first
/// lattice.point_count() points; its springs give the local spacing); `end_tolerance` (mesh
/// units) is the distance within which a fibre end's segment may touch the surface, as in the
/// check. Only free lattice points move. Throws OptionError for bad options.
SegmentContainmentReport contain_segments(const springs::Lattice& lattice, springs::SpringSystem& system,
                                          const SurfaceQuery& query, double end_tolerance,
                                          const SegmentContainmentOptions& options = {});

}  // namespace fascicle
