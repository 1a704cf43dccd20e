#include "fibres/fibre_field.h"

#include "fibres/segment_tree.h"
#include "geometry/errors.h"

#include <tbb/parallel_for.h>

namespace fascicle {

std::vector<Vec3> cell_fibre_directions(const TetMesh& mesh, const Polylines& fibres) {
  bool any = false;
  for (const auto& line : fibres.lines) any = any || line.size() >= 2;
  if (!any) throw InputError(ErrorCode::file_empty, "fibre field: the fibres have no segment");
  const SegmentTree tree(fibres);
  std::vector<Vec3> directions(mesh.tets.size(), Vec3::Zero());
  tbb::parallel_for(std::size_t(0), mesh.tets.size(), [&](std::size_t t) {
    Vec3 centre = Vec3::Zero();
    for (int v : mesh.tets[t]) centre += mesh.positions[static_cast<std::size_t>(v)];
    int segment = -1;
    tree.nearest(0.25 * centre, &segment);
    if (segment < 0) return;
    const auto& s = tree.segment(segment);
    const Vec3 d = s[1] - s[0];
    if (d.norm() > 0.0) directions[t] = d.normalized();
  });
  return directions;
}

}  // namespace fascicle
