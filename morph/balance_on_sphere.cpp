// Flip-free improvement of a bijective sphere map: Moebius centring of the surface-area measure
// and a Gauss-Seidel Newton relaxation that balances spherical areas against surface areas.
#include "geometry/errors.h"
#include "geometry/detail/for_each_index.h"
#include "morph/sphere_steps.h"

#include <Eigen/Eigenvalues>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <thread>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

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
// and reloaded it as a pair, a store the processor could not forward: about a seventh of the
// balancing's samples in `fascicle bench sphere`, docs/BENCHMARKS.md).
inline double star_det(const Vec3& b, const Vec3& d, const Vec3& p) {
  const double u0 = b[0] - p[0], u1 = b[1] - p[1], u2 = b[2] - p[2];
  const double w0 = d[0] - p[0], w1 = d[1] - p[1], w2 = d[2] - p[2];
  const double c0 = u1 * w2 - u2 * w1, c1 = u2 * w0 - u0 * w2, c2 = u0 * w1 - u1 * w0;
  return (c0 * p[0] + c1 * p[1]) + c2 * p[2];
}

}  // namespace

int mobius_center(const TriangleMesh& mesh, const std::vector<double>& shares, std::vector<Vec3>& sphere,
                  int max_steps, double tolerance, double& residual) {
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

namespace {

// A spinning thread's hint to the processor (it frees the core's other hardware thread).
inline void pause() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#endif
}

// One vertex's Gauss-Seidel step of the balancing (see balance_areas): reads the positions of
// its ring, may move x[v]. Returns 1 when the step moved by more than `still`, 0 when it moved
// less, -1 when it was refused (no step kept), 2 when the vertex was skipped (an incident
// triangle not positive: nothing to do).
int relax_vertex(int v, const MeshAdjacency& adj, const std::vector<double>& a2, std::vector<Vec3>& x, double still,
                 std::vector<double>& before) {
  const int begin = adj.corner_start[v], end = adj.corner_start[v + 1];
  before.clear();
  const Vec3 p = x[v];
  // Gradient g and Hessian h (column-major, h[i + 3 j] = h(i, j)) of the vertex's energy.
  double gs[3] = {0.0, 0.0, 0.0}, hs[9] = {};
  double local = 0.0;
  for (int c = begin; c < end; ++c) {
    // det(p, b, d) = (b x d) . p is linear in p with gradient m = b x d; its value is taken
    // relative to p for accuracy on small triangles. (The chord normal (b - p) x (d - p)
    // has the same component along p but almost no tangential one, so it is not the
    // gradient: with it the Newton steps went nearly nowhere and most sweeps were wasted.)
    const Vec3& b = x[adj.corner_next[c]];
    const Vec3& d = x[adj.corner_prev[c]];
    const double m[3] = {b[1] * d[2] - b[2] * d[1], b[2] * d[0] - b[0] * d[2], b[0] * d[1] - b[1] * d[0]};
    const double det = star_det(b, d, p);
    if (!(det > 0.0)) return 2;
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
  if (!y.allFinite()) return 2;
  // Never more than a quarter radian in one step.
  if (y.norm() > 0.25) y *= 0.25 / y.norm();
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
      return y.norm() > still ? 1 : 0;
    }
  }
  return -1;
}

// Vertices split into lanes for the sweeps on threads. Each lane is swept in increasing index
// order; a vertex waits for its lower-numbered neighbours in other lanes, and its
// higher-numbered neighbours wait for it, so every step sees exactly the positions the serial
// sweep's would: the same bits. The split is the one (of halves across a few directions) whose
// simulated sweep, everything active and a step costing its valence, finishes first.
struct Lanes {
  std::vector<std::vector<int>> members;  // per lane, increasing
  std::vector<int> lane;                  // per vertex
  double speedup = 1.0;                   // simulated, serial time over the split's
};

