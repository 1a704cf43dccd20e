#include "geometry/subdivide_mesh.h"

#include <algorithm>
#include <map>
#include <utility>

namespace fascicle {

TriangleMesh subdivide_mesh(const TriangleMesh& mesh) {
  TriangleMesh out;
  out.positions = mesh.positions;
  out.triangles.reserve(4 * mesh.triangles.size());
  std::map<std::pair<int, int>, int> midpoint_of;
  const auto midpoint = [&](int a, int b) {
    const auto [it, added] = midpoint_of.try_emplace(std::minmax(a, b), static_cast<int>(out.positions.size()));
    if (added)
      out.positions.push_back(0.5 * (mesh.positions[static_cast<std::size_t>(a)] +
                                     mesh.positions[static_cast<std::size_t>(b)]));
    return it->second;
  };
  for (const Triangle& t : mesh.triangles) {
    const int a = midpoint(t[0], t[1]), b = midpoint(t[1], t[2]), c = midpoint(t[2], t[0]);
    out.triangles.push_back({t[0], a, c});
    out.triangles.push_back({t[1], b, a});
    out.triangles.push_back({t[2], c, b});
    out.triangles.push_back({a, b, c});
  }
  return out;
}

}  // namespace fascicle
