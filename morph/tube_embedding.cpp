// The tube map for long muscles: cut along a shortest path between the two ends, Tutte-embed the
// disk into a convex hexagon, fold the hexagon onto a capped prism and project it centrally.
#include "geometry/errors.h"
#include "geometry/detail/for_each_index.h"
#include "morph/parallel_ldlt.h"
#include "morph/sphere_steps.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>

namespace fascicle::detail {
namespace {

/// Height of the hexagon's cap triangles (its sides run from y = h to y = pi - h).
constexpr double kCapHeight = M_PI / 4.0;
/// Sides of the prism the hexagon is folded onto.
constexpr int kPrismSides = 32;

/// The hexagon folded onto a convex polyhedron around the origin, then projected centrally to the
/// unit sphere. The hexagon's middle band [-pi, pi] x [h, pi - h] is cut into kPrismSides
/// vertical strips, each mapped affinely onto one side rectangle of a right prism (corners
/// (cos phi, sin phi, +-zh)); each cap triangle is cut into kPrismSides triangles from its apex,
/// each mapped affinely onto one face of a pyramid with apex (0, 0, +-za). Both banks x = +-pi
/// land on the same prism edge and pyramid edge, so they glue. Central projection of a planar
/// face keeps orientations (great circles are its straight lines), so a mesh triangle inside one
/// piece keeps its planar orientation exactly; only triangles that straddle a fold can bend,
/// and their angle is at most 360 / kPrismSides degrees.
Vec3 hexagon_to_sphere(const Eigen::Vector2d& p) {
  constexpr double h = kCapHeight, zh = 0.5, za = 1.6;
  const int k = kPrismSides;
  auto corner = [&](int i, double z) {
    const double phi = -M_PI + 2.0 * M_PI * i / k;
    return Vec3(std::cos(phi), std::sin(phi), z);
  };
  auto strip = [&](double x, double& u) {
    const double s = std::clamp((x + M_PI) / (2.0 * M_PI) * k, 0.0, static_cast<double>(k));
    const int i = std::min(k - 1, static_cast<int>(s));
    u = s - i;
    return i;
  };
  const double x = std::clamp(p.x(), -M_PI, M_PI), y = std::clamp(p.y(), 0.0, M_PI);
  Vec3 q;
  if (y >= h && y <= M_PI - h) {
    double u = 0.0;
    const int i = strip(x, u);
    const double v = (y - h) / (M_PI - 2.0 * h);
    q = (1.0 - u) * ((1.0 - v) * corner(i, zh) + v * corner(i, -zh)) +
        u * ((1.0 - v) * corner(i + 1, zh) + v * corner(i + 1, -zh));
  } else {
    // Cap: the ray from the apex through p meets the band's edge at x * h / depth.
    const bool top = y < h;
    const double depth = top ? y : M_PI - y;  // distance from the apex's row
    const Vec3 apex(0.0, 0.0, top ? za : -za);
    if (depth <= 0.0) return apex.normalized();
    double u = 0.0;
    const int i = strip(x * h / depth, u);
    const double w = depth / h;  // 0 at the apex, 1 on the band's edge
    q = (1.0 - w) * apex + w * ((1.0 - u) * corner(i, top ? zh : -zh) + u * corner(i + 1, top ? zh : -zh));
  }
  return q.normalized();
}

}  // namespace

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

struct TubeEmbedder::Impl {
  const TriangleMesh* mesh = nullptr;
  int nv = 0, n_cut = 0, n = 0;
  std::vector<int> path;
  std::vector<Triangle> cut;                   // the mesh's triangles, one bank on the copies
  std::vector<Eigen::Vector2d> uv;             // boundary positions (fixed), interior filled per solve
  std::vector<int> index;                      // cut vertex -> unknown, -1 when fixed
  Eigen::SparseMatrix<double> weights;         // clamped cotangent weights on the cut mesh
  std::vector<std::array<int, 2>> edge_faces;  // per stored weight: its faces (second -1 on the cut)
  Eigen::SparseMatrix<double> system;          // Dirichlet Laplacian, pattern fixed
  std::vector<int> system_slot;                // per stored weight: slot in system, -1 to the rhs
  std::vector<int> diagonal_slot;              // per unknown: slot of its diagonal
  ParallelLDLT solver;                         // Eigen's SimplicialLDLT, the same bits, subtrees on threads
};

TubeEmbedder::TubeEmbedder(const TriangleMesh& mesh, const MeshAdjacency& adj, const std::array<int, 2>& ends)
    : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.mesh = &mesh;
  const int nv = d.nv = static_cast<int>(mesh.positions.size());
  const int nf = static_cast<int>(mesh.triangles.size());
  // Shortest path s -> t. No edge joins two non-consecutive path vertices (it would be a
  // shortcut), so the cut disk has no dividing edge and Floater's theorem applies.
  std::vector<int> previous;
  const std::vector<double> dist = edge_distances(mesh, adj, ends[1], &previous);
  for (int v = ends[0]; v != -1; v = previous[v]) d.path.push_back(v);
  const int m = static_cast<int>(d.path.size());
  if (m < 3) return;  // ends adjacent: not a tube; valid() is false

