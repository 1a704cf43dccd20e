#pragma once
/// \file strip_cast.h
/// The search of the fibre ends' cast (fibres/decompose.h, step 6) for an attachment area that is
/// a long strip (fibres/landmark_strip.h). The cast starts the ends from the layer of fibre
/// points next to the face, shrunk towards its centroid by a factor lambda, and keeps the first
/// lambda (1, 0.8, 0.64, ...) whose every end lands within the end radius of an area point. On a
/// strip only a narrow band across it is near the area, so one factor for both directions shrinks
/// the whole face to a spot on the strip (factors well under 0.2) and the first layer of cells
/// becomes a steep funnel that folds. Here the offsets' components along the strip (its principal
/// direction seen along the cast axis) and across it are shrunk by separate factors; the pair
/// that keeps the largest face (product of the factors) is used, ties going to the larger factor
/// along the strip; the single-factor search's results are among the pairs tried.
#include "geometry/mesh.h"

#include <functional>
#include <vector>

namespace fascicle {

/// The result of cast_strip_face().
struct StripCast {
  bool placed = false;        ///< a pair of factors put every end near the area
  double lambda_long = 0.0;   ///< factor along the strip (0 when not placed)
  double lambda_cross = 0.0;  ///< factor across it (0 when not placed)
  std::vector<Vec3> ends;     ///< the ends, in the order of `offsets` (empty when not placed)
};

/// Casts ends from `centre` + scaled `offsets` along `axis`. `area_points`: the area's points;
/// `hit(start, axis, end)` casts one ray (false: no hit); `near(end)` says whether an end lies
/// close enough to the area. Factors 1, 0.8, 0.8^2, ... (`steps` of each, >= 1). The strip's
/// direction is the principal direction of `area_points` in the plane normal to `axis` (for
/// fewer than two points, or points that do not spread there, the first offset's direction).
StripCast cast_strip_face(const Vec3& centre, const std::vector<Vec3>& offsets, const Vec3& axis,
                          const std::vector<Vec3>& area_points,
                          const std::function<bool(const Vec3&, const Vec3&, Vec3&)>& hit,
                          const std::function<bool(const Vec3&)>& near, int steps = 20);

}  // namespace fascicle
