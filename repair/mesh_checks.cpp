// Census, verification and distance checks. CGAL stays in this file: exact predicates for the
// self-intersection tests, box intersection for the broad phase, AABB trees for distances.

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "repair/clean_soup.h"
#include "repair/detail/checks.h"
#include "repair/repair.h"
#include "repair/weld_vertices.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <numeric>
#include <random>
#include <unordered_map>

namespace fascicle {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;

Point to_point(const Vec3& p) { return Point(p.x(), p.y(), p.z()); }

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
}

// Do two triangles of a soup intersect anywhere other than in the corners and edge they share?
// Exact predicates (filtered) decide every case.
bool triangles_intersect(const TriangleMesh& m, const Triangle& s, const Triangle& t) {
  int shared = 0;
  int s_shared[3] = {-1, -1, -1}, t_shared[3] = {-1, -1, -1};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (s[i] == t[j]) {
        s_shared[shared] = i;
        t_shared[shared] = j;
        ++shared;
      }
  auto P = [&](int idx) { return to_point(m.positions[idx]); };
  if (shared == 0) {
    return CGAL::do_intersect(K::Triangle_3(P(s[0]), P(s[1]), P(s[2])), K::Triangle_3(P(t[0]), P(t[1]), P(t[2])));
  }
  if (shared >= 3) return true;  // the same face twice
  if (shared == 2) {
    // Common edge (a, b); they overlap only when coplanar with both third corners on one side.
    const int si = 3 - s_shared[0] - s_shared[1], ti = 3 - t_shared[0] - t_shared[1];
    const Point a = P(s[s_shared[0]]), b = P(s[s_shared[1]]), p = P(s[si]), q = P(t[ti]);
    if (!CGAL::coplanar(a, b, p, q)) return false;
    return CGAL::coplanar_orientation(a, b, p, q) == CGAL::POSITIVE;
  }
  // One common corner v: they intersect elsewhere iff the edge opposite v in one triangle meets
  // the other triangle.
  const int si = s_shared[0], ti = t_shared[0];
  const K::Segment_3 s_opposite(P(s[(si + 1) % 3]), P(s[(si + 2) % 3]));
  const K::Segment_3 t_opposite(P(t[(ti + 1) % 3]), P(t[(ti + 2) % 3]));
  const K::Triangle_3 ts(P(s[0]), P(s[1]), P(s[2])), tt(P(t[0]), P(t[1]), P(t[2]));
  if (!ts.is_degenerate() && CGAL::do_intersect(t_opposite, ts)) return true;
  if (!tt.is_degenerate() && CGAL::do_intersect(s_opposite, tt)) return true;
  return false;
}

// Counts intersecting pairs (stops after the first when `first_only`).
long count_self_intersections(const TriangleMesh& m, bool first_only) {
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
  std::vector<Box> boxes;
  boxes.reserve(m.triangles.size());
  for (std::size_t f = 0; f < m.triangles.size(); ++f) {
    const Triangle& t = m.triangles[f];
    CGAL::Bbox_3 b =
        to_point(m.positions[t[0]]).bbox() + to_point(m.positions[t[1]]).bbox() + to_point(m.positions[t[2]]).bbox();
    boxes.emplace_back(b, static_cast<int>(f));
  }
  std::vector<std::pair<int, int>> candidates;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(),
                                [&](const Box& a, const Box& b) { candidates.emplace_back(a.info(), b.info()); });
  std::atomic<long> count{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, candidates.size(), 256), [&](const auto& range) {
    long local = 0;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      if (first_only && count.load() > 0) return;
      if (triangles_intersect(m, m.triangles[candidates[i].first], m.triangles[candidates[i].second])) ++local;
    }
    count += local;
  });
  return count.load();
}

struct Topology {
  long vertices = 0, edges = 0, boundary_edges = 0, non_manifold_edges = 0, misoriented_edges = 0;
  long non_manifold_vertices = 0, components = 0;
};