  // Split every inner path vertex: faces on one bank (from edge v->after turning back to edge
  // before->v) get the copy nv + i - 1.
  d.cut = mesh.triangles;
  std::vector<Triangle>& cut = d.cut;
  for (int i = 1; i + 1 < m; ++i) {
    const int v = d.path[i], before = d.path[i - 1], after = d.path[i + 1];
    const int copy = nv + i - 1;
    int c = -1;
    for (int e = adj.corner_start[v]; e < adj.corner_start[v + 1]; ++e)
      if (adj.corner_next[e] == after) c = e;
    FASCICLE_CHECK(c >= 0, "path edge exists");
    for (int guard = 0; guard <= adj.valence(v); ++guard) {
      Triangle& t = cut[adj.corner_face[c]];
      for (int k = 0; k < 3; ++k)
        if (t[k] == v) t[k] = copy;
      if (adj.corner_prev[c] == before) break;
      int next = -1;
      for (int e = adj.corner_start[v]; e < adj.corner_start[v + 1]; ++e)
        if (adj.corner_next[e] == adj.corner_prev[c]) next = e;
      FASCICLE_CHECK(next >= 0, "fan continues");
      c = next;
    }
  }
  const int n_cut = d.n_cut = nv + m - 2;

  // Boundary: the convex hexagon s = (0, 0), (pi, h), (pi, pi - h), t = (0, pi), (-pi, pi - h),
  // (-pi, h); one bank runs down its right side s -> (pi, h) -> (pi, pi - h) -> t, the other
  // down its left side, both placed by arc length along the path.
  d.uv.assign(n_cut, Eigen::Vector2d::Zero());
  std::vector<char> fixed(n_cut, 0);
  const double total = dist[ends[0]];
  const double h = kCapHeight, slant = std::hypot(M_PI, h), side = M_PI - 2.0 * h;
  const double outline = 2.0 * slant + side;
  for (int i = 0; i < m; ++i) {
    const double along = outline * (total - dist[d.path[i]]) / total;
    Eigen::Vector2d p;
    if (along <= slant)
      p = Eigen::Vector2d(M_PI, h) * (along / slant);
    else if (along <= slant + side)
      p = Eigen::Vector2d(M_PI, h + (along - slant));
    else
      p = Eigen::Vector2d(M_PI, M_PI - h) + (Eigen::Vector2d(0.0, M_PI) - Eigen::Vector2d(M_PI, M_PI - h)) *
                                                std::min(1.0, (along - slant - side) / slant);
    if (i == 0 || i + 1 == m) {
      d.uv[d.path[i]] = Eigen::Vector2d(0.0, i == 0 ? 0.0 : M_PI);
      fixed[d.path[i]] = 1;
    } else {
      d.uv[d.path[i]] = p;
      d.uv[nv + i - 1] = Eigen::Vector2d(-p.x(), p.y());
      fixed[d.path[i]] = fixed[nv + i - 1] = 1;
    }
  }
  auto position = [&](int v) -> const Vec3& { return mesh.positions[v < nv ? v : d.path[v - nv + 1]]; };
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
  d.weights.resize(n_cut, n_cut);
  d.weights.setFromTriplets(entries.begin(), entries.end());
  d.weights.makeCompressed();
  entries.clear();
  double mean_abs = 0.0;
  for (int k = 0; k < d.weights.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(d.weights, k); it; ++it) mean_abs += std::abs(it.value());
  mean_abs /= std::max<Eigen::Index>(d.weights.nonZeros(), 1);
  for (int k = 0; k < d.weights.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(d.weights, k); it; ++it)
      it.valueRef() = std::clamp(it.value(), 1e-3 * mean_abs, 1e3 * mean_abs);
  // Faces of every stored weight.
  d.edge_faces.assign(static_cast<std::size_t>(d.weights.nonZeros()), {-1, -1});
  const double* base = d.weights.valuePtr();
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = cut[f][(k + 1) % 3], b = cut[f][(k + 2) % 3];
      for (const auto& [r, c] : {std::pair<int, int>(a, b), std::pair<int, int>(b, a)}) {
        auto& slot = d.edge_faces[static_cast<std::size_t>(&d.weights.coeffRef(r, c) - base)];
        (slot[0] < 0 ? slot[0] : slot[1]) = f;
      }
    }
  // Dirichlet system pattern: unknowns are the free vertices.
  d.index.assign(n_cut, -1);
  for (int v = 0; v < n_cut; ++v)
    if (!fixed[v]) d.index[v] = d.n++;
  for (int v = 0; v < n_cut; ++v) {
    if (d.index[v] < 0) continue;
    entries.emplace_back(d.index[v], d.index[v], 1.0);
    for (Eigen::SparseMatrix<double>::InnerIterator it(d.weights, v); it; ++it)
      if (d.index[it.row()] >= 0) entries.emplace_back(d.index[it.row()], d.index[v], 1.0);
  }
  d.system.resize(d.n, d.n);
  d.system.setFromTriplets(entries.begin(), entries.end());
  d.system.makeCompressed();
  d.system_slot.assign(static_cast<std::size_t>(d.weights.nonZeros()), -1);
  d.diagonal_slot.assign(d.n, -1);
  const double* sbase = d.system.valuePtr();
  for (int v = 0; v < n_cut; ++v) {
    if (d.index[v] < 0) continue;
    d.diagonal_slot[d.index[v]] = static_cast<int>(&d.system.coeffRef(d.index[v], d.index[v]) - sbase);
    for (Eigen::SparseMatrix<double>::InnerIterator it(d.weights, v); it; ++it)
      if (d.index[it.row()] >= 0)
        d.system_slot[static_cast<std::size_t>(&it.valueRef() - base)] =
            static_cast<int>(&d.system.coeffRef(d.index[it.row()], d.index[v]) - sbase);
  }
  d.solver.analyzePattern(d.system);
}

