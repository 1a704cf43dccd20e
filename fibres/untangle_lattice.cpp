#include "fibres/untangle_lattice.h"

#include "fibres/fibre_grid.h"
#include "geometry/errors.h"
#include "morph/signed_distance_grid.h"

#include <Eigen/LU>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <algorithm>
#include <memory>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>
#include <utility>

namespace fascicle {

void LatticeUntangleOptions::validate() const {
  solver.validate();
  if (iterations < 0 || iterations > 10'000'000)
    throw OptionError("untangle iterations: must be in 0..10000000, got " + std::to_string(iterations));
  if (!(end_anchor_weight > 0.0 && end_anchor_weight < 1e12))
    throw OptionError("end_anchor_weight: must be in (0, 1e12), got " + std::to_string(end_anchor_weight));
  if (!(end_shift >= 0.0 && end_shift < 1.0))
    throw OptionError("end_shift: must be in [0, 1), got " + std::to_string(end_shift));
  if (!(end_area_margin >= 0.0 && end_area_margin < 1.0))
    throw OptionError("end_area_margin: must be in [0, 1), got " + std::to_string(end_area_margin));
  if (!(contact_weight > 0.0 && contact_weight < 1e12))
    throw OptionError("untangle contact_weight: must be in (0, 1e12), got " + std::to_string(contact_weight));
  if (pin_rounds < 0 || pin_rounds > 100)
    throw OptionError("untangle pin_rounds: must be in 0..100, got " + std::to_string(pin_rounds));
  if (contact_stall_rounds < 0 || contact_stall_rounds > 100)
    throw OptionError("untangle contact_stall_rounds: must be in 0..100, got " + std::to_string(contact_stall_rounds));
  if (contact_rounds < 0 || contact_rounds > 100)
    throw OptionError("untangle contact_rounds: must be in 0..100, got " + std::to_string(contact_rounds));
  if (!(ring_depth >= 0.0 && ring_depth < 1.0))
    throw OptionError("untangle ring_depth: must be in [0, 1), got " + std::to_string(ring_depth));
  if (!(ring_weight > 0.0 && ring_weight < 1e12))
    throw OptionError("untangle ring_weight: must be in (0, 1e12), got " + std::to_string(ring_weight));
  if (!(contact_depth > 0.0 && contact_depth < 1.0))
    throw OptionError("untangle contact_depth: must be in (0, 1), got " + std::to_string(contact_depth));
  if (!(containment_margin >= 0.0 && containment_margin < 1.0))
    throw OptionError("untangle containment_margin: must be in [0, 1), got " + std::to_string(containment_margin));
  if (!(containment_band > 0.0 && containment_band < 1e6))
    throw OptionError("untangle containment_band: must be in (0, 1e6), got " + std::to_string(containment_band));
}

nlohmann::json LatticeUntangleReport::to_json() const {
  return {{"runs", runs},
          {"inverted_before", inverted_before},
          {"inverted_left", inverted_left},
          {"budget_left", budget_left},
          {"pinned", pinned},
          {"kept", kept},
          {"stops", stops},
          {"iterations", iterations},
          {"free_ring_tried", free_ring_tried},
          {"leaving_before", leaving_before},
          {"leaving_after", leaving_after},
          {"crossing_before", crossing_before},
          {"crossing_after", crossing_after},
          {"segments_kept", segments_kept},
          {"segments_needed", segments_needed}};
}

namespace {

// Mean length of the springs at each point of `system` among those `counts` accepts; a point with
// none of them gets otherwise[point] (0 when `otherwise` is null).
template <class Counts>
std::vector<double> mean_spring_length(const springs::SpringSystem& system, Counts counts,
                                       const std::vector<double>* otherwise) {
  std::vector<double> sum(system.positions.size(), 0.0), count(system.positions.size(), 0.0);
  for (const springs::Spring& s : system.springs) {
    if (!counts(s)) continue;
    const double l =
        (system.positions[static_cast<std::size_t>(s.a)] - system.positions[static_cast<std::size_t>(s.b)]).norm();
    sum[static_cast<std::size_t>(s.a)] += l;
    sum[static_cast<std::size_t>(s.b)] += l;
    count[static_cast<std::size_t>(s.a)] += 1.0;
    count[static_cast<std::size_t>(s.b)] += 1.0;
  }
  for (std::size_t i = 0; i < sum.size(); ++i)
    sum[i] = count[i] > 0.0 ? sum[i] / count[i] : otherwise ? (*otherwise)[i] : 0.0;
  return sum;
}

}  // namespace

std::vector<double> lattice_local_spacing(const springs::SpringSystem& system) {
  return mean_spring_length(
      system, [](const springs::Spring&) { return true; }, nullptr);
}

std::vector<double> lattice_across_spacing(const springs::Lattice& lattice, const springs::SpringSystem& system) {
  const std::vector<double> local = lattice_local_spacing(system);
  const int plane = lattice.nx * lattice.ny, n = lattice.point_count();
  return mean_spring_length(
      system, [&](const springs::Spring& s) { return s.a < n && s.b < n && s.a / plane == s.b / plane; }, &local);
}

Vec3 lattice_contact_point(const springs::SpringSystem& system, int lattice_points, const SurfaceQuery& query, int q,
                           double depth_in_spacings, const std::vector<double>& spacing) {
  const Vec3 p = system.positions[static_cast<std::size_t>(q)];
  const SurfacePoint c = query.closest_point(p);
  Vec3 inward = c.position - p;
  if (inward.norm() == 0.0) {
    // On the surface: go towards the muscle's centre of mass of the lattice neighbours.
    inward = Vec3::Zero();
    for (const springs::Spring& s : system.springs) {
      if (s.a == q) inward += system.positions[static_cast<std::size_t>(s.b)] - p;
      if (s.b == q) inward += system.positions[static_cast<std::size_t>(s.a)] - p;
    }
  }
  inward.normalize();
  double depth = depth_in_spacings * spacing[static_cast<std::size_t>(q)];
  Vec3 moved = c.position + depth * inward;
  for (int attempt = 0; attempt < 6 && query.side(moved) != Side::inside; ++attempt) {
    depth *= 0.5;
    moved = c.position + depth * inward;
  }
  if (query.side(moved) == Side::inside) return moved;
  // Thin places, where the inward normal leaves through the other side: on the way from the
  // closest surface point to a lattice neighbour that is inside (nearest first).
  std::vector<std::pair<double, Vec3>> inside_neighbours;
  for (const springs::Spring& s : system.springs) {
    const int other = s.a == q ? s.b : s.b == q ? s.a : -1;
    if (other < 0 || other >= lattice_points) continue;
    const Vec3& o = system.positions[static_cast<std::size_t>(other)];
    if (query.side(o) == Side::inside) inside_neighbours.emplace_back((o - p).norm(), o);
  }
  std::sort(inside_neighbours.begin(), inside_neighbours.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [distance, o] : inside_neighbours)
    for (double t = 0.5; t > 1e-2; t *= 0.5) {
      const Vec3 candidate = o + t * (c.position - o);
      if (query.side(candidate) == Side::inside) return candidate;
    }
  return moved;
}

std::vector<UntangleTet> lattice_cell_tets(const springs::Lattice& lattice, const std::vector<Vec3>& x) {
  const auto& kuhn = kuhn_tetrahedra();
  auto at = [&](int i, int j, int k) { return lattice.index(i, j, k); };
  auto len = [&](int a, int b) { return (x[static_cast<std::size_t>(a)] - x[static_cast<std::size_t>(b)]).norm(); };
  std::vector<UntangleTet> tets;
  double total = 0.0;
  for (int k = 0; k + 1 < lattice.nz; ++k) {
    double hr = 0.0, hs = 0.0, ht = 0.0;
    int nr = 0, ns = 0, nt = 0;
    for (int c = 0; c < 2; ++c)
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i) {
          if (i + 2 < lattice.nx) hr += len(at(i, j, k + c), at(i + 1, j, k + c)), ++nr;
          if (j + 2 < lattice.ny) hs += len(at(i, j, k + c), at(i, j + 1, k + c)), ++ns;
          if (c == 0) ht += len(at(i, j, k), at(i, j, k + 1)), ++nt;
        }
    const Vec3 h(nr ? hr / nr : 1.0, ns ? hs / ns : 1.0, nt ? ht / nt : 1.0);
    if (!(h.minCoeff() > 0.0)) continue;
    for (int j = 0; j + 1 < lattice.ny; ++j)
      for (int i = 0; i + 1 < lattice.nx; ++i) {
        const bool counted = i >= 1 && j >= 1 && i + 2 < lattice.nx && j + 2 < lattice.ny;
        int corner_index[8];
        Vec3 corner_box[8];
        for (int q = 0; q < 8; ++q) {
          const int a = q & 1, b = (q >> 1) & 1, c = (q >> 2) & 1;
          corner_index[q] = at(i + a, j + b, k + c);
          corner_box[q] = Vec3(a * h.x(), b * h.y(), c * h.z());
        }
        for (const std::array<int, 4>& local : kuhn) {
          UntangleTet tet;
          tet.counted = counted;
          tet.eps_floor = counted ? 0.0 : 0.5;
          Eigen::Matrix3d s, d;
          for (int col = 0; col < 3; ++col) {
            s.col(col) = corner_box[local[static_cast<std::size_t>(col) + 1]] - corner_box[local[0]];
            d.col(col) = x[static_cast<std::size_t>(corner_index[local[static_cast<std::size_t>(col) + 1]])] -
                         x[static_cast<std::size_t>(corner_index[local[0]])];
          }
          for (int v = 0; v < 4; ++v)
            tet.v[static_cast<std::size_t>(v)] = corner_index[local[static_cast<std::size_t>(v)]];
          tet.reference_inverse = s.inverse();
          if (counted) total += d.determinant();
          tets.push_back(tet);
        }
      }
  }
  if (total < 0.0) {
    // The lattice lies mirrored in the muscle: orient every tetrahedron (and its reference) the
    // other way.
    const Eigen::Matrix3d mirror = Eigen::Vector3d(-1.0, 1.0, 1.0).asDiagonal();
    for (UntangleTet& tet : tets) tet.reference_inverse = tet.reference_inverse * mirror;
  }
  // A tetrahedron in good shape keeps its own settled shape as the reference, so that the
  // untangling energy is least where the settle left the lattice and changes it only around
  // the folds: good = det J > 0.2 and shape distortion tr(J^T J) / (3 det^(2/3)) < 2 against the
  // layer's box (the same orientation, so an inverted tetrahedron never becomes a reference).
  for (UntangleTet& tet : tets) {
    Eigen::Matrix3d d;
    for (int col = 0; col < 3; ++col)
      d.col(col) =
          x[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(col) + 1])] - x[static_cast<std::size_t>(tet.v[0])];
    const Eigen::Matrix3d j = d * tet.reference_inverse;
    const double det = j.determinant();
    if (!(det > 0.2)) continue;
    if (j.squaredNorm() / (3.0 * std::cbrt(det * det)) < 2.0) tet.reference_inverse = d.inverse();
  }
  return tets;
}

