// The tube map for long muscles: cut along a shortest path between the two ends, Tutte-embed the
// disk into a convex hexagon, lift by Lambert's cylindrical equal-area projection.
#include "geometry/errors.h"
#include "morph/sphere_steps.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>

namespace fascicle::detail {

double elongation(const TriangleMesh& mesh, const MeshAdjacency& adj, std::array<int, 2>& ends) {
  const std::vector<double> from0 = edge_distances(mesh, adj, 0);
  ends[0] = static_cast<int>(std::max_element(from0.begin(), from0.end()) - from0.begin());
  const std::vector<double> from_s = edge_distances(mesh, adj, ends[0]);
  ends[1] = static_cast<int>(std::max_element(from_s.begin(), from_s.end()) - from_s.begin());
  const double length = from_s[ends[1]];
  double area = 0.0;
  for (const Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.positions[t[0]];
    area += 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
  }
  return area > 0.0 ? length * length / area : 0.0;
}

TutteLift tube_lift(const TriangleMesh& mesh, const MeshAdjacency& adj, const std::array<int, 2>& ends) {
  const int nv = static_cast<int>(mesh.positions.size());
  const int nf = static_cast<int>(mesh.triangles.size());
  TutteLift lift;
  lift.kind = "tube";
  // Shortest path s -> t. No edge joins two non-consecutive path vertices (it would be a
  // shortcut), so the cut disk has no dividing edge and Floater's theorem applies.
  std::vector<int> previous;
  const std::vector<double> dist = edge_distances(mesh, adj, ends[1], &previous);
  std::vector<int> path;
  for (int v = ends[0]; v != -1; v = previous[v]) path.push_back(v);
  const int m = static_cast<int>(path.size());
  if (m < 3) return lift;  // ends adjacent: not a tube; the caller uses the other map

  // Split every inner path vertex: faces on one bank (from edge v->after turning back to edge
  // before->v) get the copy nv + i - 1.
  std::vector<Triangle> cut = mesh.triangles;
  for (int i = 1; i + 1 < m; ++i) {
    const int v = path[i], before = path[i - 1], after = path[i + 1];
    const int copy = nv + i - 1;
    int c = -1;
    for (int d = adj.corner_start[v]; d < adj.corner_start[v + 1]; ++d)
      if (adj.corner_next[d] == after) c = d;
    FASCICLE_CHECK(c >= 0, "path edge exists");
    for (int guard = 0; guard <= adj.valence(v); ++guard) {
      Triangle& t = cut[adj.corner_face[c]];
      for (int k = 0; k < 3; ++k)
        if (t[k] == v) t[k] = copy;
      if (adj.corner_prev[c] == before) break;
      int next = -1;
      for (int d = adj.corner_start[v]; d < adj.corner_start[v + 1]; ++d)
        if (adj.corner_next[d] == adj.corner_prev[c]) next = d;
      FASCICLE_CHECK(next >= 0, "fan continues");
      c = next;
    }
  }
  const int n_cut = nv + m - 2;

  // Boundary: s at (0, 0), t at (0, pi), one bank at x = pi, the other at x = -pi, y by arc
  // length along the path: a convex hexagon.
  std::vector<Eigen::Vector2d> uv(n_cut, Eigen::Vector2d::Zero());
  std::vector<char> fixed(n_cut, 0);
  const double total = dist[ends[0]];
  for (int i = 0; i < m; ++i) {
    const double y = M_PI * (total - dist[path[i]]) / total;
    if (i == 0 || i + 1 == m) {
      uv[path[i]] = Eigen::Vector2d(0.0, i == 0 ? 0.0 : M_PI);
      fixed[path[i]] = 1;
    } else {
      uv[path[i]] = Eigen::Vector2d(M_PI, y);
      uv[nv + i - 1] = Eigen::Vector2d(-M_PI, y);
      fixed[path[i]] = fixed[nv + i - 1] = 1;
    }
  }
  auto position = [&](int v) -> const Vec3& { return mesh.positions[v < nv ? v : path[v - nv + 1]]; };
  // Positive (clamped) cotangent weights on the cut mesh.
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(nf) * 6);
  for (const Triangle& t : cut)
    for (int k = 0; k < 3; ++k) {
      const Vec3& o = position(t[k]);
      const Vec3 u = position(t[(k + 1) % 3]) - o, w = position(t[(k + 2) % 3]) - o;
      const double cross = u.cross(w).norm();
      const double cot = cross > 0.0 ? u.dot(w) / cross : 0.0;
      entries.emplace_back(t[(k + 1) % 3], t[(k + 2) % 3], 0.5 * cot);
      entries.emplace_back(t[(k + 2) % 3], t[(k + 1) % 3], 0.5 * cot);
    }
  Eigen::SparseMatrix<double> weights(n_cut, n_cut);
  weights.setFromTriplets(entries.begin(), entries.end());
  entries.clear();
  double mean_abs = 0.0;
  for (int k = 0; k < weights.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(weights, k); it; ++it) mean_abs += std::abs(it.value());
  mean_abs /= std::max<Eigen::Index>(weights.nonZeros(), 1);
  for (int k = 0; k < weights.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(weights, k); it; ++it)
      it.valueRef() = std::clamp(it.value(), 1e-3 * mean_abs, 1e3 * mean_abs);
  std::vector<int> index(n_cut, -1);
  int n = 0;
  for (int v = 0; v < n_cut; ++v)
    if (!fixed[v]) index[v] = n++;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 2);
  for (int v = 0; v < n_cut; ++v) {
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
  if (solver.info() != Eigen::Success) throw SolverError("sphere map: the tube system could not be factorised");
  const Eigen::MatrixXd solution = solver.solve(rhs);
  if (solver.info() != Eigen::Success || !solution.allFinite())
    throw SolverError("sphere map: the tube solve failed or produced NaN");
  for (int v = 0; v < n_cut; ++v)
    if (index[v] >= 0) uv[v] = solution.row(index[v]).transpose();

  // Lambert cylindrical equal-area: longitude x, z = 1 - 2 y / pi.
  lift.sphere.resize(nv);
  for (int v = 0; v < nv; ++v) {
    const double z = std::clamp(1.0 - 2.0 * uv[v].y() / M_PI, -1.0, 1.0);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    lift.sphere[v] = Vec3(r * std::cos(uv[v].x()), r * std::sin(uv[v].x()), z);
  }
  double orientation = 0.0;
  for (const Triangle& t : mesh.triangles)
    orientation += sphere_det(lift.sphere[t[0]], lift.sphere[t[1]], lift.sphere[t[2]]);
  if (orientation < 0.0)
    for (Vec3& p : lift.sphere) p.x() = -p.x();
  lift.margin = 0.0;
  return lift;
}

