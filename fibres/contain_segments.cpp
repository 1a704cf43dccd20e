// Fibre segments that leave the muscle moved back inside: see contain_segments.h.
#include "fibres/contain_segments.h"

#include "fibres/check_cells.h"
#include "fibres/fibre_check.h"
#include "fibres/fibre_grid.h"
#include "fibres/untangle_lattice.h"
#include "geometry/errors.h"

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <array>
#include <chrono>
#include <limits>
#include <string>
#include <vector>

namespace fascicle {

void SegmentContainmentOptions::validate() const {
  auto bad = [](const std::string& field, const std::string& rule) {
    throw OptionError("SegmentContainmentOptions::" + field + " must be " + rule);
  };
  if (sweeps < 0) bad("sweeps", ">= 0");
  if (!(margin > 0.0 && margin <= 10.0)) bad("margin", "in (0, 10]");
  if (samples < 1) bad("samples", ">= 1");
  if (steps < 1) bad("steps", ">= 1");
  if (!(max_shift > 0.0)) bad("max_shift", "> 0");
  if (patch_radius < 0) bad("patch_radius", ">= 0");
}

nlohmann::json SegmentContainmentReport::to_json() const {
  return {{"crossing_before", crossing_before},
          {"crossing_after", crossing_after},
          {"moved", moved},
          {"rejected", rejected},
          {"sweeps", sweeps},
          {"seconds", seconds}};
}

bool segment_inward_shift(const SurfaceQuery& query, const Vec3& a, const Vec3& b, bool free0, bool free1, int k,
                          int segments, double end_tolerance, double spacing, const SegmentContainmentOptions& options,
                          Vec3* d0, Vec3* d1) {
  *d0 = Vec3::Zero();
  *d1 = Vec3::Zero();
  if (!free0 && !free1) return true;
  // The deepest sample goes `margin` x its depth inside (a shift of a fraction of a spacing
  // would fold the cells of thin fibre bundles); the segment may then leave at another sample
  // (a faceted wall), so the shift is repeated from the moved segment, up to `steps` times.
  for (int step = 0; step < options.steps; ++step) {
    double t = 0.5;
    Vec3 closest = Vec3::Zero();
    const Vec3 a1 = a + *d0, b1 = b + *d1;
    double depth = segment_excursion(query, a1, b1, options.samples, &t, &closest);
    // A segment that leaves between its samples (a sliver past a facet edge): 8 times as many
    // samples.
    if (!(depth > 0.0) && fibre_segment_leaves(query, a1, b1, k, segments, end_tolerance))
      depth = segment_excursion(query, a1, b1, 8 * options.samples + 1, &t, &closest);
    if (!(depth > 0.0)) break;
    const Vec3 shift = (1.0 + options.margin) * (closest - (a1 + t * (b1 - a1)));
    if (free0) *d0 += free1 ? shift : Vec3(shift / (1.0 - t));
    if (free1) *d1 += free0 ? shift : Vec3(shift / t);
    if (std::max(d0->norm(), d1->norm()) > options.max_shift * spacing) return false;
  }
  return true;
}

std::vector<std::pair<int, Vec3>> leaving_segment_shifts(const springs::Lattice& lattice,
                                                         const springs::SpringSystem& system, const SurfaceQuery& query,
                                                         double end_tolerance,
                                                         const SegmentContainmentOptions& options) {
  options.validate();
  const std::vector<Vec3>& x = system.positions;
  const int nz = lattice.nz, lines = std::max((lattice.nx - 2) * (lattice.ny - 2), 0);
  const std::vector<double> spacing = lattice_local_spacing(system);
  // Per line, the shift of each of its points (the larger where both of its segments leave).
  std::vector<std::vector<std::pair<int, Vec3>>> found(static_cast<std::size_t>(lines));
  tbb::parallel_for(0, lines, [&](int line) {
    const int i = 1 + line % (lattice.nx - 2), j = 1 + line / (lattice.nx - 2);
    std::vector<Vec3> shift(static_cast<std::size_t>(nz), Vec3::Zero());
    for (int k = 0; k + 1 < nz; ++k) {
      const int q0 = lattice.index(i, j, k), q1 = lattice.index(i, j, k + 1);
      const Vec3& a = x[static_cast<std::size_t>(q0)];
      const Vec3& b = x[static_cast<std::size_t>(q1)];
      if (!fibre_segment_leaves(query, a, b, k, nz - 1, end_tolerance)) continue;
      const double h = 0.5 * (spacing[static_cast<std::size_t>(q0)] + spacing[static_cast<std::size_t>(q1)]);
      Vec3 d0, d1;
      segment_inward_shift(query, a, b, !system.fixed[static_cast<std::size_t>(q0)],
                           !system.fixed[static_cast<std::size_t>(q1)], k, nz - 1, end_tolerance,
                           std::numeric_limits<double>::infinity(), options, &d0, &d1);
      // A deep bend is asked for at most max_shift spacings at a time.
      const double cap = options.max_shift * h;
      if (d0.norm() > cap) d0 *= cap / d0.norm();
      if (d1.norm() > cap) d1 *= cap / d1.norm();
      Vec3& s0 = shift[static_cast<std::size_t>(k)];
      Vec3& s1 = shift[static_cast<std::size_t>(k + 1)];
      if (d0.squaredNorm() > s0.squaredNorm()) s0 = d0;
      if (d1.squaredNorm() > s1.squaredNorm()) s1 = d1;
    }
    for (int k = 0; k < nz; ++k)
      if (shift[static_cast<std::size_t>(k)].squaredNorm() > 0.0)
        found[static_cast<std::size_t>(line)].push_back({lattice.index(i, j, k), shift[static_cast<std::size_t>(k)]});
  });
  std::vector<std::pair<int, Vec3>> out;
  for (const auto& list : found) out.insert(out.end(), list.begin(), list.end());
  return out;
}

long crossing_segment_count(const springs::Lattice& lattice, const springs::SpringSystem& system,
                            const SurfaceQuery& query, const SegmentContact& contact) {
  const std::vector<Vec3>& x = system.positions;
  const int nz = lattice.nz, lines = std::max((lattice.nx - 2) * (lattice.ny - 2), 0);
  std::vector<long> count(static_cast<std::size_t>(lines), 0);
  tbb::parallel_for(0, lines, [&](int line) {
    const int i = 1 + line % (lattice.nx - 2), j = 1 + line / (lattice.nx - 2);
    for (int k = 0; k + 1 < nz; ++k) {
      const Vec3& a = x[static_cast<std::size_t>(lattice.index(i, j, k))];
      const Vec3& b = x[static_cast<std::size_t>(lattice.index(i, j, k + 1))];
      if (fibre_segment_leaves(query, a, b, k, nz - 1, contact.end_tolerance) &&
          segment_excursion(query, a, b, contact.excursion_samples) > contact.tolerance)
        ++count[static_cast<std::size_t>(line)];
    }
  });
  long total = 0;
  for (long c : count) total += c;
  return total;
}

SegmentContainmentReport contain_segments(const springs::Lattice& lattice, springs::SpringSystem& system,
                                          const SurfaceQuery& query, double end_tolerance,
                                          const SegmentContainmentOptions& options) {
  options.validate();
  const auto start = std::chrono::steady_clock::now();
  SegmentContainmentReport report;
  std::vector<Vec3>& x = system.positions;
  const int nz = lattice.nz;
  auto at = [&](int i, int j, int k) -> Vec3& { return x[static_cast<std::size_t>(lattice.index(i, j, k))]; };
  // Segment k of line (i, j) runs from point k to k + 1; the fibre ends may touch the surface.
  auto leaves = [&](int i, int j, int k) {
    return fibre_segment_leaves(query, at(i, j, k), at(i, j, k + 1), k, nz - 1, end_tolerance);
  };
  // The segments that leave, in lattice order (lines j, i, then k). A move keeps every segment
  // round its points that did not leave from leaving, so no segment outside this list can start
  // to: the list only shrinks.
  std::vector<std::array<int, 3>> crossing;
  {
    const int lines = (lattice.nx - 2) * (lattice.ny - 2);
    std::vector<std::vector<char>> flags(static_cast<std::size_t>(std::max(lines, 0)));
    tbb::parallel_for(0, std::max(lines, 0), [&](int line) {
      const int i = 1 + line % (lattice.nx - 2), j = 1 + line / (lattice.nx - 2);
      auto& f = flags[static_cast<std::size_t>(line)];
      f.resize(static_cast<std::size_t>(nz - 1));
      for (int k = 0; k + 1 < nz; ++k) f[static_cast<std::size_t>(k)] = leaves(i, j, k) ? 1 : 0;
    });
    for (int line = 0; line < lines; ++line)
      for (int k = 0; k + 1 < nz; ++k)
        if (flags[static_cast<std::size_t>(line)][static_cast<std::size_t>(k)])
          crossing.push_back({1 + line % (lattice.nx - 2), 1 + line / (lattice.nx - 2), k});
  }
  report.crossing_before = static_cast<long>(crossing.size());
  if (crossing.empty() || options.sweeps == 0) {
    report.crossing_after = report.crossing_before;
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
  }
  const std::vector<double> spacing = lattice_local_spacing(system);
  const CheckCells cells(lattice, x);
  for (int sweep = 0; sweep < options.sweeps; ++sweep) {
    ++report.sweeps;
    long kept = 0;
    std::vector<std::array<int, 3>> left;
    for (const std::array<int, 3>& segment : crossing) {
      const int i = segment[0], j = segment[1], k = segment[2];
      if (!leaves(i, j, k)) continue;  // a patch moved for another segment took it in
      left.push_back(segment);
      const int q0 = lattice.index(i, j, k), q1 = lattice.index(i, j, k + 1);
      const bool free0 = !system.fixed[static_cast<std::size_t>(q0)],
                 free1 = !system.fixed[static_cast<std::size_t>(q1)];
      const Vec3 a = x[static_cast<std::size_t>(q0)], b = x[static_cast<std::size_t>(q1)];
      if (!free0 && !free1) {
        ++report.rejected;
        continue;
      }
      const double h = 0.5 * (spacing[static_cast<std::size_t>(q0)] + spacing[static_cast<std::size_t>(q1)]);
      Vec3 d0 = Vec3::Zero(), d1 = Vec3::Zero();
      const bool too_far =
          !segment_inward_shift(query, a, b, free0, free1, k, nz - 1, end_tolerance, h, options, &d0, &d1);
      if (too_far || (d0.squaredNorm() == 0.0 && d1.squaredNorm() == 0.0)) {
        ++report.rejected;
        continue;
      }
      // The move, tried on the segment's own line first, then on a patch of lines round it
      // (Chebyshev radius 1, 2, ... patch_radius, each line's points shifted by the weight
      // 1 - distance / (radius + 1)), which carries the neighbours along where the line alone
      // would cross them.
      bool kept_move = false;
      for (int radius = 0; radius <= options.patch_radius && !kept_move; ++radius) {
        struct Moved {
          std::size_t q;
          Vec3 from, to;
        };
        std::vector<Moved> moved;
        std::vector<std::array<int, 4>> tets;
        std::vector<std::array<int, 3>> guarded;  // segments (i, j, k) that must not newly leave
        std::vector<char> guarded_before;
        for (int jj = std::max(1, j - radius); jj <= std::min(lattice.ny - 2, j + radius); ++jj)
          for (int ii = std::max(1, i - radius); ii <= std::min(lattice.nx - 2, i + radius); ++ii) {
            const double w = 1.0 - static_cast<double>(std::max(std::abs(ii - i), std::abs(jj - j))) / (radius + 1);
            for (int c = 0; c < 2; ++c) {
              const std::size_t q = static_cast<std::size_t>(lattice.index(ii, jj, k + c));
              if (system.fixed[q]) continue;
              moved.push_back({q, x[q], x[q] + w * (c == 0 ? d0 : d1)});
              const auto more = cells.around(ii, jj, k + c);
              tets.insert(tets.end(), more.begin(), more.end());
            }
            for (int kk = std::max(0, k - 1); kk <= std::min(nz - 2, k + 1); ++kk)
              if (ii != i || jj != j || kk != k) guarded.push_back({ii, jj, kk});
          }
        std::vector<char> good_before(tets.size());
        for (std::size_t n = 0; n < tets.size(); ++n) good_before[n] = cells.good(tets[n]) ? 1 : 0;
        guarded_before.resize(guarded.size());
        for (std::size_t n = 0; n < guarded.size(); ++n)
          guarded_before[n] = leaves(guarded[n][0], guarded[n][1], guarded[n][2]) ? 1 : 0;
        for (const Moved& m : moved) x[m.q] = m.to;
        bool ok = !leaves(i, j, k);
        for (std::size_t n = 0; ok && n < moved.size(); ++n) ok = query.side(x[moved[n].q]) == Side::inside;
        for (std::size_t n = 0; ok && n < guarded.size(); ++n)
          if (!guarded_before[n]) ok = !leaves(guarded[n][0], guarded[n][1], guarded[n][2]);
        for (std::size_t n = 0; ok && n < tets.size(); ++n)
          if (good_before[n] && !cells.good(tets[n])) ok = false;
        if (ok) {
          kept_move = true;
        } else {
          for (const Moved& m : moved) x[m.q] = m.from;
        }
      }
      if (kept_move) {
        ++kept;
        ++report.moved;
        left.pop_back();
      } else {
        ++report.rejected;
      }
    }
    crossing.swap(left);
    if (kept == 0) break;
  }
  // A segment kept in the list may have been taken in by a later patch of the same sweep.
  report.crossing_after = static_cast<long>(std::count_if(
      crossing.begin(), crossing.end(), [&](const std::array<int, 3>& c) { return leaves(c[0], c[1], c[2]); }));
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace fascicle
