// Closest point and exact inside test on a plain triangle mesh through CGAL: the AABB tree over
// the triangles (closest point with its primitive), and Side_of_triangle_mesh over a
// Surface_mesh copy (ray crossing counts with exact predicates). Rays: a plain bounding-volume
// hierarchy over the triangles' boxes.
#include "morph/surface_query.h"

#include "geometry/errors.h"
#include "morph/inside_grid.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <mutex>
#include <numeric>
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

// Bounding-volume hierarchy over the triangles for first_hit(): median split of the triangle
// centres along the longest axis of their box, leaves of up to 4 triangles; each node's box
// holds its triangles' boxes, padded by 1e-6 of the mesh's diagonal so that a hit that rounding
// puts a hair outside a triangle (a ray grazing it) is not culled with its node.
struct RayTree {
  struct Node {
    Vec3 lo, hi;
    int first = 0, count = 0;   // leaf: triangles order[first, first + count)
    int left = -1, right = -1;  // inner node: children
  };
  std::vector<Node> nodes;
  std::vector<int> order;

  void build(const TriangleMesh& mesh) {
    const std::size_t n = mesh.triangles.size();
    order.resize(n);
    std::iota(order.begin(), order.end(), 0);
    std::vector<Vec3> lo(n), hi(n), centre(n);
    Vec3 all_lo = Vec3::Constant(1e300), all_hi = Vec3::Constant(-1e300);
    for (std::size_t f = 0; f < n; ++f) {
      const Triangle& t = mesh.triangles[f];
      const Vec3& a = mesh.positions[t[0]];
      const Vec3& b = mesh.positions[t[1]];
      const Vec3& c = mesh.positions[t[2]];
      lo[f] = a.cwiseMin(b).cwiseMin(c);
      hi[f] = a.cwiseMax(b).cwiseMax(c);
      centre[f] = 0.5 * (lo[f] + hi[f]);
      all_lo = all_lo.cwiseMin(lo[f]);
      all_hi = all_hi.cwiseMax(hi[f]);
    }
    const double pad = 1e-6 * (all_hi - all_lo).norm();
    nodes.clear();
    nodes.reserve(2 * n / 4 + 2);
    const auto make = [&](auto&& self, int first, int count) -> int {
      const int id = static_cast<int>(nodes.size());
      nodes.emplace_back();
      Vec3 box_lo = Vec3::Constant(1e300), box_hi = Vec3::Constant(-1e300);
      Vec3 c_lo = box_lo, c_hi = box_hi;
      for (int i = first; i < first + count; ++i) {
        const int f = order[static_cast<std::size_t>(i)];
        box_lo = box_lo.cwiseMin(lo[static_cast<std::size_t>(f)]);
        box_hi = box_hi.cwiseMax(hi[static_cast<std::size_t>(f)]);
        c_lo = c_lo.cwiseMin(centre[static_cast<std::size_t>(f)]);
        c_hi = c_hi.cwiseMax(centre[static_cast<std::size_t>(f)]);
      }
      nodes[static_cast<std::size_t>(id)].lo = box_lo - Vec3::Constant(pad);
      nodes[static_cast<std::size_t>(id)].hi = box_hi + Vec3::Constant(pad);
      if (count <= 4) {
        nodes[static_cast<std::size_t>(id)].first = first;
        nodes[static_cast<std::size_t>(id)].count = count;
        return id;
      }
      int axis = 0;
      (c_hi - c_lo).maxCoeff(&axis);
      const int mid = first + count / 2;
      std::nth_element(order.begin() + first, order.begin() + mid, order.begin() + first + count, [&](int x, int y) {
        return centre[static_cast<std::size_t>(x)][axis] < centre[static_cast<std::size_t>(y)][axis];
      });
      const int left = self(self, first, mid - first);
      const int right = self(self, mid, first + count - mid);
      nodes[static_cast<std::size_t>(id)].left = left;
      nodes[static_cast<std::size_t>(id)].right = right;
      return id;
    };
    if (n > 0) make(make, 0, static_cast<int>(n));
  }
};

