#pragma once
/// \file align_on_sphere.h
/// Feature alignment on the sphere (pipeline step 4 of ../shared/docs/METHOD.md; thesis ch. 6.3,
/// formula 6.2): a template's sphere map is moved so that its origin and insertion centres land
/// on the muscle's, without ever flipping a triangle.

#include "geometry/mesh.h"
#include "morph/surface_query.h"

#include <nlohmann/json_fwd.hpp>

#include <vector>

namespace fascicle {

/// Options of the alignment.
struct AlignOptions {
  /// Radius of the first pull, as a chord length on the unit sphere (default 0.6); it never
  /// exceeds 0.9 of the distance between the insertion and origin centres, so the origin stays put.
  double initial_radius = 0.6;
  /// Factor applied to the radius after each round (default 0.8).
  double shrink = 0.8;
  /// Largest number of pull rounds (default 60).
  int max_rounds = 60;
  /// Stop when the insertion centre is this close to its target, radians (default 1e-6).
  double tolerance = 1e-6;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// What the alignment did.
struct AlignReport {
  double origin_error_deg = 0.0;              ///< angle between the origin centres at the end
  double insertion_error_rotation_deg = 0.0;  ///< insertion angle after the two rotations
  double insertion_error_deg = 0.0;           ///< insertion angle at the end
  int rounds = 0;                             ///< pull rounds taken
  int halvings = 0;                           ///< pulls halved because a triangle would flip
  long flipped = 0;                           ///< triangles with det <= 0 at the end (always 0)
  nlohmann::json to_json() const;
};

/// Aligns the sphere map `sphere` (#V unit vectors, `triangles` positively oriented) so that the
/// surface points `origin` and `insertion` of it (face + barycentric coordinates on these
/// triangles) move onto the unit vectors `target_origin` and `target_insertion`:
///  1. the rotation taking the origin centre onto its target (exact);
///  2. the rotation about the target origin axis that brings the insertion centre closest;
///  3. formula 6.2: every vertex within chord distance d of the insertion centre v_f moves by
///     t (1 - |v_j - v_f| / d) (t = target - v_f; the thesis's weight, normalised to 1 at the
///     centre) and is renormalised; d shrinks each round (but stays at least 3 |t|, as a
///     narrower pull folds the sphere). A pull that would leave any triangle
///     with det below the degenerate limit is halved until it does not (or skipped), so the
///     map stays a bijection. The origin face's corners never move.
/// Throws std::invalid_argument when the targets or centres coincide.
AlignReport align_on_sphere(const std::vector<Triangle>& triangles, std::vector<Vec3>& sphere,
                            const SurfacePoint& origin, const SurfacePoint& insertion, const Vec3& target_origin,
                            const Vec3& target_insertion, const AlignOptions& options = {});

}  // namespace fascicle
