// Quality of a sphere map; the orientation of every spherical triangle is decided by CGAL's
// exact orientation predicate (filtered, so as fast as doubles where the answer is clear).
#include "geometry/errors.h"
#include "morph/sphere_map.h"
#include "morph/sphere_steps.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fascicle {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

Kernel::Point_3 point(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

/// Angle at a of the geodesic triangle (a, b, c): between the tangent directions towards b, c.
double sphere_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 tb = b - a.dot(b) * a, tc = c - a.dot(c) * a;
  return std::atan2(tb.cross(tc).norm(), tb.dot(tc));
}

double plane_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 u = b - a, w = c - a;
  return std::atan2(u.cross(w).norm(), u.dot(w));
}

}  // namespace

bool SphereQuality::bijective() const {
  return flipped == 0 && degenerate == 0 && std::abs(area_sum - 4.0 * M_PI) < 1e-6;
}

namespace detail {

std::vector<double> area_shares(const TriangleMesh& mesh) {
  std::vector<double> shares(mesh.triangles.size());
  double total = 0.0;
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Triangle& t = mesh.triangles[f];
    const Vec3& a = mesh.positions[t[0]];
    shares[f] = 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
    total += shares[f];
  }
  if (!(total > 0.0)) {
    std::fill(shares.begin(), shares.end(), 1.0 / static_cast<double>(shares.size()));
    return shares;
  }
  const double floor = 1e-12 / static_cast<double>(shares.size());
  for (double& s : shares) s = std::max(s / total, floor);
  return shares;
}

}  // namespace detail

SphereQuality measure_sphere_map(const TriangleMesh& mesh, const std::vector<Vec3>& sphere) {
  FASCICLE_CHECK(sphere.size() == mesh.positions.size(), "one sphere point per vertex");
  SphereQuality q;
  q.triangles = static_cast<long>(mesh.triangles.size());
  const Kernel::Point_3 origin(0, 0, 0);
  double total_surface = 0.0;
  std::vector<double> surface(mesh.triangles.size());
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Triangle& t = mesh.triangles[f];
    const Vec3& a = mesh.positions[t[0]];
    surface[f] = 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
    total_surface += surface[f];
  }
  // Each triangle's orientation, spherical area and angle errors on threads; the sums below in the
  // triangles' order, so the figures do not depend on the threads.
  const std::size_t nf = mesh.triangles.size();
  std::vector<double> sphere_area(nf), angle_error(3 * nf, 0.0);
  std::vector<signed char> orientation(nf);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nf, 1024), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t f = range.begin(); f != range.end(); ++f) {
      const Triangle& t = mesh.triangles[f];
      const Vec3 &a = sphere[t[0]], &b = sphere[t[1]], &c = sphere[t[2]];
      orientation[f] = static_cast<signed char>(CGAL::orientation(origin, point(a), point(b), point(c)));
      sphere_area[f] = detail::sphere_triangle_area(a, b, c);
      if (surface[f] > 0.0 && total_surface > 0.0) {
        const Vec3 &pa = mesh.positions[t[0]], &pb = mesh.positions[t[1]], &pc = mesh.positions[t[2]];
        angle_error[3 * f] = std::abs(sphere_angle(a, b, c) - plane_angle(pa, pb, pc));
        angle_error[3 * f + 1] = std::abs(sphere_angle(b, c, a) - plane_angle(pb, pc, pa));
        angle_error[3 * f + 2] = std::abs(sphere_angle(c, a, b) - plane_angle(pc, pa, pb));
      }
    }
  });
  double log_sum = 0.0, angle_sum = 0.0;
  long log_count = 0, angle_count = 0;
  q.area_ratio_min = std::numeric_limits<double>::infinity();
  q.area_ratio_max = 0.0;
  for (std::size_t f = 0; f < nf; ++f) {
    const CGAL::Orientation o = static_cast<CGAL::Orientation>(orientation[f]);
    const double area = sphere_area[f];
    if (o == CGAL::NEGATIVE)
      ++q.flipped;
    else if (o == CGAL::COPLANAR || area < degenerate_area)
      ++q.degenerate;
    q.area_sum += area;
    if (surface[f] > 0.0 && total_surface > 0.0) {
      const double ratio = (area / (4.0 * M_PI)) / (surface[f] / total_surface);
      q.area_ratio_min = std::min(q.area_ratio_min, ratio);
      q.area_ratio_max = std::max(q.area_ratio_max, ratio);
      if (ratio > 0.0) {
        log_sum += std::abs(std::log(ratio));
        ++log_count;
      }
      for (int k = 0; k < 3; ++k) {
        const double e = angle_error[3 * f + static_cast<std::size_t>(k)];
        angle_sum += e;
        q.angle_error_max_deg = std::max(q.angle_error_max_deg, e * 180.0 / M_PI);
        ++angle_count;
      }
    }
  }
  if (log_count == 0) q.area_ratio_min = 0.0;
  q.area_log_mean = log_count ? log_sum / static_cast<double>(log_count) : 0.0;
  q.angle_error_mean_deg = angle_count ? angle_sum / static_cast<double>(angle_count) * 180.0 / M_PI : 0.0;
  return q;
}

nlohmann::json to_json(const SphereQuality& q) {
  return nlohmann::json{{"triangles", q.triangles},
                        {"flipped", q.flipped},
                        {"degenerate", q.degenerate},
                        {"area_sum", q.area_sum},
                        {"area_sum_error", q.area_sum - 4.0 * M_PI},
                        {"area_ratio_min", q.area_ratio_min},
                        {"area_ratio_max", q.area_ratio_max},
                        {"area_log_mean", q.area_log_mean},
                        {"angle_error_mean_deg", q.angle_error_mean_deg},
                        {"angle_error_max_deg", q.angle_error_max_deg},
                        {"bijective", q.bijective()}};
}

}  // namespace fascicle
