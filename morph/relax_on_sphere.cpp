// The thesis's sphere map (Zeleny 2011, ch. 6.3, after Alexa 2000, "Merging polyhedral shapes
// with scattered features"), kept so that it can be compared with the default method.
#include "geometry/errors.h"
#include "morph/sphere_steps.h"
#include "morph/surface_query.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace fascicle::detail {
namespace {

/// Ritter 1990, "An efficient bounding sphere": start from the most distant of the six axis
/// extreme pairs, then grow the sphere over every point outside it.
void ritter_sphere(const std::vector<Vec3>& points, Vec3& centre, double& radius) {
  int lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (int i = 0; i < static_cast<int>(points.size()); ++i)
    for (int k = 0; k < 3; ++k) {
      if (points[i][k] < points[lo[k]][k]) lo[k] = i;
      if (points[i][k] > points[hi[k]][k]) hi[k] = i;
    }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if ((points[hi[k]] - points[lo[k]]).squaredNorm() > (points[hi[axis]] - points[lo[axis]]).squaredNorm()) axis = k;
  centre = 0.5 * (points[lo[axis]] + points[hi[axis]]);
  radius = 0.5 * (points[hi[axis]] - points[lo[axis]]).norm();
  for (const Vec3& p : points) {
    const double d = (p - centre).norm();
    if (d > radius) {
      const double grown = 0.5 * (radius + d);
      centre += (d - grown) / d * (p - centre);
      radius = grown;
    }
  }
}

/// Index of the sphere vertex nearest to `target`.
int nearest_vertex(const std::vector<Vec3>& x, const Vec3& target) {
  int best = 0;
  double best_d = 1e300;
  for (int i = 0; i < static_cast<int>(x.size()); ++i) {
    const double d = (x[i] - target).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

/// Jacobi centroid relaxation with renormalisation; returns iterations, stops when the largest
/// move is under `threshold` or after `max_iterations`.
int relax(const MeshAdjacency& adj, const std::vector<char>& fixed, std::vector<Vec3>& x, double threshold,
          int max_iterations, bool& converged) {
  std::vector<Vec3> next(x.size());
  converged = false;
  int it = 0;
  while (it < max_iterations) {
    ++it;
    double largest = 0.0;
    for (int v = 0; v < static_cast<int>(x.size()); ++v) {
      if (fixed[v]) {
        next[v] = x[v];
        continue;
      }
      Vec3 c = Vec3::Zero();
      for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) c += x[adj.neighbours[i]];
      const double n = c.norm();
      next[v] = n > 0.0 ? Vec3(c / n) : x[v];
      largest = std::max(largest, (next[v] - x[v]).norm());
    }
    x.swap(next);
    if (largest < threshold) {
      converged = true;
      break;
    }
  }
  return it;
}

long count_flipped(const TriangleMesh& mesh, const std::vector<Vec3>& x) {
  long flipped = 0;
  for (const Triangle& t : mesh.triangles)
    if (!(sphere_det(x[t[0]], x[t[1]], x[t[2]]) > 0.0)) ++flipped;
  return flipped;
}

}  // namespace

std::vector<Vec3> thesis_relax(const TriangleMesh& mesh, const MeshAdjacency& adj, const SphereMapOptions& options,
                               SphereMapReport& report) {
  const int nv = static_cast<int>(mesh.positions.size());
  // 1. Bounding sphere; its centre must be inside the muscle for the projection to be one-to-one
  //    on star-shaped parts. If it is not (exact test), move it just inside, next to the closest
  //    surface point.
  Vec3 centre;
  double radius = 0.0;
  ritter_sphere(mesh.positions, centre, radius);
  const SurfaceQuery query(mesh);
  if (!query.inside(centre)) {
    const SurfacePoint near = query.closest_point(centre);
    const Triangle& t = mesh.triangles[near.face];
    const Vec3 normal =
        (mesh.positions[t[1]] - mesh.positions[t[0]]).cross(mesh.positions[t[2]] - mesh.positions[t[0]]).normalized();
    double depth = 1e-3 * radius;
    Vec3 moved = near.position - depth * normal;
    for (int attempt = 0; attempt < 40 && !query.inside(moved); ++attempt) {
      depth *= 0.5;
      moved = near.position - depth * normal;
    }
    if (query.inside(moved)) {
      centre = moved;
      report.center_moved_inside = true;
    }
  }
  // 2. Normalise: translate and scale to the unit sphere, project every vertex.
  std::vector<Vec3> start(nv);
  for (int v = 0; v < nv; ++v) {
    const Vec3 d = (mesh.positions[v] - centre) / radius;
    const double n = d.norm();
    start[v] = n > 0.0 ? Vec3(d / n) : Vec3::UnitZ();
  }

  std::mt19937 random(options.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double tetra_edge = std::sqrt(8.0 / 3.0);
  std::vector<Vec3> x;
  int iterations = 0;
  bool collapsed = true;
  for (int attempt = 0; attempt <= options.relax_restarts; ++attempt) {
    if (attempt > 0) ++report.restarts;
    // 3. A randomly rotated regular tetrahedron; its corners' nearest vertices are fixed.
    const Eigen::Quaterniond rotation =
        Eigen::Quaterniond(gauss(random), gauss(random), gauss(random), gauss(random)).normalized();
    const Vec3 corners[4] = {Vec3(1, 1, 1) / std::sqrt(3.0), Vec3(1, -1, -1) / std::sqrt(3.0),
                             Vec3(-1, 1, -1) / std::sqrt(3.0), Vec3(-1, -1, 1) / std::sqrt(3.0)};
    x = start;
    std::vector<char> fixed(nv, 0);
    std::vector<int> anchors;
    for (const Vec3& corner : corners) {
      const int v = nearest_vertex(x, rotation * corner);
      fixed[v] = 1;
      anchors.push_back(v);
    }
    bool converged = false;
    iterations += relax(adj, fixed, x, options.relax_threshold, options.relax_max_iterations, converged);
    // 4. Collapse check: near each point antipodal to an anchor there must be a vertex closer
    //    than a tetrahedron edge; otherwise everything crowded around the anchors: restart.
    collapsed = false;
    std::vector<int> antipodal;
    for (int v : anchors) {
      const int w = nearest_vertex(x, -x[v]);
      if ((x[w] + x[v]).norm() >= tetra_edge) collapsed = true;
      antipodal.push_back(w);
    }
    if (collapsed) continue;
    for (int w : antipodal) fixed[w] = 1;
    // 5. Relax with the antipodal vertices fixed too, then the orientation check (formula 6.1):
    //    if a triangle is flipped, lower the threshold and relax again.
    double threshold = options.relax_threshold;
    iterations += relax(adj, fixed, x, threshold, options.relax_max_iterations, converged);
    while (count_flipped(mesh, x) > 0 && report.threshold_lowerings < options.relax_threshold_lowerings) {
      ++report.threshold_lowerings;
      threshold *= 0.1;
      iterations += relax(adj, fixed, x, threshold, options.relax_max_iterations, converged);
    }
    report.iterations = iterations;
    const long flipped = count_flipped(mesh, x);
    if (flipped > 0) {
      report.failure = std::to_string(flipped) + " of " + std::to_string(mesh.triangles.size()) +
                       " triangles flipped after " + std::to_string(iterations) + " iterations and " +
                       std::to_string(report.threshold_lowerings) + " threshold lowerings" +
                       (converged ? "" : " (relaxation did not converge)");
    }
    return x;
  }
  report.iterations = iterations;
  report.failure = "collapse check failed for " + std::to_string(options.relax_restarts + 1) +
                   " random tetrahedra (vertices crowd around the anchors)";
  return x;
}

}  // namespace fascicle::detail
