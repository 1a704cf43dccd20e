#include "geometry/inject_defects.h"

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "geometry/splitmix64.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <set>
#include <unordered_map>
#include <utility>

namespace fascicle {

namespace {

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// Randomness with results that do not depend on the standard library's distributions.

using Rng = std::mt19937_64;

/// Uniform double in [0, 1) from the top 53 bits.
double uniform01(Rng& rng) { return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0); }

/// Integer in [0, n), n > 0 (modulo bias below 2^-40 for any mesh size; irrelevant here).
std::size_t below(Rng& rng, std::size_t n) { return static_cast<std::size_t>(rng() % n); }

Vec3 random_unit(Rng& rng) {
  for (;;) {
    const Vec3 v(2 * uniform01(rng) - 1, 2 * uniform01(rng) - 1, 2 * uniform01(rng) - 1);
    const double n2 = v.squaredNorm();
    if (n2 > 1e-6 && n2 <= 1.0) return v / std::sqrt(n2);
  }
}

/// `count` distinct values of [0, n) in draw order (partial Fisher-Yates).
std::vector<int> choose_distinct(Rng& rng, int n, int count) {
  std::vector<int> all(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) all[static_cast<std::size_t>(i)] = i;
  count = std::min(count, n);
  for (int i = 0; i < count; ++i) {
    const std::size_t j = static_cast<std::size_t>(i) + below(rng, static_cast<std::size_t>(n - i));
    std::swap(all[static_cast<std::size_t>(i)], all[j]);
  }
  all.resize(static_cast<std::size_t>(count));
  return all;
}

std::string fmt_double(double v) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6g", v);
  return buffer;
}

// ---------------------------------------------------------------------------------------------
// Plain adjacency by point index.

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

template <typename F>
void for_each_edge(const std::vector<int>& polygon, F&& f) {
  const std::size_t n = polygon.size();
  if (n < 2) return;
  for (std::size_t k = 0; k < n; ++k) {
    const int a = polygon[k], b = polygon[(k + 1) % n];
    if (a != b) f(a, b);
  }
}