long inverted_tets(const std::vector<Vec3>& x, const std::vector<UntangleTet>& tets) {
  long n = 0;
  const std::vector<double> dets = tet_jacobian_dets(x, tets);
  for (std::size_t t = 0; t < tets.size(); ++t) n += tets[t].counted && !(dets[t] > 0.0) ? 1 : 0;
  return n;
}

std::vector<int> outside_free_points(const springs::SpringSystem& system, const SurfaceQuery& query) {
  const std::size_t n = system.positions.size();
  std::vector<char> out_flag(n, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t q = range.begin(); q != range.end(); ++q)
      out_flag[q] = !system.fixed[q] && query.side(system.positions[q]) != Side::inside;
  });
  std::vector<int> out;
  for (std::size_t q = 0; q < n; ++q)
    if (out_flag[q]) out.push_back(static_cast<int>(q));
  return out;
}

namespace {

// The point of `area` nearest to p (p itself when the area is empty).
Vec3 nearest_area_point(const std::vector<Vec3>& area, const Vec3& p) {
  Vec3 best = p;
  double best_d = std::numeric_limits<double>::infinity();
  for (const Vec3& a : area) {
    const double d = (a - p).squaredNorm();
    if (d < best_d) best_d = d, best = a;
  }
  return best;
}

}  // namespace

