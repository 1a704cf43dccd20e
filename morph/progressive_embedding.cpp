// Progressive-mesh sphere embedding (Shapiro and Tal 1998, "Polyhedron realization for shape
// transformation"; Praun and Hoppe 2003, "Spherical parametrization and remeshing"): the mesh is
// simplified by half-edge collapses that keep it a closed genus-0 manifold down to a tetrahedron,
// the tetrahedron is placed on the sphere, and the vertices are split back in reverse order, each
// new vertex inside the kernel of its ring and its neighbourhood relaxed by moves that never let
// a triangle flip. Every accepted state is a bijection, so the result is one by construction.
#include "geometry/errors.h"
#include "morph/sphere_steps.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <queue>
#include <tuple>

namespace fascicle::detail {
namespace {

/// Rotates face `t` so that `v` comes first (v must be one of its corners).
inline std::array<int, 3> rotate_to(const Triangle& t, int v) {
  if (t[0] == v) return {t[0], t[1], t[2]};
  if (t[1] == v) return {t[1], t[2], t[0]};
  return {t[2], t[0], t[1]};
}

inline bool has(const Triangle& t, int v) { return t[0] == v || t[1] == v || t[2] == v; }

inline void erase_one(std::vector<int>& list, int value) {
  const auto it = std::find(list.begin(), list.end(), value);
  if (it != list.end()) {
    *it = list.back();
    list.pop_back();
  }
}

/// det(p, b, d) that is certainly positive in spite of rounding: the formula's error is a few
/// units in the last place of |b - p| |d - p| (p, b, d unit vectors), the margin is 1e-12 of it.
inline bool robust_positive(const Vec3& p, const Vec3& b, const Vec3& d, double det) {
  return det > 1e-12 * (b - p).norm() * (d - p).norm();
}

/// The dynamic mesh of the simplification and of the refinement: faces (original ids, corners
/// rewritten by the collapses) and the live faces around every vertex.
struct DynamicMesh {
  std::vector<Triangle> faces;
  std::vector<std::vector<int>> vertex_faces;
  std::vector<char> vertex_alive;
  std::vector<int> stamp;  // scratch marks for neighbour sets
  int clock = 0;

  explicit DynamicMesh(const TriangleMesh& mesh)
      : faces(mesh.triangles),
        vertex_faces(mesh.positions.size()),
        vertex_alive(mesh.positions.size(), 1),
        stamp(mesh.positions.size(), 0) {
    for (std::size_t f = 0; f < faces.size(); ++f)
      for (int k = 0; k < 3; ++k) vertex_faces[faces[f][k]].push_back(static_cast<int>(f));
  }

  /// Valence of a live vertex of a closed manifold = number of its faces.
  int valence(int v) const { return static_cast<int>(vertex_faces[v].size()); }

  /// True when u and v share an edge.
  bool adjacent(int u, int v) const {
    for (int f : vertex_faces[u])
      if (has(faces[f], v)) return true;
    return false;
  }

  /// Half-edge collapse u -> v is allowed: the edge exists, the link condition holds (u and v have
  /// exactly two common neighbours, the opposite corners of the edge's faces), more than four
  /// vertices are left, the opposite corners keep valence >= 3 and v's valence stays <= max_valence.
  bool can_collapse(int u, int v, int live_vertices, int max_valence, std::array<int, 2>& dead) {
    if (live_vertices <= 4 || !vertex_alive[u] || !vertex_alive[v] || u == v) return false;
    if (valence(u) + valence(v) - 4 > max_valence) return false;
    int found = 0;
    for (int f : vertex_faces[u])
      if (has(faces[f], v)) {
        if (found == 2) return false;
        dead[found++] = f;
      }
    if (found != 2) return false;
    int opposite[2];
    for (int k = 0; k < 2; ++k) {
      const auto r = rotate_to(faces[dead[k]], u);
      opposite[k] = r[1] == v ? r[2] : r[1];
      if (valence(opposite[k]) < 4) return false;
    }
    if (opposite[0] == opposite[1]) return false;
    ++clock;
    for (int f : vertex_faces[u])
      for (int k = 0; k < 3; ++k) stamp[faces[f][k]] = clock;
    ++clock;  // marks of v's neighbours: clock; of u's: clock - 1
    int common = 0;
    for (int f : vertex_faces[v])
      for (int k = 0; k < 3; ++k) {
        const int w = faces[f][k];
        if (w == u || w == v) continue;
        if (stamp[w] == clock - 1) {
          stamp[w] = clock;
          ++common;
        }
      }
    return common == 2;
  }

