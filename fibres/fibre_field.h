#pragma once
/// \file fibre_field.h
/// The fibres as a direction field on a tetrahedral mesh of the muscle, for finite-element
/// models that take one fibre direction per element: each tetrahedron takes the unit direction
/// (origin to insertion) of the fibre segment nearest to its centroid (fibres/segment_tree.h).
#include "geometry/mesh.h"

#include <vector>

namespace fascicle {

/// #T unit vectors, one per tetrahedron of `mesh`, from `fibres` (polylines from origin to
/// insertion). Throws InputError(file_empty) when the fibres have no segment.
std::vector<Vec3> cell_fibre_directions(const TetMesh& mesh, const Polylines& fibres);

}  // namespace fascicle