Topology topology_of(const TriangleMesh& m) {
  Topology topo;
  const int n = static_cast<int>(m.positions.size());
  // Edge use: count of faces and the sum of orientations (+1 a->b with a<b, -1 otherwise).
  std::unordered_map<std::uint64_t, std::pair<int, int>> edges;
  edges.reserve(m.triangles.size() * 2);
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<char> used(n, 0);
  for (const Triangle& t : m.triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      used[a] = 1;
      auto& e = edges[edge_key(a, b)];
      e.first += 1;
      e.second += a < b ? 1 : -1;
      const int ra = find(a), rb = find(b);
      if (ra != rb) parent[ra] = rb;
    }
  for (int v = 0; v < n; ++v)
    if (used[v]) {
      ++topo.vertices;
      if (find(v) == v) ++topo.components;
    }
  topo.edges = static_cast<long>(edges.size());
  for (const auto& [key, use] : edges) {
    if (use.first == 1) ++topo.boundary_edges;
    if (use.first > 2) ++topo.non_manifold_edges;
    if (use.first == 2 && use.second != 0) ++topo.misoriented_edges;
  }
  // Vertex manifoldness: the faces around a vertex must form one fan (connected through edges
  // at the vertex). Each incident face links its two other corners; count the link's pieces
  // with a tiny union-find over the (few) neighbours, found by linear search.
  std::vector<int> first(n + 1, 0);
  for (const Triangle& t : m.triangles)
    for (int v : t) ++first[v + 1];
  for (int v = 0; v < n; ++v) first[v + 1] += first[v];
  std::vector<int> incident(first[n]);
  std::vector<int> fill(first.begin(), first.end() - 1);
  for (std::size_t f = 0; f < m.triangles.size(); ++f)
    for (int v : m.triangles[f]) incident[fill[v]++] = static_cast<int>(f);
  std::vector<int> neighbour, link;
  for (int v = 0; v < n; ++v) {
    const int begin = first[v], end = first[v + 1];
    if (end - begin < 2) continue;
    neighbour.clear();
    link.clear();
    auto local = [&](int w) {
      for (std::size_t i = 0; i < neighbour.size(); ++i)
        if (neighbour[i] == w) return static_cast<int>(i);
      neighbour.push_back(w);
      link.push_back(static_cast<int>(link.size()));
      return static_cast<int>(neighbour.size()) - 1;
    };
    auto root = [&](int a) {
      while (link[a] != a) a = link[a] = link[link[a]];
      return a;
    };
    int pieces = 0;
    for (int i = begin; i < end; ++i) {
      const Triangle& t = m.triangles[incident[i]];
      int others[2], k = 0;
      for (int w : t)
        if (w != v && k < 2) others[k++] = w;
      if (k < 2) continue;
      const int ra = root(local(others[0])), rb = root(local(others[1]));
      if (ra != rb) link[ra] = rb;
    }
    for (std::size_t i = 0; i < link.size(); ++i)
      if (root(static_cast<int>(i)) == static_cast<int>(i)) ++pieces;
    if (pieces > 1) ++topo.non_manifold_vertices;
  }
  return topo;
}

}  // namespace

namespace detail {

bool is_oriented_manifold_soup(const TriangleMesh& soup) {
  for (const Triangle& t : soup.triangles)
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) return false;
  const Topology topo = topology_of(soup);
  return topo.non_manifold_edges == 0 && topo.misoriented_edges == 0 && topo.non_manifold_vertices == 0;
}

MeshCensus census_of_triangles(const TriangleMesh& mesh, bool count_intersections) {
  MeshCensus c;
  const Topology topo = topology_of(mesh);
  c.vertices = topo.vertices;
  c.faces = static_cast<long>(mesh.triangles.size());
  c.components = topo.components;
  c.boundary_edges = topo.boundary_edges;
  c.non_manifold_edges = topo.non_manifold_edges;
  c.non_manifold_vertices = topo.non_manifold_vertices;
  c.euler = topo.vertices - topo.edges + c.faces;
  if (topo.boundary_edges == 0 && topo.non_manifold_edges == 0 && topo.non_manifold_vertices == 0 && c.faces > 0)
    c.genus = (2 * topo.components - c.euler) / 2;
  c.self_intersections = count_intersections ? count_self_intersections(mesh, false) : 0;
  c.volume = signed_volume(mesh);
  c.area = surface_area(mesh);
  return c;
}

double one_sided_distance(const TriangleMesh& from_mesh, const TriangleMesh& to_mesh, int samples, std::uint64_t seed) {
  using Tri = K::Triangle_3;
  using Primitive = CGAL::AABB_triangle_primitive<K, std::vector<Tri>::const_iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

  auto one_sided = [&](const TriangleMesh& from, const TriangleMesh& to) {
    std::vector<Tri> tris;
    tris.reserve(to.triangles.size());
    for (const Triangle& t : to.triangles) {
      Tri tri(to_point(to.positions[t[0]]), to_point(to.positions[t[1]]), to_point(to.positions[t[2]]));
      if (!tri.is_degenerate()) tris.push_back(tri);
    }
    if (tris.empty() || from.triangles.empty()) return 0.0;
    Tree tree(tris.begin(), tris.end());
    tree.accelerate_distance_queries();

    // Sample points: vertices (a random subset when there are many) and area-weighted points.
    std::mt19937_64 rng(seed);
    auto uniform = [&rng] { return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0); };
    std::vector<Vec3> pts;
    std::vector<char> used(from.positions.size(), 0);
    for (const Triangle& t : from.triangles)
      for (int v : t) used[v] = 1;
    std::vector<int> verts;
    for (std::size_t v = 0; v < used.size(); ++v)
      if (used[v]) verts.push_back(static_cast<int>(v));
    if (static_cast<int>(verts.size()) > samples) {
      for (int i = 0; i < samples; ++i) pts.push_back(from.positions[verts[rng() % verts.size()]]);
    } else {
      for (int v : verts) pts.push_back(from.positions[v]);
    }
    std::vector<double> cumulative;
    cumulative.reserve(from.triangles.size());
    double total = 0.0;
    for (const Triangle& t : from.triangles) {
      total += (from.positions[t[1]] - from.positions[t[0]]).cross(from.positions[t[2]] - from.positions[t[0]]).norm();
      cumulative.push_back(total);
    }
    if (total > 0.0)
      for (int i = 0; i < samples; ++i) {
        const double r = uniform() * total;
        const std::size_t f = std::min<std::size_t>(
            static_cast<std::size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), r) - cumulative.begin()),
            from.triangles.size() - 1);
        double u = uniform(), v = uniform();
        if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
        const Triangle& t = from.triangles[f];
        pts.push_back(from.positions[t[0]] + u * (from.positions[t[1]] - from.positions[t[0]]) +
                      v * (from.positions[t[2]] - from.positions[t[0]]));
      }
    std::vector<double> d2(pts.size(), 0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pts.size(), 512), [&](const auto& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i) d2[i] = tree.squared_distance(to_point(pts[i]));
    });
    return std::sqrt(d2.empty() ? 0.0 : *std::max_element(d2.begin(), d2.end()));
  };
  return one_sided(from_mesh, to_mesh);
}

