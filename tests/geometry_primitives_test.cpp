// Test shapes: closed, consistently outward, right genus, right volume.

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <functional>
#include <cmath>
#include <map>
#include <numeric>
#include <utility>

using namespace fascicle;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Counts over undirected edges: how many faces use each, and whether two users traverse it in
// opposite directions (consistent orientation).
struct EdgeCounts {
  int boundary = 0;      // used by one face
  int manifold = 0;      // used by two faces
  int non_manifold = 0;  // used by three or more
  int inconsistent = 0;  // two users traversing it the same way
};

EdgeCounts count_edges(const std::vector<std::vector<int>>& polygons) {
  std::map<std::pair<int, int>, std::pair<int, int>> uses;  // (min, max) -> (forward, backward)
  for (const auto& p : polygons)
    for (std::size_t k = 0; k < p.size(); ++k) {
      const int a = p[k], b = p[(k + 1) % p.size()];
      if (a < b)
        ++uses[{a, b}].first;
      else
        ++uses[{b, a}].second;
    }
  EdgeCounts c;
  for (const auto& [edge, u] : uses) {
    const int n = u.first + u.second;
    if (n == 1)
      ++c.boundary;
    else if (n == 2) {
      ++c.manifold;
      if (u.first != 1) ++c.inconsistent;
    } else
      ++c.non_manifold;
  }
  return c;
}

std::vector<std::vector<int>> polygons_of(const TriangleMesh& m) {
  std::vector<std::vector<int>> p;
  for (const auto& t : m.triangles) p.push_back({t[0], t[1], t[2]});
  return p;
}

// Number of face fans around vertex v: faces containing v, joined when they share an edge at v.
int fans_at(const std::vector<std::vector<int>>& polygons, int v) {
  std::vector<int> faces;
  for (std::size_t f = 0; f < polygons.size(); ++f)
    if (std::find(polygons[f].begin(), polygons[f].end(), v) != polygons[f].end()) faces.push_back(static_cast<int>(f));
  std::vector<int> parent(faces.size());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int i) { return parent[i] == i ? i : parent[i] = find(parent[i]); };
  auto neighbours = [&](int f) {
    std::vector<int> n;
    const auto& p = polygons[static_cast<std::size_t>(f)];
    for (std::size_t k = 0; k < p.size(); ++k)
      if (p[k] == v) {
        n.push_back(p[(k + 1) % p.size()]);
        n.push_back(p[(k + p.size() - 1) % p.size()]);
      }
    return n;
  };
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (std::size_t j = i + 1; j < faces.size(); ++j) {
      const auto a = neighbours(faces[i]), b = neighbours(faces[j]);
      for (int x : a)
        if (std::find(b.begin(), b.end(), x) != b.end()) parent[find(static_cast<int>(i))] = find(static_cast<int>(j));
    }
  int fans = 0;
  for (std::size_t i = 0; i < faces.size(); ++i) fans += find(static_cast<int>(i)) == static_cast<int>(i);
  return fans;
}

// Every property a clean primitive promises, checked together.
void check_clean_closed(const TriangleMesh& m, long euler) {
  const EdgeCounts e = count_edges(polygons_of(m));
  CHECK(e.boundary == 0);
  CHECK(e.non_manifold == 0);
  CHECK(e.inconsistent == 0);
  CHECK(e.manifold > 0);
  CHECK(euler_characteristic(m) == euler);
  CHECK(signed_volume(m) > 0);
  // No duplicate points, every point used, no degenerate triangle.
  std::vector<std::array<double, 3>> sorted;
  for (const Vec3& p : m.positions) sorted.push_back({p.x(), p.y(), p.z()});
  std::sort(sorted.begin(), sorted.end());
  CHECK(std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end());
  std::vector<char> used(m.positions.size(), 0);
  double min_area = 1e300;
  for (const auto& t : m.triangles) {
    for (int v : t) used[static_cast<std::size_t>(v)] = 1;
    const Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    min_area = std::min(min_area, 0.5 * (b - a).cross(c - a).norm());
  }
  CHECK(std::count(used.begin(), used.end(), 0) == 0);
  CHECK(min_area > 1e-12 * std::pow(bounding_box(m.positions).diagonal(), 2));
}

}  // namespace

