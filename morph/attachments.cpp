#include "morph/attachments.h"

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "morph/sphere_locator.h"

#include <cstdio>

namespace fascicle {
namespace {

std::string number(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.4g", value);
  return buffer;
}

}  // namespace

void AttachmentOptions::validate() const {
  if (!(max_landmark_distance > 0.0))
    throw OptionError("attachment option max_landmark_distance = " + std::to_string(max_landmark_distance) +
                      ": must be > 0");
  if (!(end_fraction > 0.0 && end_fraction < 0.5))
    throw OptionError("attachment option end_fraction = " + std::to_string(end_fraction) + ": must be in (0, 0.5)");
}

Vec3 AttachmentArea::centroid() const {
  Vec3 sum = Vec3::Zero();
  for (const SurfacePoint& p : points) sum += p.position;
  return points.empty() ? sum : Vec3(sum / static_cast<double>(points.size()));
}

AttachmentArea project_landmarks(const SurfaceQuery& query, double diagonal, const std::vector<Vec3>& landmarks,
                                 const std::string& source, const AttachmentOptions& options) {
  options.validate();
  if (landmarks.empty())
    throw InputError(ErrorCode::landmarks, source + ": no landmark points");
  AttachmentArea area;
  area.source = source;
  const double tolerance = options.max_landmark_distance * diagonal;
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    SurfacePoint p = query.closest_point(landmarks[i]);
    if (p.distance > tolerance)
      throw InputError(ErrorCode::landmarks,
                       source + ": landmark " + std::to_string(i + 1) + " is " + number(p.distance) +
                           " from the muscle surface; at most " + number(tolerance) + " (" +
                           number(options.max_landmark_distance) +
                           " of the muscle's bounding-box diagonal) is accepted: is it the right muscle's file?");
    area.max_distance = std::max(area.max_distance, p.distance);
    area.points.push_back(p);
  }
  return area;
}

Attachments landmark_attachments(const TriangleMesh& mesh, const std::vector<Vec3>& origin,
                                 const std::string& origin_source, const std::vector<Vec3>& insertion,
                                 const std::string& insertion_source, const AttachmentOptions& options) {
  const SurfaceQuery query(mesh);
  const double diagonal = bounding_box(mesh.positions).diagonal();
  Attachments out;
  out.origin = project_landmarks(query, diagonal, origin, origin_source, options);
  out.insertion = project_landmarks(query, diagonal, insertion, insertion_source, options);
  if ((out.origin.centroid() - out.insertion.centroid()).norm() < 1e-6 * diagonal)
    throw InputError(ErrorCode::landmarks, origin_source + " and " + insertion_source +
                                               ": origin and insertion areas have the same centre");
  return out;
}

Attachments automatic_attachments(const TriangleMesh& mesh, const AttachmentOptions& options) {
  options.validate();
  if (mesh.positions.empty() || mesh.triangles.empty())
    throw TopologyError("automatic attachments: the mesh is empty");
  const std::size_t nv = mesh.positions.size();
  const PrincipalAxes principal = principal_axes(mesh.positions);
  const Vec3& mean = principal.mean;
  Vec3 axis = principal.major();
  if (axis.z() < 0.0) axis = -axis;
  double lo = 1e300, hi = -1e300;
  std::vector<double> along(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    along[v] = (mesh.positions[v] - mean).dot(axis);
    lo = std::min(lo, along[v]);
    hi = std::max(hi, along[v]);
  }
  const double band = options.end_fraction * (hi - lo);
  // One face and corner per vertex, to express vertices as surface points.
  std::vector<int> face_of(nv, -1), corner_of(nv, 0);
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles[f][k];
      if (face_of[v] < 0) {
        face_of[v] = static_cast<int>(f);
        corner_of[v] = k;
      }
    }
  Attachments out;
  out.automatic = true;
  out.origin.source = out.insertion.source = "automatic";
  for (std::size_t v = 0; v < nv; ++v) {
    if (face_of[v] < 0) continue;
    SurfacePoint p;
    p.face = face_of[v];
    p.barycentric = Vec3::Zero();
    p.barycentric[corner_of[v]] = 1.0;
    p.position = mesh.positions[v];
    if (along[v] >= hi - band) out.origin.points.push_back(p);
    if (along[v] <= lo + band) out.insertion.points.push_back(p);
  }
  return out;
}

Vec3 sphere_centre(const AttachmentArea& area, const std::vector<Vec3>& sphere, const std::vector<Triangle>& triangles) {
  Vec3 sum = Vec3::Zero();
  for (const SurfacePoint& p : area.points) sum += point_on_sphere(sphere, triangles, p);
  const double n = sum.norm();
  return n > 0.0 ? Vec3(sum / n) : Vec3::UnitZ();
}

}  // namespace fascicle
