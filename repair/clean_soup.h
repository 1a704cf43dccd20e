#pragma once
/// \file clean_soup.h
/// Soup clean-up before a mesh is built (no CGAL): apply a weld, triangulate polygons, drop faces
/// that are degenerate by their indices and duplicate faces, drop unreferenced points.

#include "geometry/mesh.h"

namespace fascicle {

/// Counts of what clean_soup changed.
struct CleanSoupCounts {
  long polygons_triangulated = 0;  ///< polygons with more than three corners split into triangles
  long degenerate_removed = 0;     ///< faces with fewer than three distinct corners after welding
  long duplicates_removed = 0;     ///< faces repeating another face's corners (either orientation)
  long unreferenced_removed = 0;   ///< points no face uses
};

/// Returns a triangle soup: the polygons of `soup` with corner i replaced by
/// `representative[i]`, polygons of more than three corners triangulated (ear clipping in the
/// plane of the polygon's Newell normal, fan as fallback), faces with repeated corners and
/// duplicate faces removed, points compacted. `representative` has #P entries (weld_vertices).
TriangleMesh clean_soup(const PolygonSoup& soup, const std::vector<int>& representative,
                        CleanSoupCounts* counts = nullptr);

}  // namespace fascicle
