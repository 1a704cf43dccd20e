#pragma once
/// \file tetrahedralize.h
/// The volume of a closed surface as tetrahedra: CGAL 3D mesh generation (Mesh_3, Delaunay
/// refinement of a polyhedral domain; Jamin, Alliez, Yvinec and Boissonnat 2015, "CGALmesh: a
/// generic framework for Delaunay mesh generation"). Boundary vertices lie on the input surface;
/// boundary facets approximate it within `facet_distance`. Sequential and without the random
/// perturbation and sliver exudation stages, so the same surface and options give the same mesh.

#include "geometry/mesh.h"

#include <nlohmann/json_fwd.hpp>

namespace fascicle {

/// Sizes of the tetrahedra, in the surface's units.
struct TetrahedralizeOptions {
  double cell_size = 1.0;          ///< largest circumradius of a tetrahedron, > 0 (default 1)
  double facet_size = 1.0;         ///< largest circumradius of a boundary facet's Delaunay ball, > 0 (default 1)
  double facet_distance = 0.1;     ///< largest distance of a boundary facet from the surface, > 0 (default 0.1)
  double facet_angle_deg = 25.0;   ///< smallest angle of a boundary facet, degrees, in (0, 30] (default 25)
  double radius_edge_ratio = 3.0;  ///< largest circumradius-to-shortest-edge ratio of a tetrahedron, >= 2 (default 3)
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// Options for tetrahedra of even size, about `tets` of them in a volume `volume` (mesh units
/// cubed): edge a = (6 sqrt(2) volume / tets)^(1/3), the edge of `tets` regular tetrahedra
/// filling it; cell and facet circumradii 0.8 a (0.61 a is a regular tetrahedron's: the
/// refinement's tetrahedra are not regular, and at 0.61 a it made 2.3 times as many), facet
/// distance a / 6. Throws OptionError when volume or tets is not > 0.
TetrahedralizeOptions sized_tetrahedra(double volume, long tets);

/// What the mesh generation made.
struct TetrahedralizeReport {
  long vertices = 0, tets = 0, boundary_vertices = 0;
  double seconds = 0.0;
  nlohmann::json to_json() const;
};

/// Tetrahedra filling the volume bounded by `surface` (closed, outward, no self-intersection:
/// repair it first). Throws TopologyError when the surface bounds no volume or the generator
/// makes no tetrahedron, OptionError for bad options.
TetMesh tetrahedralize(const TriangleMesh& surface, const TetrahedralizeOptions& options,
                       TetrahedralizeReport* report = nullptr);

}  // namespace fascicle