struct Topology {
  explicit Topology(const PolygonSoup& soup) : vertex_faces(soup.points.size()) {
    for (std::size_t f = 0; f < soup.polygons.size(); ++f) {
      const int face = static_cast<int>(f);
      for_each_edge(soup.polygons[f], [&](int a, int b) { edge_faces[edge_key(a, b)].push_back(face); });
      for (int v : soup.polygons[f]) {
        auto& list = vertex_faces[static_cast<std::size_t>(v)];
        if (list.empty() || list.back() != face) list.push_back(face);
      }
    }
    for (auto& list : vertex_faces) list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  const std::vector<int>& faces_of_edge(int a, int b) const {
    static const std::vector<int> none;
    auto it = edge_faces.find(edge_key(a, b));
    return it == edge_faces.end() ? none : it->second;
  }
  std::unordered_map<std::uint64_t, std::vector<int>> edge_faces;  // lookups only, never iterated
  std::vector<std::vector<int>> vertex_faces;                      // ascending face indices
};

const Vec3& point(const PolygonSoup& soup, int v) { return soup.points[static_cast<std::size_t>(v)]; }

Vec3 centroid(const PolygonSoup& soup, int f) {
  Vec3 c = Vec3::Zero();
  const auto& polygon = soup.polygons[static_cast<std::size_t>(f)];
  for (int v : polygon) c += point(soup, v);
  return polygon.empty() ? c : Vec3(c / static_cast<double>(polygon.size()));
}

/// Newell's normal: twice the area times the unit normal for a planar polygon.
Vec3 newell_normal(const PolygonSoup& soup, int f) {
  Vec3 n = Vec3::Zero();
  const auto& polygon = soup.polygons[static_cast<std::size_t>(f)];
  for (std::size_t k = 0; k < polygon.size(); ++k) {
    const Vec3& p = point(soup, polygon[k]);
    const Vec3& q = point(soup, polygon[(k + 1) % polygon.size()]);
    n += p.cross(q);
  }
  return n;
}

Vec3 unit_or(const Vec3& v, const Vec3& fallback) {
  const double n = v.norm();
  return n > 0 && std::isfinite(n) ? Vec3(v / n) : fallback;
}

Vec3 vertex_normal(const PolygonSoup& soup, const Topology& topo, int v) {
  Vec3 n = Vec3::Zero();
  for (int f : topo.vertex_faces[static_cast<std::size_t>(v)]) n += newell_normal(soup, f);
  return unit_or(n, Vec3::UnitZ());
}

BoundingBox finite_box(const PolygonSoup& soup) {
  std::vector<Vec3> finite;
  finite.reserve(soup.points.size());
  for (const Vec3& p : soup.points)
    if (p.allFinite()) finite.push_back(p);
  return bounding_box(finite);
}

double scale_of(const PolygonSoup& soup) {
  const double d = finite_box(soup).diagonal();
  return d > 0 ? d : 1.0;
}

/// The link of `v` as one cycle in the direction of its faces, when the star of v is a disc whose
/// removal leaves a clean boundary loop: every face around v has v once and no repeated index,
/// the faces chain around v through edges used once in each direction, the link visits no vertex
/// twice, and each link edge lies in exactly two faces. Empty otherwise.
std::vector<int> disc_link(const PolygonSoup& soup, const Topology& topo, int v) {
  const auto& faces = topo.vertex_faces[static_cast<std::size_t>(v)];
  if (faces.size() < 3) return {};
  std::vector<std::vector<int>> paths;
  paths.reserve(faces.size());
  for (int f : faces) {
    const auto& polygon = soup.polygons[static_cast<std::size_t>(f)];
    const std::size_t n = polygon.size();
    if (n < 3) return {};
    std::vector<int> sorted = polygon;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return {};
    const std::size_t k = static_cast<std::size_t>(std::find(polygon.begin(), polygon.end(), v) - polygon.begin());
    std::vector<int> path;
    for (std::size_t i = 1; i < n; ++i) path.push_back(polygon[(k + i) % n]);
    paths.push_back(std::move(path));
  }
  std::vector<char> used(paths.size(), 0);
  std::vector<int> cycle = paths[0];
  used[0] = 1;
  for (std::size_t step = 1; step < paths.size(); ++step) {
    int next = -1;
    for (std::size_t i = 0; i < paths.size(); ++i)
      if (!used[i] && paths[i].front() == cycle.back()) {
        if (next >= 0) return {};
        next = static_cast<int>(i);
      }
    if (next < 0) return {};
    used[static_cast<std::size_t>(next)] = 1;
    cycle.insert(cycle.end(), paths[static_cast<std::size_t>(next)].begin() + 1,
                 paths[static_cast<std::size_t>(next)].end());
  }
  if (cycle.back() != cycle.front()) return {};
  cycle.pop_back();
  std::vector<int> sorted = cycle;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return {};
  for (std::size_t i = 0; i < cycle.size(); ++i) {
    if (topo.faces_of_edge(v, cycle[i]).size() != 2) return {};
    if (topo.faces_of_edge(cycle[i], cycle[(i + 1) % cycle.size()]).size() != 2) return {};
  }
  return cycle;
}

/// Vertices with a disc link, ascending, and their links.
struct DiscStars {
  std::vector<int> vertices;
  std::vector<std::vector<int>> links;  // indexed by vertex; empty when not a disc
};

DiscStars disc_stars(const PolygonSoup& soup, const Topology& topo) {
  DiscStars stars;
  stars.links.resize(soup.points.size());
  for (std::size_t v = 0; v < soup.points.size(); ++v) {
    if (!soup.points[v].allFinite()) continue;
    stars.links[v] = disc_link(soup, topo, static_cast<int>(v));
    if (!stars.links[v].empty()) stars.vertices.push_back(static_cast<int>(v));
  }
  return stars;
}

/// True when the closed stars of a and b (the vertex and its link) share no vertex.
bool stars_disjoint(const DiscStars& stars, int a, int b) {
  const auto& la = stars.links[static_cast<std::size_t>(a)];
  const auto& lb = stars.links[static_cast<std::size_t>(b)];
  auto in_a = [&](int x) { return x == a || std::find(la.begin(), la.end(), x) != la.end(); };
  if (in_a(b)) return false;
  for (int x : lb)
    if (in_a(x)) return false;
  return true;
}

/// A connected patch of up to `size` faces grown from `seed` across shared edges, nearest
/// centroids first (a geodesic-ball-like disc rather than a BFS layer with ragged ends).
std::vector<int> grow_patch(const PolygonSoup& soup, const Topology& topo, int seed, std::size_t size) {
  const Vec3 c0 = centroid(soup, seed);
  std::vector<char> seen(soup.polygons.size(), 0);
  std::set<std::pair<double, int>> frontier;
  frontier.emplace(0.0, seed);
  seen[static_cast<std::size_t>(seed)] = 1;
  std::vector<int> patch;
  while (patch.size() < size && !frontier.empty()) {
    const int f = frontier.begin()->second;
    frontier.erase(frontier.begin());
    patch.push_back(f);
    for_each_edge(soup.polygons[static_cast<std::size_t>(f)], [&](int a, int b) {
      for (int g : topo.faces_of_edge(a, b))
        if (!seen[static_cast<std::size_t>(g)]) {
          seen[static_cast<std::size_t>(g)] = 1;
          const double d = (centroid(soup, g) - c0).norm();
          frontier.emplace(std::isfinite(d) ? d : std::numeric_limits<double>::max(), g);
        }
    });
  }
  return patch;
}

/// Drops points no polygon references, keeping the order of the others.
void compact(PolygonSoup& soup) {
  std::vector<int> remap(soup.points.size(), -1);
  for (const auto& polygon : soup.polygons)
    for (int v : polygon) remap[static_cast<std::size_t>(v)] = 0;
  std::vector<Vec3> points;
  for (std::size_t v = 0; v < remap.size(); ++v)
    if (remap[v] == 0) {
      remap[v] = static_cast<int>(points.size());
      points.push_back(soup.points[v]);
    }
  for (auto& polygon : soup.polygons)
    for (int& v : polygon) v = remap[static_cast<std::size_t>(v)];
  soup.points = std::move(points);
}

void remove_faces(PolygonSoup& soup, const std::vector<int>& faces) {
  std::vector<char> gone(soup.polygons.size(), 0);
  for (int f : faces) gone[static_cast<std::size_t>(f)] = 1;
  std::vector<std::vector<int>> kept;
  kept.reserve(soup.polygons.size());
  for (std::size_t f = 0; f < soup.polygons.size(); ++f)
    if (!gone[f]) kept.push_back(std::move(soup.polygons[f]));
  soup.polygons = std::move(kept);
}

void append(PolygonSoup& soup, const TriangleMesh& mesh, const Vec3& shift) {
  const int base = static_cast<int>(soup.points.size());
  for (const Vec3& p : mesh.positions) soup.points.push_back(p + shift);
  for (const Triangle& t : mesh.triangles) soup.polygons.push_back({t[0] + base, t[1] + base, t[2] + base});
}

// Möller-Trumbore ray/triangle test; the parameter t of the hit or +inf.
double ray_triangle(const Vec3& origin, const Vec3& dir, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e1 = b - a, e2 = c - a;
  const Vec3 p = dir.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-300) return std::numeric_limits<double>::infinity();
  const double inv = 1.0 / det;
  const Vec3 s = origin - a;
  const double u = s.dot(p) * inv;
  if (u < 0 || u > 1) return std::numeric_limits<double>::infinity();
  const Vec3 q = s.cross(e1);
  const double w = dir.dot(q) * inv;
  if (w < 0 || u + w > 1) return std::numeric_limits<double>::infinity();
  const double t = e2.dot(q) * inv;
  return t > 0 ? t : std::numeric_limits<double>::infinity();
}

