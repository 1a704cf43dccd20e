#pragma once
/// \file mesh_adjacency.h
/// Vertex neighbourhoods of a closed triangle mesh in flat (CSR) arrays, and the topology check
/// that every sphere-map method needs: a closed, oriented 2-manifold of genus 0, connected.

#include "geometry/mesh.h"

#include <vector>

namespace fascicle {

/// Compressed neighbourhoods of a closed, oriented, genus-0 triangle mesh with #V vertices.
/// - neighbours of vertex v: `neighbours[neighbour_start[v] .. neighbour_start[v+1])`, each once;
/// - faces around v: `corner_face[corner_start[v] .. corner_start[v+1])` with, for each, the two
///   other corners `corner_next` / `corner_prev` so that (v, next, prev) is the face's own
///   counter-clockwise order.
struct MeshAdjacency {
  std::vector<int> neighbour_start, neighbours;
  std::vector<int> corner_start, corner_face, corner_next, corner_prev;
  /// Neighbour count of v.
  int valence(int v) const { return neighbour_start[v + 1] - neighbour_start[v]; }
};

/// Checks that `mesh` is what a sphere map needs and builds its adjacency.
/// Requirements: at least 4 vertices and 4 triangles, every index in range, every vertex used,
/// no triangle with a repeated index, every directed edge used once and its reverse once (closed,
/// edge-manifold, consistently oriented), one fan of faces around every vertex, connected,
/// Euler characteristic V - E + F = 2 (genus 0).
/// Throws TopologyError(topology) naming the first failed requirement and an example element.
MeshAdjacency check_sphere_topology(const TriangleMesh& mesh);

}  // namespace fascicle
