#pragma once
/// \file landmark_strip.h
/// Landmark areas joined into strips. Landmark files often mark an attachment along a bone crest
/// by a row of points several region radii apart (the region radius is 1 % of the muscle length).
/// The union of small disks round such points is a string of separate blobs: the placement's
/// star radius from the region centre stops at the first gap, and the cast of the fibre ends
/// shrinks the face until every end lies near one landmark, so the fibres start on a small part
/// of the crest and leave the rest of the muscle uncovered. Joining the landmarks along their
/// minimum spanning tree (edges no longer than `max_gap` of the muscle length) and sampling
/// points along each join, projected onto the surface, turns the row into a gapless strip: the
/// region, the face placed into it, the cast and the check's attachment distances then follow
/// the whole crest. The check then measures the ends' distance to the strip, not to the nearest
/// listed landmark, which where the joins are long can lie several times farther.
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/surface_query.h"

#include <nlohmann/json_fwd.hpp>

namespace fascicle {

/// Options of the joining of landmark areas.
struct StripOptions {
  /// Join the landmarks of each landmark area into a strip (default true; automatic areas are
  /// never joined: they are already every vertex of an end).
  bool join = true;
  /// Longest join, share of the muscle length, (0, 1] (default 0.1: long enough to join the rows of
  /// one landmark area into one strip); longer gaps stay gaps.
  double max_gap = 0.1;
  /// Spacing of the points added along a join, share of the muscle length, (0, 0.1] (default
  /// 0.004: well under the region radius of 0.01, so that the disks round the points overlap).
  double step = 0.004;
  /// Areas with more points than this are left as they are (dense enough, and the spanning tree
  /// costs the square of the count), >= 2 (default 4096).
  int max_points = 4096;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// What the joining did to one area.
struct StripReport {
  bool joined = false;      ///< false: the area was left as it was (off, one point, too many)
  int landmarks = 0;        ///< points of the area before
  int joins = 0;            ///< spanning-tree edges joined (at most landmarks - 1)
  int gaps = 0;             ///< spanning-tree edges longer than max_gap, left open
  long added = 0;           ///< points added along the joins
  double longest_join = 0;  ///< longest joined edge, fraction of the muscle length
  nlohmann::json to_json() const;
};

/// The area `area` (points on the surface `query` was built on) with its points joined: for each
/// edge of the Euclidean minimum spanning tree of its points no longer than
/// options.max_gap * `length`, points every options.step * `length` along the segment, each
/// projected onto the closest surface point. The original points come first, unchanged; the
/// area's source and max_distance are kept. Throws OptionError for bad options or a length that
/// is not positive and finite.
AttachmentArea join_landmark_strip(const AttachmentArea& area, const SurfaceQuery& query, double length,
                                   const StripOptions& options = {}, StripReport* report = nullptr);

/// Both areas of `areas` joined in place by join_landmark_strip() when options.join (the one way
/// `fascicle decompose` and `fascicle check` join landmark areas, so that the check measures
/// what the decomposition aimed at). Returns what was done, for a report:
/// {"face_shape": "joined_strip", "origin": StripReport, "insertion": StripReport}, or
/// {"face_shape": "landmark_disks"} when options.join is false (areas left as they are).
nlohmann::json join_landmark_strips(Attachments& areas, const SurfaceQuery& query, double length,
                                    const StripOptions& options);

}  // namespace fascicle