TubeEmbedder::~TubeEmbedder() = default;

bool TubeEmbedder::valid() const { return impl_->n > 0; }

std::vector<Eigen::Vector2d> TubeEmbedder::solve(const std::vector<double>* face_scale) {
  Impl& d = *impl_;
  if (!valid()) return {};
  // Assemble values: weight w(row, v) scaled by the geometric mean of its faces' factors.
  double* values = d.system.valuePtr();
  std::fill(values, values + d.system.nonZeros(), 0.0);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(d.n, 2);
  const double* base = d.weights.valuePtr();
  for (int v = 0; v < d.n_cut; ++v) {
    const int iv = d.index[v];
    if (iv < 0) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(d.weights, v); it; ++it) {
      const std::size_t k = static_cast<std::size_t>(&it.value() - base);
      double w = it.value();
      if (face_scale) {
        const auto& faces = d.edge_faces[k];
        w *= faces[1] >= 0 ? std::sqrt((*face_scale)[faces[0]] * (*face_scale)[faces[1]]) : (*face_scale)[faces[0]];
      }
      values[d.diagonal_slot[iv]] += w;
      if (d.system_slot[k] >= 0)
        values[d.system_slot[k]] = -w;
      else
        rhs.row(iv) += w * d.uv[it.row()].transpose();
    }
  }
  d.solver.factorize(d.system);
  if (d.solver.info() != Eigen::Success) throw SolverError("sphere map: the tube system could not be factorised");
  const Eigen::MatrixXd solution = d.solver.solve_columns(rhs);
  if (d.solver.info() != Eigen::Success || !solution.allFinite())
    throw SolverError("sphere map: the tube solve failed or produced NaN");
  std::vector<Eigen::Vector2d> uv = d.uv;
  for (int v = 0; v < d.n_cut; ++v)
    if (d.index[v] >= 0) uv[v] = solution.row(d.index[v]).transpose();
  return uv;
}

