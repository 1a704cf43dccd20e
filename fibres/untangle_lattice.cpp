#include "fibres/untangle_lattice.h"

#include "fibres/fibre_grid.h"
#include "geometry/errors.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
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
  if (!(contact_weight > 0.0 && contact_weight < 1e12))
    throw OptionError("untangle contact_weight: must be in (0, 1e12), got " + std::to_string(contact_weight));
  if (pin_rounds < 0 || pin_rounds > 100)
    throw OptionError("untangle pin_rounds: must be in 0..100, got " + std::to_string(pin_rounds));
  if (contact_stall_rounds < 0 || contact_stall_rounds > 100)
    throw OptionError("untangle contact_stall_rounds: must be in 0..100, got " + std::to_string(contact_stall_rounds));
  if (contact_rounds < 0 || contact_rounds > 100)
    throw OptionError("untangle contact_rounds: must be in 0..100, got " + std::to_string(contact_rounds));
  if (!(contact_depth > 0.0 && contact_depth < 1.0))
    throw OptionError("untangle contact_depth: must be in (0, 1), got " + std::to_string(contact_depth));
}

nlohmann::json LatticeUntangleReport::to_json() const {
  return {{"runs", runs},         {"inverted_before", inverted_before}, {"inverted_left", inverted_left},
          {"budget_left", budget_left}, {"pinned", pinned},             {"kept", kept},
          {"stops", stops},             {"iterations", iterations}};
}

std::vector<double> lattice_local_spacing(const springs::SpringSystem& system) {
  std::vector<double> sum(system.positions.size(), 0.0), count(system.positions.size(), 0.0);
  for (const springs::Spring& s : system.springs) {
    const double l = (system.positions[static_cast<std::size_t>(s.a)] - system.positions[static_cast<std::size_t>(s.b)]).norm();
    sum[static_cast<std::size_t>(s.a)] += l;
    sum[static_cast<std::size_t>(s.b)] += l;
    count[static_cast<std::size_t>(s.a)] += 1.0;
    count[static_cast<std::size_t>(s.b)] += 1.0;
  }
  for (std::size_t i = 0; i < sum.size(); ++i) sum[i] = count[i] > 0.0 ? sum[i] / count[i] : 0.0;
  return sum;
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
          for (int v = 0; v < 4; ++v) tet.v[static_cast<std::size_t>(v)] = corner_index[local[static_cast<std::size_t>(v)]];
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
      d.col(col) = x[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(col) + 1])] - x[static_cast<std::size_t>(tet.v[0])];
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

namespace {

std::vector<int> outside_free_points(const springs::SpringSystem& system, const SurfaceQuery& query) {
  std::vector<int> out;
  for (std::size_t q = 0; q < system.positions.size(); ++q)
    if (!system.fixed[q] && query.side(system.positions[q]) != Side::inside) out.push_back(static_cast<int>(q));
  return out;
}

}  // namespace

