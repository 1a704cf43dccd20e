#include "fibres/untangle.h"

#include "fibres/untangle_terms.h"

#include "geometry/errors.h"

#include <Eigen/LU>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <deque>
#include <limits>
#include <string>

namespace fascicle {

namespace {

using Clock = std::chrono::steady_clock;

// Active tetrahedra from which an energy evaluation runs in parallel: below that the threads'
// start costs more than they save; low enough that the containment rounds' few hundred points
// still run in parallel.
constexpr std::size_t kParallelTets = 256;

// Tetrahedra whose energy terms are computed step by step together (Energy::evaluate).
constexpr std::size_t kBlock = 8;

// The smallest eps of the stages (the barrier in force for any det J above round-off).
constexpr double kSmallestEps = 1e-13;

Eigen::Matrix3d edge_matrix(const std::vector<Vec3>& x, const std::array<int, 4>& v) {
  Eigen::Matrix3d d;
  const Vec3& p0 = x[static_cast<std::size_t>(v[0])];
  for (int c = 0; c < 3; ++c) d.col(c) = x[static_cast<std::size_t>(v[static_cast<std::size_t>(c) + 1])] - p0;
  return d;
}

// Cofactor matrix: d det(J) / dJ.
Eigen::Matrix3d cofactor(const Eigen::Matrix3d& j) {
  Eigen::Matrix3d c;
  c.col(0) = j.col(1).cross(j.col(2));
  c.col(1) = j.col(2).cross(j.col(0));
  c.col(2) = j.col(0).cross(j.col(1));
  return c;
}

// c^(2/3) for c > 0 without libm's cbrt (a third of the untangling's time went to it): the
// inverse cube root from an estimate made of the exponent bits (y's bits ~ 4/3 of the bias minus
// a third of c's), refined by four Newton steps y <- y (4 - c y^3) / 3 (quadratic convergence:
// the estimate's few per cent fall to round-off, within 1e-15 of cbrt's), then c^(2/3) = c y.
// Outside the range where the estimate holds (and for 0, inf, nan) it is std::cbrt(c * c).
double two_thirds_power(double c) {
  if (!(c > 1e-200 && c < 1e200)) return std::cbrt(c * c);
  std::uint64_t bits;
  std::memcpy(&bits, &c, sizeof bits);
  bits = 0x553ef0ff289dd796ull - bits / 3;
  double y;
  std::memcpy(&y, &bits, sizeof y);
  for (int step = 0; step < 4; ++step) y = y * (4.0 - c * y * y * y) * (1.0 / 3.0);
  return c * y;
}

double chi(double d, double eps) { return 0.5 * (d + std::sqrt(eps * eps + d * d)); }
double chi_derivative(double d, double eps) { return 0.5 * (1.0 + d / std::sqrt(eps * eps + d * d)); }

// The vector terms gather coordinates from the positions as one array of doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 holds three contiguous doubles");

// The problem in the free coordinates.
class Energy {
 public:
  Energy(std::vector<Vec3>& positions, const std::vector<char>& fixed, const std::vector<UntangleTet>& tets,
         double lambda, const std::vector<UntangleAnchor>& anchors, const UntangleContainment& containment)
      : positions_(positions),
        anchors_(anchors),
        containment_(containment),
        lambda_(lambda),
        slot_(positions.size(), -1) {
    for (std::size_t q = 0; q < positions.size(); ++q)
      if (!fixed[q]) {
        slot_[q] = static_cast<int>(free_.size());
        free_.push_back(static_cast<int>(q));
      }
    for (std::size_t t = 0; t < tets.size(); ++t) {
      bool any = false;
      for (int v : tets[t].v) any = any || slot_[static_cast<std::size_t>(v)] >= 0;
      if (any) active_.push_back(static_cast<int>(t));
    }
    // Per active tetrahedron: its vertices' slots, and its constants one array an entry (the
    // vector path loads four tetrahedra's at once); per free point, the (tetrahedron, corner)
    // pairs it is a corner of, in the tetrahedra's order (the gradient's sum, point by point).
    const std::size_t n = active_.size();
    std::vector<std::array<int, 4>> corner_slots(n);
    corner_points_.resize(n);
    for (auto& k : reference_) k.resize(n);
    for (auto& k : corner_offsets_) k.resize(n);
    weight_.resize(n);
    eps_floor_.resize(n);
    std::vector<int> count(free_.size() + 1, 0);
    for (std::size_t a = 0; a < n; ++a) {
      const UntangleTet& tet = tets[static_cast<std::size_t>(active_[a])];
      corner_points_[a] = tet.v;
      for (int v = 0; v < 4; ++v) {
        if (tet.v[static_cast<std::size_t>(v)] > std::numeric_limits<int>::max() / 3)
          throw Error(ErrorCode::internal, "untangle: too many points for the vector terms");
        corner_offsets_[static_cast<std::size_t>(v)][a] = 3 * tet.v[static_cast<std::size_t>(v)];
        corner_slots[a][static_cast<std::size_t>(v)] =
            slot_[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(v)])];
        if (corner_slots[a][static_cast<std::size_t>(v)] >= 0)
          ++count[static_cast<std::size_t>(corner_slots[a][static_cast<std::size_t>(v)]) + 1];
      }
      for (int k = 0; k < 9; ++k) reference_[static_cast<std::size_t>(k)][a] = tet.reference_inverse.data()[k];
      weight_[a] = tet.weight;
      eps_floor_[a] = tet.eps_floor;
    }
    for (std::size_t f = 0; f < free_.size(); ++f) count[f + 1] += count[f];
    corner_row_ = count;
    corners_.resize(static_cast<std::size_t>(count.back()));
    for (std::size_t a = 0; a < n; ++a)
      for (int v = 0; v < 4; ++v) {
        const int s = corner_slots[a][static_cast<std::size_t>(v)];
        if (s >= 0)
          corners_[static_cast<std::size_t>(count[static_cast<std::size_t>(s)]++)] =
              static_cast<int>(4 * a + static_cast<std::size_t>(v));
      }
    if (containment.signed_distance)
      for (const UntangleContainment::Point& c : containment.points)
        if (slot_[static_cast<std::size_t>(c.point)] >= 0) contained_.push_back(c);
  }
  // Free containment points outside (signed distance > 0) at the current positions.
  long outside_count() const {
    long n = 0;
    for (const UntangleContainment::Point& c : contained_)
      n += containment_.signed_distance(positions_[static_cast<std::size_t>(c.point)], nullptr) > 0.0 ? 1 : 0;
    return n;
  }
  // Multiplier of the containment weights (raised by the stages while a point is outside).
  double containment_scale = 1.0;
  std::size_t free_count() const { return free_.size(); }
  Eigen::VectorXd get() const {
    Eigen::VectorXd x(3 * static_cast<Eigen::Index>(free_.size()));
    for (std::size_t f = 0; f < free_.size(); ++f)
      x.segment<3>(3 * static_cast<Eigen::Index>(f)) = positions_[static_cast<std::size_t>(free_[f])];
    return x;
  }
  void set(const Eigen::VectorXd& x) {
    for (std::size_t f = 0; f < free_.size(); ++f)
      positions_[static_cast<std::size_t>(free_[f])] = x.segment<3>(3 * static_cast<Eigen::Index>(f));
  }
  // Energy at x (with eps), gradient into g when given. The tetrahedra's terms are computed in
  // parallel (one slot each) and summed in their order, so the result is the same, bit for bit,
  // as the serial sum's, whatever the threads.
  double evaluate(const Eigen::VectorXd& x, double eps, Eigen::VectorXd* g) {
    set(x);
    ++evaluations;
    if (g) g->setZero(x.size());
    const std::size_t n = active_.size();
    terms_.resize(n);
    if (g)
      for (auto& k : gradients_) k.resize(n);
    // In blocks of kBlock tetrahedra, one step at a time over the block (the Jacobians and chi,
    // then c^(2/3), then the terms and gradients): a tetrahedron's arithmetic is a long chain of
    // dependent operations (square root, four Newton steps, divisions), and the chains of a
    // block's tetrahedra overlap in the processor where one tetrahedron after the other would
    // wait on each. The same operations in the same order as tetrahedron by tetrahedron: the
    // result is the same to the bit.
    // With AVX2 or AVX-512, four or eight tetrahedra a vector (fibres/untangle_terms.h: the same
    // operations, the same bits), the rest of the range below.
    const int lanes = simd_lanes_;
    auto terms = [&](std::size_t begin, std::size_t end) {
      if (lanes > 0) {
        const std::size_t step = static_cast<std::size_t>(lanes);
        const double* base = positions_.data()->data();
        for (; begin + step <= end; begin += step) {
          const int* corners[4];
          for (std::size_t v = 0; v < 4; ++v) corners[v] = corner_offsets_[v].data() + begin;
          const double* r[9];
          double* gradient[9];
          for (std::size_t k = 0; k < 9; ++k) {
            r[k] = reference_[k].data() + begin;
            gradient[k] = g ? gradients_[k].data() + begin : nullptr;
          }
          detail::untangle_terms_simd(lanes, base, corners, r, weight_.data() + begin, eps_floor_.data() + begin, eps,
                                      lambda_, terms_.data() + begin, g ? gradient : nullptr);
        }
      }
      Eigen::Matrix3d js[kBlock], references[kBlock];
      double dets[kBlock], epss[kBlock], cs[kBlock], c23s[kBlock];
      for (std::size_t b0 = begin; b0 < end; b0 += kBlock) {
        const std::size_t m = std::min(kBlock, end - b0);
        for (std::size_t i = 0; i < m; ++i) {
          const std::size_t a = b0 + i;
          for (std::size_t k = 0; k < 9; ++k) references[i].data()[k] = reference_[k][a];
          js[i] = edge_matrix(positions_, corner_points_[a]) * references[i];
          dets[i] = js[i].determinant();
          epss[i] = std::max(eps, eps_floor_[a]);
          cs[i] = chi(dets[i], epss[i]);
        }
        for (std::size_t i = 0; i < m; ++i) c23s[i] = two_thirds_power(cs[i]);
        for (std::size_t i = 0; i < m; ++i) {
          const std::size_t a = b0 + i;
          const Eigen::Matrix3d& j = js[i];
          const double det = dets[i], eps_t = epss[i], c = cs[i], c23 = c23s[i];
          const double frob = j.squaredNorm();
          const double shape = frob / c23;
          const double volume = (det * det + 1.0) / c;
          terms_[a] = weight_[a] * ((1.0 - lambda_) * shape + lambda_ * volume);
          if (!g) continue;
          const double dc = chi_derivative(det, eps_t);
          const Eigen::Matrix3d cof = cofactor(j);
          // d shape / dJ = 2 J / c^(2/3) - (2/3) frob c^(-5/3) dc cof
          // d volume / dJ = (2 det / c - (det^2 + 1) dc / c^2) cof
          const Eigen::Matrix3d dj = (1.0 - lambda_) * (2.0 / c23 * j - (2.0 / 3.0) * shape / c * dc * cof) +
                                     lambda_ * (2.0 * det / c - (det * det + 1.0) * dc / (c * c)) * cof;
          const Eigen::Matrix3d gradient = weight_[a] * dj * references[i].transpose();
          for (std::size_t k = 0; k < 9; ++k) gradients_[k][a] = gradient.data()[k];
        }
      }
    };
    if (n >= kParallelTets) {
      // In whole vectors (64 tetrahedra at least a task): a range that split a vector would leave
      // its rest to the scalar path, several times slower a tetrahedron.
      const std::size_t unit = 8, units = (n + unit - 1) / unit;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, units, 8), [&](const tbb::blocked_range<std::size_t>& r) {
        terms(r.begin() * unit, std::min(n, r.end() * unit));
      });
    } else
      terms(0, n);
    double e = 0.0;
    const auto sum_terms = [&] {
      for (std::size_t a = 0; a < n; ++a) e += terms_[a];
    };
    if (!g) {
      sum_terms();
    } else {
      // Each free point's gradient: its corners' columns (corner 0: minus the sum of the three)
      // added in the tetrahedra's order, as one loop over the tetrahedra would; points in
      // parallel.
      auto gather = [&](std::size_t f0, std::size_t f1) {
        for (std::size_t f = f0; f < f1; ++f) {
          Vec3 sum = Vec3::Zero();
          for (int k = corner_row_[f]; k < corner_row_[f + 1]; ++k) {
            const std::size_t a = static_cast<std::size_t>(corners_[static_cast<std::size_t>(k)]) / 4;
            const int corner = corners_[static_cast<std::size_t>(k)] % 4;
            Vec3 column;
            if (corner > 0) {
              for (int row = 0; row < 3; ++row)
                column[row] = gradients_[static_cast<std::size_t>(row + 3 * (corner - 1))][a];
            } else {
              column = Vec3::Zero();
              for (int col = 0; col < 3; ++col)
                for (int row = 0; row < 3; ++row) column[row] -= gradients_[static_cast<std::size_t>(row + 3 * col)][a];
            }
            sum += column;
          }
          g->segment<3>(3 * static_cast<Eigen::Index>(f)) = sum;
        }
      };
      if (n >= kParallelTets) {
        // The energy's sum (one chain of dependent additions) beside the gather's blocks.
        tbb::parallel_invoke(sum_terms, [&] {
          tbb::parallel_for(tbb::blocked_range<std::size_t>(0, free_.size(), 128),
                            [&](const tbb::blocked_range<std::size_t>& r) { gather(r.begin(), r.end()); });
        });
      } else {
        sum_terms();
        gather(0, free_.size());
      }
    }
    for (const UntangleAnchor& a : anchors_) {
      const int s = slot_[static_cast<std::size_t>(a.point)];
      if (s < 0) continue;
      const Vec3 d = positions_[static_cast<std::size_t>(a.point)] - a.target;
      if (a.normal.squaredNorm() > 0.0) {  // half-space: only the offset along the normal
        const double along = a.normal.dot(d);
        if (along <= 0.0 && a.one_sided) continue;
        e += a.weight * along * along;
        if (g) g->segment<3>(3 * s) += 2.0 * a.weight * along * a.normal;
      } else if (a.radius > 0.0) {  // ball: only the distance beyond the radius
        const double r = d.norm();
        if (r <= a.radius) continue;
        e += a.weight * (r - a.radius) * (r - a.radius);
        if (g) g->segment<3>(3 * s) += 2.0 * a.weight * (r - a.radius) / r * d;
      } else {
        e += a.weight * d.squaredNorm();
        if (g) g->segment<3>(3 * s) += 2.0 * a.weight * d;
      }
    }
    // Containment: weight max(0, d + margin)^2 on the signed distance d (serial, in the points'
    // order: the signed distance may fill a cache).
    for (const UntangleContainment::Point& c : contained_) {
      Vec3 gradient = Vec3::Zero();
      const double d =
          containment_.signed_distance(positions_[static_cast<std::size_t>(c.point)], g ? &gradient : nullptr);
      const double over = d + c.margin;
      if (!(over > 0.0)) continue;
      const double w = c.weight * containment_scale;
      e += w * over * over;
      if (g) g->segment<3>(3 * slot_[static_cast<std::size_t>(c.point)]) += 2.0 * w * over * gradient;
    }
    return e;
  }
  int evaluations = 0;

 private:
  std::vector<Vec3>& positions_;
  const std::vector<UntangleAnchor>& anchors_;
  const UntangleContainment& containment_;
  std::vector<UntangleContainment::Point> contained_;  // the containment's free points
  double lambda_;
  int simd_lanes_ = detail::untangle_simd_lanes();  // the vector terms (fibres/untangle_terms.h)
  std::vector<int> slot_, free_, active_;
  std::vector<double> terms_;  // each active tetrahedron's energy term
  // and its gradient by the edge vectors, entry k (column-major) of every tetrahedron in gradients_[k]
  std::array<std::vector<double>, 9> gradients_;
  // Per active tetrahedron: its reference inverse (entry k in reference_[k]), weight and eps
  // floor; per free point f, corners_[corner_row_[f] ..
  // corner_row_[f + 1]) = 4 a + corner of the tetrahedra it is a corner of, in order.
  std::vector<std::array<int, 4>> corner_points_;  // each active tetrahedron's points
  // and 3 times them, vertex by vertex (the vector terms gather the coordinates with them)
  std::array<std::vector<int>, 4> corner_offsets_;
  std::array<std::vector<double>, 9> reference_;
  std::vector<double> weight_, eps_floor_;
  std::vector<int> corner_row_, corners_;
};