/// Calls f(a, b, c) for the fan triangles of every polygon except those marked in `skip`.
template <typename F>
void for_each_fan_triangle(const PolygonSoup& soup, const std::vector<char>& skip, F&& f) {
  for (std::size_t i = 0; i < soup.polygons.size(); ++i) {
    if (!skip.empty() && skip[i]) continue;
    const auto& polygon = soup.polygons[i];
    for (std::size_t k = 2; k < polygon.size(); ++k)
      f(point(soup, polygon[0]), point(soup, polygon[k - 1]), point(soup, polygon[k]));
  }
}

/// Nearest hit along a ray, ignoring marked faces; +inf when none.
double nearest_hit(const PolygonSoup& soup, const Vec3& origin, const Vec3& dir, const std::vector<char>& skip) {
  double best = std::numeric_limits<double>::infinity();
  for_each_fan_triangle(soup, skip, [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    best = std::min(best, ray_triangle(origin, dir, a, b, c));
  });
  return best;
}

/// Crossings of a ray with the surface (odd: inside a closed surface).
int crossings(const PolygonSoup& soup, const Vec3& origin, const Vec3& dir) {
  int n = 0;
  for_each_fan_triangle(soup, {}, [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    if (std::isfinite(ray_triangle(origin, dir, a, b, c))) ++n;
  });
  return n;
}

/// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double distance_to_surface(const PolygonSoup& soup, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for_each_fan_triangle(soup, {}, [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    best = std::min(best, (closest_on_triangle(p, a, b, c) - p).norm());
  });
  return best;
}

/// Indices of triangles (three distinct indices) in ascending order.
std::vector<int> proper_triangles(const PolygonSoup& soup) {
  std::vector<int> result;
  for (std::size_t f = 0; f < soup.polygons.size(); ++f) {
    const auto& p = soup.polygons[f];
    if (p.size() == 3 && p[0] != p[1] && p[1] != p[2] && p[0] != p[2]) result.push_back(static_cast<int>(f));
  }
  return result;
}

int share_count(double fraction, std::size_t n) {
  return static_cast<int>(std::max<double>(1.0, std::round(fraction * static_cast<double>(n))));
}

[[noreturn]] void no_place(DefectKind kind, const std::string& why) {
  throw TopologyError(std::string("cannot inject ") + defect_name(kind) + ": " + why);
}

// ---------------------------------------------------------------------------------------------
// The defects. Each takes the soup by reference and returns the record's count and note.

struct Outcome {
  int count = 0;
  std::string note;
};

std::size_t patch_size(const PolygonSoup& soup, const DefectParams& params) {
  return std::min<std::size_t>(static_cast<std::size_t>(params.patch_faces),
                               std::max<std::size_t>(1, soup.polygons.size() / 4));
}

Outcome make_holes(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  std::string sizes;
  for (int i = 0; i < params.count; ++i) {
    const std::size_t size = patch_size(soup, params);
    if (soup.polygons.size() <= size) no_place(DefectKind::holes, "too few faces left");
    const Topology topo(soup);
    const int seed = static_cast<int>(below(rng, soup.polygons.size()));
    const std::vector<int> patch = grow_patch(soup, topo, seed, size);
    remove_faces(soup, patch);
    sizes += (sizes.empty() ? "" : ", ") + std::to_string(patch.size());
  }
  compact(soup);
  return {params.count, std::to_string(params.count) + " hole(s) of " + sizes + " faces"};
}

Outcome make_flipped_patch(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  std::string sizes;
  for (int i = 0; i < params.count; ++i) {
    const Topology topo(soup);
    const int seed = static_cast<int>(below(rng, soup.polygons.size()));
    const std::vector<int> patch = grow_patch(soup, topo, seed, patch_size(soup, params));
    for (int f : patch)
      std::reverse(soup.polygons[static_cast<std::size_t>(f)].begin(),
                   soup.polygons[static_cast<std::size_t>(f)].end());
    sizes += (sizes.empty() ? "" : ", ") + std::to_string(patch.size());
  }
  return {params.count, std::to_string(params.count) + " patch(es) of " + sizes + " faces reversed"};
}

