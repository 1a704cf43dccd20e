// Point location on a sphere map: AABB tree over the chord triangles, a ray from the centre, and
// exact orientation predicates for the final decision.
#include "morph/sphere_locator.h"

#include "geometry/errors.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <list>
#include <stdexcept>

namespace fascicle {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Triangle3 = Kernel::Triangle_3;
using Iterator = std::vector<Triangle3>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

Point to_point(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

struct SphereLocator::Impl {
  std::vector<Vec3> sphere;
  std::vector<Triangle> triangles;
  std::vector<Triangle3> chords;
  Tree tree;

  /// Exact containment: the three signs, or false when any is negative. `on_boundary` is set
  /// when one of them is zero (edge or vertex).
  bool contains(int f, const Point& p, bool& on_boundary) const {
    const Point origin(0, 0, 0);
    on_boundary = false;
    for (int k = 0; k < 3; ++k) {
      const CGAL::Orientation o =
          CGAL::orientation(origin, chords[f].vertex(k), chords[f].vertex((k + 1) % 3), p);
      if (o == CGAL::NEGATIVE) return false;
      if (o == CGAL::COPLANAR) on_boundary = true;
    }
    return true;
  }

  SurfacePoint result(int f, const Vec3& p) const {
    const Triangle& t = triangles[f];
    const Vec3 &a = sphere[t[0]], &b = sphere[t[1]], &c = sphere[t[2]];
    // Barycentric coordinates of the ray's hit on the chord triangle: proportional to the
    // volumes det(p, b, c), det(p, c, a), det(p, a, b).
    Vec3 bary(p.dot(b.cross(c)), p.dot(c.cross(a)), p.dot(a.cross(b)));
    bary = bary.cwiseMax(0.0);
    const double sum = bary.sum();
    bary = sum > 0.0 ? Vec3(bary / sum) : Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);
    SurfacePoint out;
    out.face = f;
    out.barycentric = bary;
    out.position = bary[0] * a + bary[1] * b + bary[2] * c;
    return out;
  }

  SurfacePoint locate(const Vec3& p) const {
    const double n = p.norm();
    if (!(n > 0.0) || !std::isfinite(n)) throw std::invalid_argument("sphere locator: zero or non-finite direction");
    const Point q = to_point(p);
    const Kernel::Ray_3 ray(Point(0, 0, 0), q);
    bool boundary = false;
    const auto hit = tree.any_intersected_primitive(ray);
    if (hit) {
      const int f = static_cast<int>(*hit - chords.cbegin());
      if (contains(f, q, boundary) && !boundary) return result(f, p);
    }
    // On an edge or a vertex (or a map that is not a bijection): every face the ray meets,
    // the smallest index that contains p exactly wins.
    std::list<Tree::Primitive_id> all;
    tree.all_intersected_primitives(ray, std::back_inserter(all));
    int best = -1;
    for (const auto& id : all) {
      const int f = static_cast<int>(id - chords.cbegin());
      if ((best < 0 || f < best) && contains(f, q, boundary)) best = f;
    }
    if (best >= 0) return result(best, p);
    // Not covered (only possible when the map is not a bijection): the face whose worst
    // normalised edge test is least negative.
    double best_score = -std::numeric_limits<double>::infinity();
    const Vec3 u = p / n;
    for (const auto& id : all) {
      const int f = static_cast<int>(id - chords.cbegin());
      const Triangle& t = triangles[f];
      double score = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        const Vec3 e = sphere[t[k]].cross(sphere[t[(k + 1) % 3]]);
        const double en = e.norm();
        if (en > 0.0) score = std::min(score, e.dot(u) / en);
      }
      if (score > best_score) {
        best_score = score;
        best = f;
      }
    }
    FASCICLE_CHECK(best >= 0, "a ray from the centre meets the sphere map");
    return result(best, p);
  }
};

SphereLocator::SphereLocator(const std::vector<Vec3>& sphere, const std::vector<Triangle>& triangles)
    : impl_(std::make_unique<Impl>()) {
  if (triangles.empty() || sphere.empty()) throw TopologyError("sphere locator: the sphere map is empty");
  impl_->sphere = sphere;
  impl_->triangles = triangles;
  impl_->chords.reserve(triangles.size());
  for (const Triangle& t : triangles)
    impl_->chords.emplace_back(to_point(sphere[t[0]]), to_point(sphere[t[1]]), to_point(sphere[t[2]]));
  impl_->tree.insert(impl_->chords.cbegin(), impl_->chords.cend());
  impl_->tree.build();
}

SphereLocator::~SphereLocator() = default;

SurfacePoint SphereLocator::locate(const Vec3& p) const { return impl_->locate(p); }

std::vector<SurfacePoint> SphereLocator::locate_all(const std::vector<Vec3>& directions) const {
  std::vector<SurfacePoint> out(directions.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, directions.size(), 1024),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) out[i] = impl_->locate(directions[i]);
                    });
  return out;
}

Vec3 point_on_mesh(const TriangleMesh& mesh, const SurfacePoint& located) {
  const Triangle& t = mesh.triangles.at(static_cast<std::size_t>(located.face));
  return located.barycentric[0] * mesh.positions[t[0]] + located.barycentric[1] * mesh.positions[t[1]] +
         located.barycentric[2] * mesh.positions[t[2]];
}

Vec3 point_on_sphere(const std::vector<Vec3>& sphere, const std::vector<Triangle>& triangles,
                     const SurfacePoint& surface_point) {
  const Triangle& t = triangles.at(static_cast<std::size_t>(surface_point.face));
  const Vec3 p = surface_point.barycentric[0] * sphere[t[0]] + surface_point.barycentric[1] * sphere[t[1]] +
                 surface_point.barycentric[2] * sphere[t[2]];
  return p.normalized();
}

}  // namespace fascicle