double hausdorff_distance(const TriangleMesh& a, const TriangleMesh& b, int samples, std::uint64_t seed) {
  return std::max(one_sided_distance(a, b, samples, seed), one_sided_distance(b, a, samples, seed));
}

std::string face_key(std::array<Vec3, 3> c) {
  std::sort(c.begin(), c.end(), [](const Vec3& a, const Vec3& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  std::string k(sizeof(double) * 9, '\0');
  for (int i = 0; i < 3; ++i) std::memcpy(&k[sizeof(double) * 3 * i], c[i].data(), sizeof(double) * 3);
  return k;
}

bool same_faces(const TriangleMesh& a, const TriangleMesh& b) {
  if (a.triangles.size() != b.triangles.size()) return false;
  auto corners = [](const TriangleMesh& m, const Triangle& t) {
    return std::array<Vec3, 3>{m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
  };
  std::unordered_map<std::string, long> count;
  count.reserve(a.triangles.size());
  for (const Triangle& t : a.triangles) ++count[face_key(corners(a, t))];
  for (const Triangle& t : b.triangles) {
    auto it = count.find(face_key(corners(b, t)));
    if (it == count.end() || it->second == 0) return false;
    --it->second;
  }
  return true;
}

}  // namespace detail

MeshCensus census_of(const PolygonSoup& soup) {
  const WeldResult weld = weld_vertices(soup.points, 0.0);
  // Census of what is stored: polygons as fans, degenerate ones counted as faces too.
  TriangleMesh tri;
  tri.positions = soup.points;
  long faces = 0;
  for (const auto& polygon : soup.polygons) {
    ++faces;
    for (std::size_t k = 2; k < polygon.size(); ++k)
      tri.triangles.push_back(
          {weld.representative[polygon[0]], weld.representative[polygon[k - 1]], weld.representative[polygon[k]]});
  }
  // Triangles with repeated corners carry no topology; drop them from the counting only.
  tri.triangles.erase(std::remove_if(tri.triangles.begin(), tri.triangles.end(),
                                     [](const Triangle& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; }),
                      tri.triangles.end());
  MeshCensus c = detail::census_of_triangles(tri);
  c.faces = faces;
  return c;
}

std::string verify_genus0(const TriangleMesh& mesh) { return detail::verify_genus0(mesh, true); }

std::string detail::verify_genus0(const TriangleMesh& mesh, bool test_intersections) {
  if (mesh.triangles.empty()) return "the mesh has no faces";
  for (const Vec3& p : mesh.positions)
    if (!p.allFinite()) return "a vertex has a non-finite coordinate";
  const Topology topo = topology_of(mesh);
  if (topo.components != 1) return std::to_string(topo.components) + " connected components (need 1)";
  if (topo.boundary_edges > 0) return std::to_string(topo.boundary_edges) + " boundary edges (not closed)";
  if (topo.non_manifold_edges > 0) return std::to_string(topo.non_manifold_edges) + " non-manifold edges";
  if (topo.non_manifold_vertices > 0) return std::to_string(topo.non_manifold_vertices) + " non-manifold vertices";
  if (topo.misoriented_edges > 0) return std::to_string(topo.misoriented_edges) + " inconsistently oriented edges";
  const long euler = topo.vertices - topo.edges + static_cast<long>(mesh.triangles.size());
  if (euler != 2)
    return "Euler characteristic " + std::to_string(euler) + " (genus " + std::to_string((2 - euler) / 2) + ", need 0)";
  for (const Triangle& t : mesh.triangles)
    if (CGAL::collinear(to_point(mesh.positions[t[0]]), to_point(mesh.positions[t[1]]), to_point(mesh.positions[t[2]])))
      return "a face is degenerate (zero area)";
  if (test_intersections && count_self_intersections(mesh, true) > 0) return "the surface intersects itself";
  if (!(signed_volume(mesh) > 0.0)) return "the enclosed volume is not positive (inward orientation or flat)";
  return {};
}

}  // namespace fascicle