// Entry parameter of the segment p + t d, t in [0, t_max], into the box [lo, hi] (slab test);
// false when it misses.
bool segment_meets_box(const Vec3& p, const Vec3& inverse_d, double t_max, const Vec3& lo, const Vec3& hi) {
  double t0 = 0.0, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    if (std::isinf(inverse_d[a])) {  // parallel to the slab
      if (p[a] < lo[a] || p[a] > hi[a]) return false;
      continue;
    }
    double near = (lo[a] - p[a]) * inverse_d[a], far = (hi[a] - p[a]) * inverse_d[a];
    if (near > far) std::swap(near, far);
    t0 = std::max(t0, near);
    t1 = std::min(t1, far);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

bool ray_triangle_hit(const Vec3& p, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c, double& t) {
  const Vec3 e1 = b - a, e2 = c - a, h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-300) return false;
  const Vec3 s = p - a;
  const double u = s.dot(h) / det;
  if (u < 0.0 || u > 1.0) return false;
  const Vec3 qv = s.cross(e1);
  const double v = d.dot(qv) / det;
  if (v < 0.0 || u + v > 1.0) return false;
  t = e2.dot(qv) / det;
  return true;
}

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
  RayTree rays;
  std::once_flag inside_once;
  std::optional<Inside> inside;
  std::optional<InsideGrid> grid;

  // Builds the exact test and the grid over it, once.
  void build_inside() {
    std::call_once(inside_once, [this] {
      std::vector<Mesh::Vertex_index> vertices;
      vertices.reserve(mesh.positions.size());
      for (const Vec3& v : mesh.positions) vertices.push_back(surface.add_vertex(to_point(v)));
      for (const Triangle& t : mesh.triangles)
        if (surface.add_face(vertices[t[0]], vertices[t[1]], vertices[t[2]]) == Mesh::null_face())
          throw TopologyError("inside test: the mesh is not an oriented 2-manifold");
      inside.emplace(surface);
      grid.emplace(mesh, [this](const Vec3& p) { return exact_side(p) == Side::inside; });
    });
  }
  Side exact_side(const Vec3& p) const {
    switch ((*inside)(to_point(p))) {
      case CGAL::ON_BOUNDED_SIDE: return Side::inside;
      case CGAL::ON_BOUNDARY: return Side::boundary;
      default: return Side::outside;
    }
  }
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
  impl_->rays.build(mesh);
}

SurfaceQuery::~SurfaceQuery() = default;

namespace {

// Interleaves the low 10 bits of x, y, z (Morton order).
std::uint32_t morton3(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  auto spread = [](std::uint32_t v) {
    v &= 0x3FFu;
    v = (v | (v << 16)) & 0x030000FFu;
    v = (v | (v << 8)) & 0x0300F00Fu;
    v = (v | (v << 4)) & 0x030C30C3u;
    v = (v | (v << 2)) & 0x09249249u;
    return v;
  };
  return spread(x) | (spread(y) << 1) | (spread(z) << 2);
}

// The closest point `hit` of the tree (point, triangle) as a SurfacePoint of `mesh`.
SurfacePoint surface_point(const TriangleMesh& mesh, const std::vector<Triangle3>& triangles, const Vec3& p,
                           const std::pair<Point, Iterator>& hit) {
  SurfacePoint result;
  result.face = static_cast<int>(hit.second - triangles.cbegin());
  const Triangle& t = mesh.triangles[result.face];
  const Vec3& a = mesh.positions[t[0]];
  const Vec3& b = mesh.positions[t[1]];
  const Vec3& c = mesh.positions[t[2]];
  result.barycentric = triangle_barycentric(to_vec(hit.first), a, b, c);
  result.position = result.barycentric[0] * a + result.barycentric[1] * b + result.barycentric[2] * c;
  result.distance = (result.position - p).norm();
  return result;
}

}  // namespace

SurfacePoint SurfaceQuery::closest_point(const Vec3& p) const {
  return surface_point(impl_->mesh, impl_->triangles, p, impl_->tree.closest_point_and_primitive(to_point(p)));
}