struct Census {
  long inverted = 0, uncounted_inverted = 0;
  double min_det = std::numeric_limits<double>::infinity();
};

Census census(const std::vector<Vec3>& positions, const std::vector<UntangleTet>& tets, double min_det) {
  Census c;
  const std::vector<double> dets = tet_jacobian_dets(positions, tets);
  bool any = false;
  for (std::size_t t = 0; t < tets.size(); ++t) {
    const double d = dets[t];
    if (!tets[t].counted) {
      c.uncounted_inverted += d > 0.0 ? 0 : 1;
      continue;
    }
    any = true;
    c.min_det = std::min(c.min_det, d);
    if (!(d > min_det)) ++c.inverted;
  }
  if (!any) c.min_det = 0.0;
  return c;
}

// L-BFGS with a backtracking (Armijo) line search, `iterations` steps at fixed eps; returns the
// iterations done (stops early at a stationary point or when no step decreases the energy).
int minimise(Energy& energy, Eigen::VectorXd& x, double eps, int iterations, int history) {
  Eigen::VectorXd g;
  double e = energy.evaluate(x, eps, &g);
  // (s, y) and s . y, computed once (y . s and s . y are the same sum of the same products).
  struct Pair {
    Eigen::VectorXd s, y;
    double sy;
  };
  std::deque<Pair> pairs;
  int done = 0;
  for (; done < iterations; ++done) {
    if (!(g.squaredNorm() > 0.0) || !std::isfinite(e)) break;
    // Two-loop recursion.
    Eigen::VectorXd q = g;
    std::vector<double> alpha(pairs.size());
    for (std::size_t i = pairs.size(); i-- > 0;) {
      const double rho = 1.0 / pairs[i].sy;
      alpha[i] = rho * pairs[i].s.dot(q);
      q -= alpha[i] * pairs[i].y;
    }
    if (!pairs.empty())
      q *= pairs.back().sy / pairs.back().y.squaredNorm();
    else
      q *= 1.0 / std::max(1.0, g.cwiseAbs().maxCoeff());
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const double rho = 1.0 / pairs[i].sy;
      const double beta = rho * pairs[i].y.dot(q);
      q += (alpha[i] - beta) * pairs[i].s;
    }
    Eigen::VectorXd direction = -q;
    double slope = g.dot(direction);
    if (!(slope < 0.0)) {  // not a descent direction: restart from the gradient
      pairs.clear();
      direction = -g / std::max(1.0, g.cwiseAbs().maxCoeff());
      slope = g.dot(direction);
    }
    double step = 1.0;
    Eigen::VectorXd trial, g_trial;
    double e_trial = 0.0;
    bool accepted = false;
    for (int halving = 0; halving < 30; ++halving, step *= 0.5) {
      trial = x + step * direction;
      e_trial = energy.evaluate(trial, eps, &g_trial);
      if (std::isfinite(e_trial) && e_trial <= e + 1e-4 * step * slope) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      energy.set(x);
      if (pairs.empty()) break;
      pairs.clear();
      continue;
    }
    Eigen::VectorXd s = trial - x, y = g_trial - g;
    const double sy = s.dot(y);
    if (sy > 1e-12 * s.norm() * y.norm()) {
      pairs.push_back({std::move(s), std::move(y), sy});
      if (static_cast<int>(pairs.size()) > history) pairs.pop_front();
    }
    x = std::move(trial);
    g = std::move(g_trial);
    const double decrease = e - e_trial;
    e = e_trial;
    if (decrease <= 1e-13 * std::abs(e)) {
      ++done;
      break;
    }
  }
  energy.set(x);
  return done;
}

}  // namespace