Outcome make_pinched_vertex(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  std::string note;
  for (int i = 0; i < params.count; ++i) {
    const Topology topo(soup);
    const DiscStars stars = disc_stars(soup, topo);
    if (stars.vertices.empty()) no_place(DefectKind::pinched_vertex, "no vertex with a disc-shaped star");
    std::vector<Vec3> normals(soup.points.size(), Vec3::Zero());
    for (int v : stars.vertices) normals[static_cast<std::size_t>(v)] = vertex_normal(soup, topo, v);
    // Partner of a: the nearest vertex on the opposite side (normals apart by more than 120
    // degrees) whose star is apart from a's, else the nearest such vertex on any side. Of a few
    // random candidates for a, the pair closest together wins: a thin part pinched shut.
    auto partner = [&](int a) {
      int best_opposite = -1, best_any = -1;
      double d_opposite = std::numeric_limits<double>::infinity(), d_any = d_opposite;
      for (int b : stars.vertices) {
        if (b == a || !stars_disjoint(stars, a, b)) continue;
        const double d = (point(soup, b) - point(soup, a)).norm();
        if (d < d_any) d_any = d, best_any = b;
        if (d < d_opposite && normals[static_cast<std::size_t>(b)].dot(normals[static_cast<std::size_t>(a)]) < -0.5)
          d_opposite = d, best_opposite = b;
      }
      return best_opposite >= 0 ? best_opposite : best_any;
    };
    int a = -1, b = -1;
    double closest = std::numeric_limits<double>::infinity();
    for (int attempt = 0; attempt < 16; ++attempt) {
      const int candidate = stars.vertices[below(rng, stars.vertices.size())];
      const int other = partner(candidate);
      if (other < 0) continue;
      const double d = (point(soup, other) - point(soup, candidate)).norm();
      if (d < closest) closest = d, a = candidate, b = other;
    }
    if (b < 0) no_place(DefectKind::pinched_vertex, "no second vertex whose star is apart from the first");
    const Vec3 middle = 0.5 * (point(soup, a) + point(soup, b));
    const double distance = (point(soup, b) - point(soup, a)).norm();
    soup.points[static_cast<std::size_t>(a)] = middle;
    for (int f : topo.vertex_faces[static_cast<std::size_t>(b)])
      for (int& v : soup.polygons[static_cast<std::size_t>(f)])
        if (v == b) v = a;
    note += (note.empty() ? "" : "; ") + std::string("glued two vertices ") + fmt_double(distance) +
            " apart at their midpoint";
    compact(soup);
  }
  return {params.count, note};
}

Outcome make_non_manifold_edge(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  const std::vector<int> triangles = proper_triangles(soup);
  for (int i = 0; i < params.count; ++i) {
    // Any polygon with an edge of two distinct points will do; triangles are tried first.
    int f = -1;
    if (!triangles.empty()) f = triangles[below(rng, triangles.size())];
    if (f < 0) no_place(DefectKind::non_manifold_edge, "no triangle to attach a fin to");
    const auto& polygon = soup.polygons[static_cast<std::size_t>(f)];
    const std::size_t k = below(rng, 3);
    const int a = polygon[k], b = polygon[(k + 1) % 3];
    const Vec3 n = unit_or(newell_normal(soup, f), Vec3::UnitZ());
    const double length = (point(soup, b) - point(soup, a)).norm();
    const Vec3 tip = 0.5 * (point(soup, a) + point(soup, b)) + 0.8 * length * n;
    soup.points.push_back(tip);
    soup.polygons.push_back({a, b, static_cast<int>(soup.points.size()) - 1});
  }
  return {params.count, std::to_string(params.count) + " fin triangle(s) on existing edges"};
}

// Joins two rings of point indices by a strip of triangles (a_i, a_i+1, b_j) / (a_i, b_j+1, b_j),
// advancing on whichever ring's next point has the smaller arc-length fraction. The strip uses
// ring A in its own direction and ring B reversed, so chained strips are consistently oriented.
void zip(PolygonSoup& soup, const std::vector<int>& A, const std::vector<int>& B) {
  auto fractions = [&](const std::vector<int>& r) {
    std::vector<double> t(r.size() + 1, 0.0);
    for (std::size_t i = 0; i < r.size(); ++i)
      t[i + 1] = t[i] + (point(soup, r[(i + 1) % r.size()]) - point(soup, r[i])).norm();
    const double total = t.back() > 0 ? t.back() : 1.0;
    for (double& x : t) x /= total;
    return t;
  };
  const std::vector<double> ta = fractions(A), tb = fractions(B);
  const std::size_t p = A.size(), q = B.size();
  std::size_t i = 0, j = 0;
  while (i < p || j < q) {
    const bool advance_a = j == q || (i < p && ta[i + 1] <= tb[j + 1]);
    if (advance_a) {
      soup.polygons.push_back({A[i % p], A[(i + 1) % p], B[j % q]});
      ++i;
    } else {
      soup.polygons.push_back({A[i % p], B[(j + 1) % q], B[j % q]});
      ++j;
    }
  }
}

