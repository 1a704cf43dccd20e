// Flip-free improvement of a bijective sphere map: Moebius centring of the surface-area measure
// and a Gauss-Seidel Newton relaxation that balances spherical areas against surface areas.
#include "geometry/errors.h"
#include "morph/sphere_steps.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fascicle::detail {
namespace {

/// Area centroid: sum over triangles of share_t times the unit vector through the chord centroid.
Vec3 area_centroid(const TriangleMesh& mesh, const std::vector<double>& shares, const std::vector<Vec3>& x) {
  Vec3 c = Vec3::Zero();
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Triangle& t = mesh.triangles[f];
    const Vec3 m = x[t[0]] + x[t[1]] + x[t[2]];
    const double norm = m.norm();
    if (norm > 0.0) c += shares[f] / norm * m;
  }
  return c;
}

/// True when the Moebius step with centre `step` treated every triangle as a conformal map
/// would: a small triangle's area shrinks at most by ((1 - |s|) / (1 + |s|))^2; a triangle that
/// shrinks by more than 0.9 of that (a sliver bending over) or drops below min_step_det refuses it.
bool conformal_enough(const TriangleMesh& mesh, const std::vector<Vec3>& before, const std::vector<Vec3>& after,
                      double step) {
  const double bound = 0.9 * std::pow((1.0 - step) / (1.0 + step), 2);
  for (const Triangle& t : mesh.triangles) {
    const double d = sphere_det(after[t[0]], after[t[1]], after[t[2]]);
    const double old = sphere_det(before[t[0]], before[t[1]], before[t[2]]);
    if (!(d >= bound * old) || !(d > std::min(min_step_det, old))) return false;
  }
  return true;
}

// det(p, b, d) relative to p, ((b - p) x (d - p)) . p, in scalars: the operations of Eigen's
// cross and dot on Vec3 in their order (the dot as (c0 p0 + c1 p1) + c2 p2), so the same bits;
// written out so the compiler keeps them in registers (the Eigen form stored the cross product
// and reloaded it as a pair, a store the processor could not forward; measured by
// `fascicle bench sphere`, docs/BENCHMARKS.md).
inline double star_det(const Vec3& b, const Vec3& d, const Vec3& p) {
  const double u0 = b[0] - p[0], u1 = b[1] - p[1], u2 = b[2] - p[2];
  const double w0 = d[0] - p[0], w1 = d[1] - p[1], w2 = d[2] - p[2];
  const double c0 = u1 * w2 - u2 * w1, c1 = u2 * w0 - u0 * w2, c2 = u0 * w1 - u1 * w0;
  return (c0 * p[0] + c1 * p[1]) + c2 * p[2];
}

}  // namespace

int mobius_center(const TriangleMesh& mesh, const std::vector<double>& shares, std::vector<Vec3>& sphere, int max_steps,
                  double tolerance, double& residual) {
  std::vector<Vec3> trial(sphere.size());
  Vec3 c = area_centroid(mesh, shares, sphere);
  int steps = 0;
  double factor = 1.0;
  while (steps < max_steps && c.norm() > tolerance) {
    // Stay well inside the unit ball: |c| near 1 would send nearly everything to one point.
    Vec3 step = factor * c;
    if (step.norm() > 0.9) step *= 0.9 / step.norm();
    const double k = 1.0 - step.squaredNorm();
    for (std::size_t i = 0; i < sphere.size(); ++i) {
      const Vec3 d = sphere[i] - step;
      const double d2 = d.squaredNorm();
      trial[i] = d2 > 0.0 ? Vec3(k / d2 * d - step) : sphere[i];
      trial[i].normalize();
    }
    ++steps;
    if (!conformal_enough(mesh, sphere, trial, step.norm())) {
      factor *= 0.5;
      if (factor < 1e-6) break;
      continue;
    }
    const Vec3 next = area_centroid(mesh, shares, trial);
    if (next.norm() >= c.norm()) {
      factor *= 0.5;
      if (factor < 1e-6) break;
      continue;
    }
    sphere.swap(trial);
    c = next;
    factor = std::min(1.0, factor * 2.0);
  }
  residual = c.norm();
  return steps;
}

