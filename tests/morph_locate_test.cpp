// Point location on a sphere map: vertices, edges, face interiors, round trips, inside tests.
#include "geometry/mesh_stats.h"
#include "morph/inside_grid.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "morph/surface_query.h"
#include "tests/morph_test_shapes.h"

#include <catch2/catch.hpp>

#include <random>

using namespace fascicle;

namespace {

/// Faces whose spherical triangle holds p (brute force, doubles; for checking only).
std::vector<int> faces_holding(const std::vector<Vec3>& s, const std::vector<Triangle>& tris, const Vec3& p) {
  std::vector<int> out;
  for (std::size_t f = 0; f < tris.size(); ++f) {
    const Triangle& t = tris[f];
    if (s[t[0]].cross(s[t[1]]).dot(p) >= -1e-14 && s[t[1]].cross(s[t[2]]).dot(p) >= -1e-14 &&
        s[t[2]].cross(s[t[0]]).dot(p) >= -1e-14)
      out.push_back(static_cast<int>(f));
  }
  return out;
}

std::vector<Vec3> random_directions(int n, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> gauss;
  std::vector<Vec3> out;
  for (int i = 0; i < n; ++i) out.push_back(Vec3(gauss(random), gauss(random), gauss(random)).normalized());
  return out;
}

}  // namespace

TEST_CASE("locating a vertex gives barycentric 1 at that vertex", "[morph][locate]") {
  const TriangleMesh mesh = test::icosphere(2);
  const SphereMap map = map_to_sphere(mesh);
  const SphereLocator locator(map.positions, mesh.triangles);
  for (int v = 0; v < static_cast<int>(mesh.positions.size()); ++v) {
    const SurfacePoint hit = locator.locate(map.positions[v]);
    const Triangle& t = mesh.triangles[hit.face];
    int corner = -1;
    for (int k = 0; k < 3; ++k)
      if (t[k] == v) corner = k;
    REQUIRE(corner >= 0);
    CHECK(hit.barycentric[corner] == Approx(1.0).margin(1e-12));
    // Consistent: the smallest face index around the vertex.
    int smallest = static_cast<int>(mesh.triangles.size());
    for (int f = 0; f < static_cast<int>(mesh.triangles.size()); ++f)
      for (int k = 0; k < 3; ++k)
        if (mesh.triangles[f][k] == v) smallest = std::min(smallest, f);
    CHECK(hit.face == smallest);
    CHECK((point_on_mesh(mesh, hit) - mesh.positions[v]).norm() < 1e-12);
  }
}

TEST_CASE("locating an edge point is consistent and has a zero coordinate", "[morph][locate]") {
  const TriangleMesh mesh = test::subdivided_cube(3);
  const SphereMap map = map_to_sphere(mesh);
  const SphereLocator locator(map.positions, mesh.triangles);
  int checked = 0;
  for (const Triangle& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const Vec3 p = (map.positions[t[k]] + map.positions[t[(k + 1) % 3]]).normalized();
      const SurfacePoint hit = locator.locate(p);
      const std::vector<int> holders = faces_holding(map.positions, mesh.triangles, p);
      REQUIRE_FALSE(holders.empty());
      // The located face holds p, and the answer is the same from either side.
      CHECK(std::find(holders.begin(), holders.end(), hit.face) != holders.end());
      CHECK(locator.locate(p).face == hit.face);
      CHECK(hit.barycentric.minCoeff() < 1e-9);
      ++checked;
    }
  CHECK(checked == 3 * static_cast<int>(mesh.triangles.size()));
}

TEST_CASE("locating face interiors agrees with brute force", "[morph][locate]") {
  const TriangleMesh mesh = test::capsule(1.0, 20.0, 12);
  const SphereMap map = map_to_sphere(mesh);
  REQUIRE(map.report.quality.bijective());
  const SphereLocator locator(map.positions, mesh.triangles);
  const std::vector<Vec3> points = random_directions(500, 7);
  const std::vector<SurfacePoint> hits = locator.locate_all(points);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::vector<int> holders = faces_holding(map.positions, mesh.triangles, points[i]);
    REQUIRE(holders.size() >= 1);
    CHECK(std::find(holders.begin(), holders.end(), hits[i].face) != holders.end());
    CHECK(hits[i].barycentric.sum() == Approx(1.0));
    CHECK(hits[i].barycentric.minCoeff() >= 0.0);
    // The chord hit point lies on the ray through the direction.
    CHECK(hits[i].position.normalized().dot(points[i]) == Approx(1.0).epsilon(1e-12));
    CHECK(locator.locate(points[i]).face == hits[i].face);
  }
  CHECK_THROWS_AS(locator.locate(Vec3::Zero()), std::invalid_argument);
}

