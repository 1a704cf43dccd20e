// Closest point and exact inside test on a plain triangle mesh through CGAL: the AABB tree over
// the triangles (closest point with its primitive), and Side_of_triangle_mesh over a
// Surface_mesh copy (ray crossing counts with exact predicates).
#include "morph/surface_query.h"

#include "geometry/errors.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <mutex>
#include <optional>

namespace fascicle {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Triangle3 = Kernel::Triangle_3;
using Iterator = std::vector<Triangle3>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
using Mesh = CGAL::Surface_mesh<Point>;
using Inside = CGAL::Side_of_triangle_mesh<Mesh, Kernel>;

Point to_point(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3 to_vec(const Point& p) { return {p.x(), p.y(), p.z()}; }

}  // namespace

Vec3 triangle_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 u = b - a, w = c - a, d = p - a;
  const double uu = u.dot(u), uw = u.dot(w), ww = w.dot(w), du = d.dot(u), dw = d.dot(w);
  const double den = uu * ww - uw * uw;
  Vec3 bary;
  if (den > 0.0) {
    const double l1 = (ww * du - uw * dw) / den, l2 = (uu * dw - uw * du) / den;
    bary = Vec3(1.0 - l1 - l2, l1, l2);
  } else {
    bary = Vec3(1.0, 0.0, 0.0);
  }
  bary = bary.cwiseMax(0.0);
  const double sum = bary.sum();
  return sum > 0.0 ? Vec3(bary / sum) : Vec3(1.0, 0.0, 0.0);
}

struct SurfaceQuery::Impl {
  TriangleMesh mesh;
  std::vector<Triangle3> triangles;
  Tree tree;
  Mesh surface;
  std::once_flag inside_once;
  std::optional<Inside> inside;
};

SurfaceQuery::SurfaceQuery(const TriangleMesh& mesh) : impl_(std::make_unique<Impl>()) {
  if (mesh.triangles.empty()) throw TopologyError("surface query: the mesh has no triangles");
  impl_->mesh = mesh;
  impl_->triangles.reserve(mesh.triangles.size());
  for (const Triangle& t : mesh.triangles)
    impl_->triangles.emplace_back(to_point(mesh.positions[t[0]]), to_point(mesh.positions[t[1]]),
                                  to_point(mesh.positions[t[2]]));
  impl_->tree.insert(impl_->triangles.cbegin(), impl_->triangles.cend());
  impl_->tree.build();
  impl_->tree.accelerate_distance_queries();
}

SurfaceQuery::~SurfaceQuery() = default;

SurfacePoint SurfaceQuery::closest_point(const Vec3& p) const {
  const auto hit = impl_->tree.closest_point_and_primitive(to_point(p));
  SurfacePoint result;
  result.face = static_cast<int>(hit.second - impl_->triangles.cbegin());
  const Triangle& t = impl_->mesh.triangles[result.face];
  const Vec3& a = impl_->mesh.positions[t[0]];
  const Vec3& b = impl_->mesh.positions[t[1]];
  const Vec3& c = impl_->mesh.positions[t[2]];
  result.barycentric = triangle_barycentric(to_vec(hit.first), a, b, c);
  result.position = result.barycentric[0] * a + result.barycentric[1] * b + result.barycentric[2] * c;
  result.distance = (result.position - p).norm();
  return result;
}

Side SurfaceQuery::side(const Vec3& p) const {
  // Built on first use: most callers only need closest points.
  std::call_once(impl_->inside_once, [this] {
    Mesh& m = impl_->surface;
    std::vector<Mesh::Vertex_index> vertices;
    vertices.reserve(impl_->mesh.positions.size());
    for (const Vec3& v : impl_->mesh.positions) vertices.push_back(m.add_vertex(to_point(v)));
    for (const Triangle& t : impl_->mesh.triangles)
      if (m.add_face(vertices[t[0]], vertices[t[1]], vertices[t[2]]) == Mesh::null_face())
        throw TopologyError("inside test: the mesh is not an oriented 2-manifold");
    impl_->inside.emplace(m);
  });
  switch ((*impl_->inside)(to_point(p))) {
    case CGAL::ON_BOUNDED_SIDE: return Side::inside;
    case CGAL::ON_BOUNDARY: return Side::boundary;
    default: return Side::outside;
  }
}

}  // namespace fascicle
