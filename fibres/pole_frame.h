#pragma once
/// \file pole_frame.h
/// A frame on the unit sphere in which two chosen points are the poles: a rotation followed by a
/// Moebius transformation (in stereographic coordinates) sends `origin` to the north pole
/// (0, 0, 1) and `insertion` to the south pole (0, 0, -1). Moebius transformations are the
/// conformal, orientation-preserving bijections of the sphere (e.g. Needham, "Visual Complex
/// Analysis", ch. 3), so the frame moves a bijective sphere map to another bijective map without
/// touching its connectivity; the decomposition uses it to put the origin and insertion areas of
/// the muscle and of the template at the same poles exactly.
#include "geometry/mesh.h"

#include <complex>

namespace fascicle {

/// Rotation + Moebius transformation with origin -> north pole, insertion -> south pole.
class PoleFrame {
 public:
  /// `origin`, `insertion`: non-zero vectors (only their directions count), not parallel in the
  /// same direction (angle > 1e-9 rad). `scale` > 0 multiplies the stereographic coordinate after
  /// the transformation (a hyperbolic Moebius map fixing both poles: scale > 1 moves points
  /// towards the south pole). Throws std::invalid_argument for coinciding or bad directions.
  PoleFrame(const Vec3& origin, const Vec3& insertion, double scale = 1.0);

  /// Image of a unit vector in the pole frame (a unit vector).
  Vec3 to_pole(const Vec3& p) const;
  /// Inverse of to_pole.
  Vec3 from_pole(const Vec3& q) const;

  /// Changes the scale (see the constructor); to_pole/from_pole use the new value.
  void set_scale(double scale);
  double scale() const { return scale_; }

  /// Stereographic coordinate of a unit vector, projected from the south pole (north -> 0).
  static std::complex<double> stereographic(const Vec3& p);
  /// Inverse stereographic projection (0 -> north pole; infinity -> south pole).
  static Vec3 from_stereographic(std::complex<double> w);

 private:
  Eigen::Matrix3d rotation_;   // origin -> north pole
  std::complex<double> pole_;  // stereographic coordinate of the rotated insertion
  bool moebius_ = false;       // false when the insertion is already at the south pole
  double scale_ = 1.0;
};

/// Polar angle (from the north pole, radians in [0, pi]) and azimuth (radians in (-pi, pi]) of a
/// unit vector.
inline double polar_angle(const Vec3& q) { return std::atan2(std::hypot(q.x(), q.y()), q.z()); }
inline double azimuth(const Vec3& q) { return std::atan2(q.y(), q.x()); }
/// Unit vector of polar angle `theta` and azimuth `phi`.
inline Vec3 from_polar(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

}  // namespace fascicle