Outcome make_handle(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  std::string note;
  for (int instance = 0; instance < params.count; ++instance) {
    const Topology topo(soup);
    const DiscStars stars = disc_stars(soup, topo);
    if (stars.vertices.empty()) no_place(DefectKind::handle, "no vertex with a disc-shaped star");
    const int v1 = stars.vertices[below(rng, stars.vertices.size())];
    // The far end: the disc-star vertex nearest to where the inward normal ray leaves the body,
    // so the tunnel runs inside (as when a segmentation joins two sides of a thin part); without
    // a hit, the vertex farthest from v1.
    const Vec3 n1 = vertex_normal(soup, topo, v1);
    std::vector<char> skip(soup.polygons.size(), 0);
    for (int f : topo.vertex_faces[static_cast<std::size_t>(v1)]) skip[static_cast<std::size_t>(f)] = 1;
    const double hit = nearest_hit(soup, point(soup, v1), -n1, skip);
    const Vec3 exit = point(soup, v1) - (std::isfinite(hit) ? hit : 0.0) * n1;
    int v2 = -1;
    double best_distance = std::numeric_limits<double>::infinity();
    for (int v : stars.vertices) {
      if (v == v1 || !stars_disjoint(stars, v1, v)) continue;
      const double d = std::isfinite(hit) ? (point(soup, v) - exit).norm() : -(point(soup, v) - exit).norm();
      if (d < best_distance) best_distance = d, v2 = v;
    }
    if (v2 < 0) no_place(DefectKind::handle, "no second vertex whose star is apart from the first");
    std::vector<int> ring1 = stars.links[static_cast<std::size_t>(v1)];
    std::vector<int> ring2 = stars.links[static_cast<std::size_t>(v2)];
    std::reverse(ring2.begin(), ring2.end());
    auto mean = [&](const std::vector<int>& r) {
      Vec3 c = Vec3::Zero();
      for (int v : r) c += point(soup, v);
      return Vec3(c / static_cast<double>(r.size()));
    };
    const Vec3 c1 = mean(ring1), c2 = mean(ring2);
    const Vec3 axis = c2 - c1;
    const double length = axis.norm();
    if (!(length > 0) || !std::isfinite(length)) no_place(DefectKind::handle, "the two stars coincide");
    // Frame (e1, e2, w), right-handed, w pointing from the far end back to ring 1.
    const Vec3 w = -axis / length;
    const Vec3 e1 = w.unitOrthogonal(), e2 = w.cross(e1);
    double winding = 0, radius1 = 0, radius2 = 0, edge = 0;
    for (std::size_t i = 0; i < ring1.size(); ++i) {
      const Vec3 p = point(soup, ring1[i]) - c1, q = point(soup, ring1[(i + 1) % ring1.size()]) - c1;
      winding += p.cross(q).dot(w);
      radius1 += (p - p.dot(w) * w).norm() / static_cast<double>(ring1.size());
      edge += (q - p).norm() / static_cast<double>(ring1.size());
    }
    for (int v : ring2) {
      const Vec3 p = point(soup, v) - c2;
      radius2 += (p - p.dot(w) * w).norm() / static_cast<double>(ring2.size());
    }
    const double sign = winding < 0 ? -1.0 : 1.0;
    // Start each boundary ring at the point closest in angle to e1, where the new rings start.
    auto align = [&](std::vector<int>& r, const Vec3& c) {
      std::size_t best = 0;
      double best_cos = -2;
      for (std::size_t i = 0; i < r.size(); ++i) {
        const Vec3 d = unit_or(point(soup, r[i]) - c, e1);
        if (d.dot(e1) > best_cos) best_cos = d.dot(e1), best = i;
      }
      std::rotate(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(best), r.end());
    };
    align(ring1, c1);
    align(ring2, c2);
    const int count = static_cast<int>(std::clamp(std::round(length / std::max(edge, 1e-300)), 1.0, 200.0));
    const int m = static_cast<int>(std::max(ring1.size(), ring2.size()));
    std::vector<std::vector<int>> rings{ring1};
    for (int k = 1; k <= count; ++k) {
      const double t = static_cast<double>(k) / (count + 1);
      const Vec3 center = c1 + t * axis;
      const double radius = (1 - t) * radius1 + t * radius2;
      std::vector<int> r;
      for (int j = 0; j < m; ++j) {
        const double angle = sign * 2 * kPi * j / m;
        soup.points.push_back(center + radius * (std::cos(angle) * e1 + std::sin(angle) * e2));
        r.push_back(static_cast<int>(soup.points.size()) - 1);
      }
      rings.push_back(std::move(r));
    }
    rings.push_back(ring2);
    std::vector<int> star = topo.vertex_faces[static_cast<std::size_t>(v1)];
    star.insert(star.end(), topo.vertex_faces[static_cast<std::size_t>(v2)].begin(),
                topo.vertex_faces[static_cast<std::size_t>(v2)].end());
    remove_faces(soup, star);
    for (std::size_t k = 0; k + 1 < rings.size(); ++k) zip(soup, rings[k], rings[k + 1]);
    compact(soup);
    note += (note.empty() ? "" : "; ") + std::string("tunnel of length ") + fmt_double(length) + " with " +
            std::to_string(count) + " rings of " + std::to_string(m) + " points";
  }
  return {params.count, note};
}

