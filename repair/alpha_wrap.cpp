// The alpha-wrap fallback, in its own translation unit: CGAL's Alpha_wrap_3 headers are the
// heaviest the project includes. It runs in the wrap worker process (repair/worker/); the
// process handling is in wrap_worker_client.cpp.

#include "repair/detail/alpha_wrap.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/alpha_wrap_3.h>

#include <array>
#include <vector>

namespace fascicle::detail {

TriangleMesh alpha_wrap(const TriangleMesh& soup, double alpha, double offset) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = K::Point_3;
  using Mesh = CGAL::Surface_mesh<Point>;

  std::vector<Point> points;
  points.reserve(soup.positions.size());
  for (const Vec3& p : soup.positions) points.emplace_back(p.x(), p.y(), p.z());
  std::vector<std::array<std::size_t, 3>> faces;
  faces.reserve(soup.triangles.size());
  for (const Triangle& t : soup.triangles)
    faces.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]), static_cast<std::size_t>(t[2])});

  Mesh wrap;
  CGAL::alpha_wrap_3(points, faces, alpha, offset, wrap);

  TriangleMesh out;
  std::vector<int> index(wrap.number_of_vertices() + wrap.number_of_removed_vertices(), -1);
  for (auto v : wrap.vertices()) {
    index[v.idx()] = static_cast<int>(out.positions.size());
    const Point& p = wrap.point(v);
    out.positions.emplace_back(p.x(), p.y(), p.z());
  }
  for (auto f : wrap.faces()) {
    Triangle t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(wrap.halfedge(f), wrap)) {
      if (k < 3) t[k] = index[v.idx()];
      ++k;
    }
    if (k == 3) out.triangles.push_back(t);
  }
  return out;
}

}  // namespace fascicle::detail