long untangle(const TriangleMesh& mesh, const MeshAdjacency& adj, std::vector<Vec3>& x, int max_sweeps) {
  const int nv = static_cast<int>(x.size());
  auto min_det = [&](int v, const Vec3& p) {
    double worst = std::numeric_limits<double>::infinity();
    for (int c = adj.corner_start[v]; c < adj.corner_start[v + 1]; ++c) {
      const Vec3& b = x[adj.corner_next[c]];
      const Vec3& d = x[adj.corner_prev[c]];
      worst = std::min(worst, (b - p).cross(d - p).dot(p));
    }
    return worst;
  };
  auto count_bad = [&](std::vector<char>* mark) {
    long bad = 0;
    if (mark) mark->assign(nv, 0);
    for (const Triangle& t : mesh.triangles)
      if (!(sphere_det(x[t[0]], x[t[1]], x[t[2]]) > min_step_det)) {
        ++bad;
        if (mark)
          for (int k = 0; k < 3; ++k) (*mark)[t[k]] = 1;
      }
    return bad;
  };
  std::vector<char> mark;
  long bad = count_bad(&mark);
  for (int sweep = 0; sweep < max_sweeps && bad > 0; ++sweep) {
    // Grow the marked set by one ring so that neighbours can make room too.
    std::vector<char> grown = mark;
    for (int v = 0; v < nv; ++v)
      if (mark[v])
        for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) grown[adj.neighbours[i]] = 1;
    for (int v = 0; v < nv; ++v) {
      if (!grown[v]) continue;
      Vec3 c = Vec3::Zero();
      for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) c += x[adj.neighbours[i]];
      if (!(c.norm() > 0.0)) continue;
      const double before = min_det(v, x[v]);
      for (double t : {1.0, 0.5, 0.25, 0.125, 0.0625}) {
        const Vec3 p = ((1.0 - t) * x[v] + t * c.normalized()).normalized();
        if (min_det(v, p) > before) {
          x[v] = p;
          break;
        }
      }
    }
    bad = count_bad(&mark);
  }
  return bad;
}

}  // namespace fascicle::detail