Outcome make_fold(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  std::string note;
  const double diagonal = scale_of(soup);
  for (int i = 0; i < params.count; ++i) {
    const Topology topo(soup);
    const DiscStars stars = disc_stars(soup, topo);
    if (stars.vertices.empty()) no_place(DefectKind::self_intersection_fold, "no vertex with a disc-shaped star");
    const int v = stars.vertices[below(rng, stars.vertices.size())];
    const Vec3 n = vertex_normal(soup, topo, v);
    std::vector<char> skip(soup.polygons.size(), 0);
    for (int f : topo.vertex_faces[static_cast<std::size_t>(v)]) skip[static_cast<std::size_t>(f)] = 1;
    const auto& link = stars.links[static_cast<std::size_t>(v)];
    double edge = 0;
    for (int x : link) edge += (point(soup, x) - point(soup, v)).norm() / static_cast<double>(link.size());
    const double hit = nearest_hit(soup, point(soup, v), -n, skip);
    const double push = std::isfinite(hit) ? hit + std::max(0.5 * hit, 2 * edge) : 0.5 * diagonal;
    soup.points[static_cast<std::size_t>(v)] -= push * n;
    note += (note.empty() ? "" : "; ") + std::string("vertex pushed ") + fmt_double(push) +
            (std::isfinite(hit) ? " inward through the opposite side at " + fmt_double(hit) : " inward");
  }
  return {params.count, note};
}

Outcome make_stray(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  for (int i = 0; i < params.count; ++i) {
    const BoundingBox box = finite_box(soup);
    const double diagonal = scale_of(soup);
    const double radius = 0.03 * diagonal;
    const Vec3 center = box.center() + (0.6 * diagonal + radius) * random_unit(rng);
    append(soup, make_icosphere(1, radius), center);
  }
  return {params.count, std::to_string(params.count) + " sphere(s) of 80 faces outside the bounding sphere"};
}

Outcome make_inner_shell(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  std::string note;
  for (int i = 0; i < params.count; ++i) {
    // Best of a few tries: halfway along the inward normal of a random face to the next surface
    // hit, kept when a parity test says the point is inside; radius half the clearance.
    const std::vector<int> triangles = proper_triangles(soup);
    if (triangles.empty()) no_place(DefectKind::inner_shell, "no triangles");
    Vec3 best_center = Vec3::Zero();
    double best_radius = 0;
    for (int attempt = 0; attempt < 16; ++attempt) {
      const int f = triangles[below(rng, triangles.size())];
      const Vec3 n = unit_or(newell_normal(soup, f), Vec3::Zero());
      if (n.isZero()) continue;
      std::vector<char> skip(soup.polygons.size(), 0);
      skip[static_cast<std::size_t>(f)] = 1;
      const Vec3 c = centroid(soup, f);
      const double hit = nearest_hit(soup, c, -n, skip);
      if (!std::isfinite(hit)) continue;
      const Vec3 p = c - 0.5 * hit * n;
      if (crossings(soup, p, random_unit(rng)) % 2 == 0) continue;
      const double radius = 0.5 * distance_to_surface(soup, p);
      if (radius > best_radius) best_radius = radius, best_center = p;
    }
    if (!(best_radius > 0)) no_place(DefectKind::inner_shell, "found no point inside the surface");
    append(soup, make_icosphere(1, best_radius), best_center);
    note += (note.empty() ? "" : "; ") + std::string("sphere of radius ") + fmt_double(best_radius) + " inside";
  }
  return {params.count, note};
}

Outcome make_outer_shell(PolygonSoup& soup, const DefectParams& params) {
  for (int i = 0; i < params.count; ++i) {
    const BoundingBox box = finite_box(soup);
    // Every point lies within half the diagonal of the box centre; the level-2 icosphere's
    // faces stay above 0.98 of its radius, so 1.25 leaves a clear gap.
    append(soup, make_icosphere(2, 0.5 * 1.25 * scale_of(soup)), box.center());
  }
  return {params.count, std::to_string(params.count) + " sphere(s) of 320 faces enclosing the mesh"};
}

// Splits triangle f = (a, b, c) at point p inside it into (a, b, p), (b, c, p), (c, a, p): closed
// and consistently oriented if the input was.
void split_at(PolygonSoup& soup, int f, const Vec3& p) {
  const std::vector<int> t = soup.polygons[static_cast<std::size_t>(f)];
  soup.points.push_back(p);
  const int q = static_cast<int>(soup.points.size()) - 1;
  soup.polygons[static_cast<std::size_t>(f)] = {t[0], t[1], q};
  soup.polygons.push_back({t[1], t[2], q});
  soup.polygons.push_back({t[2], t[0], q});
}

Outcome make_slivers(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  const std::vector<int> triangles = proper_triangles(soup);
  if (triangles.empty()) no_place(DefectKind::slivers, "no triangles");
  const int count = share_count(params.fraction, triangles.size());
  const std::vector<int> chosen = choose_distinct(rng, static_cast<int>(triangles.size()), count);
  int caps = 0, needles = 0;
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    const int f = triangles[static_cast<std::size_t>(chosen[i])];
    const auto& t = soup.polygons[static_cast<std::size_t>(f)];
    const Vec3 a = point(soup, t[0]), b = point(soup, t[1]), c = point(soup, t[2]);
    if (i % 2 == 0) {  // cap: a point just off the middle of bc makes (b, c, p) nearly flat
      const Vec3 m = 0.5 * (b + c);
      split_at(soup, f, m + 1e-3 * (a - m));
      ++caps;
    } else {  // needles: a point next to b makes (a, b, p) and (b, c, p) long and thin
      split_at(soup, f, b + 1e-3 * ((a + b + c) / 3.0 - b));
      ++needles;
    }
  }
  return {static_cast<int>(chosen.size()), std::to_string(chosen.size()) + " triangles split into slivers (" +
                                               std::to_string(caps) + " caps, " + std::to_string(needles) +
                                               " needle pairs)"};
}

