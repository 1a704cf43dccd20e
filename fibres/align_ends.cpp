// Fibre ends continued along their fibres: see align_ends.h.
#include "fibres/align_ends.h"

#include "fibres/check_cells.h"
#include "geometry/errors.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <vector>

namespace fascicle {

void EndAlignmentOptions::validate() const {
  if (!(max_extension > 0.0))
    throw OptionError("EndAlignmentOptions::max_extension must be > 0, got " + std::to_string(max_extension));
}

nlohmann::json EndAlignmentReport::to_json() const {
  return {{"moved", moved}, {"halfway", halfway}, {"three_quarters", three_quarters}, {"kept", kept}};
}

EndAlignmentReport align_ends(const springs::Lattice& lattice, springs::SpringSystem& system,
                              const SurfaceQuery& query, const Attachments& areas, double radius,
                              const EndAlignmentOptions& options) {
  options.validate();
  EndAlignmentReport report;
  if (lattice.nz < 3) return report;
  std::vector<Vec3>& x = system.positions;
  const CheckCells cells(lattice, x);
  auto at = [&](int i, int j, int k) -> Vec3& { return x[static_cast<std::size_t>(lattice.index(i, j, k))]; };
  const int last = lattice.nz - 1;
  for (const auto& [k_end, step, area] :
       {std::tuple<int, int, const AttachmentArea*>{0, 1, &areas.origin},
        std::tuple<int, int, const AttachmentArea*>{last, -1, &areas.insertion}}) {
    const int k1 = k_end + step, k2 = k_end + 2 * step;
    // The end layer's tetrahedra that were good before any move.
    const int ck = std::min(k_end, k1);
    std::vector<std::array<int, 4>> tets;
    for (int cj = 1; cj + 2 < lattice.ny; ++cj)
      for (int ci = 1; ci + 2 < lattice.nx; ++ci)
        for (int t = 0; t < 6; ++t)
          if (cells.good({ci, cj, ck, t})) tets.push_back({ci, cj, ck, t});
    std::vector<char> done(static_cast<std::size_t>(lattice.nx * lattice.ny), 0);
    for (const double blend : {0.0, 0.5, 0.75}) {
      // Every end's cast first; then all moved at once, so that neighbours move together.
      struct Move {
        int i, j;
        Vec3 from, to;
        bool kept;
      };
      std::vector<Move> moves;
      std::vector<int> move_of(static_cast<std::size_t>(lattice.nx * lattice.ny), -1);
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i) {
          if (done[static_cast<std::size_t>(i + lattice.nx * j)]) continue;
          const Vec3 p1 = at(i, j, k1), p2 = at(i, j, k2), end = at(i, j, k_end);
          const Vec3 along = (p1 - p2).normalized(), to_end = (end - p1).normalized();
          const Vec3 direction = ((1.0 - blend) * along + blend * to_end).normalized();
          const double reach = options.max_extension * std::max((p1 - p2).norm(), (end - p1).norm());
          Vec3 hit;
          if (!direction.allFinite() || !query.first_hit(p1, direction, reach, hit)) continue;
          if (!area->near(hit, radius)) continue;
          move_of[static_cast<std::size_t>(i + lattice.nx * j)] = static_cast<int>(moves.size());
          moves.push_back({i, j, end, hit, true});
          at(i, j, k_end) = hit;
        }
      // A tetrahedron that turned bad takes back every move at its cell's end corners; repeated
      // until none turns bad (each round takes back at least one move).
      for (bool changed = true; changed;) {
        changed = false;
        for (const auto& tet : tets) {
          if (cells.good(tet)) continue;
          for (int dj = 0; dj < 2; ++dj)
            for (int di = 0; di < 2; ++di) {
              const int m = move_of[static_cast<std::size_t>(tet[0] + di + lattice.nx * (tet[1] + dj))];
              if (m < 0 || !moves[static_cast<std::size_t>(m)].kept) continue;
              Move& move = moves[static_cast<std::size_t>(m)];
              move.kept = false;
              at(move.i, move.j, k_end) = move.from;
              changed = true;
            }
        }
      }
      for (const Move& m : moves)
        if (m.kept) {
          done[static_cast<std::size_t>(m.i + lattice.nx * m.j)] = 1;
          ++(blend == 0.0 ? report.moved : blend == 0.5 ? report.halfway : report.three_quarters);
        }
    }
    report.kept += static_cast<long>((lattice.nx - 2) * (lattice.ny - 2)) -
                   static_cast<long>(std::count(done.begin(), done.end(), 1));
  }
  return report;
}

}  // namespace fascicle
