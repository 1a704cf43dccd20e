#pragma once
/// \file subdivide_mesh.h
/// Midpoint subdivision: a finer mesh of exactly the same surface (benches of how a stage scales
/// with the number of triangles).
#include "geometry/mesh.h"

namespace fascicle {

/// `mesh` with every triangle split into four at its edge midpoints: 4 #F triangles, #V + #E
/// vertices (the first #V those of `mesh`), the same surface and orientation.
TriangleMesh subdivide_mesh(const TriangleMesh& mesh);

}  // namespace fascicle
