// Repair of flipped regions in a sphere map by local Tutte re-embedding in gnomonic coordinates.
#include "geometry/errors.h"
#include "morph/sphere_steps.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>

namespace fascicle::detail {
namespace {

std::vector<char> bad_vertices(const TriangleMesh& mesh, const std::vector<Vec3>& x, long& bad) {
  std::vector<char> mark(x.size(), 0);
  bad = 0;
  for (const Triangle& t : mesh.triangles)
    if (!(sphere_det(x[t[0]], x[t[1]], x[t[2]]) > min_step_det)) {
      ++bad;
      for (int k = 0; k < 3; ++k) mark[t[k]] = 1;
    }
  return mark;
}

/// Grows a vertex set by one ring.
void grow(const MeshAdjacency& adj, std::vector<char>& set) {
  const std::vector<char> before = set;
  for (int v = 0; v < static_cast<int>(set.size()); ++v)
    if (before[v])
      for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) set[adj.neighbours[i]] = 1;
}

/// Tries to re-embed the region (vertex set) around one cluster; true when every face touching
/// it is valid afterwards (the positions are then kept), false with the positions unchanged.
bool reembed(const TriangleMesh& mesh, const MeshAdjacency& adj, const std::vector<char>& region,
             std::vector<Vec3>& x) {
  const int nv = static_cast<int>(x.size());
  Vec3 c = Vec3::Zero();
  for (int v = 0; v < nv; ++v)
    if (region[v]) c += x[v];
  if (!(c.norm() > 0.0)) return false;
  c.normalize();
  for (int v = 0; v < nv; ++v)
    if (region[v] && x[v].dot(c) < 0.3) return false;  // too large for one gnomonic chart
  // Interior: every face around the vertex lies in the region; the rest of the region is the
  // fixed boundary.
  std::vector<int> index(nv, -1);
  int n = 0;
  bool has_boundary = false;
  for (int v = 0; v < nv; ++v) {
    if (!region[v]) continue;
    bool interior = true;
    for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i)
      if (!region[adj.neighbours[i]]) interior = false;
    if (interior)
      index[v] = n++;
    else
      has_boundary = true;
  }
  if (n == 0 || !has_boundary) return false;
  // Gnomonic chart at c: great circles are straight lines, so a planar triangle and the geodesic
  // triangle of the same corners have the same orientation.
  const Vec3 e1 = (std::abs(c.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(c).normalized();
  const Vec3 e2 = c.cross(e1);
  auto chart = [&](int v) {
    const double k = 1.0 / x[v].dot(c);
    return Eigen::Vector2d(k * x[v].dot(e1), k * x[v].dot(e2));
  };
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 2);
  for (int v = 0; v < nv; ++v) {
    if (index[v] < 0) continue;
    const int valence = adj.valence(v);
    entries.emplace_back(index[v], index[v], static_cast<double>(valence));
    for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) {
      const int w = adj.neighbours[i];
      if (index[w] >= 0)
        entries.emplace_back(index[v], index[w], -1.0);
      else
        rhs.row(index[v]) += chart(w).transpose();
    }
  }
  Eigen::SparseMatrix<double> system(n, n);
  system.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(system);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::MatrixXd solution = solver.solve(rhs);
  if (!solution.allFinite()) return false;
  std::vector<std::pair<int, Vec3>> saved;
  for (int v = 0; v < nv; ++v)
    if (index[v] >= 0) {
      saved.emplace_back(v, x[v]);
      x[v] = (c + solution(index[v], 0) * e1 + solution(index[v], 1) * e2).normalized();
    }
  for (const auto& [v, old] : saved)
    for (int k = adj.corner_start[v]; k < adj.corner_start[v + 1]; ++k) {
      const Triangle& t = mesh.triangles[adj.corner_face[k]];
      if (!(sphere_det(x[t[0]], x[t[1]], x[t[2]]) > min_step_det)) {
        for (const auto& [w, p] : saved) x[w] = p;
        return false;
      }
    }
  return true;
}

}  // namespace

long reembed_patches(const TriangleMesh& mesh, const MeshAdjacency& adj, std::vector<Vec3>& x, int max_rings) {
  long bad = 0;
  std::vector<char> mark = bad_vertices(mesh, x, bad);
  const int nv = static_cast<int>(x.size());
  for (int round = 0; round < 64 && bad > 0; ++round) {
    // One cluster: the bad vertices connected (through one ring) to the first one.
    std::vector<char> near = mark;
    grow(adj, near);
    std::vector<char> cluster(nv, 0);
    int seed = static_cast<int>(std::find(mark.begin(), mark.end(), 1) - mark.begin());
    std::vector<int> stack{seed};
    cluster[seed] = 1;
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) {
        const int w = adj.neighbours[i];
        if (near[w] && !cluster[w]) {
          cluster[w] = 1;
          stack.push_back(w);
        }
      }
    }
    bool fixed = false;
    std::vector<char> region = cluster;
    for (int rings = 1; rings <= max_rings && !fixed; ++rings) {
      grow(adj, region);
      fixed = reembed(mesh, adj, region, x);
    }
    const long before = bad;
    mark = bad_vertices(mesh, x, bad);
    if (!fixed && bad >= before) {
      // This cluster resists; the others may still be fixable, so drop its marks and go on.
      bool other = false;
      for (int v = 0; v < nv; ++v)
        if (cluster[v])
          mark[v] = 0;
        else if (mark[v])
          other = true;
      if (!other) break;
    }
  }
  long remaining = 0;
  bad_vertices(mesh, x, remaining);
  return remaining;
}

}  // namespace fascicle::detail
