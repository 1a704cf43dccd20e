// Tutte embedding of the mesh minus one triangle, lifted to the sphere by inverse stereographic
// projection with an orientation-preserving choice of origin and scale.
#include "geometry/errors.h"
#include "morph/sphere_steps.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>

namespace fascicle::detail {

std::vector<double> edge_distances(const TriangleMesh& mesh, const MeshAdjacency& adj, int source,
                                   std::vector<int>* previous) {
  std::vector<double> dist(mesh.positions.size(), std::numeric_limits<double>::infinity());
  if (previous) previous->assign(mesh.positions.size(), -1);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  dist[source] = 0.0;
  queue.emplace(0.0, source);
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > dist[v]) continue;
    for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) {
      const int w = adj.neighbours[i];
      const double nd = d + (mesh.positions[w] - mesh.positions[v]).norm();
      if (nd < dist[w]) {
        dist[w] = nd;
        if (previous) (*previous)[w] = v;
        queue.emplace(nd, w);
      }
    }
  }
  return dist;
}

namespace {

using Vec2 = Eigen::Vector2d;

double orient2d(const Vec2& a, const Vec2& b, const Vec2& c) {
  return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

/// Circumcentre and squared radius of a planar triangle (false when degenerate).
bool circumcircle(const Vec2& a, const Vec2& b, const Vec2& c, Vec2& centre, double& r2) {
  const Vec2 u = b - a, w = c - a;
  const double d = 2.0 * (u.x() * w.y() - u.y() * w.x());
  if (d == 0.0) return false;
  const double uu = u.squaredNorm(), ww = w.squaredNorm();
  const Vec2 m((w.y() * uu - u.y() * ww) / d, (u.x() * ww - w.x() * uu) / d);
  centre = a + m;
  r2 = m.squaredNorm();
  return true;
}

}  // namespace

TutteLift tutte_lift(const TriangleMesh& mesh, const MeshAdjacency& adj, bool anisotropic) {
  const int nv = static_cast<int>(mesh.positions.size());
  const int nf = static_cast<int>(mesh.triangles.size());
  // Positions relative to the box centre: CT offsets of 1e7 cost no precision.
  Vec3 lo_corner = mesh.positions[0], hi_corner = mesh.positions[0];
  for (const Vec3& p : mesh.positions) {
    lo_corner = lo_corner.cwiseMin(p);
    hi_corner = hi_corner.cwiseMax(p);
  }
  const Vec3 middle = 0.5 * (lo_corner + hi_corner);
  std::vector<Vec3> q(nv);
  for (int v = 0; v < nv; ++v) q[v] = mesh.positions[v] - middle;

  // Long direction and elongation. A conformal (cotangent) embedding of a tube of length L and
  // circumference C crowds its ends by exp(-2 pi L / C); with any positive weights Tutte's
  // theorem still holds, so conduction along the tube is raised by k^2 (k = L^2 / area, about
  // L / C), which embeds it as if it were k times shorter. The local long direction is the
  // gradient of the edge distance from one end; the ends are a double sweep's far pair.
  std::vector<Vec3> direction(nf, Vec3::Zero());
  double k2 = 1.0;
  if (anisotropic) {
    const std::vector<double> from0 = edge_distances(mesh, adj, 0);
    const int s_end = static_cast<int>(std::max_element(from0.begin(), from0.end()) - from0.begin());
    const std::vector<double> from_s = edge_distances(mesh, adj, s_end);
    const double length = *std::max_element(from_s.begin(), from_s.end());
    double area = 0.0;
    for (int f = 0; f < nf; ++f) {
      const Triangle& t = mesh.triangles[f];
      const Vec3 u = q[t[1]] - q[t[0]], w = q[t[2]] - q[t[0]];
      const Vec3 n = u.cross(w);
      const double n2 = n.squaredNorm();
      area += 0.5 * std::sqrt(n2);
      if (n2 > 0.0) {
        // Gradient of the linear interpolant of from_s on the triangle.
        const double d1 = from_s[t[1]] - from_s[t[0]], d2 = from_s[t[2]] - from_s[t[0]];
        const Vec3 g = (d1 * w.cross(n) + d2 * n.cross(u)) / n2;
        const double gn = g.norm();
        if (gn > 0.0) direction[f] = g / gn;
      }
    }
    const double k = std::clamp(length * length / std::max(area, 1e-300), 1.0, 1e3);
    k2 = k * k;
  }

  // Cotangent weights clamped to be positive, times the conduction factor along the long
  // direction (mean of the two faces at the edge).
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(nf) * 6);
  int cut = 0;
  double cut_area = -1.0;
  std::vector<double> face_area2(nf);
  for (int f = 0; f < nf; ++f) {
    const Triangle& t = mesh.triangles[f];
    face_area2[f] = (q[t[1]] - q[t[0]]).cross(q[t[2]] - q[t[0]]).norm();
    if (face_area2[f] > cut_area * (1.0 + 1e-9)) {  // ties: first one, so scaling cannot change the pick
      cut_area = face_area2[f];
      cut = f;
    }
    for (int k = 0; k < 3; ++k) {
      const Vec3& o = q[t[k]];
      const Vec3 u = q[t[(k + 1) % 3]] - o, w = q[t[(k + 2) % 3]] - o;
      const double cross = u.cross(w).norm();
      const double cot = cross > 0.0 ? u.dot(w) / cross : 0.0;
      entries.emplace_back(t[(k + 1) % 3], t[(k + 2) % 3], 0.5 * cot);
      entries.emplace_back(t[(k + 2) % 3], t[(k + 1) % 3], 0.5 * cot);
    }
  }
  Eigen::SparseMatrix<double> weights(nv, nv);
  weights.setFromTriplets(entries.begin(), entries.end());
  entries.clear();
  double mean_abs = 0.0;
  for (int k = 0; k < weights.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(weights, k); it; ++it) mean_abs += std::abs(it.value());
  mean_abs /= std::max<Eigen::Index>(weights.nonZeros(), 1);
  const double lo = 1e-3 * mean_abs, hi = 1e3 * mean_abs;
  for (int k = 0; k < weights.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(weights, k); it; ++it)
      it.valueRef() = std::clamp(it.value(), lo, hi);
  if (k2 > 1.0) {
    // Each directed edge (a, b) lies in exactly one face; the undirected edge's factor uses both.
    for (int v = 0; v < nv; ++v)
      for (int c = adj.corner_start[v]; c < adj.corner_start[v + 1]; ++c) {
        const int w = adj.corner_next[c];
        const int f = adj.corner_face[c];
        // The face across the edge holds the corner of w whose next is v.
        int g = f;
        for (int d = adj.corner_start[w]; d < adj.corner_start[w + 1]; ++d)
          if (adj.corner_next[d] == v) g = adj.corner_face[d];
        Vec3 a = direction[f] + direction[g];
        const double an = a.norm();
        if (!(an > 0.0)) continue;
        const Vec3 e = (q[w] - q[v]).normalized();
        const double cos_a = e.dot(a / an);
        weights.coeffRef(v, w) *= 1.0 + (k2 - 1.0) * cos_a * cos_a;
      }
  }