double TubeEmbedder::planar_log_ratio(const std::vector<Eigen::Vector2d>& uv, const std::vector<double>& shares,
                                      std::vector<double>& ratio) const {
  const Impl& d = *impl_;
  const std::size_t nf = d.cut.size();
  ratio.resize(nf);
  double total = 0.0;
  for (std::size_t f = 0; f < nf; ++f) {
    const Triangle& t = d.cut[f];
    const Eigen::Vector2d u = uv[t[1]] - uv[t[0]], w = uv[t[2]] - uv[t[0]];
    ratio[f] = std::abs(u.x() * w.y() - u.y() * w.x());
    total += ratio[f];
  }
  double sum = 0.0;
  for (std::size_t f = 0; f < nf; ++f) {
    ratio[f] = ratio[f] / total / shares[f];
    sum += std::abs(std::log(std::max(ratio[f], 1e-300)));
  }
  return sum / static_cast<double>(nf);
}

TutteLift TubeEmbedder::lift(const std::vector<Eigen::Vector2d>& uv, TubeFold fold) const {
  const Impl& d = *impl_;
  TutteLift lift;
  if (uv.empty()) return lift;
  lift.sphere.resize(d.nv);
  lift.kind = fold == TubeFold::prism ? "tube" : "tube-lambert";
  for_each_index(static_cast<std::size_t>(d.nv), [&](std::size_t v) {
    const Eigen::Vector2d& p = uv[v];
    if (fold == TubeFold::prism) {
      lift.sphere[v] = hexagon_to_sphere(p);
    } else {
      // Lambert's cylindrical equal-area projection: longitude x, z = 1 - 2 y / pi.
      const double z = std::clamp(1.0 - 2.0 * p.y() / M_PI, -1.0, 1.0);
      const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
      lift.sphere[v] = Vec3(r * std::cos(p.x()), r * std::sin(p.x()), z);
    }
  });
  // The triangles' dets on threads, summed in their order.
  const std::vector<Triangle>& triangles = d.mesh->triangles;
  std::vector<double> dets(triangles.size());
  for_each_index(triangles.size(), [&](std::size_t f) {
    const Triangle& t = triangles[f];
    dets[f] = sphere_det(lift.sphere[t[0]], lift.sphere[t[1]], lift.sphere[t[2]]);
  });
  double orientation = 0.0;
  for (double det : dets) orientation += det;
  if (orientation < 0.0)
    for (Vec3& p : lift.sphere) p.x() = -p.x();
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
