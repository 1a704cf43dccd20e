#include "morph/align_on_sphere.h"

#include "geometry/errors.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_steps.h"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cmath>
#include <stdexcept>

namespace fascicle {
namespace {

double angle_deg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI; }

void rotate(std::vector<Vec3>& sphere, const Eigen::Matrix3d& r) {
  for (Vec3& p : sphere) p = (r * p).normalized();
}

}  // namespace

void AlignOptions::validate() const {
  if (!(initial_radius > 0.0 && initial_radius <= 2.0))
    throw OptionError("align option initial_radius = " + std::to_string(initial_radius) + ": must be in (0, 2]");
  if (!(shrink > 0.0 && shrink < 1.0))
    throw OptionError("align option shrink = " + std::to_string(shrink) + ": must be in (0, 1)");
  if (max_rounds < 0) throw OptionError("align option max_rounds = " + std::to_string(max_rounds) + ": must be >= 0");
  if (!(tolerance > 0.0)) throw OptionError("align option tolerance = " + std::to_string(tolerance) + ": must be > 0");
}

nlohmann::json AlignReport::to_json() const {
  return {{"origin_error_deg", origin_error_deg},
          {"insertion_error_rotation_deg", insertion_error_rotation_deg},
          {"insertion_error_deg", insertion_error_deg},
          {"rounds", rounds},
          {"halvings", halvings},
          {"flipped", flipped}};
}

AlignReport align_on_sphere(const std::vector<Triangle>& triangles, std::vector<Vec3>& sphere,
                            const SurfacePoint& origin, const SurfacePoint& insertion, const Vec3& target_origin,
                            const Vec3& target_insertion, const AlignOptions& options) {
  options.validate();
  const Vec3 to = target_origin.normalized(), ti = target_insertion.normalized();
  if (!(to.cross(ti).norm() > 1e-12) && to.dot(ti) > 0.0)
    throw std::invalid_argument("align on sphere: origin and insertion targets coincide");
  AlignReport report;
  // 1. Origin centre onto its target.
  Vec3 o = point_on_sphere(sphere, triangles, origin);
  rotate(sphere, Eigen::Quaterniond::FromTwoVectors(o, to).toRotationMatrix());
  // 2. About that axis, insertion centre as close as a rotation allows.
  Vec3 i = point_on_sphere(sphere, triangles, insertion);
  const Vec3 pi = i - i.dot(to) * to, pt = ti - ti.dot(to) * to;
  if (pi.norm() > 1e-15 && pt.norm() > 1e-15) {
    const double angle = std::atan2(pi.cross(pt).dot(to), pi.dot(pt));
    rotate(sphere, Eigen::AngleAxisd(angle, to).toRotationMatrix());
  }
  // Re-pin the origin exactly after the round-off of two rotations.
  o = point_on_sphere(sphere, triangles, origin);
  rotate(sphere, Eigen::Quaterniond::FromTwoVectors(o, to).toRotationMatrix());
  i = point_on_sphere(sphere, triangles, insertion);
  report.insertion_error_rotation_deg = angle_deg(i, ti);

  // 3. Formula 6.2 pulls with shrinking radius, never accepting a flip.
  std::vector<std::vector<int>> faces_of(sphere.size());
  for (std::size_t f = 0; f < triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) faces_of[triangles[f][k]].push_back(static_cast<int>(f));
  std::vector<char> pinned(sphere.size(), 0);
  for (int k = 0; k < 3; ++k) pinned[triangles.at(static_cast<std::size_t>(origin.face))[k]] = 1;
  double d = options.initial_radius;
  std::vector<int> moved;
  std::vector<Vec3> saved;
  for (int round = 0; round < options.max_rounds; ++round) {
    i = point_on_sphere(sphere, triangles, insertion);
    const Vec3 t = ti - i;
    if (std::atan2(i.cross(ti).norm(), i.dot(ti)) < options.tolerance) break;
    ++report.rounds;
    // A pull narrower than a few times its length folds the sphere; the radius shrinks round by
    // round but not below 3 |t|, and never reaches the origin.
    const double radius = std::min(std::max(d, 3.0 * t.norm()), 0.9 * (i - to).norm());
    double scale = 1.0;
    bool accepted = false;
    for (int attempt = 0; attempt < 30 && !accepted; ++attempt, scale *= 0.5) {
      moved.clear();
      saved.clear();
      for (std::size_t j = 0; j < sphere.size(); ++j) {
        if (pinned[j]) continue;
        const double dist = (sphere[j] - i).norm();
        if (dist >= radius) continue;
        moved.push_back(static_cast<int>(j));
        saved.push_back(sphere[j]);
        sphere[j] = (sphere[j] + scale * (1.0 - dist / radius) * t).normalized();
      }
      accepted = true;
      for (int j : moved) {
        for (int f : faces_of[j]) {
          const Triangle& tri = triangles[f];
          if (!(detail::sphere_det(sphere[tri[0]], sphere[tri[1]], sphere[tri[2]]) > detail::min_step_det)) {
            accepted = false;
            break;
          }
        }
        if (!accepted) break;
      }
      if (!accepted) {
        for (std::size_t m = 0; m < moved.size(); ++m) sphere[moved[m]] = saved[m];
        ++report.halvings;
      }
    }
    d *= options.shrink;
  }
  report.origin_error_deg = angle_deg(point_on_sphere(sphere, triangles, origin), to);
  report.insertion_error_deg = angle_deg(point_on_sphere(sphere, triangles, insertion), ti);
  for (const Triangle& tri : triangles)
    if (!(detail::sphere_det(sphere[tri[0]], sphere[tri[1]], sphere[tri[2]]) > 0.0)) ++report.flipped;
  return report;
}

}  // namespace fascicle