TEST_CASE("tetrahedron is a closed outward unit corner tetrahedron", "[geometry][primitives]") {
  const TriangleMesh m = make_tetrahedron(2.0);
  REQUIRE(m.positions.size() == 4);
  REQUIRE(m.triangles.size() == 4);
  check_clean_closed(m, 2);
  CHECK(signed_volume(m) == Approx(8.0 / 6.0));
}

TEST_CASE("subdivided cube: counts, exact volume, closed", "[geometry][primitives]") {
  for (int n : {1, 2, 5}) {
    INFO("per edge " << n);
    const TriangleMesh m = make_cube(3.0, n);
    CHECK(m.positions.size() == static_cast<std::size_t>(6 * n * n + 2));
    CHECK(m.triangles.size() == static_cast<std::size_t>(12 * n * n));
    check_clean_closed(m, 2);
    CHECK(signed_volume(m) == Approx(27.0).epsilon(1e-12));
    const BoundingBox box = bounding_box(m.positions);
    CHECK(box.min.isApprox(Vec3::Constant(-1.5)));
    CHECK(box.max.isApprox(Vec3::Constant(1.5)));
  }
}

TEST_CASE("icosphere: counts, points on the sphere, volume converges from below", "[geometry][primitives]") {
  double previous = 0;
  const double sphere = 4.0 / 3.0 * kPi * 8.0;
  for (int k = 0; k <= 4; ++k) {
    INFO("subdivisions " << k);
    const TriangleMesh m = make_icosphere(k, 2.0);
    const std::size_t faces = 20u << (2 * k);
    CHECK(m.triangles.size() == faces);
    CHECK(m.positions.size() == faces / 2 + 2);
    check_clean_closed(m, 2);
    for (const Vec3& p : m.positions) CHECK(p.norm() == Approx(2.0).epsilon(1e-12));
    const double v = signed_volume(m);
    CHECK(v < sphere);
    CHECK(v > previous);
    previous = v;
    if (k >= 3) CHECK(v == Approx(sphere).epsilon(0.01));
  }
}

TEST_CASE("capsule with aspect 50:1 is closed and has the analytic volume", "[geometry][primitives]") {
  const double length = 100.0, radius = 1.0;
  const TriangleMesh m = make_capsule(length, radius, 32);
  check_clean_closed(m, 2);
  const double analytic = kPi * radius * radius * (length - 2 * radius) + 4.0 / 3.0 * kPi * radius * radius * radius;
  CHECK(signed_volume(m) < analytic);
  CHECK(signed_volume(m) == Approx(analytic).epsilon(0.02));
  const BoundingBox box = bounding_box(m.positions);
  CHECK(box.min.x() == Approx(-50.0));
  CHECK(box.max.x() == Approx(50.0));
  CHECK(box.max.y() == Approx(1.0));
  // Quads along the cylinder stay near square: the longest edge is at most twice the ring edge.
  double longest = 0;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) longest = std::max(longest, (m.positions[t[k]] - m.positions[t[(k + 1) % 3]]).norm());
  CHECK(longest < 2.0 * 2 * kPi * radius / 32 * std::sqrt(2.0));
  // Length exactly twice the radius: a sphere.
  const TriangleMesh ball = make_capsule(2.0, 1.0, 24);
  check_clean_closed(ball, 2);
  CHECK(signed_volume(ball) == Approx(4.0 / 3.0 * kPi).epsilon(0.05));
}

TEST_CASE("bent tube is closed genus 0 with Pappus volume", "[geometry][primitives]") {
  const double R = 30, r = 5, angle = 2 * kPi / 3;
  const TriangleMesh m = make_bent_tube(R, r, angle, 32);
  check_clean_closed(m, 2);
  CHECK(signed_volume(m) == Approx(kPi * r * r * R * angle).epsilon(0.02));
  const TriangleMesh almost_ring = make_bent_tube(R, r, 1.9 * kPi, 16, 40);
  check_clean_closed(almost_ring, 2);
}