int balance_areas(const TriangleMesh& mesh, const MeshAdjacency& adj, const std::vector<double>& shares,
                  std::vector<Vec3>& x, int max_sweeps, double tolerance, int& rejected) {
  // Energy E = sum_t a_t^2 / det_t: convex in each vertex on its own (det_t is linear in it),
  // infinite at a flip, smallest when det_t is proportional to a_t. Each vertex takes one
  // damped Newton step of its own part of E on the tangent plane, then is renormalised; a step
  // that leaves any incident det below min_step_det or raises the energy is halved, up to 10
  // times, then refused.
  const int nv = static_cast<int>(x.size());
  std::vector<double> a2(shares.size());
  for (std::size_t f = 0; f < shares.size(); ++f) a2[f] = shares[f] * shares[f];
  auto total_energy = [&]() {
    double e = 0.0;
    for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
      const Triangle& t = mesh.triangles[f];
      const double d = sphere_det(x[t[0]], x[t[1]], x[t[2]]);
      if (!(d > 0.0)) return std::numeric_limits<double>::infinity();
      e += a2[f] / d;
    }
    return e;
  };
  double energy = total_energy();
  if (!std::isfinite(energy)) return 0;  // not a valid start: nothing to balance safely
  std::vector<double> before;
  // Active set: a vertex is relaxed again only when it or a neighbour moved by more than
  // `still` (1e-3 of the mean edge length) in the sweep before; the rest is already balanced
  // locally and would only cost time.
  const double still =
      1e-3 * std::sqrt(4.0 * M_PI / static_cast<double>(std::max<std::size_t>(mesh.triangles.size(), 1)));
  std::vector<char> active(nv, 1), next_active(nv, 0);
  int sweep = 0;
  for (; sweep < max_sweeps; ++sweep) {
    std::fill(next_active.begin(), next_active.end(), 0);
    for (int v = 0; v < nv; ++v) {
      if (!active[v]) continue;
      const int begin = adj.corner_start[v], end = adj.corner_start[v + 1];
      before.clear();
      const Vec3 p = x[v];
      // Gradient g and Hessian h (column-major, h[i + 3 j] = h(i, j)) of the vertex's energy.
      double gs[3] = {0.0, 0.0, 0.0}, hs[9] = {};
      double local = 0.0;
      bool ok = true;
      for (int c = begin; c < end; ++c) {
        // det(p, b, d) = (b x d) . p is linear in p with gradient m = b x d; its value is taken
        // relative to p for accuracy on small triangles. (The chord normal (b - p) x (d - p)
        // has the same component along p but almost no tangential one, so it is not the
        // gradient: with it the Newton steps went nearly nowhere and most sweeps were wasted.)
        const Vec3& b = x[adj.corner_next[c]];
        const Vec3& d = x[adj.corner_prev[c]];
        const double m[3] = {b[1] * d[2] - b[2] * d[1], b[2] * d[0] - b[0] * d[2], b[0] * d[1] - b[1] * d[0]};
        const double det = star_det(b, d, p);
        if (!(det > 0.0)) {
          ok = false;
          break;
        }
        const double w = a2[adj.corner_face[c]];
        before.push_back(det);
        local += w / det;
        // g -= (w / det^2) m; h += ((2 w / det^3) m) m^T, entry by entry as Eigen forms them.
        const double gf = w / (det * det), hf = 2.0 * w / (det * det * det);
        const double hm[3] = {hf * m[0], hf * m[1], hf * m[2]};
        for (int i = 0; i < 3; ++i) gs[i] -= gf * m[i];
        for (int j = 0; j < 3; ++j)
          for (int i = 0; i < 3; ++i) hs[i + 3 * j] += m[j] * hm[i];
      }
      if (!ok) continue;
      const Vec3 g(gs[0], gs[1], gs[2]);
      const Eigen::Matrix3d h = Eigen::Map<const Eigen::Matrix3d>(hs);
      // Tangent frame at p.
      const Vec3 e1 = (std::abs(p.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(p).normalized();
      const Vec3 e2 = p.cross(e1);
      Eigen::Matrix<double, 3, 2> frame;
      frame << e1, e2;
      const Eigen::Vector2d g2 = frame.transpose() * g;
      // Moving along the sphere adds the curvature term -(g . p) |y|^2.
      const Eigen::Matrix2d h2 = frame.transpose() * h * frame + (-g.dot(p)) * Eigen::Matrix2d::Identity();
      Eigen::Vector2d y = -h2.ldlt().solve(g2);
      if (!y.allFinite()) continue;
      // Never more than a quarter radian in one step.
      if (y.norm() > 0.25) y *= 0.25 / y.norm();
      bool moved = false;
      for (int attempt = 0; attempt < 10; ++attempt, y *= 0.5) {
        const Vec3 q = (p + frame * y).normalized();
        double trial = 0.0;
        bool valid = true;
        for (int c = begin; c < end; ++c) {
          const Vec3& b = x[adj.corner_next[c]];
          const Vec3& d = x[adj.corner_prev[c]];
          const double det = star_det(b, d, q);
          // A triangle may not drop below min_step_det (or below its own det if it started there).
          if (!(det > std::min(min_step_det, before[c - begin]))) {
            valid = false;
            break;
          }
          trial += a2[adj.corner_face[c]] / det;
        }
        if (valid && trial <= local) {
          x[v] = q;
          moved = true;
          if (y.norm() > still) {
            next_active[v] = 1;
            for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i)
              next_active[adj.neighbours[i]] = 1;
          }
          break;
        }
      }
      if (!moved) ++rejected;
    }
    active.swap(next_active);
    if ((sweep + 1) % 5 == 0 || sweep + 1 == max_sweeps) {
      const double next = total_energy();
      const bool done = energy - next < tolerance * 5.0 * energy;
      energy = next;
      if (done) {
        ++sweep;
        break;
      }
    }
  }
  return sweep;
}

}  // namespace fascicle::detail