TEST_CASE("sphere -> muscle -> sphere round trip", "[morph][locate]") {
  const TriangleMesh mesh = test::bent_capsule(1.0, 15.0, 16, 120.0);
  const SphereMap map = map_to_sphere(mesh);
  REQUIRE(map.report.quality.bijective());
  const SphereLocator locator(map.positions, mesh.triangles);
  const SurfaceQuery muscle(mesh);
  for (const Vec3& p : random_directions(300, 11)) {
    const SurfacePoint on_sphere = locator.locate(p);
    const Vec3 q = point_on_mesh(mesh, on_sphere);
    const SurfacePoint back = muscle.closest_point(q);
    CHECK(back.distance < 1e-9);
    const Vec3 again = point_on_sphere(map.positions, mesh.triangles, back);
    CHECK((again - p).norm() < 1e-6);
  }
}

TEST_CASE("inside test on a closed mesh", "[morph][locate]") {
  const TriangleMesh mesh = test::bent_capsule(1.0, 15.0, 16, 120.0);
  const SurfaceQuery query(mesh);
  // Points on the bent centre line are inside; points far off are outside; a vertex is on the
  // boundary.
  const double bend = 15.0 / (120.0 * M_PI / 180.0);
  for (double z = 0.5; z < 14.6; z += 0.25) {
    const Vec3 p(bend - bend * std::cos(z / bend), 0.0, bend * std::sin(z / bend));
    CHECK(query.inside(p));
    // 1.2 radii off the centre line, sideways: outside.
    CHECK_FALSE(query.inside(p + Vec3(0, 1.2, 0)));
  }
  CHECK(query.side(Vec3(100, 100, 100)) == Side::outside);
  CHECK(query.side(Vec3(0, 5, 7)) == Side::outside);
  CHECK(query.side(mesh.positions[5]) == Side::boundary);
}

TEST_CASE("first_hit finds the hit of a test of every triangle, to the bit", "[morph][locate]") {
  const TriangleMesh mesh = test::bent_capsule(1.0, 15.0, 16, 120.0);
  const SurfaceQuery query(mesh);
  // Every triangle in turn, as the fibre ends' cast did before first_hit (decompose.cpp).
  const auto brute = [&](const Vec3& p, const Vec3& d, double reach, Vec3& hit) {
    double best = reach;
    bool found = false;
    const Vec3 q = p + reach * d;
    const Vec3 lo = p.cwiseMin(q), hi = p.cwiseMax(q);
    for (const Triangle& t : mesh.triangles) {
      const Vec3 &a = mesh.positions[t[0]], &b = mesh.positions[t[1]], &c = mesh.positions[t[2]];
      if ((a.cwiseMax(b).cwiseMax(c) - lo).minCoeff() < 0.0 || (hi - a.cwiseMin(b).cwiseMin(c)).minCoeff() < 0.0)
        continue;
      double t_hit = 0.0;
      if (ray_triangle_hit(p, d, a, b, c, t_hit) && t_hit > 0.0 && t_hit < best) best = t_hit, found = true;
    }
    if (found) hit = p + best * d;
    return found;
  };
  std::mt19937 random(9);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const std::vector<Vec3> directions = random_directions(600, 13);
  long hits = 0, misses = 0;
  for (std::size_t n = 0; n < directions.size(); ++n) {
    // Starts inside (on the bent centre line, off it), outside, and on vertices; short and long
    // reaches; a few directions along the axes (parallel to box faces).
    const double bend = 15.0 / (120.0 * M_PI / 180.0), z = 0.5 + 14.0 * (0.5 + 0.5 * unit(random));
    Vec3 p(bend - bend * std::cos(z / bend), 0.0, bend * std::sin(z / bend));
    if (n % 3 == 1) p += 3.0 * Vec3(unit(random), unit(random), unit(random));
    if (n % 5 == 4) p = mesh.positions[n % mesh.positions.size()];
    Vec3 d = directions[n];
    if (n % 11 == 0) d = Vec3::Unit(static_cast<Eigen::Index>(n % 3));
    if (n % 7 == 0) d *= 3.5;
    const double reach = n % 4 == 0 ? 0.7 : 80.0;
    Vec3 a = Vec3::Constant(-1.0), b = Vec3::Constant(-2.0);
    const bool found_a = query.first_hit(p, d, reach, a), found_b = brute(p, d, reach, b);
    REQUIRE(found_a == found_b);
    if (found_a) CHECK((a.array() == b.array()).all());
    (found_a ? hits : misses) += 1;
  }
  CHECK(hits > 300);
  CHECK(misses > 20);
}

