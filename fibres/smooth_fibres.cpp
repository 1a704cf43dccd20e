// Each fibre smoothed along itself: see smooth_fibres.h.
#include "fibres/smooth_fibres.h"

#include "fibres/check_cells.h"
#include "fibres/fibre_check.h"
#include "geometry/errors.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

namespace fascicle {
namespace {

// The turning at joint b of a line through a, b, c (the check's angle).
double turning_deg(const Vec3& a, const Vec3& b, const Vec3& c) { return turning_angle_deg(b - a, c - b); }

// Calls visit(angle) for every inner joint of the interior lattice lines at `positions`.
template <class Visit>
void for_each_joint(const springs::Lattice& lattice, const std::vector<Vec3>& positions, Visit visit) {
  auto at = [&](int i, int j, int k) -> const Vec3& {
    return positions[static_cast<std::size_t>(lattice.index(i, j, k))];
  };
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i)
      for (int k = 1; k + 1 < lattice.nz; ++k) visit(turning_deg(at(i, j, k - 1), at(i, j, k), at(i, j, k + 1)));
}

}  // namespace

long sharp_joints(const springs::Lattice& lattice, const std::vector<Vec3>& positions, double max_deg) {
  long count = 0;
  for_each_joint(lattice, positions, [&](double angle) { count += angle > max_deg ? 1 : 0; });
  return count;
}

void FibreSmoothingOptions::validate() const {
  if (steps < 0 || steps > 10000)
    throw OptionError("FibreSmoothingOptions::steps must be in 0..10000 (got " + std::to_string(steps) + ")");
  if (!(weight > 0.0 && weight <= 1.0))
    throw OptionError("FibreSmoothingOptions::weight must be in (0, 1] (got " + std::to_string(weight) + ")");
  if (!(max_turning_deg >= 0.0 && max_turning_deg < 180.0))
    throw OptionError("FibreSmoothingOptions::max_turning_deg must be in [0, 180) (got " +
                      std::to_string(max_turning_deg) + ")");
}

nlohmann::json FibreSmoothingReport::to_json() const {
  return {{"moved", moved},
          {"refused_outside", refused_outside},
          {"refused_segments", refused_segments},
          {"refused_cells", refused_cells},
          {"above_deg", above_deg},
          {"max_turning_before_deg", max_turning_before_deg},
          {"max_turning_after_deg", max_turning_after_deg},
          {"crossing_after", crossing_after},
          {"seconds", seconds}};
}

FibreSmoothingReport smooth_fibres(const springs::Lattice& lattice, springs::SpringSystem& system,
                                   const SurfaceQuery& query, double end_tolerance,
                                   const FibreSmoothingOptions& options) {
  options.validate();
  const auto start = std::chrono::steady_clock::now();
  FibreSmoothingReport report;
  report.above_deg = options.max_turning_deg;
  std::vector<Vec3>& x = system.positions;
  auto at = [&](int i, int j, int k) -> Vec3& { return x[static_cast<std::size_t>(lattice.index(i, j, k))]; };
  const int segments = lattice.nz - 1;
  auto max_turning = [&] {
    double worst = 0.0;
    for_each_joint(lattice, x, [&](double angle) { worst = std::max(worst, angle); });
    return worst;
  };
  report.max_turning_before_deg = max_turning();
  if (lattice.nz >= 3 && options.steps > 0) {
    const CheckCells cells(lattice, x);
    auto leaves = [&](int i, int j, int k) {  // segment k of line (i, j)
      return fibre_segment_leaves(query, at(i, j, k), at(i, j, k + 1), k, segments, end_tolerance);
    };
    // Moves point k of line (i, j) to `target` under the guards; whether it moved.
    auto try_move = [&](int i, int j, int k, const Vec3& target) {
      if (!query.inside(target)) {
        ++report.refused_outside;
        return false;
      }
      Vec3& p = at(i, j, k);
      std::vector<std::array<int, 4>> good;
      for (const auto& tet : cells.around(i, j, k))
        if (cells.good(tet)) good.push_back(tet);
      // A segment inside must stay inside, and one that leaves may not leave deeper.
      auto depth = [&](int n) { return segment_excursion(query, at(i, j, n), at(i, j, n + 1), 16); };
      const bool before_in = !leaves(i, j, k - 1), after_in = !leaves(i, j, k);
      const double before_depth = before_in ? 0.0 : depth(k - 1), after_depth = after_in ? 0.0 : depth(k);
      const Vec3 old = p;
      p = target;
      if ((before_in ? leaves(i, j, k - 1) : depth(k - 1) > before_depth) ||
          (after_in ? leaves(i, j, k) : depth(k) > after_depth)) {
        p = old;
        ++report.refused_segments;
        return false;
      }
      if (!std::all_of(good.begin(), good.end(), [&](const std::array<int, 4>& tet) { return cells.good(tet); })) {
        p = old;
        ++report.refused_cells;
        return false;
      }
      ++report.moved;
      return true;
    };
    for (int step = 0; step < options.steps; ++step) {
      long moved_before = report.moved;
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i)
          for (int k = 1; k < segments; ++k) {
            const Vec3 p = at(i, j, k), a = at(i, j, k - 1), b = at(i, j, k + 1);
            if (turning_deg(a, p, b) <= options.max_turning_deg) continue;
            // The point towards its neighbours' midpoint; where the muscle's wall is in the way
            // (the joint bends round it), its inner neighbours towards the straight continuation
            // of the other segment instead.
            bool moved = false;
            for (double share = options.weight; share > 0.1 * options.weight && !moved; share *= 0.5)
              moved = try_move(i, j, k, p + share * (0.5 * (a + b) - p));
            if (moved) continue;
            for (const int n : {k - 1, k + 1}) {
              if (n < 1 || n >= segments) continue;
              const Vec3 other = n < k ? b : a, q = at(i, j, n);
              const Vec3 straight = p + (p - other).normalized() * (q - p).norm();
              bool done = false;
              for (double share = options.weight; share > 0.1 * options.weight && !done; share *= 0.5)
                done = try_move(i, j, n, q + share * (straight - q));
            }
          }
      if (report.moved == moved_before) break;
    }
  }
  report.max_turning_after_deg = max_turning();
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i)
      for (int k = 0; k < segments; ++k)
        report.crossing_after += fibre_segment_leaves(query, at(i, j, k), at(i, j, k + 1), k, segments, end_tolerance);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace fascicle