void UntangleOptions::validate() const {
  if (!(lambda > 0.0 && lambda < 1.0))
    throw OptionError("untangle lambda: must be in (0, 1), got " + std::to_string(lambda));
  if (history < 1 || history > 100)
    throw OptionError("untangle history: must be in 1..100, got " + std::to_string(history));
  if (stage_iterations < 1 || stage_iterations > 100000)
    throw OptionError("untangle stage_iterations: must be in 1..100000, got " + std::to_string(stage_iterations));
  if (stall_stages < 1 || stall_stages > 10000)
    throw OptionError("untangle stall_stages: must be in 1..10000, got " + std::to_string(stall_stages));
  if (max_stages < 1 || max_stages > 10000)
    throw OptionError("untangle max_stages: must be in 1..10000, got " + std::to_string(max_stages));
  if (polish_iterations < 0 || polish_iterations > 100000)
    throw OptionError("untangle polish_iterations: must be in 0..100000, got " + std::to_string(polish_iterations));
  if (!(min_sigma > 0.0 && min_sigma < 1.0))
    throw OptionError("untangle min_sigma: must be in (0, 1), got " + std::to_string(min_sigma));
  if (!(min_det >= 0.0 && min_det < 1.0))
    throw OptionError("untangle min_det: must be in [0, 1), got " + std::to_string(min_det));
}