LatticeUntangleReport untangle_lattice(const springs::Lattice& lattice, springs::SpringSystem& system,
                                       const SurfaceQuery& query, double length, const LatticeUntangleOptions& options,
                                       const Attachments* areas, const SegmentContact* segments,
                                       springs::SpringSystem* unheld,
                                       const std::function<bool(const springs::SpringSystem&)>& segments_needed) {
  options.validate();
  LatticeUntangleReport report;
  // The area each end layer belongs to (k = 0: origin, k = nz - 1: insertion); empty: the ends
  // keep the cast-place rule.
  std::vector<Vec3> origin_area, insertion_area;
  if (areas && options.end_area_margin > 0.0 && !areas->origin.points.empty() && !areas->insertion.points.empty()) {
    for (const SurfacePoint& p : areas->origin.points) origin_area.push_back(p.position);
    for (const SurfacePoint& p : areas->insertion.points) insertion_area.push_back(p.position);
  }
  const bool by_area = !origin_area.empty();
  auto area_of = [&](int q) -> const std::vector<Vec3>& {
    return q / (lattice.nx * lattice.ny) == 0 ? origin_area : insertion_area;
  };
  const double area_limit = options.end_area_margin * length;  // farthest an end may lie from its area
  const double area_ball = 0.8 * area_limit;                   // where its soft pin starts to pull
  const std::vector<UntangleTet> tets = lattice_cell_tets(lattice, system.positions);
  // The local spacing the depths are measured in (across_spacing); the weights stay per squared
  // lattice_local_spacing().
  auto spacing_now = [&] {
    return options.across_spacing ? lattice_across_spacing(lattice, system) : lattice_local_spacing(system);
  };
  // The signed-distance grid of the containment energy, made on first use (cells a quarter of the
  // 10th-percentile local spacing, over the lattice's box widened by 3 of the largest spacings).
  std::unique_ptr<SignedDistanceGrid> distance_grid;
  auto grid = [&]() -> SignedDistanceGrid& {
    if (!distance_grid) {
      std::vector<double> sp = lattice_local_spacing(system);
      sp.resize(static_cast<std::size_t>(lattice.point_count()));
      std::vector<double> sorted = sp;
      std::sort(sorted.begin(), sorted.end());
      const double small = std::max(sorted[sorted.size() / 10], 1e-9 + 1e-6 * sorted.back());
      Vec3 low = Vec3::Constant(std::numeric_limits<double>::infinity()), high = -low;
      for (int q = 0; q < lattice.point_count(); ++q) {
        low = low.cwiseMin(system.positions[static_cast<std::size_t>(q)]);
        high = high.cwiseMax(system.positions[static_cast<std::size_t>(q)]);
      }
      low.array() -= 3.0 * sorted.back();
      high.array() += 3.0 * sorted.back();
      distance_grid = std::make_unique<SignedDistanceGrid>(query, low, high, 0.25 * small, 4'000'000);
    }
    return *distance_grid;
  };
  nlohmann::json& runs = report.runs;
  auto inverted_count = [&] { return inverted_tets(system.positions, tets); };
  report.inverted_before = inverted_count();
  auto contact_target = [&](int q, const std::vector<double>& spacing) {
    return lattice_contact_point(system, lattice.point_count(), query, q, options.contact_depth, spacing);
  };
  std::vector<int> outside;
  // The counted tetrahedra at each point (for the pins' target search).
  std::vector<std::vector<int>> tets_at(system.positions.size());
  for (std::size_t t = 0; t < tets.size(); ++t)
    if (tets[t].counted)
      for (int v : tets[t].v) tets_at[static_cast<std::size_t>(v)].push_back(static_cast<int>(t));
  // Where a pin at the end puts the outside point q: the shallowest of a few depths under its
  // closest surface point that is inside and folds none of q's counted tetrahedra, else the one
  // inside that folds the fewest; contact_target() when none is inside.
  auto pin_target = [&](int q, const std::vector<double>& spacing) {
    Vec3& x = system.positions[static_cast<std::size_t>(q)];
    const Vec3 original = x;
    std::vector<Vec3> candidates;
    for (double depth : {0.02, 0.05, 0.1, 0.2, 0.3, 0.5})
      if (depth <= options.contact_depth) {
        const Vec3 c = lattice_contact_point(system, lattice.point_count(), query, q, depth, spacing);
        if (query.side(c) == Side::inside) candidates.push_back(c);
      }
    Vec3 best = contact_target(q, spacing);
    long best_folded = std::numeric_limits<long>::max();
    for (const Vec3& c : candidates) {
      x = c;
      long folded = 0;
      for (int t : tets_at[static_cast<std::size_t>(q)]) {
        const UntangleTet& tet = tets[static_cast<std::size_t>(t)];
        Eigen::Matrix3d d;
        for (int col = 0; col < 3; ++col)
          d.col(col) = system.positions[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(col) + 1])] -
                       system.positions[static_cast<std::size_t>(tet.v[0])];
        folded += (d * tet.reference_inverse).determinant() > 0.0 ? 0 : 1;
      }
      if (folded < best_folded) best_folded = folded, best = c;
      if (folded == 0) break;
    }
    x = original;
    return best;
  };
  // One attempt: rounds of (local, then wider) untangling and soft containment. With
  // `free_ends` the fibre ends may give way too (into the muscle, or along the surface), held
  // by ball pins round their areas (or soft pins at their cast places without areas): a cell
  // against an end face can need that. With `free_ring` the surface ring may slide along the
  // surface as well.
  int budget = options.iterations;
  auto attempt = [&](bool free_ends, bool free_ring, bool contain, bool hold_segments = false) {
    std::vector<UntangleAnchor> anchors;
    std::unordered_map<int, std::size_t> anchor_of;    // lattice point -> its containment anchor
    std::unordered_map<int, std::size_t> end_anchor;   // fibre end -> its anchor (cast place or area ball)
    std::unordered_map<int, Vec3> cast_place;          // fibre end -> where the cast put it
    std::unordered_map<int, std::size_t> ring_anchor;  // freed surface-ring point -> its anchor
    if (free_ends) {
      const std::vector<double> spacing = lattice_local_spacing(system);
      for (int k : {0, lattice.nz - 1})
        for (int j = 1; j + 1 < lattice.ny; ++j)
          for (int i = 1; i + 1 < lattice.nx; ++i) {
            const int q = lattice.index(i, j, k);
            const double h = spacing[static_cast<std::size_t>(q)];
            const Vec3 x = system.positions[static_cast<std::size_t>(q)];
            system.fixed[static_cast<std::size_t>(q)] = 0;
            end_anchor[q] = anchors.size();
            cast_place[q] = x;
            UntangleAnchor a{q, x, options.end_anchor_weight / (h * h)};
            if (by_area) {
              // Free within a ball round the nearest area point (renewed each round).
              a.target = nearest_area_point(area_of(q), x);
              a.radius = area_ball;
            }
            anchors.push_back(a);
          }
      // The surface ring free too (free_ring), each point held on a plane (renew_ring below).
      if (free_ring)
        for (int k = 0; k < lattice.nz; ++k) {
          for (int j = 0; j < lattice.ny; ++j)
            for (int i = 0; i < lattice.nx; ++i)
              if (i == 0 || j == 0 || i + 1 == lattice.nx || j + 1 == lattice.ny) {
                const int q = lattice.index(i, j, k);
                if (!system.fixed[static_cast<std::size_t>(q)]) continue;
                system.fixed[static_cast<std::size_t>(q)] = 0;
                const double h = spacing[static_cast<std::size_t>(q)];
                ring_anchor[q] = anchors.size();
                UntangleAnchor a{q, Vec3::Zero(), options.ring_weight / (h * h)};
                a.one_sided = false;
                anchors.push_back(a);
              }
        }
    }
    // A freed ring point is held on the plane through the point `ring_depth` local spacings under
    // its closest surface point, across the direction from its interior neighbour in its layer
    // (the outward direction there; renewed each round): it may slide along the surface.
    auto renew_ring = [&] {
      if (ring_anchor.empty()) return;
      const std::vector<double> sp = spacing_now();
      for (const auto& [q, a] : ring_anchor) {
        const Vec3& x = system.positions[static_cast<std::size_t>(q)];
        const int plane = lattice.nx * lattice.ny;
        const int k = q / plane, j = (q % plane) / lattice.nx, i = q % lattice.nx;
        const Vec3& inner = system.positions[static_cast<std::size_t>(
            lattice.index(std::clamp(i, 1, lattice.nx - 2), std::clamp(j, 1, lattice.ny - 2), k))];
        const Vec3 n = x - inner;
        anchors[a].normal = n.norm() > 0.0 ? Vec3(n.normalized()) : Vec3::UnitX();
        anchors[a].target =
            query.closest_point(x).position - options.ring_depth * sp[static_cast<std::size_t>(q)] * anchors[a].normal;
      }
    };
    renew_ring();
    // The ends are fixed again, at most `end_shift` (a share of the muscle length) from their
    // cast places (with areas: at most end_area_margin from the nearest area point) so that they
    // stay on their attachment areas; one the untangling left outside goes to the closest surface
    // point.
    auto clamp_ends = [&] {
      if (!free_ends) return;
      for (int k : {0, lattice.nz - 1})
        for (int j = 1; j + 1 < lattice.ny; ++j)
          for (int i = 1; i + 1 < lattice.nx; ++i) {
            const int q = lattice.index(i, j, k);
            if (system.fixed[static_cast<std::size_t>(q)]) continue;
            Vec3& x = system.positions[static_cast<std::size_t>(q)];
            const Vec3 centre = by_area ? nearest_area_point(area_of(q), x) : cast_place.at(q);
            const double limit = by_area ? area_limit : options.end_shift * length;
            if ((x - centre).norm() > limit) x = centre + limit * (x - centre).normalized();
            if (query.side(x) == Side::outside) x = query.closest_point(x).position;
            system.fixed[static_cast<std::size_t>(q)] = 1;
          }
    };
    // Containment inside the energy (containment_energy): the free points near the surface or
    // outside it, renewed each round, but the ring (held by its plane pins; it starts on the
    // surface, half of it just outside, and its containment pulled against the unfolding) and
    // the fibre ends (held by their area pins and clamped onto the surface at the end). The points
    // are listed in index order (the result must not depend on a hash map's order).
    UntangleContainment containment;
    if (contain) {
      SignedDistanceGrid& field = grid();
      containment.signed_distance = [&field](const Vec3& p, Vec3* gradient) { return field(p, gradient); };
    }
    auto renew_containment = [&] {
      if (!contain) return;
      const std::vector<double> sp = spacing_now();
      const std::vector<double> weight_sp = lattice_local_spacing(system);
      std::vector<int> candidates;
      for (int k = 0; k < lattice.nz; ++k)
        for (int j = 0; j < lattice.ny; ++j)
          for (int i = 0; i < lattice.nx; ++i) {
            const int q = lattice.index(i, j, k);
            if (!system.fixed[static_cast<std::size_t>(q)] && !ring_anchor.count(q) && !end_anchor.count(q))
              candidates.push_back(q);
          }
      std::vector<char> near(candidates.size(), 0);
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(0, candidates.size(), 256), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t c = r.begin(); c < r.end(); ++c) {
              const std::size_t q = static_cast<std::size_t>(candidates[c]);
              near[c] = query.closest_point(system.positions[q]).distance < options.containment_band * sp[q] ? 1 : 0;
            }
          });
      std::unordered_set<int> out(outside.begin(), outside.end());
      containment.points.clear();
      for (std::size_t c = 0; c < candidates.size(); ++c) {
        const int q = candidates[c];
        if (!near[c] && !out.count(q)) continue;
        const double h = weight_sp[static_cast<std::size_t>(q)];
        containment.points.push_back(
            {q, options.contact_weight / (h * h), options.containment_margin * sp[static_cast<std::size_t>(q)]});
      }
    };
    outside.clear();
    renew_containment();
    long best_round = inverted_count();  // fewest folded tetrahedra after a round of this attempt
    long best_outside = -1;              // fewest points outside after a round of this attempt (-1: none yet)
    int outside_stalled = 0;             // rounds in a row since the last that left fewer outside
    for (int round = 0;; ++round) {
      const std::size_t runs_before = runs.size();
      const std::vector<Vec3> round_start(system.positions.begin(), system.positions.begin() + lattice.point_count());
      long previous_free = -1;  // free points of the previous run of this round
      // Local first: only the points within `radius` lattice steps (Chebyshev) of an inverted
      // cell or an anchored point move, the rest of the settled lattice stays as it is; the
      // region grows while cells stay inverted, up to the whole lattice only once the surface
      // ring has been freed (its attempt and the one that goes on from it): with the ring where
      // the settle put it, the points far from the folds are held where they are by it.
      for (int radius : {2, 6, 1 << 20}) {
        if (radius > 6 && !report.free_ring_tried) break;
        if (budget <= 0) break;
        const std::vector<double> dets = tet_jacobian_dets(system.positions, tets);
        std::vector<char> near(static_cast<std::size_t>(lattice.point_count()), 0);
        bool inverted = false;
        for (std::size_t t = 0; t < tets.size(); ++t) {
          if (!tets[t].counted || dets[t] > options.solver.min_det) continue;
          inverted = true;
          for (int v : tets[t].v) near[static_cast<std::size_t>(v)] = 1;
        }
        if (!inverted && (radius > 2 || anchors.empty())) break;
        for (const UntangleAnchor& a : anchors) near[static_cast<std::size_t>(a.point)] = 1;
        const bool whole = radius >= std::max({lattice.nx, lattice.ny, lattice.nz});
        std::vector<char> local_fixed = system.fixed;
        if (!whole) {
          std::vector<char> region(near.size(), 0);
          for (int k = 0; k < lattice.nz; ++k)
            for (int j = 0; j < lattice.ny; ++j)
              for (int i = 0; i < lattice.nx; ++i) {
                if (!near[static_cast<std::size_t>(lattice.index(i, j, k))]) continue;
                for (int c = std::max(0, k - radius); c <= std::min(lattice.nz - 1, k + radius); ++c)
                  for (int b = std::max(0, j - radius); b <= std::min(lattice.ny - 1, j + radius); ++b)
                    for (int a = std::max(0, i - radius); a <= std::min(lattice.nx - 1, i + radius); ++a)
                      region[static_cast<std::size_t>(lattice.index(a, b, c))] = 1;
              }
          for (std::size_t q = 0; q < region.size(); ++q)
            if (!region[q]) local_fixed[q] = 1;
        }
        // A wider region that frees no more points than the last run is the same problem again:
        // skip it (its last run already stopped where it could not improve).
        long free = 0;
        for (char f : local_fixed) free += f ? 0 : 1;
        if (free == previous_free) break;
        previous_free = free;
        const UntangleReport untangled =
            untangle(system.positions, local_fixed, tets, options.solver, anchors, containment);
        nlohmann::json run = untangled.to_json();
        run["radius"] = whole ? -1 : radius;
        run["round"] = round;
        run["anchors"] = anchors.size();
        if (contain) run["contained"] = containment.points.size();
        runs.push_back(run);
        budget -= untangled.iterations;
        report.iterations += untangled.iterations;
        if (untangled.untangled()) break;
      }
      outside = outside_free_points(system, query);
      if (!ring_anchor.empty())
        outside.erase(std::remove_if(outside.begin(), outside.end(), [&](int q) { return ring_anchor.count(q) > 0; }),
                      outside.end());
      // Segment contact: the free points of fibre segments that leave the muscle (not outside
      // themselves, nor freed ends or ring points, which have pins of their own).
      std::vector<std::pair<int, Vec3>> leaving;
      if (segments && hold_segments) {
        leaving = leaving_segment_shifts(lattice, system, query, segments->end_tolerance, segments->shifts);
        const std::unordered_set<int> out(outside.begin(), outside.end());
        leaving.erase(std::remove_if(leaving.begin(), leaving.end(),
                                     [&](const std::pair<int, Vec3>& l) {
                                       return out.count(l.first) > 0 || ring_anchor.count(l.first) > 0 ||
                                              end_anchor.count(l.first) > 0;
                                     }),
                      leaving.end());
      }
      // A segment round after the first that moved no lattice point left everything as the round
      // before did but the pins' weights: the untangling found no step that lowers its energy
      // (the cells' barrier against the pins that hold the segments in), and further rounds stall
      // alike. (The other attempts go on: their stronger pins can still move a point later.)
      const bool unmoved = hold_segments && round > 0 &&
                           std::equal(round_start.begin(), round_start.end(), system.positions.begin());
      if (runs.size() > runs_before) {
        runs.back()["outside"] = outside.size();
        if (hold_segments) runs.back()["leaving_points"] = leaving.size();
        runs.back()["free_ends"] = free_ends;
      }
      const long now_outside = static_cast<long>(outside.size() + leaving.size());
      if (best_outside < 0 || now_outside < best_outside) {
        best_outside = now_outside;
        outside_stalled = 0;
      } else {
        ++outside_stalled;
      }
      std::string stop = outside.empty() && leaving.empty() ? "contained"
                         : round == options.contact_rounds  ? "rounds"
                         : budget <= 0                      ? "budget"
                         : unmoved                          ? "unmoved"
                                                            : "";
      if (stop.empty()) {
        // Rounds that do not leave fewer points outside than the best round before: the soft
        // pins only push the fold around (points come in here, others go out there); the pins
        // at the end take the points still outside.
        if (options.contact_stall_rounds > 0 && outside_stalled >= options.contact_stall_rounds)
          stop = "outside_stalled";
      }
      if (stop.empty()) {
        // A round that left cells folded and did not fold fewer than the best round before is a
        // stall: the containment pins of further rounds only pull against the same fold (the
        // attempts after this one start elsewhere). With fold_stall_needs_outside_stall, only when
        // it did not leave fewer points outside either: while the pins still bring points in, the
        // rounds go on (the pins at the end would take those points and pinch the cells).
        const long now = inverted_count();
        if (now > 0 && now >= best_round && (!options.fold_stall_needs_outside_stall || outside_stalled > 0))
          stop = "fold_stalled";
        best_round = std::min(best_round, now);
      }
      if (!stop.empty()) {
        if (runs.size() > runs_before) runs.back()["stop"] = stop;
        report.stops[stop] = report.stops.value(stop, 0) + 1;
        break;
      }
      renew_ring();
      renew_containment();
      // The ends' balls follow them: round the area point nearest to where each end is now.
      if (by_area)
        for (const auto& [q, a] : end_anchor)
          anchors[a].target = nearest_area_point(area_of(q), system.positions[static_cast<std::size_t>(q)]);
      // Containment: an outside point gets a soft pin just inside, 4x stronger each round (with
      // sliding_contact a half-space under the tangent plane at its closest surface point).
      const std::vector<double> spacing = spacing_now();
      const std::vector<double> weight_spacing = lattice_local_spacing(system);
      for (const auto& [q, shift] : leaving) {
        const Vec3 target = system.positions[static_cast<std::size_t>(q)] + shift;
        const auto it = anchor_of.find(q);
        if (it == anchor_of.end()) {
          const double h = weight_spacing[static_cast<std::size_t>(q)];
          anchor_of[q] = anchors.size();
          UntangleAnchor a{q, target, options.contact_weight / (h * h)};
          a.normal = -shift.normalized();  // a half-space: the point may go deeper
          anchors.push_back(a);
        } else {
          anchors[it->second].target = target;
          anchors[it->second].normal = -shift.normalized();
          anchors[it->second].weight *= 4.0;
        }
      }
      for (int q : outside) {
        const Vec3 target = contact_target(q, spacing);
        Vec3 normal = Vec3::Zero();
        if (options.sliding_contact) {
          const Vec3& p = system.positions[static_cast<std::size_t>(q)];
          const Vec3 out = p - query.closest_point(p).position;
          if (out.norm() > 0.0) normal = out.normalized();
        }
        const auto it = anchor_of.find(q);
        if (it == anchor_of.end()) {
          const double h = weight_spacing[static_cast<std::size_t>(q)];
          anchor_of[q] = anchors.size();
          UntangleAnchor a{q, target, options.contact_weight / (h * h)};
          a.normal = normal;
          anchors.push_back(a);
        } else {
          anchors[it->second].target = target;
          anchors[it->second].normal = normal;
          anchors[it->second].weight *= 4.0;
        }
      }
    }
    clamp_ends();
    return inverted_count();
  };
  // The ends held first, from the settled lattice (cheap where the folds are local: most
  // muscles); while cells stay inverted, from the settled lattice with the ends free, then on
  // from there with the ends held. The result with the fewest inverted cells stays. Each attempt
  // has the whole iteration budget and stops early when a round does not improve.
  const std::vector<Vec3> settled = system.positions;
  const std::vector<char> settled_fixed = system.fixed;
  // Containment inside the loop: the points still outside (and interior points the settle's
  // containment fixed at a place that is not inside: the fallback of lattice_contact_point) are
  // fixed just inside, and, since that can fold the cells around them, the untangling runs again
  // with them fixed (the ends held), until no point is outside, at most `pin_rounds` times.
  // Returns the folded tetrahedra after it; `pinned` counts the points it fixed.
  auto finish = [&](long& pinned) {
    std::unordered_set<int> pinned_here;  // points this stage fixed just inside
    long left = inverted_count();
    for (int pass = 0;; ++pass) {
      outside = outside_free_points(system, query);
      for (int k = 1; k + 1 < lattice.nz; ++k)
        for (int j = 1; j + 1 < lattice.ny; ++j)
          for (int i = 1; i + 1 < lattice.nx; ++i) {
            const int q = lattice.index(i, j, k);
            if (system.fixed[static_cast<std::size_t>(q)] && !pinned_here.count(q) &&
                query.side(system.positions[static_cast<std::size_t>(q)]) != Side::inside)
              outside.push_back(q);
          }
      if (pass == 0) runs.back()["outside_at_finish"] = outside.size();
      if (outside.empty()) break;
      const std::vector<double> spacing = spacing_now();
      for (int q : outside) {
        system.positions[static_cast<std::size_t>(q)] =
            options.pin_search ? pin_target(q, spacing) : contact_target(q, spacing);
        system.fixed[static_cast<std::size_t>(q)] = 1;
        pinned_here.insert(q);
        ++pinned;
      }
      left = inverted_count();
      if (left == 0 || pass == options.pin_rounds) break;
      // Every point is inside now; an untangling that does not fold fewer cells is undone.
      const std::vector<Vec3> pinned_positions = system.positions;
      budget = options.iterations;
      const long again = attempt(false, false, options.containment_energy_everywhere && options.containment_energy);
      runs.back()["after_pins"] = pass + 1;
      if (again >= left) {
        system.positions = pinned_positions;
        break;
      }
      left = again;
    }
    return left;
  };
  // Each attempt is finished (the pins above) and judged by the folds left after its pins: an
  // attempt that unfolds every cell but leaves many points outside can end worse than one that
  // leaves a few cells folded with every point inside.
  long inverted_left = 0;
  std::string kept;
  std::vector<Vec3> best;
  std::vector<char> best_fixed;
  std::vector<Vec3> free_result;  // the free-ends attempt's result before its pins
  auto run_from = [&](const std::vector<Vec3>& from, bool free_ends, bool free_ring, bool contain,
                      const std::string& name) {
    system.positions = from;
    system.fixed = settled_fixed;
    budget = options.iterations;
    attempt(free_ends, free_ring, contain);
    if (free_ends) free_result = system.positions;
    runs.push_back({{"attempt", name}});
    const std::size_t marker = runs.size() - 1;  // finish() may append the runs after its pins
    long pinned = 0;
    const long n = finish(pinned);
    runs[marker]["finished"] = n;
    if (kept.empty() || n < inverted_left) {
      inverted_left = n;
      best = system.positions;
      best_fixed = system.fixed;
      kept = name;
      report.pinned = pinned;
    }
    return n;
  };
  // The ring is freed only after the attempts with it held: a freed ring moves the surface lines,
  // which raises the coverage p95 of muscles the held ring already unfolds.
  const bool everywhere = options.containment_energy && options.containment_energy_everywhere;
  const long held = run_from(settled, false, false, everywhere, "held_ends");
  // A free attempt's result is continued with the ends held only where it left fewer folded cells
  // than the held ends did from the settled lattice: from a start no better than that one, the
  // held ends stall on the same folds.
  auto continue_held = [&](long free_left, bool contain, const std::string& name) {
    if (inverted_left > 0 && free_left < held) run_from(free_result, false, false, contain, name);
  };
  if (inverted_left > 0) {
    const long free_left = run_from(settled, true, false, everywhere, "free_ends");
    continue_held(free_left, everywhere, "free_then_held_ends");
  }
  if (inverted_left > 0 && options.free_ring) {
    report.free_ring_tried = true;
    const long ring_left = run_from(settled, true, true, options.containment_energy, "free_ring");
    continue_held(ring_left, everywhere, "free_ring_then_held_ends");
  }
  // The segment attempt (with `segments`): from the kept result, ends and ring held, rounds whose
  // pins hold the leaving fibre segments in; kept when it folds no more cells, leaves fewer points
  // on leaving segments and no more segments out by more than the tolerance.
  auto leaving_count = [&] {
    return static_cast<long>(
        leaving_segment_shifts(lattice, system, query, segments->end_tolerance, segments->shifts).size());
  };
  if (segments) {
    system.positions = best;
    system.fixed = best_fixed;
    report.leaving_before = report.leaving_after = leaving_count();
    report.crossing_before = report.crossing_after = crossing_segment_count(lattice, system, query, *segments);
  }
  if (segments && report.crossing_before > 0) report.segments_needed = !segments_needed || segments_needed(system);
  if (report.segments_needed) {
    budget = options.iterations;
    attempt(false, false, everywhere, true);
    runs.push_back({{"attempt", "segments"}});
    const std::size_t marker = runs.size() - 1;
    long pinned = 0;
    const long n = finish(pinned);
    runs[marker]["finished"] = n;
    const long leaving = leaving_count(), crossing = crossing_segment_count(lattice, system, query, *segments);
    if (n <= inverted_left && crossing <= report.crossing_before && leaving < report.leaving_before) {
      if (unheld) {
        *unheld = system;
        unheld->positions = best;
        unheld->fixed = best_fixed;
      }
      inverted_left = n;
      best = system.positions;
      best_fixed = system.fixed;
      kept += "+segments";
      report.pinned += pinned;
      report.leaving_after = leaving;
      report.crossing_after = crossing;
      report.segments_kept = true;
    }
  }
  system.positions = best;
  system.fixed = best_fixed;
  runs.push_back({{"kept", kept}});
  report.inverted_left = inverted_left;
  report.budget_left = budget;
  report.kept = kept;
  return report;
}

}  // namespace fascicle