Outcome make_zero_area(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  const std::vector<int> triangles = proper_triangles(soup);
  if (triangles.empty()) no_place(DefectKind::zero_area_faces, "no triangles");
  const int count = share_count(params.fraction, triangles.size());
  const std::vector<int> chosen = choose_distinct(rng, static_cast<int>(triangles.size()), count);
  for (int index : chosen) {
    const int f = triangles[static_cast<std::size_t>(index)];
    const auto& t = soup.polygons[static_cast<std::size_t>(f)];
    // The midpoint of bc makes (b, c, p) collinear: zero area up to rounding.
    split_at(soup, f, 0.5 * (point(soup, t[1]) + point(soup, t[2])));
  }
  return {static_cast<int>(chosen.size()),
          std::to_string(chosen.size()) + " triangles split at an edge midpoint (one collinear part each)"};
}

Outcome make_duplicates(PolygonSoup& soup, Rng& rng, const DefectParams& params, bool near) {
  const Topology topo(soup);
  std::vector<int> referenced;
  for (std::size_t v = 0; v < soup.points.size(); ++v)
    if (!topo.vertex_faces[v].empty()) referenced.push_back(static_cast<int>(v));
  if (referenced.empty())
    no_place(near ? DefectKind::near_duplicate_vertices : DefectKind::duplicate_vertices, "no referenced vertex");
  const int count = share_count(params.fraction, referenced.size());
  const double distance = near ? params.near_distance * scale_of(soup) : 0.0;
  const std::vector<int> chosen = choose_distinct(rng, static_cast<int>(referenced.size()), count);
  int rereferenced = 0;
  for (int index : chosen) {
    const int v = referenced[static_cast<std::size_t>(index)];
    Vec3 copy = point(soup, v);
    if (near) copy += distance * random_unit(rng);
    soup.points.push_back(copy);
    const int c = static_cast<int>(soup.points.size()) - 1;
    const auto& faces = topo.vertex_faces[static_cast<std::size_t>(v)];
    std::vector<int> moved;
    for (int f : faces)
      if (rng() & 1) moved.push_back(f);
    if (moved.empty()) moved.push_back(faces.front());
    for (int f : moved)
      for (int& x : soup.polygons[static_cast<std::size_t>(f)])
        if (x == v) x = c;
    rereferenced += static_cast<int>(moved.size());
  }
  std::string note = std::to_string(chosen.size()) + " vertices copied" +
                     (near ? " " + fmt_double(distance) + " away" : " exactly") + ", " + std::to_string(rereferenced) +
                     " face references moved to the copies";
  return {static_cast<int>(chosen.size()), note};
}

Outcome make_nan(PolygonSoup& soup, Rng& rng, const DefectParams& params) {
  const Topology topo(soup);
  std::vector<int> referenced;
  for (std::size_t v = 0; v < soup.points.size(); ++v)
    if (!topo.vertex_faces[v].empty()) referenced.push_back(static_cast<int>(v));
  if (referenced.empty()) no_place(DefectKind::nan_coordinates, "no referenced vertex");
  for (int i = 0; i < params.count; ++i) {
    const int v = referenced[below(rng, referenced.size())];
    soup.points[static_cast<std::size_t>(v)][static_cast<Eigen::Index>(below(rng, 3))] =
        std::numeric_limits<double>::quiet_NaN();
  }
  return {params.count, std::to_string(params.count) + " coordinate(s) set to NaN"};
}

const char* const kNames[] = {"holes",
                              "flipped_patch",
                              "pinched_vertex",
                              "non_manifold_edge",
                              "handle",
                              "self_intersection_fold",
                              "stray_component",
                              "inner_shell",
                              "outer_shell",
                              "slivers",
                              "zero_area_faces",
                              "duplicate_vertices",
                              "near_duplicate_vertices",
                              "scale",
                              "offset",
                              "nan_coordinates"};
constexpr int kKindCount = static_cast<int>(sizeof(kNames) / sizeof(kNames[0]));
static_assert(kKindCount == static_cast<int>(DefectKind::nan_coordinates) + 1, "one name per kind");

}  // namespace

const char* defect_name(DefectKind kind) {
  const int i = static_cast<int>(kind);
  FASCICLE_CHECK(i >= 0 && i < kKindCount, "defect kind out of range");
  return kNames[i];
}

DefectKind defect_kind_from_name(const std::string& name) {
  std::string valid;
  for (int i = 0; i < kKindCount; ++i) {
    if (name == kNames[i]) return static_cast<DefectKind>(i);
    valid += (i ? ", " : "") + std::string(kNames[i]);
  }
  throw OptionError("unknown defect kind '" + name + "' (valid: " + valid + ")");
}

std::vector<DefectKind> all_defect_kinds() {
  std::vector<DefectKind> kinds;
  for (int i = 0; i < kKindCount; ++i) kinds.push_back(static_cast<DefectKind>(i));
  return kinds;
}