std::vector<SurfacePoint> SurfaceQuery::closest_points(const std::vector<Vec3>& points) const {
  std::vector<SurfacePoint> out(points.size());
  if (points.empty()) return out;
  Vec3 lo = points.front(), hi = points.front();
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vec3 extent = (hi - lo).cwiseMax(Vec3::Constant(1e-300));
  std::vector<std::pair<std::uint32_t, std::size_t>> order(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 u =
        ((points[i] - lo).cwiseQuotient(extent) * 1023.0).cwiseMax(Vec3::Zero()).cwiseMin(Vec3::Constant(1023.0));
    order[i] = {morton3(static_cast<std::uint32_t>(u.x()), static_cast<std::uint32_t>(u.y()),
                        static_cast<std::uint32_t>(u.z())),
                i};
  }
  std::sort(order.begin(), order.end());
  // Runs of consecutive points along the curve, one task each; a run's first query searches for
  // its start (the tree's own hint), the others start from the previous closest point.
  constexpr std::size_t kRun = 256;
  const std::size_t runs = (points.size() + kRun - 1) / kRun;
  tbb::parallel_for(std::size_t(0), runs, [&](std::size_t run) {
    const std::size_t begin = run * kRun, end = std::min(points.size(), begin + kRun);
    Tree::Point_and_primitive_id hint;
    for (std::size_t k = begin; k < end; ++k) {
      const std::size_t i = order[k].second;
      const Point q = to_point(points[i]);
      hint = k == begin ? impl_->tree.closest_point_and_primitive(q) : impl_->tree.closest_point_and_primitive(q, hint);
      out[i] = surface_point(impl_->mesh, impl_->triangles, points[i], hint);
    }
  });
  return out;
}

Side SurfaceQuery::side(const Vec3& p) const {
  // Built on first use: most callers only need closest points.
  impl_->build_inside();
  switch (impl_->grid->classify(p)) {
    case InsideGrid::Known::inside: return Side::inside;
    case InsideGrid::Known::outside: return Side::outside;
    default: return impl_->exact_side(p);
  }
}

Side SurfaceQuery::exact_side(const Vec3& p) const {
  impl_->build_inside();
  return impl_->exact_side(p);
}

const InsideGrid& SurfaceQuery::inside_grid() const {
  impl_->build_inside();
  return *impl_->grid;
}

bool SurfaceQuery::first_hit(const Vec3& p, const Vec3& d, double reach, Vec3& hit) const {
  const RayTree& tree = impl_->rays;
  if (tree.nodes.empty()) return false;
  const TriangleMesh& mesh = impl_->mesh;
  double best = reach;
  bool found = false;
  const Vec3 q = p + reach * d;
  const Vec3 lo = p.cwiseMin(q), hi = p.cwiseMax(q);
  const Vec3 inverse_d(1.0 / d.x(), 1.0 / d.y(), 1.0 / d.z());
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const RayTree::Node& node = tree.nodes[static_cast<std::size_t>(stack[--top])];
    // Nodes beyond the best hit so far cannot hold a nearer one (their padded boxes hold every
    // hit of their triangles).
    if (!segment_meets_box(p, inverse_d, best, node.lo, node.hi)) continue;
    if (node.count == 0) {
      stack[top++] = node.left;
      stack[top++] = node.right;
      continue;
    }
    for (int i = node.first; i < node.first + node.count; ++i) {
      const Triangle& t = mesh.triangles[static_cast<std::size_t>(tree.order[static_cast<std::size_t>(i)])];
      const Vec3& a = mesh.positions[t[0]];
      const Vec3& b = mesh.positions[t[1]];
      const Vec3& c = mesh.positions[t[2]];
      if ((a.cwiseMax(b).cwiseMax(c) - lo).minCoeff() < 0.0 || (hi - a.cwiseMin(b).cwiseMin(c)).minCoeff() < 0.0)
        continue;
      double t_hit = 0.0;
      if (ray_triangle_hit(p, d, a, b, c, t_hit) && t_hit > 0.0 && t_hit < best) {
        best = t_hit;
        found = true;
      }
    }
  }
  if (found) hit = p + best * d;
  return found;
}

}  // namespace fascicle