  // Dirichlet problem: the cut triangle's corners fixed on an equilateral triangle of
  // circumradius 1, every other vertex the weighted mean of its neighbours.
  const Triangle boundary = mesh.triangles[cut];
  std::vector<Vec2> uv(nv, Vec2::Zero());
  std::vector<int> index(nv, -1);
  for (int k = 0; k < 3; ++k) {
    const double angle = M_PI / 2 + 2.0 * M_PI * k / 3.0;
    uv[boundary[k]] = Vec2(std::cos(angle), std::sin(angle));
  }
  int n = 0;
  for (int v = 0; v < nv; ++v)
    if (v != boundary[0] && v != boundary[1] && v != boundary[2]) index[v] = n++;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 2);
  entries.reserve(static_cast<std::size_t>(weights.nonZeros()) + n);
  for (int v = 0; v < nv; ++v) {
    if (index[v] < 0) continue;
    double diagonal = 0.0;
    for (Eigen::SparseMatrix<double>::InnerIterator it(weights, v); it; ++it) {
      const int w = static_cast<int>(it.row());
      diagonal += it.value();
      if (index[w] >= 0)
        entries.emplace_back(index[v], index[w], -it.value());
      else
        rhs.row(index[v]) += it.value() * uv[w].transpose();
    }
    entries.emplace_back(index[v], index[v], diagonal);
  }
  Eigen::SparseMatrix<double> system(n, n);
  system.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(system);
  if (solver.info() != Eigen::Success)
    throw SolverError("sphere map: the Tutte system could not be factorised (mesh has " + std::to_string(nv) +
                      " vertices)");
  const Eigen::MatrixXd solution = solver.solve(rhs);
  if (solver.info() != Eigen::Success || !solution.allFinite())
    throw SolverError("sphere map: the Tutte solve failed or produced NaN");
  for (int v = 0; v < nv; ++v)
    if (index[v] >= 0) uv[v] = solution.row(index[v]).transpose();

  // Origin and scale of the lift. The geodesic triangle through three lifted points keeps the
  // planar orientation iff the chosen origin O has power ratio: for every interior triangle whose
  // circumcircle contains O, s^2 (r^2 - |m - O|^2) < 1, while for the cut triangle
  // s^2 (r_B^2 - |O|^2) > 1 (it must become the cap over the north pole). Candidates for O: the
  // centroids of the smallest planar triangles (where the embedding is crowded the circles are
  // small) and of the triangle nearest the planar centre.
  std::vector<int> order(nf);
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> planar_area(nf);
  (void)face_area2;
  std::vector<Vec2> centre(nf);
  std::vector<double> radius2(nf, -1.0);
  int nearest = -1;
  double nearest_d = 1e300;
  for (int f = 0; f < nf; ++f) {
    const Triangle& t = mesh.triangles[f];
    planar_area[f] = std::abs(orient2d(uv[t[0]], uv[t[1]], uv[t[2]]));
    if (f == cut) continue;
    if (!circumcircle(uv[t[0]], uv[t[1]], uv[t[2]], centre[f], radius2[f])) radius2[f] = -1.0;  // skipped
    const double d = ((uv[t[0]] + uv[t[1]] + uv[t[2]]) / 3.0).squaredNorm();
    if (d < nearest_d) {
      nearest_d = d;
      nearest = f;
    }
  }
  const int candidates = std::min(nf - 1, 8);
  std::partial_sort(order.begin(), order.begin() + candidates, order.end(),
                    [&](int a, int b) { return planar_area[a] < planar_area[b]; });
  std::vector<int> tries(order.begin(), order.begin() + candidates);
  if (nearest >= 0) tries.push_back(nearest);
  double best_ratio = -1.0, best_max = 0.0;
  Vec2 best_origin = Vec2::Zero();
  for (int f : tries) {
    if (f == cut) continue;
    const Triangle& t = mesh.triangles[f];
    const Vec2 o = (uv[t[0]] + uv[t[1]] + uv[t[2]]) / 3.0;
    const double outer = 1.0 - o.squaredNorm();
    if (!(outer > 0.0)) continue;
    double worst = 0.0;
    for (int g = 0; g < nf; ++g) {
      if (g == cut || radius2[g] < 0.0) continue;  // a collinear triangle is counted degenerate later
      worst = std::max(worst, radius2[g] - (centre[g] - o).squaredNorm());
    }
    const double ratio = worst > 0.0 ? outer / worst : 1e300;
    if (ratio > best_ratio) {
      best_ratio = ratio;
      best_max = worst;
      best_origin = o;
    }
  }
  TutteLift lift;
  lift.cut_face = cut;
  lift.margin = best_ratio;
  const double outer = 1.0 - best_origin.squaredNorm();
  // Geometric mean of the two bounds when both exist.
  const double s2 = best_max > 0.0 ? 1.0 / std::sqrt(outer * best_max) : 4.0 / outer;
  const double s = std::sqrt(s2);
  lift.sphere.resize(nv);
  for (int v = 0; v < nv; ++v) {
    const Vec2 w = s * (uv[v] - best_origin);
    const double r2 = w.squaredNorm();
    lift.sphere[v] = Vec3(2.0 * w.x(), 2.0 * w.y(), r2 - 1.0) / (1.0 + r2);
    lift.sphere[v].normalize();
  }
  // The mesh's faces may have come out clockwise on the sphere: mirror if so (mirroring flips
  // every orientation at once).
  double total = 0.0;
  for (const Triangle& t : mesh.triangles) total += sphere_det(lift.sphere[t[0]], lift.sphere[t[1]], lift.sphere[t[2]]);
  if (total < 0.0)
    for (Vec3& p : lift.sphere) p.x() = -p.x();
  return lift;
}

}  // namespace fascicle::detail
