#pragma once
/// \file cross_section.h
/// The shape of a closed mesh's cross-sections normal to its major axis: how many times as
/// broad as thick each is, from the second moments of its area (Green's theorem over the
/// triangles' cuts, so no outline needs chaining and the mesh's vertex density does not matter).

#include "geometry/mesh.h"

#include <vector>

namespace fascicle {

/// Where to cut: `slices` planes normal to the major axis of the vertices (principal_axes()),
/// evenly from `from` to `to` of their extent along it.
struct CrossSectionOptions {
  int slices = 7;     ///< planes, >= 1 (default 7)
  double from = 0.2;  ///< first plane's share of the extent, [0, 1] (default 0.2: past the end's taper)
  double to = 0.8;    ///< last plane's share, [from, 1] (default 0.8)
};

/// Per plane, the aspect of the area it cuts: sqrt(largest / smallest eigenvalue of the area's
/// second moments about its centroid), 1 for a disc, a : b for an ellipse of those axes; and
/// their median over the planes that cut an area (0 when none does).
struct CrossSectionShape {
  std::vector<double> aspects;  ///< one per plane that cut an area, in order along the axis
  double median_aspect = 0.0;
};

/// The cross-sections of `mesh`, closed and consistently oriented (either way: the moments'
/// sign is taken from the area's). Throws nothing; an empty mesh gives no plane.
CrossSectionShape cross_section_shape(const TriangleMesh& mesh, const CrossSectionOptions& options = {});

}  // namespace fascicle