TEST_CASE("side() answers as the exact test, the grid answering points away from the surface", "[morph][locate]") {
  // Points inside, outside, far away, next to the surface and on it (vertices, edge midpoints),
  // on two shapes: a bent capsule (one inside region) and a cube.
  for (const TriangleMesh& mesh : {test::bent_capsule(1.0, 15.0, 16, 120.0), test::subdivided_cube(6)}) {
    const SurfaceQuery query(mesh);
    const BoundingBox box = bounding_box(mesh.positions);
    std::mt19937 random(11);
    std::uniform_real_distribution<double> unit(-0.2, 1.2);
    std::vector<Vec3> points;
    for (int i = 0; i < 4000; ++i)
      points.push_back(box.min + (box.max - box.min).cwiseProduct(Vec3(unit(random), unit(random), unit(random))));
    for (const Vec3& v : mesh.positions) points.push_back(v);
    for (const Triangle& t : mesh.triangles) {
      const Vec3 mid = 0.5 * (mesh.positions[t[0]] + mesh.positions[t[1]]);
      const Vec3 centre = (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0;
      points.push_back(mid);
      points.push_back(centre + 1e-12 * (centre - box.min));
    }
    long by_grid = 0, inside = 0, outside = 0, boundary = 0;
    const InsideGrid& grid = query.inside_grid();
    for (const Vec3& p : points) {
      const Side exact = query.exact_side(p);
      CHECK(query.side(p) == exact);
      by_grid += grid.classify(p) != InsideGrid::Known::unknown;
      inside += exact == Side::inside;
      outside += exact == Side::outside;
      boundary += exact == Side::boundary;
    }
    CHECK(grid.regions() >= 2);  // at least the outside and the inside
    CHECK(inside > 500);
    CHECK(outside > 500);
    CHECK(boundary >= static_cast<long>(mesh.positions.size()));
    CHECK(by_grid > 2000);  // most random points are answered by their cell
  }
}

TEST_CASE("closest_points gives closest_point's answer for many points at once", "[morph][locate]") {
  // Points inside, outside and far away, in random order (the batch sorts them along a curve and
  // starts each query from the previous answer): the same face and position where one triangle
  // is closest, the same distance to rounding everywhere; an empty batch is empty.
  const TriangleMesh mesh = test::bent_capsule(1.0, 15.0, 16, 120.0);
  const SurfaceQuery query(mesh);
  std::mt19937 random(4);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Vec3> points;
  for (int i = 0; i < 3000; ++i) {
    const double scale = i % 10 == 0 ? 40.0 : 6.0;
    points.emplace_back(scale * unit(random), scale * unit(random), 7.5 + 1.5 * scale * unit(random));
  }
  const std::vector<SurfacePoint> batch = query.closest_points(points);
  REQUIRE(batch.size() == points.size());
  long same_face = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const SurfacePoint one = query.closest_point(points[i]);
    CHECK(batch[i].distance == Approx(one.distance).epsilon(1e-12).margin(1e-12));
    if (batch[i].face == one.face) {
      ++same_face;
      CHECK((batch[i].position.array() == one.position.array()).all());
      CHECK(batch[i].distance == one.distance);
    } else {  // a tie: the same point, on an edge or a vertex shared by both faces
      CHECK((batch[i].position - one.position).norm() <= 1e-9);
    }
  }
  // Far points are mostly nearest to a vertex (six faces tie); most others find the same face.
  CHECK(same_face > 1500);
  CHECK(query.closest_points({}).empty());
}