Lanes split_lanes(const TriangleMesh& mesh, const MeshAdjacency& adj) {
  const int nv = static_cast<int>(mesh.positions.size());
  Lanes best;
  std::vector<double> cost(static_cast<std::size_t>(nv));
  double serial = 0.0;
  for (int v = 0; v < nv; ++v) serial += cost[v] = 4.0 + adj.valence(v);
  // Candidate directions: the axes and the principal axes of the vertices.
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : mesh.positions) mean += p;
  mean /= std::max(nv, 1);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : mesh.positions) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> principal(cov);
  std::vector<Vec3> directions = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  for (int k = 0; k < 3; ++k) directions.push_back(principal.eigenvectors().col(k));
  std::vector<double> along(static_cast<std::size_t>(nv)), finish(static_cast<std::size_t>(nv));
  std::vector<int> lane(static_cast<std::size_t>(nv));
  for (const Vec3& dir : directions) {
    for (int v = 0; v < nv; ++v) along[v] = mesh.positions[v].dot(dir);
    std::vector<double> sorted = along;
    std::nth_element(sorted.begin(), sorted.begin() + nv / 2, sorted.end());
    const double median = sorted[static_cast<std::size_t>(nv / 2)];
    for (int v = 0; v < nv; ++v) lane[v] = along[v] < median ? 0 : 1;
    // Simulated sweep: a vertex starts when its lane is free and its lower-numbered neighbours
    // in the other lane are done.
    double clock[2] = {0.0, 0.0};
    for (int v = 0; v < nv; ++v) {
      double start = clock[lane[v]];
      for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) {
        const int u = adj.neighbours[i];
        if (u < v && lane[u] != lane[v]) start = std::max(start, finish[u]);
      }
      finish[v] = clock[lane[v]] = start + cost[v];
    }
    const double speedup = serial / std::max(clock[0], clock[1]);
    if (speedup > best.speedup) {
      best.speedup = speedup;
      best.lane = lane;
    }
  }
  if (!best.lane.empty()) {
    best.members.assign(2, {});
    for (int v = 0; v < nv; ++v) best.members[best.lane[v]].push_back(v);
  }
  return best;
}

}  // namespace