void DefectParams::validate() const {
  if (count < 1 || count > 1000000)
    throw OptionError("defect count = " + std::to_string(count) + " is invalid: must be in [1, 1e6]");
  if (patch_faces < 1 || patch_faces > 10000000)
    throw OptionError("defect patch_faces = " + std::to_string(patch_faces) + " is invalid: must be in [1, 1e7]");
  if (!(fraction > 0 && fraction <= 1))
    throw OptionError("defect fraction = " + fmt_double(fraction) + " is invalid: must be in (0, 1]");
  if (!(near_distance > 0 && near_distance <= 1e-2))
    throw OptionError("defect near_distance = " + fmt_double(near_distance) + " is invalid: must be in (0, 0.01]");
  if (!(std::isfinite(scale_factor) && scale_factor > 0))
    throw OptionError("defect scale_factor = " + fmt_double(scale_factor) + " is invalid: must be finite and positive");
  if (!offset.allFinite()) throw OptionError("defect offset is invalid: must be finite");
}

PolygonSoup inject(const PolygonSoup& mesh, DefectKind kind, std::uint64_t seed, const DefectParams& params,
                   DefectLog* log) {
  params.validate();
  defect_name(kind);  // range check
  if (mesh.polygons.empty()) no_place(kind, "the mesh has no faces");
  for (const auto& polygon : mesh.polygons)
    for (int v : polygon)
      FASCICLE_CHECK(v >= 0 && static_cast<std::size_t>(v) < mesh.points.size(), "polygon index out of range");
  PolygonSoup soup = mesh;
  Rng rng(seed);
  Outcome outcome;
  switch (kind) {
    case DefectKind::holes: outcome = make_holes(soup, rng, params); break;
    case DefectKind::flipped_patch: outcome = make_flipped_patch(soup, rng, params); break;
    case DefectKind::pinched_vertex: outcome = make_pinched_vertex(soup, rng, params); break;
    case DefectKind::non_manifold_edge: outcome = make_non_manifold_edge(soup, rng, params); break;
    case DefectKind::handle: outcome = make_handle(soup, rng, params); break;
    case DefectKind::self_intersection_fold: outcome = make_fold(soup, rng, params); break;
    case DefectKind::stray_component: outcome = make_stray(soup, rng, params); break;
    case DefectKind::inner_shell: outcome = make_inner_shell(soup, rng, params); break;
    case DefectKind::outer_shell: outcome = make_outer_shell(soup, params); break;
    case DefectKind::slivers: outcome = make_slivers(soup, rng, params); break;
    case DefectKind::zero_area_faces: outcome = make_zero_area(soup, rng, params); break;
    case DefectKind::duplicate_vertices: outcome = make_duplicates(soup, rng, params, false); break;
    case DefectKind::near_duplicate_vertices: outcome = make_duplicates(soup, rng, params, true); break;
    case DefectKind::scale:
      for (Vec3& p : soup.points) p *= params.scale_factor;
      outcome = {1, "coordinates multiplied by " + fmt_double(params.scale_factor)};
      break;
    case DefectKind::offset:
      for (Vec3& p : soup.points) p += params.offset;
      outcome = {1, "translated by (" + fmt_double(params.offset.x()) + ", " + fmt_double(params.offset.y()) + ", " +
                        fmt_double(params.offset.z()) + ")"};
      break;
    case DefectKind::nan_coordinates: outcome = make_nan(soup, rng, params); break;
  }
  if (log) log->records.push_back({kind, outcome.count, outcome.note});
  return soup;
}

PolygonSoup inject(const TriangleMesh& mesh, DefectKind kind, std::uint64_t seed, const DefectParams& params,
                   DefectLog* log) {
  return inject(to_soup(mesh), kind, seed, params, log);
}

PolygonSoup inject_random_combination(const PolygonSoup& mesh, std::uint64_t seed, int count, DefectLog* log) {
  const int pool = kKindCount - 1;  // every kind but nan_coordinates, the last
  if (count < 0 || count > pool)
    throw OptionError("random defect count = " + std::to_string(count) + " is invalid: must be in [0, " +
                      std::to_string(pool) + "]");
  Rng rng(seed);
  std::vector<int> chosen = choose_distinct(rng, pool, count);
  std::sort(chosen.begin(), chosen.end());
  PolygonSoup soup = mesh;
  for (std::size_t i = 0; i < chosen.size(); ++i)
    soup = inject(soup, static_cast<DefectKind>(chosen[i]), derive_seed(seed, 1 + i), DefectParams{}, log);
  return soup;
}

PolygonSoup inject_random_combination(const TriangleMesh& mesh, std::uint64_t seed, int count, DefectLog* log) {
  return inject_random_combination(to_soup(mesh), seed, count, log);
}

std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t step) {
  // SplitMix64 applied twice: once to the seed, once with the step.
  return splitmix64(splitmix64(seed) ^ step);
}

TriangleMesh soup_triangles(const PolygonSoup& soup) {
  TriangleMesh mesh;
  mesh.positions = soup.points;
  mesh.triangles.reserve(soup.polygons.size());
  for (std::size_t f = 0; f < soup.polygons.size(); ++f) {
    const auto& p = soup.polygons[f];
    if (p.size() != 3)
      throw TopologyError("polygon " + std::to_string(f) + " has " + std::to_string(p.size()) + " corners, not 3");
    mesh.triangles.push_back({p[0], p[1], p[2]});
  }
  return mesh;
}

}  // namespace fascicle