TEST_CASE("torus is closed with Euler characteristic 0", "[geometry][primitives]") {
  const TriangleMesh m = make_torus(20, 5, 64, 32);
  check_clean_closed(m, 0);
  CHECK(signed_volume(m) == Approx(2 * kPi * kPi * 20 * 25).epsilon(0.02));
}

TEST_CASE("two tetrahedra sharing a vertex: one non-manifold vertex, edges fine", "[geometry][primitives]") {
  const PolygonSoup soup = make_two_tetrahedra_sharing_vertex();
  REQUIRE(soup.points.size() == 7);
  REQUIRE(soup.polygons.size() == 8);
  const EdgeCounts e = count_edges(soup.polygons);
  CHECK(e.boundary == 0);
  CHECK(e.non_manifold == 0);
  CHECK(e.inconsistent == 0);
  CHECK(fans_at(soup.polygons, 0) == 2);
  for (int v = 1; v < 7; ++v) CHECK(fans_at(soup.polygons, v) == 1);
  // Each tetrahedron is outward on its own.
  for (int half = 0; half < 2; ++half) {
    TriangleMesh tet;
    tet.positions = soup.points;
    for (int f = 4 * half; f < 4 * half + 4; ++f)
      tet.triangles.push_back({soup.polygons[f][0], soup.polygons[f][1], soup.polygons[f][2]});
    CHECK(signed_volume(tet) == Approx(1.0 / 6.0));
  }
}

TEST_CASE("closed tube is outward whichever way the rings wind", "[geometry][primitives]") {
  std::vector<std::vector<Vec3>> rings;
  for (int i = 0; i < 5; ++i) {
    std::vector<Vec3> ring;
    for (int j = 0; j < 6; ++j) ring.emplace_back(i + 1.0, std::cos(2 * kPi * j / 6), std::sin(2 * kPi * j / 6));
    rings.push_back(ring);
  }
  const TriangleMesh forward = make_closed_tube(rings, Vec3(0, 0, 0), Vec3(6, 0, 0));
  for (auto& ring : rings) std::reverse(ring.begin(), ring.end());
  const TriangleMesh backward = make_closed_tube(rings, Vec3(0, 0, 0), Vec3(6, 0, 0));
  check_clean_closed(forward, 2);
  check_clean_closed(backward, 2);
  CHECK(signed_volume(forward) == Approx(signed_volume(backward)));
  CHECK(forward.triangles.size() == 2 * 5 * 6);
}

TEST_CASE("primitives reject invalid sizes with OptionError", "[geometry][primitives]") {
  CHECK_THROWS_AS(make_tetrahedron(0.0), OptionError);
  CHECK_THROWS_AS(make_cube(1.0, 0), OptionError);
  CHECK_THROWS_AS(make_cube(-1.0, 2), OptionError);
  CHECK_THROWS_AS(make_icosphere(9), OptionError);
  CHECK_THROWS_AS(make_icosphere(2, std::nan("")), OptionError);
  CHECK_THROWS_AS(make_capsule(1.0, 1.0), OptionError);
  CHECK_THROWS_AS(make_capsule(10.0, 1.0, 2), OptionError);
  CHECK_THROWS_AS(make_bent_tube(5, 5, 1.0), OptionError);
  CHECK_THROWS_AS(make_bent_tube(10, 1, 2 * kPi), OptionError);
  CHECK_THROWS_AS(make_torus(1, 2), OptionError);
  CHECK_THROWS_AS(make_closed_tube({}, Vec3::Zero(), Vec3::Zero()), OptionError);
  CHECK_THROWS_AS(make_closed_tube({{Vec3::Zero(), Vec3::UnitX()}}, Vec3::Zero(), Vec3::Zero()), OptionError);
}
