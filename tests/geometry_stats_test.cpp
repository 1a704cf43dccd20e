#include "geometry/mesh_stats.h"

#include <catch2/catch.hpp>

using namespace fascicle;

namespace {
TriangleMesh unit_tetrahedron(const Vec3& offset = Vec3::Zero()) {
  TriangleMesh m;
  m.positions = {Vec3(0, 0, 0) + offset, Vec3(1, 0, 0) + offset, Vec3(0, 1, 0) + offset, Vec3(0, 0, 1) + offset};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}
}  // namespace

TEST_CASE("signed volume, area and Euler characteristic of a tetrahedron", "[geometry]") {
  const TriangleMesh tet = unit_tetrahedron();
  CHECK(signed_volume(tet) == Approx(1.0 / 6.0));
  CHECK(surface_area(tet) == Approx(1.5 + std::sqrt(3.0) / 2.0));
  CHECK(euler_characteristic(tet) == 2);
  TriangleMesh flipped = tet;
  for (auto& t : flipped.triangles) std::swap(t[1], t[2]);
  CHECK(signed_volume(flipped) == Approx(-1.0 / 6.0));
}

TEST_CASE("signed volume keeps its digits at CT scanner offsets", "[geometry]") {
  const TriangleMesh tet = unit_tetrahedron(Vec3(1e7, -1e7, 1e7));
  CHECK(signed_volume(tet) == Approx(1.0 / 6.0).epsilon(1e-9));
}

TEST_CASE("bounding box diagonal", "[geometry]") {
  const BoundingBox box = bounding_box({Vec3(0, 0, 0), Vec3(3, 4, 0), Vec3(1, 1, 12)});
  CHECK(box.diagonal() == Approx(13.0));
  CHECK(bounding_box({}).diagonal() == 0.0);
}
