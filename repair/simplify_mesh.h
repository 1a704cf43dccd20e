#pragma once
/// \file simplify_mesh.h
/// A coarser copy of a closed surface, for the steps whose cost grows faster than the surface's
/// size and that need its shape, not its detail (the sphere map and the template placement:
/// fibres/decompose.h, step 3). Edge collapse (CGAL Surface_mesh_simplification), shortest edge
/// first onto its midpoint, so that the copy's triangles stay even in size (a sphere map's
/// distortion follows them); a collapse that would turn a face's normal over is refused (a fold
/// would send a point placed on the copy to the wrong side of a thin part), one that would change
/// the topology is never made, so a closed genus-0 manifold stays one. Lindstrom-Turk's quadric
/// cost and placement keep the shape closer for the same count but took 3 times as long.
#include "geometry/mesh.h"

#include <nlohmann/json_fwd.hpp>

namespace fascicle {

/// What the simplification did.
struct SimplifyReport {
  long faces_before = 0, faces_after = 0;
  double seconds = 0.0;
  nlohmann::json to_json() const;
};

/// `mesh` (closed, outward, no degenerate face) with edges collapsed until it has at most
/// `max_faces` triangles (or no edge can be collapsed); a mesh at or under `max_faces` is returned
/// as it is. Units and orientation are kept. Deterministic: the same mesh gives the same copy.
/// Throws OptionError when max_faces < 4, TopologyError when `mesh` is not a closed manifold.
TriangleMesh simplify_mesh(const TriangleMesh& mesh, long max_faces, SimplifyReport* report = nullptr);

}  // namespace fascicle
