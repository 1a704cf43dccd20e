#include "morph/mesh_adjacency.h"

#include "geometry/errors.h"

#include <algorithm>
#include <string>
#include <unordered_map>

namespace fascicle {
namespace {

std::uint64_t edge_key(int a, int b) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

[[noreturn]] void fail(const std::string& what) {
  throw TopologyError("sphere map needs a closed genus-0 mesh: " + what + " (run `fascicle repair` first)");
}

}  // namespace

MeshAdjacency check_sphere_topology(const TriangleMesh& mesh) {
  const int nv = static_cast<int>(mesh.positions.size());
  const int nf = static_cast<int>(mesh.triangles.size());
  if (nv < 4 || nf < 4) fail(std::to_string(nv) + " vertices and " + std::to_string(nf) + " triangles are too few");

  MeshAdjacency adj;
  adj.corner_start.assign(nv + 1, 0);
  for (int f = 0; f < nf; ++f) {
    const Triangle& t = mesh.triangles[f];
    for (int k = 0; k < 3; ++k)
      if (t[k] < 0 || t[k] >= nv)
        fail("triangle " + std::to_string(f) + " refers to vertex " + std::to_string(t[k]) + " of " +
             std::to_string(nv));
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) fail("triangle " + std::to_string(f) + " repeats a vertex");
    for (int k = 0; k < 3; ++k) ++adj.corner_start[t[k] + 1];
  }
  for (int v = 0; v < nv; ++v) {
    if (adj.corner_start[v + 1] == 0) fail("vertex " + std::to_string(v) + " is not used by any triangle");
    adj.corner_start[v + 1] += adj.corner_start[v];
  }
  const int ncorners = adj.corner_start[nv];
  adj.corner_face.resize(ncorners);
  adj.corner_next.resize(ncorners);
  adj.corner_prev.resize(ncorners);
  {
    std::vector<int> fill(adj.corner_start.begin(), adj.corner_start.end() - 1);
    for (int f = 0; f < nf; ++f) {
      const Triangle& t = mesh.triangles[f];
      for (int k = 0; k < 3; ++k) {
        const int c = fill[t[k]]++;
        adj.corner_face[c] = f;
        adj.corner_next[c] = t[(k + 1) % 3];
        adj.corner_prev[c] = t[(k + 2) % 3];
      }
    }
  }

  // Directed edges: each exactly once, each with its reverse.
  std::unordered_map<std::uint64_t, int> directed;
  directed.reserve(static_cast<std::size_t>(3 * nf) * 2);
  for (int f = 0; f < nf; ++f) {
    const Triangle& t = mesh.triangles[f];
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      if (!directed.emplace(edge_key(a, b), f).second)
        fail("edge " + std::to_string(a) + "-" + std::to_string(b) +
             " is used twice in the same direction (non-manifold or inconsistently oriented)");
    }
  }
  for (const auto& [key, f] : directed) {
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffu);
    if (!directed.count(edge_key(b, a)))
      fail("edge " + std::to_string(a) + "-" + std::to_string(b) + " of triangle " + std::to_string(f) +
           " has no opposite triangle (open mesh)");
  }

  // One fan per vertex: following next -> the corner whose prev is that vertex must visit all.
  adj.neighbour_start.assign(nv + 1, 0);
  adj.neighbours.reserve(ncorners);
  for (int v = 0; v < nv; ++v) {
    const int begin = adj.corner_start[v], end = adj.corner_start[v + 1];
    const int count = end - begin;
    int c = begin, visited = 0;
    do {
      adj.neighbours.push_back(adj.corner_next[c]);
      ++visited;
      // The face on the other side of edge (v, next) contains the directed edge (next, v), so
      // in it v's prev corner is `next`.
      const int w = adj.corner_next[c];
      int found = -1;
      for (int d = begin; d < end; ++d)
        if (adj.corner_prev[d] == w) {
          found = d;
          break;
        }
      FASCICLE_CHECK(found >= 0, "reverse edge exists");
      c = found;
    } while (c != begin && visited <= count);
    if (visited != count)
      fail("vertex " + std::to_string(v) + " joins more than one fan of triangles (non-manifold vertex)");
    adj.neighbour_start[v + 1] = static_cast<int>(adj.neighbours.size());
  }

  // Connected?
  std::vector<char> seen(nv, 0);
  std::vector<int> stack{0};
  seen[0] = 1;
  int reached = 1;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    for (int i = adj.neighbour_start[v]; i < adj.neighbour_start[v + 1]; ++i) {
      const int w = adj.neighbours[i];
      if (!seen[w]) {
        seen[w] = 1;
        ++reached;
        stack.push_back(w);
      }
    }
  }
  if (reached != nv)
    fail("the mesh has more than one connected component (" + std::to_string(reached) + " of " + std::to_string(nv) +
         " vertices reached from vertex 0)");

  const long edges = static_cast<long>(directed.size()) / 2;
  const long euler = static_cast<long>(nv) - edges + nf;
  if (euler != 2)
    fail("Euler characteristic is " + std::to_string(euler) + ", genus " + std::to_string((2 - euler) / 2) +
         " (a sphere map needs genus 0)");
  return adj;
}

}  // namespace fascicle
