#pragma once
/// \file azimuth_cast.h
/// The search of the fibre ends' cast (fibres/decompose.h, step 6) with one shrink factor per
/// azimuth round the cast axis. The cast starts the ends from the layer of fibre points next to
/// the face, shrunk towards its centroid, and needs every end to land within the end radius of
/// an area point. One factor for the whole face (the largest step 1, 0.8, 0.8^2, ... at which
/// every end lands) is set by the end that needs the most shrink, so an area that is narrow on
/// one side of the layer's centre (a tapering end, an area off the axis) gathers all the ends.
/// Here that uniform factor is the floor, and the factor is lambda(phi), piecewise linear in the
/// azimuth phi of an offset seen along the axis: each bin at most the largest step at which every
/// end it brackets still lands on the area, from a start inside the muscle, no deeper along the
/// axis than the deepest uniform end and no shallower than the shallowest (so the face keeps the
/// uniform face's depth and no end is cast far past the others). The map r -> lambda(phi) r keeps
/// the order of the points along every azimuth and has a positive Jacobian (lambda(phi)^2), so the
/// face is a homeomorphic copy of the layer and no cell between them turns over.
#include "geometry/mesh.h"

#include <array>
#include <functional>
#include <vector>

namespace fascicle {

/// The result of cast_azimuth_face(): lambda(phi) and the ends it gave.
struct AzimuthCast {
  static constexpr int kBins = 24;  ///< azimuth bins (every 15 degrees)
  bool placed = false;              ///< every end landed near the area
  Vec3 u = Vec3::UnitX(), v = Vec3::UnitY();  ///< basis of the plane across the axis (phi from u towards v)
  std::array<double, kBins> bins{};           ///< lambda at each bin's azimuth, 2 pi i / kBins
  std::vector<Vec3> ends;                     ///< the ends, in the order of `offsets` (empty when not placed)
  /// lambda(phi) of an offset (its component across the axis gives phi).
  double factor(const Vec3& offset) const;
  double smallest() const;  ///< least bin factor (0 when not placed)
  double largest() const;   ///< largest bin factor (0 when not placed)
};

/// Casts ends from `centre` + lambda(phi) `offsets` along `axis`. `hit(start, axis, end)` casts one
/// ray (false: no hit); `near(end)` says whether an end lies close enough to the area; `inside(p)`
/// whether a point lies inside the muscle (a factor above the uniform one needs its start inside).
/// Steps 1, 0.8, 0.8^2, ... (`steps` of them, >= 1). Not placed when no step puts every end on the
/// area; an end that misses between its bins' steps lowers them (never below the uniform factor).
AzimuthCast cast_azimuth_face(const Vec3& centre, const std::vector<Vec3>& offsets, const Vec3& axis,
                              const std::function<bool(const Vec3&, const Vec3&, Vec3&)>& hit,
                              const std::function<bool(const Vec3&)>& near,
                              const std::function<bool(const Vec3&)>& inside, int steps = 20);

}  // namespace fascicle