int balance_areas(const TriangleMesh& mesh, const MeshAdjacency& adj, const std::vector<double>& shares,
                  std::vector<Vec3>& x, int max_sweeps, double tolerance, int& rejected) {
  // Energy E = sum_t a_t^2 / det_t: convex in each vertex on its own (det_t is linear in it),
  // infinite at a flip, smallest when det_t is proportional to a_t. Each vertex takes one
  // damped Newton step of its own part of E on the tangent plane, then is renormalised; a step
  // that leaves any incident det below min_step_det or raises the energy is halved, up to 10
  // times, then refused.
  const int nv = static_cast<int>(x.size());
  const std::size_t nf = mesh.triangles.size();
  std::vector<double> a2(shares.size());
  for (std::size_t f = 0; f < shares.size(); ++f) a2[f] = shares[f] * shares[f];
  // The energy: every term on threads, summed in the faces' order (the serial sum's bits).
  std::vector<double> terms(nf);
  auto total_energy = [&]() {
    for_each_index(nf, [&](std::size_t f) {
      const Triangle& t = mesh.triangles[f];
      const double d = sphere_det(x[t[0]], x[t[1]], x[t[2]]);
      terms[f] = d > 0.0 ? a2[f] / d : std::numeric_limits<double>::quiet_NaN();
    });
    double e = 0.0;
    for (double term : terms) {
      if (std::isnan(term)) return std::numeric_limits<double>::infinity();
      e += term;
    }
    return e;
  };
  double energy = total_energy();
  if (!std::isfinite(energy)) return 0;  // not a valid start: nothing to balance safely
  // Active set: a vertex is relaxed again only when it or a neighbour moved by more than
  // `still` (1e-3 of the mean edge length) in the sweep before; the rest is already balanced
  // locally and would only cost time.
  const double still = 1e-3 * std::sqrt(4.0 * M_PI / static_cast<double>(std::max<std::size_t>(nf, 1)));
  std::vector<char> active(nv, 1), far(nv, 0);
  // Sweeps on two lanes where the machine has two threads and the split pays.
  const bool threads = tbb::this_task_arena::max_concurrency() > 1 && nv >= 2048;
  const Lanes lanes = threads ? split_lanes(mesh, adj) : Lanes{};
  const bool on_lanes = lanes.speedup > 1.3;
  std::vector<std::atomic<int>> done(on_lanes ? static_cast<std::size_t>(nv) : 0);
  for (auto& d : done) d.store(-1, std::memory_order_relaxed);
  int sweep = 0;
  for (; sweep < max_sweeps; ++sweep) {
    if (!on_lanes) {
      std::vector<double> before;
      for (int v = 0; v < nv; ++v) {
        if (!active[v]) continue;
        const int result = relax_vertex(v, adj, a2, x, still, before);
        far[v] = result == 1;
        if (result < 0) ++rejected;
      }
    } else {
      // Each lane under its own lock: the thread that holds it advances its cursor. A vertex
      // waiting for another lane's vertex takes that lane (when free) and advances it that far
      // itself, so the sweep finishes on any number of threads, one included.
      struct Lane {
        std::atomic<bool> busy{false};
        std::size_t cursor = 0;
        int rejected = 0;
        std::vector<double> before;
      };
      std::array<Lane, 2> state;
      const int stamp = sweep;
      std::function<void(int, std::size_t)> advance;  // lane l (held) up to members index `until`
      // Waits are short while both lanes run (they advance side by side); when the other
      // lane's thread is not running (more threads than cores: a batch of processes), spinning
      // would take the core it needs, so after a few microseconds the waiter sleeps.
      auto wait_for = [&](int u) {
        for (int spin = 0; done[u].load(std::memory_order_acquire) != stamp; ++spin) {
          Lane& other = state[static_cast<std::size_t>(lanes.lane[u])];
          bool expected = false;
          if (other.busy.compare_exchange_strong(expected, true, std::memory_order_acquire)) {
            const auto& list = lanes.members[static_cast<std::size_t>(lanes.lane[u])];
            advance(lanes.lane[u], static_cast<std::size_t>(std::lower_bound(list.begin(), list.end(), u) - list.begin()) + 1);
            other.busy.store(false, std::memory_order_release);
          } else if (spin < 512) {
            pause();
          } else {
            std::this_thread::sleep_for(std::chrono::microseconds(20));
          }
        }
      };
      advance = [&](int l, std::size_t until) {
        Lane& me = state[static_cast<std::size_t>(l)];
        const auto& list = lanes.members[static_cast<std::size_t>(l)];
        for (; me.cursor < until; ++me.cursor) {
          const int v = list[me.cursor];
          if (active[v]) {
            for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) {
              const int u = adj.neighbours[i];
              if (u < v && lanes.lane[u] != l) wait_for(u);
            }
            const int result = relax_vertex(v, adj, a2, x, still, me.before);
            far[v] = result == 1;
            if (result < 0) ++me.rejected;
          }
          done[v].store(stamp, std::memory_order_release);
        }
      };
      tbb::parallel_for(0, 2, [&](int l) {
        Lane& me = state[static_cast<std::size_t>(l)];
        const std::size_t size = lanes.members[static_cast<std::size_t>(l)].size();
        for (;;) {
          bool expected = false;
          if (me.busy.compare_exchange_strong(expected, true, std::memory_order_acquire)) {
            advance(l, size);
            me.busy.store(false, std::memory_order_release);
            return;
          }
          std::this_thread::sleep_for(std::chrono::microseconds(20));
        }
      });
      for (const Lane& l : state) rejected += l.rejected;
    }
    // Next sweep's active set: the vertices that moved far and their neighbours.
    for (int v = 0; v < nv; ++v) {
      char next = far[v];
      for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1] && !next; ++i) next = far[adj.neighbours[i]];
      active[v] = next;
    }
    // Only vertices relaxed this sweep can have moved: the others' flags are cleared here.
    std::fill(far.begin(), far.end(), 0);
    if ((sweep + 1) % 5 == 0 || sweep + 1 == max_sweeps) {
      const double next = total_energy();
      const bool done_now = energy - next < tolerance * 5.0 * energy;
      energy = next;
      if (done_now) {
        ++sweep;
        break;
      }
    }
  }
  return sweep;
}

}  // namespace fascicle::detail
