#include "fibres/decompose_mesh.h"

#include <chrono>
#include <utility>

namespace fascicle {

Decomposition decompose(const PolygonSoup& soup, const Landmarks& landmarks, const DecomposeOptions& options,
                        const RepairOptions& repair) {
  // Options are checked before the repair, which can take seconds on a large scan.
  options.validate();
  repair.validate();
  const auto start = std::chrono::steady_clock::now();
  if (options.progress) options.progress("repair");
  RepairResult repaired = repair_mesh(soup, repair);
  const double repair_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  Decomposition out = decompose_repaired(repaired.mesh, landmarks, options);
  out.report.repair = repaired.report.to_json();
  out.report.repair_seconds = repair_seconds;
  out.report.seconds += repair_seconds;
  return out;
}

}  // namespace fascicle