LatticeUntangleReport untangle_lattice(const springs::Lattice& lattice, springs::SpringSystem& system,
                                       const SurfaceQuery& query, double length,
                                       const LatticeUntangleOptions& options) {
  options.validate();
  LatticeUntangleReport report;
  const std::vector<UntangleTet> tets = lattice_cell_tets(lattice, system.positions);
  nlohmann::json& runs = report.runs;
  auto inverted_count = [&] { return inverted_tets(system.positions, tets); };
  report.inverted_before = inverted_count();
  auto contact_target = [&](int q, const std::vector<double>& spacing) {
    return lattice_contact_point(system, lattice.point_count(), query, q, options.contact_depth, spacing);
  };
  std::vector<int> outside;
  // One attempt: rounds of (local, then wider) untangling and soft containment. With
  // `free_ends` the fibre ends may give way too (into the muscle, or along the surface), held
  // by soft pins at the places the cast gave them: a cell against an end face can need that.
  int budget = options.iterations;
  auto attempt = [&](bool free_ends) {
    std::vector<UntangleAnchor> anchors;
    std::unordered_map<int, std::size_t> anchor_of;  // lattice point -> its anchor
    std::unordered_map<int, Vec3> cast_place;         // fibre end -> where the cast put it
    if (free_ends) {
      const std::vector<double> spacing = lattice_local_spacing(system);
      for (int k : {0, lattice.nz - 1})
        for (int j = 1; j + 1 < lattice.ny; ++j)
          for (int i = 1; i + 1 < lattice.nx; ++i) {
            const int q = lattice.index(i, j, k);
            const double h = spacing[static_cast<std::size_t>(q)];
            system.fixed[static_cast<std::size_t>(q)] = 0;
            anchor_of[q] = anchors.size();
            cast_place[q] = system.positions[static_cast<std::size_t>(q)];
            anchors.push_back({q, system.positions[static_cast<std::size_t>(q)], options.end_anchor_weight / (h * h)});
          }
    }
    long best_round = inverted_count();  // fewest folded tetrahedra after a round of this attempt
    long best_outside = -1;  // fewest points outside after a round of this attempt (-1: none yet)
    int outside_stalled = 0;  // rounds in a row since the last that left fewer outside
    for (int round = 0;; ++round) {
      const std::size_t runs_before = runs.size();
      long previous_free = -1;  // free points of the previous run of this round
      // Local first: only the points within `radius` lattice steps (Chebyshev) of an inverted
      // cell or an anchored point move, the rest of the settled lattice stays as it is; the
      // region grows while cells stay inverted, up to the whole lattice.
      for (int radius : {2, 6, 1 << 20}) {
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
        const UntangleReport untangled = untangle(system.positions, local_fixed, tets, options.solver, anchors);
        nlohmann::json run = untangled.to_json();
        run["radius"] = whole ? -1 : radius;
        run["round"] = round;
        run["anchors"] = anchors.size();
        runs.push_back(run);
        budget -= untangled.iterations;
        report.iterations += untangled.iterations;
        if (untangled.untangled()) break;
      }
      outside = outside_free_points(system, query);
      if (runs.size() > runs_before) {
        runs.back()["outside"] = outside.size();
        runs.back()["free_ends"] = free_ends;
      }
      const long now_outside = static_cast<long>(outside.size());
      if (best_outside < 0 || now_outside < best_outside) {
        best_outside = now_outside;
        outside_stalled = 0;
      } else {
        ++outside_stalled;
      }
      std::string stop = outside.empty()                  ? "contained"
                         : round == options.contact_rounds ? "rounds"
                         : budget <= 0                     ? "budget"
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
        // attempts after this one start elsewhere).
        const long now = inverted_count();
        if (now > 0 && now >= best_round) stop = "fold_stalled";
        best_round = std::min(best_round, now);
      }
      if (!stop.empty()) {
        if (runs.size() > runs_before) runs.back()["stop"] = stop;
        report.stops[stop] = report.stops.value(stop, 0) + 1;
        break;
      }
      // Containment: an outside point gets a soft pin just inside, 4x stronger each round.
      const std::vector<double> spacing = lattice_local_spacing(system);
      for (int q : outside) {
        const Vec3 target = contact_target(q, spacing);
        const auto it = anchor_of.find(q);
        if (it == anchor_of.end()) {
          const double h = spacing[static_cast<std::size_t>(q)];
          anchor_of[q] = anchors.size();
          anchors.push_back({q, target, options.contact_weight / (h * h)});
        } else {
          anchors[it->second].target = target;
          anchors[it->second].weight *= 4.0;
        }
      }
    }
    // The ends are fixed again, at most `end_shift` (a share of the muscle length) from their
    // cast places so that they stay on their attachment areas; one the untangling left outside
    // goes to the closest surface point.
    if (free_ends)
      for (int k : {0, lattice.nz - 1})
        for (int j = 1; j + 1 < lattice.ny; ++j)
          for (int i = 1; i + 1 < lattice.nx; ++i) {
            const int q = lattice.index(i, j, k);
            Vec3& x = system.positions[static_cast<std::size_t>(q)];
            const Vec3 cast = cast_place.at(q);
            const double limit = options.end_shift * length;
            if ((x - cast).norm() > limit) x = cast + limit * (x - cast).normalized();
            if (query.side(x) == Side::outside) x = query.closest_point(x).position;
            system.fixed[static_cast<std::size_t>(q)] = 1;
          }
    return inverted_count();
  };
  // The ends held first, from the settled lattice (cheap where the folds are local: most
  // muscles); while cells stay inverted, from the settled lattice with the ends free, then on
  // from there with the ends held. The result with the fewest inverted cells stays. Each attempt
  // has the whole iteration budget and stops early when a round does not improve.
  const std::vector<Vec3> settled = system.positions;
  const std::vector<char> settled_fixed = system.fixed;
  std::unordered_set<int> pinned_here;  // points this stage fixed just inside
  long inverted_left = attempt(false);
  std::string kept = "held_ends";
  std::vector<Vec3> best = system.positions;
  auto run_from = [&](const std::vector<Vec3>& from, bool free_ends, const std::string& name) {
    system.positions = from;
    system.fixed = settled_fixed;
    budget = options.iterations;
    const long n = attempt(free_ends);
    if (n < inverted_left) {
      inverted_left = n;
      best = system.positions;
      kept = name;
    }
  };
  if (inverted_left > 0) {
    run_from(settled, true, "free_ends");
    const std::vector<Vec3> free_result = system.positions;
    if (inverted_left > 0) run_from(free_result, false, "free_then_held_ends");
  }
  system.positions = best;
  system.fixed = settled_fixed;
  runs.push_back({{"kept", kept}});
  // Containment inside the loop: the points still outside (and interior points the settle's
  // containment fixed at a place that is not inside: the fallback of lattice_contact_point) are
  // fixed just inside, and, since that can fold the cells around them, the untangling runs again
  // with them fixed (the ends held), until no point is outside, at most `pin_rounds` times.
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
    if (outside.empty()) break;
    const std::vector<double> spacing = lattice_local_spacing(system);
    for (int q : outside) {
      system.positions[static_cast<std::size_t>(q)] = contact_target(q, spacing);
      system.fixed[static_cast<std::size_t>(q)] = 1;
      pinned_here.insert(q);
      ++report.pinned;
    }
    inverted_left = inverted_count();
    if (inverted_left == 0 || pass == options.pin_rounds) break;
    // Every point is inside now; an untangling that does not fold fewer cells is undone.
    const std::vector<Vec3> pinned_positions = system.positions;
    budget = options.iterations;
    const long again = attempt(false);
    runs.back()["after_pins"] = pass + 1;
    if (again >= inverted_left) {
      system.positions = pinned_positions;
      break;
    }
    inverted_left = again;
  }
  report.inverted_left = inverted_left;
  report.budget_left = budget;
  report.kept = kept;
  return report;
}

}  // namespace fascicle