  /// Performs the collapse u -> v (checked by can_collapse); appends the faces whose u corner
  /// became v to `moved`.
  void collapse(int u, int v, const std::array<int, 2>& dead, std::vector<int>& moved,
                std::array<int, 4>* receivers = nullptr) {
    if (receivers) {
      // Each dead face (u, v, o) hands its area to the faces across its edges u-o and v-o, which
      // become neighbours across the merged edge v-o.
      for (int k = 0; k < 2; ++k) {
        const auto r = rotate_to(faces[dead[k]], u);
        const int o = r[1] == v ? r[2] : r[1];
        (*receivers)[2 * k] = (*receivers)[2 * k + 1] = -1;
        for (int f : vertex_faces[u])
          if (f != dead[0] && f != dead[1] && has(faces[f], o)) (*receivers)[2 * k] = f;
        for (int f : vertex_faces[v])
          if (f != dead[0] && f != dead[1] && has(faces[f], o)) (*receivers)[2 * k + 1] = f;
      }
    }
    for (int f : dead)
      for (int k = 0; k < 3; ++k)
        if (faces[f][k] != u) erase_one(vertex_faces[faces[f][k]], f);
    for (int f : vertex_faces[u]) {
      if (f == dead[0] || f == dead[1]) continue;
      for (int k = 0; k < 3; ++k)
        if (faces[f][k] == u) faces[f][k] = v;
      vertex_faces[v].push_back(f);
      moved.push_back(f);
    }
    vertex_faces[u].clear();
    vertex_alive[u] = 0;
  }
};

/// One damped Newton step of E(p) = sum over the faces f = (p, b, d) of w_f^2 / det(p, b, d) on
/// the tangent plane at p (the balancing move of balance_on_sphere.cpp; w_f is the surface area
/// the face stands for at its level, so the minimum has det proportional to it), halved
/// until every face keeps a robustly positive det (and at least min(min_step_det, its det before))
/// and E does not rise. det is linear in the unnormalised point, so a move whose end keeps every
/// det positive keeps it positive along the whole way: the map stays a bijection.
bool relax_vertex(const DynamicMesh& dm, const std::vector<double>& weight, std::vector<Vec3>& x, int w) {
  thread_local std::vector<std::pair<int, int>> corners;
  thread_local std::vector<double> before, a2;
  corners.clear();
  before.clear();
  a2.clear();
  const Vec3 p = x[w];
  Vec3 g = Vec3::Zero();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  double local = 0.0;
  for (int f : dm.vertex_faces[w]) {
    const auto r = rotate_to(dm.faces[f], w);
    const Vec3& b = x[r[1]];
    const Vec3& d = x[r[2]];
    const Vec3 m = b.cross(d);
    const double det = (b - p).cross(d - p).dot(p);
    if (!(det > 0.0)) return false;
    const double c = weight[f] * weight[f];
    corners.emplace_back(r[1], r[2]);
    before.push_back(det);
    a2.push_back(c);
    local += c / det;
    g -= (c / (det * det)) * m;
    h += (2.0 * c / (det * det * det)) * m * m.transpose();
  }
  const Vec3 e1 = (std::abs(p.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(p).normalized();
  const Vec3 e2 = p.cross(e1);
  Eigen::Matrix<double, 3, 2> frame;
  frame << e1, e2;
  const Eigen::Vector2d g2 = frame.transpose() * g;
  const Eigen::Matrix2d h2 = frame.transpose() * h * frame + (-g.dot(p)) * Eigen::Matrix2d::Identity();
  Eigen::Vector2d y = -h2.ldlt().solve(g2);
  if (!y.allFinite()) return false;
  if (y.norm() > 0.25) y *= 0.25 / y.norm();
  for (int attempt = 0; attempt < 12; ++attempt, y *= 0.5) {
    const Vec3 q = (p + frame * y).normalized();
    double trial = 0.0;
    bool valid = true;
    for (std::size_t c = 0; c < corners.size(); ++c) {
      const Vec3& b = x[corners[c].first];
      const Vec3& d = x[corners[c].second];
      const double det = (b - q).cross(d - q).dot(q);
      if (!(det > std::min(min_step_det, before[c])) || !robust_positive(q, b, d, det)) {
        valid = false;
        break;
      }
      trial += a2[c] / det;
    }
    if (valid && trial <= local) {
      x[w] = q;
      return true;
    }
  }
  return false;
}

}  // namespace

CollapseSequence collapse_to_tetrahedron(const TriangleMesh& mesh, const MeshAdjacency& adjacency, int max_valence) {
  DynamicMesh dm(mesh);
  CollapseSequence seq;
  seq.moved_start.push_back(0);
  const int nv = static_cast<int>(mesh.positions.size());
  int live = nv;
  using Edge = std::tuple<double, int, int>;
  std::priority_queue<Edge, std::vector<Edge>, std::greater<Edge>> queue;
  auto push = [&](int a, int b) {
    queue.emplace((mesh.positions[a] - mesh.positions[b]).squaredNorm(), std::min(a, b), std::max(a, b));
  };
  auto push_all = [&]() {
    for (int v = 0; v < nv; ++v) {
      if (!dm.vertex_alive[v]) continue;
      for (int f : dm.vertex_faces[v]) {
        const auto r = rotate_to(dm.faces[f], v);
        if (r[1] > v) push(v, r[1]);
      }
    }
  };
  (void)adjacency;  // the topology was checked by the caller; the collapses use their own lists
  push_all();
  int limit = max_valence;
  long since_rebuild = 0;
  std::array<int, 2> dead{};
  while (live > 4) {
    if (queue.empty()) {
      // Every edge left failed its checks: allow higher valences and look at all edges again. A
      // triangulated sphere other than the tetrahedron always has an edge that can be contracted
      // (Steinitz), so a pass without any collapse under no valence limit means a broken mesh.
      if (since_rebuild == 0 && limit >= nv)
        throw TopologyError("progressive sphere embedding: no edge can be collapsed with " + std::to_string(live) +
                            " vertices left (mesh is not a closed genus-0 manifold)");
      limit = since_rebuild == 0 ? nv : std::min(nv, limit + 2);
      since_rebuild = 0;
      push_all();
      continue;
    }
    const auto [length, a, b] = queue.top();
    queue.pop();
    (void)length;
    if (!dm.vertex_alive[a] || !dm.vertex_alive[b]) continue;
    int u = a, v = b;
    if (!dm.can_collapse(u, v, live, limit, dead)) {
      std::swap(u, v);
      if (!dm.can_collapse(u, v, live, limit, dead)) continue;
    }
    std::array<int, 4> receivers{};
    dm.collapse(u, v, dead, seq.moved, &receivers);
    seq.receivers.push_back(receivers);
    seq.removed.push_back(u);
    seq.kept.push_back(v);
    seq.dead.push_back(dead);
    seq.moved_start.push_back(static_cast<int>(seq.moved.size()));
    --live;
    ++since_rebuild;
    for (int f : dm.vertex_faces[v]) {
      const auto r = rotate_to(dm.faces[f], v);
      push(v, r[1]);
    }
  }
  int k = 0;
  for (int v = 0; v < nv; ++v)
    if (dm.vertex_alive[v]) {
      FASCICLE_CHECK(k < 4, "four vertices left");
      seq.base[k++] = v;
    }
  k = 0;
  for (int v : seq.base)
    for (int f : dm.vertex_faces[v])
      if (std::find(seq.base_faces.begin(), seq.base_faces.begin() + k, f) == seq.base_faces.begin() + k) {
        FASCICLE_CHECK(k < 4, "four faces left");
        seq.base_faces[k++] = f;
      }
  FASCICLE_CHECK(k == 4, "the simplification ends in a tetrahedron");
  return seq;
}

TriangleMesh collapsed_mesh(const TriangleMesh& mesh, const CollapseSequence& sequence, std::size_t collapses) {
  FASCICLE_CHECK(collapses <= sequence.removed.size(), "collapse count in range");
  std::vector<Triangle> faces = mesh.triangles;
  std::vector<char> face_alive(faces.size(), 1), vertex_alive(mesh.positions.size(), 1);
  for (std::size_t i = 0; i < collapses; ++i) {
    const int u = sequence.removed[i], v = sequence.kept[i];
    for (int f : sequence.dead[i]) face_alive[f] = 0;
    for (int j = sequence.moved_start[i]; j < sequence.moved_start[i + 1]; ++j)
      for (int& c : faces[sequence.moved[j]])
        if (c == u) c = v;
    vertex_alive[u] = 0;
  }
  std::vector<int> index(mesh.positions.size(), -1);
  TriangleMesh out;
  for (std::size_t v = 0; v < mesh.positions.size(); ++v)
    if (vertex_alive[v]) {
      index[v] = static_cast<int>(out.positions.size());
      out.positions.push_back(mesh.positions[v]);
    }
  for (std::size_t f = 0; f < faces.size(); ++f)
    if (face_alive[f]) out.triangles.push_back({index[faces[f][0]], index[faces[f][1]], index[faces[f][2]]});
  return out;
}

ProgressiveResult progressive_embedding(const TriangleMesh& mesh, const MeshAdjacency& adjacency, int max_valence,
                                        int relax_rounds) {
  const CollapseSequence seq = collapse_to_tetrahedron(mesh, adjacency, max_valence);
  ProgressiveResult result;
  result.collapses = static_cast<long>(seq.removed.size());
  // Rebuild the dynamic mesh in its collapsed state, and the area each face stands for there:
  // the surface share of the face itself plus what dead faces handed to it.
  DynamicMesh dm(mesh);
  std::vector<double> weight = area_shares(mesh);
  std::vector<std::array<double, 2>> given(seq.removed.size());
  {
    std::vector<int> moved;
    for (std::size_t i = 0; i < seq.removed.size(); ++i) {
      moved.clear();
      for (int k = 0; k < 2; ++k) {
        const int d = seq.dead[i][k];
        given[i][k] = weight[d];
        const int r0 = seq.receivers[i][2 * k], r1 = seq.receivers[i][2 * k + 1];
        if (r0 >= 0) weight[r0] += (r1 >= 0 ? 0.5 : 1.0) * weight[d];
        if (r1 >= 0) weight[r1] += (r0 >= 0 ? 0.5 : 1.0) * weight[d];
      }
      dm.collapse(seq.removed[i], seq.kept[i], seq.dead[i], moved);
    }
  }
  const double weight_floor = 1e-12 / static_cast<double>(std::max<std::size_t>(mesh.triangles.size(), 1));
  std::vector<Vec3> x(mesh.positions.size(), Vec3::Zero());
  // The base tetrahedron: a regular one, mirrored if its first face comes out clockwise.
  const Vec3 corners[4] = {Vec3(1, 1, 1).normalized(), Vec3(1, -1, -1).normalized(), Vec3(-1, 1, -1).normalized(),
                           Vec3(-1, -1, 1).normalized()};
  for (int k = 0; k < 4; ++k) x[seq.base[k]] = corners[k];
  {
    const Triangle& t = dm.faces[seq.base_faces[0]];
    if (sphere_det(x[t[0]], x[t[1]], x[t[2]]) < 0.0) std::swap(x[seq.base[0]], x[seq.base[1]]);
    for (int f : seq.base_faces) {
      const Triangle& s = dm.faces[f];
      FASCICLE_CHECK(sphere_det(x[s[0]], x[s[1]], x[s[2]]) > 0.0, "base tetrahedron oriented");
    }
    for (int round = 0; round < 4 * relax_rounds; ++round)
      for (int v : seq.base) relax_vertex(dm, weight, x, v);
  }
  // Whole-level sweeps each time the vertex count doubles: the local moves after a split only
  // see its neighbourhood, these spread area over the whole coarse mesh while it is small.
  std::size_t next_sweep = 8;
  std::vector<int> relax_list;
  for (std::size_t step = seq.removed.size(); step-- > 0;) {
    const int u = seq.removed[step], v = seq.kept[step];
    const Vec3 pv = x[v];
    // The wedge at v that u takes over: the moved faces (v, a, b) form a fan; sum their angles at
    // v and start from the fan's first spoke (an `a` that is no face's `b`).
    double wedge = 0.0;
    int first = -1;
    for (int j = seq.moved_start[step]; j < seq.moved_start[step + 1]; ++j) {
      const auto r = rotate_to(dm.faces[seq.moved[j]], v);
      const Vec3 ta = x[r[1]] - x[r[1]].dot(pv) * pv, tb = x[r[2]] - x[r[2]].dot(pv) * pv;
      wedge += std::atan2(ta.cross(tb).dot(pv), ta.dot(tb));
      bool is_end = false;
      for (int k = seq.moved_start[step]; k < seq.moved_start[step + 1] && !is_end; ++k)
        is_end = rotate_to(dm.faces[seq.moved[k]], v)[2] == r[1];
      if (!is_end) first = r[1];
    }
    FASCICLE_CHECK(first >= 0, "fan of the split vertex has a first spoke");
    const Vec3 t0 = (x[first] - x[first].dot(pv) * pv).normalized();
    const Vec3 dir = std::cos(0.5 * wedge) * t0 + std::sin(0.5 * wedge) * pv.cross(t0);
    // Split: the moved faces get u back, the two dead faces return.
    for (int j = seq.moved_start[step]; j < seq.moved_start[step + 1]; ++j) {
      const int f = seq.moved[j];
      for (int& c : dm.faces[f])
        if (c == v) c = u;
      erase_one(dm.vertex_faces[v], f);
      dm.vertex_faces[u].push_back(f);
    }
    for (int f : seq.dead[step])
      for (int c : dm.faces[f]) dm.vertex_faces[c].push_back(f);
    for (int k = 0; k < 2; ++k) {
      const int r0 = seq.receivers[step][2 * k], r1 = seq.receivers[step][2 * k + 1];
      const double g = given[step][k];
      if (r0 >= 0) weight[r0] = std::max(weight_floor, weight[r0] - (r1 >= 0 ? 0.5 : 1.0) * g);
      if (r1 >= 0) weight[r1] = std::max(weight_floor, weight[r1] - (r0 >= 0 ? 0.5 : 1.0) * g);
      weight[seq.dead[step][k]] = g;
    }
    dm.vertex_alive[u] = 1;
    // u a small step from v into the wedge: halve the step until every face of u is valid.
    double reach = 4.0;
    for (int f : dm.vertex_faces[u])
      for (int c : dm.faces[f])
        if (c != u && c != v) reach = std::min(reach, (x[c] - pv).norm());
    double eps = 0.3 * reach;
    bool placed = false;
    for (int attempt = 0; attempt < 200 && !placed; ++attempt, eps *= 0.5) {
      x[u] = (pv + eps * dir).normalized();
      placed = true;
      for (int f : dm.vertex_faces[u]) {
        const auto r = rotate_to(dm.faces[f], u);
        const double det = sphere_det(x[u], x[r[1]], x[r[2]]);
        if (!robust_positive(x[u], x[r[1]], x[r[2]], det)) {
          placed = false;
          break;
        }
      }
    }
    if (!placed) ++result.failed_splits;
    // Relax u, v and u's ring a few rounds, so that triangles stay far from degenerate.
    relax_list.clear();
    relax_list.push_back(u);
    relax_list.push_back(v);
    for (int f : dm.vertex_faces[u])
      for (int c : dm.faces[f])
        if (std::find(relax_list.begin(), relax_list.end(), c) == relax_list.end()) relax_list.push_back(c);
    for (int round = 0; round < relax_rounds; ++round)
      for (int w : relax_list) relax_vertex(dm, weight, x, w);
    const std::size_t live = mesh.positions.size() - step;
    if (live >= next_sweep) {
      next_sweep *= 2;
      for (int round = 0; round < 4 * relax_rounds; ++round)
        for (std::size_t w = 0; w < mesh.positions.size(); ++w)
          if (dm.vertex_alive[w]) relax_vertex(dm, weight, x, static_cast<int>(w));
    }
  }
  result.sphere = std::move(x);
  return result;
}

}  // namespace fascicle::detail