nlohmann::json UntangleReport::to_json() const {
  return {{"tets", tets},
          {"free_points", free_points},
          {"inverted_before", inverted_before},
          {"inverted_after", inverted_after},
          {"counted", counted},
          {"uncounted_inverted_after", uncounted_inverted_after},
          {"min_det_before", min_det_before},
          {"min_det_after", min_det_after},
          {"stages", stages},
          {"iterations", iterations},
          {"evaluations", evaluations},
          {"eps", eps},
          {"outside_before", outside_before},
          {"outside_after", outside_after},
          {"containment_scale", containment_scale},
          {"reverted", reverted},
          {"seconds", seconds}};
}

std::vector<double> tet_jacobian_dets(const std::vector<Vec3>& positions, const std::vector<UntangleTet>& tets) {
  std::vector<double> out(tets.size());
  for (std::size_t t = 0; t < tets.size(); ++t)
    out[t] = (edge_matrix(positions, tets[t].v) * tets[t].reference_inverse).determinant();
  return out;
}

UntangleReport untangle(std::vector<Vec3>& positions, const std::vector<char>& fixed,
                        const std::vector<UntangleTet>& tets, const UntangleOptions& options,
                        const std::vector<UntangleAnchor>& anchors, const UntangleContainment& containment) {
  options.validate();
  const auto start = Clock::now();
  if (fixed.size() != positions.size())
    throw Error(ErrorCode::internal, "untangle: " + std::to_string(fixed.size()) + " fixed flags for " +
                                         std::to_string(positions.size()) + " points");
  for (const UntangleTet& t : tets)
    for (int v : t.v)
      if (v < 0 || static_cast<std::size_t>(v) >= positions.size())
        throw Error(ErrorCode::internal, "untangle: tetrahedron vertex " + std::to_string(v) + " out of range");
  for (const UntangleAnchor& a : anchors)
    if (a.point < 0 || static_cast<std::size_t>(a.point) >= positions.size() || !(a.weight >= 0.0) ||
        !a.target.allFinite() || !(a.radius >= 0.0) || !a.normal.allFinite())
      throw Error(ErrorCode::internal, "untangle: bad anchor of point " + std::to_string(a.point));
  if (containment.active()) {
    if (!(containment.growth >= 1.0) || !(containment.max_scale >= 1.0))
      throw Error(ErrorCode::internal, "untangle: containment growth and max_scale must be >= 1");
    for (const UntangleContainment::Point& c : containment.points)
      if (c.point < 0 || static_cast<std::size_t>(c.point) >= positions.size() || !(c.weight >= 0.0) ||
          !(c.margin >= 0.0))
        throw Error(ErrorCode::internal, "untangle: bad containment point " + std::to_string(c.point));
  }
  for (const Vec3& p : positions)
    if (!p.allFinite()) throw Error(ErrorCode::internal, "untangle: a point is not finite");

  UntangleReport report;
  report.tets = static_cast<long>(tets.size());
  for (const UntangleTet& t : tets) report.counted += t.counted ? 1 : 0;
  Census before = census(positions, tets, options.min_det);
  report.inverted_before = before.inverted;
  report.min_det_before = before.min_det;
  Energy energy(positions, fixed, tets, options.lambda, anchors, containment);
  report.free_points = static_cast<long>(energy.free_count());
  Census now = before;
  long outside = energy.outside_count();
  report.outside_before = outside;
  if ((before.inverted > 0 || !anchors.empty() || outside > 0) && energy.free_count() > 0) {
    Eigen::VectorXd x = energy.get();
    // Initial eps: large enough that the most inverted tetrahedron still has a finite,
    // well-scaled energy (Garanzha et al. 2021: eps ~ the depth of the worst inversion).
    double eps = std::max(1e-2, 2.0 * std::max(0.0, -now.min_det));
    double e_prev = energy.evaluate(x, eps, nullptr);
    double best_min_det = now.min_det;
    long best_inverted = now.inverted;
    long best_outside = outside;
    // The best state met (the entry one first): fewest inverted, then fewest containment points
    // outside, then the largest smallest det J (also when none is inverted). The run returns it
    // when it ends worse: a run that starts near an unfolded state with a wider eps can fold
    // more cells than it found, and soft pins that gain nothing on either count only worsen
    // the worst cell (the pins at the end of the lattice untangling place what is still outside).
    std::vector<Vec3> kept_positions = positions;
    Census kept = now;
    long kept_outside = outside;
    auto better = [](const Census& a, long a_out, const Census& b, long b_out) {
      if (a.inverted != b.inverted) return a.inverted < b.inverted;
      if (a_out != b_out) return a_out < b_out;
      return a.min_det > b.min_det;
    };
    int stalled = 0;
    for (int stage = 0; stage < options.max_stages; ++stage) {
      report.iterations += minimise(energy, x, eps, options.stage_iterations, options.history);
      ++report.stages;
      report.eps = eps;
      now = census(positions, tets, options.min_det);
      outside = energy.outside_count();
      if (options.keep_best && better(now, outside, kept, kept_outside)) {
        kept_positions = positions;
        kept = now;
        kept_outside = outside;
      }
      if (now.inverted == 0 && outside == 0) break;
      // Progress: fewer inverted, a larger smallest det while some are inverted, fewer outside.
      if ((now.inverted > 0 && now.min_det > best_min_det + 1e-6) || now.inverted < best_inverted ||
          outside < best_outside) {
        best_min_det = std::max(best_min_det, now.min_det);
        best_inverted = std::min(best_inverted, now.inverted);
        best_outside = std::min(best_outside, outside);
        stalled = 0;
      } else if (++stalled >= options.stall_stages) {
        break;
      }
      // The paper's rule: sigma from the relative energy decrease (at least min_sigma: where a few
      // folded cells are a small part of the energy the decrease stays below the paper's floor
      // of 0.1 and eps would fall by only ~8% a stage), mu a share of chi(min det).
      const double e_new = energy.evaluate(x, eps, nullptr);
      const double sigma = std::max(1.0 - e_new / e_prev, options.min_sigma);
      const double mu = (1.0 - sigma) * chi(now.min_det, eps);
      eps = now.min_det < mu ? 2.0 * std::sqrt(mu * (mu - now.min_det)) : kSmallestEps;
      eps = std::max(eps, kSmallestEps);
      // The containment tightens each stage that leaves a point outside, not only once every
      // tetrahedron is positive: where one fold outlasts the stages that never happens, and
      // hundreds of points go out and are pinned, folding cells.
      if (outside > 0)
        energy.containment_scale = std::min(containment.max_scale, energy.containment_scale * containment.growth);
      e_prev = energy.evaluate(x, eps, nullptr);
    }
    if (options.keep_best && better(kept, kept_outside, now, outside)) {
      positions = kept_positions;
      now = kept;
      x = energy.get();
      ++report.reverted;
    }
    if (now.inverted == 0 && options.polish_iterations > 0) {
      // Improve the shapes with the barrier in force (a small eps keeps every det positive).
      const std::vector<Vec3> untangled = positions;
      const double polish_eps = std::min(report.eps, 1e-8);
      report.iterations += minimise(energy, x, polish_eps, options.polish_iterations, options.history);
      const Census polished = census(positions, tets, options.min_det);
      if (polished.inverted == 0)
        now = polished;
      else
        positions = untangled;
    }
  }
  report.inverted_after = now.inverted;
  report.outside_after = energy.outside_count();
  report.containment_scale = energy.containment_scale;
  report.uncounted_inverted_after = census(positions, tets, options.min_det).uncounted_inverted;
  report.min_det_after = now.min_det;
  report.evaluations = energy.evaluations;
  report.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return report;
}

}  // namespace fascicle
