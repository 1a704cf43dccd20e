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
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <list>
#include <mutex>
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
  // Built on first use: most maps never need it (every walk ends strictly inside a face).
  mutable Tree tree;
  mutable std::once_flag tree_built;
  std::vector<std::array<int, 3>> across;  // face across edge (t[k], t[k+1]), -1 if none
  int grid = 1;                            // cube-map cells per face side
  std::vector<int> start;                  // per cube-map cell: a face near it
  int max_steps = 0;

  const Tree& built_tree() const {
    std::call_once(tree_built, [this] {
      tree.insert(chords.cbegin(), chords.cend());
      tree.build();
    });
    return tree;
  }

  int cell(const Vec3& p) const {
    const Vec3 a = p.cwiseAbs();
    int axis = 0;
    if (a.y() > a[axis]) axis = 1;
    if (a.z() > a[axis]) axis = 2;
    const int side = p[axis] < 0.0 ? 1 : 0;
    const double u = p[(axis + 1) % 3] / a[axis], v = p[(axis + 2) % 3] / a[axis];
    const int iu = std::clamp(static_cast<int>((u + 1.0) * 0.5 * grid), 0, grid - 1);
    const int iv = std::clamp(static_cast<int>((v + 1.0) * 0.5 * grid), 0, grid - 1);
    return ((axis * 2 + side) * grid + iu) * grid + iv;
  }

  Vec3 cell_centre(int c) const {
    const int iv = c % grid, iu = (c / grid) % grid, face = c / (grid * grid);
    const int axis = face / 2, side = face % 2;
    Vec3 p;
    p[axis] = side ? -1.0 : 1.0;
    p[(axis + 1) % 3] = (iu + 0.5) / grid * 2.0 - 1.0;
    p[(axis + 2) % 3] = (iv + 0.5) / grid * 2.0 - 1.0;
    return p.normalized();
  }

  /// Visibility walk from `f` towards p with exact predicates: cross an edge whose plane through
  /// the centre has p on its negative side, starting the edge scan at a rotating index so the
  /// walk cannot cycle for long. Returns the face, or -1 after max_steps.
  int walk(int f, const Point& p, bool& on_boundary) const {
    const Point origin(0, 0, 0);
    unsigned rotation = 0;
    for (int step = 0; step < max_steps; ++step) {
      on_boundary = false;
      int exit = -1;
      for (int i = 0; i < 3; ++i) {
        const int k = static_cast<int>((i + rotation) % 3);
        const CGAL::Orientation o = CGAL::orientation(origin, chords[f].vertex(k), chords[f].vertex((k + 1) % 3), p);
        if (o == CGAL::NEGATIVE) {
          exit = k;
          break;
        }
        if (o == CGAL::COPLANAR) on_boundary = true;
      }
      if (exit < 0) return f;
      f = across[f][exit];
      if (f < 0) return -1;
      rotation = rotation * 1103515245u + 12345u;
      rotation >>= 3;
    }
    return -1;
  }

  /// Exact containment: the three signs, or false when any is negative. `on_boundary` is set
  /// when one of them is zero (edge or vertex).
  bool contains(int f, const Point& p, bool& on_boundary) const {
    const Point origin(0, 0, 0);
    on_boundary = false;
    for (int k = 0; k < 3; ++k) {
      const CGAL::Orientation o = CGAL::orientation(origin, chords[f].vertex(k), chords[f].vertex((k + 1) % 3), p);
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
    bool boundary = false;
    // Fast path: walk from the face stored for p's cube-map cell.
    const int walked = walk(start[cell(p / n)], q, boundary);
    if (walked >= 0 && !boundary) return result(walked, p);
    const Kernel::Ray_3 ray(Point(0, 0, 0), q);
    if (walked < 0) {
      const auto hit = built_tree().any_intersected_primitive(ray);
      if (hit) {
        const int f = static_cast<int>(*hit - chords.cbegin());
        if (contains(f, q, boundary) && !boundary) return result(f, p);
      }
    }
    // On an edge or a vertex (or a map that is not a bijection): every face the ray meets,
    // the smallest index that contains p exactly wins.
    std::list<Tree::Primitive_id> all;
    built_tree().all_intersected_primitives(ray, std::back_inserter(all));
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
  Impl& d = *impl_;
  d.sphere = sphere;
  d.triangles = triangles;
  d.chords.resize(triangles.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, triangles.size(), 2048),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t f = range.begin(); f != range.end(); ++f) {
                        const Triangle& t = triangles[f];
                        d.chords[f] = Triangle3(to_point(sphere[t[0]]), to_point(sphere[t[1]]), to_point(sphere[t[2]]));
                      }
                    });
  // Neighbours across edges: the half-edges leaving each vertex (counting sort), then for the
  // half-edge a -> b its twin among those leaving b.
  const int nf = static_cast<int>(triangles.size());
  const int nv = static_cast<int>(sphere.size());
  std::vector<int> first(static_cast<std::size_t>(nv) + 1, 0), leaving(static_cast<std::size_t>(nf) * 3);
  for (const Triangle& t : triangles)
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= nv) throw TopologyError("sphere locator: a triangle indexes a missing vertex");
      ++first[static_cast<std::size_t>(t[k]) + 1];
    }
  for (int v = 0; v < nv; ++v) first[static_cast<std::size_t>(v) + 1] += first[static_cast<std::size_t>(v)];
  {
    std::vector<int> fill(first.begin(), first.end() - 1);
    for (int f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k)
        leaving[static_cast<std::size_t>(fill[static_cast<std::size_t>(triangles[f][k])]++)] = f * 3 + k;
  }
  d.across.assign(nf, {-1, -1, -1});
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, 2048), [&](const tbb::blocked_range<int>& range) {
    for (int f = range.begin(); f != range.end(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int a = triangles[f][k], b = triangles[f][(k + 1) % 3];
        for (int i = first[static_cast<std::size_t>(b)]; i < first[static_cast<std::size_t>(b) + 1]; ++i) {
          const int h = leaving[static_cast<std::size_t>(i)];
          if (triangles[h / 3][(h % 3 + 1) % 3] == a) {
            d.across[f][k] = h / 3;
            break;
          }
        }
      }
  });
  // Cube map with about one vertex per two cells; each cell starts at a face of a vertex in it.
  // An empty cell walks from a filled neighbour's face to its centre; cells no walk reaches ask
  // the AABB tree. The start face only decides where a walk begins: located faces do not
  // depend on it.
  d.grid = std::max(2, static_cast<int>(std::sqrt(static_cast<double>(sphere.size()) / 12.0)));
  d.max_steps = 64 + 4 * static_cast<int>(std::sqrt(static_cast<double>(nf)));
  d.start.assign(static_cast<std::size_t>(6 * d.grid * d.grid), -1);
  // Each vertex's cell on threads; a cell takes the first face (by index) with a corner in it.
  std::vector<int> vertex_cell(static_cast<std::size_t>(nv), -1);
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 2048), [&](const tbb::blocked_range<int>& range) {
    for (int v = range.begin(); v != range.end(); ++v) {
      const Vec3& p = sphere[static_cast<std::size_t>(v)];
      if (p.norm() > 0.0) vertex_cell[static_cast<std::size_t>(v)] = d.cell(p.normalized());
    }
  });
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int c = vertex_cell[static_cast<std::size_t>(triangles[f][k])];
      if (c < 0) continue;
      int& s = d.start[static_cast<std::size_t>(c)];
      if (s < 0) s = f;
    }
  const int g = d.grid;
  for (;;) {
    std::vector<int> next = d.start;
    std::vector<int> empty;
    for (int c = 0; c < static_cast<int>(d.start.size()); ++c)
      if (d.start[static_cast<std::size_t>(c)] < 0) empty.push_back(c);
    std::atomic<bool> any{false};
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, empty.size(), 64), [&](const tbb::blocked_range<std::size_t>& range) {
          for (std::size_t e = range.begin(); e != range.end(); ++e) {
            const int c = empty[e];
            const int iv = c % g, iu = (c / g) % g, face = c / (g * g);
            int from = -1;
            for (const auto& [du, dv] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
              const int u = iu + du, v = iv + dv;
              if (u < 0 || u >= g || v < 0 || v >= g) continue;
              from = d.start[static_cast<std::size_t>((face * g + u) * g + v)];
              if (from >= 0) break;
            }
            if (from < 0) continue;
            bool on_boundary = false;
            const int walked = d.walk(from, to_point(d.cell_centre(c)), on_boundary);
            next[static_cast<std::size_t>(c)] = walked >= 0 ? walked : from;
            any = true;
          }
        });
    d.start.swap(next);
    if (!any) break;
  }
  for (std::size_t c = 0; c < d.start.size(); ++c)
    if (d.start[c] < 0) {
      const auto hit = d.built_tree().any_intersected_primitive(
          Kernel::Ray_3(Point(0, 0, 0), to_point(d.cell_centre(static_cast<int>(c)))));
      d.start[c] = hit ? static_cast<int>(*hit - d.chords.cbegin()) : 0;
    }
}

SphereLocator::~SphereLocator() = default;

SurfacePoint SphereLocator::locate(const Vec3& p) const { return impl_->locate(p); }

std::vector<SurfacePoint> SphereLocator::locate_all(const std::vector<Vec3>& directions) const {
  std::vector<SurfacePoint> out(directions.size());
  // Ranges of 128: a lattice's ring of several hundred points is located on both cores.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, directions.size(), 128),
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
