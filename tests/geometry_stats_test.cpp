#include "geometry/mesh_stats.h"
#include "geometry/cross_section.h"
#include "geometry/primitives.h"

#include <Eigen/Geometry>
#include <cmath>

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

TEST_CASE("principal axes of a rotated, offset box", "[geometry]") {
  // Corners of a box with half extents 5, 2, 1 along three orthonormal directions, centred at a
  // CT-like offset: the variances are 25, 4, 1 and the axes those directions (up to sign).
  const Vec3 u = Vec3(1, 2, 2).normalized();
  const Vec3 v = Vec3(2, -1, 0).normalized();
  const Vec3 w = u.cross(v);
  const Vec3 centre(1e4, -2e4, 3e3);
  std::vector<Vec3> corners;
  for (int a : {-1, 1})
    for (int b : {-1, 1})
      for (int c : {-1, 1}) corners.push_back(centre + 5.0 * a * u + 2.0 * b * v + 1.0 * c * w);
  const PrincipalAxes axes = principal_axes(corners);
  CHECK((axes.mean - centre).norm() < 1e-9);
  CHECK(axes.variances.x() == Approx(1.0));
  CHECK(axes.variances.y() == Approx(4.0));
  CHECK(axes.variances.z() == Approx(25.0));
  CHECK(std::abs(axes.major().dot(u)) == Approx(1.0));
  CHECK(std::abs(axes.axes.col(1).dot(v)) == Approx(1.0));
  CHECK(std::abs(axes.axes.col(0).dot(w)) == Approx(1.0));
  CHECK((axes.axes.transpose() * axes.axes - Eigen::Matrix3d::Identity()).norm() < 1e-12);
}

TEST_CASE("principal axes of no point are the identity at the origin", "[geometry]") {
  const PrincipalAxes axes = principal_axes({});
  CHECK(axes.mean == Vec3::Zero());
  CHECK(axes.axes == Eigen::Matrix3d::Identity());
  CHECK(axes.variances == Vec3::Zero());
}

namespace {
// An elliptic cylinder along z, semi-axes a and b, `n` points a ring, closed by fans.
TriangleMesh elliptic_cylinder(double a, double b, double length, int n = 256) {
  std::vector<std::vector<Vec3>> rings;
  for (int k = 0; k <= 20; ++k) {
    std::vector<Vec3> ring;
    for (int j = 0; j < n; ++j) {
      const double phi = 2.0 * 3.14159265358979323846 * j / n;
      ring.emplace_back(a * std::cos(phi), b * std::sin(phi), length * k / 20.0);
    }
    rings.push_back(ring);
  }
  return make_closed_tube(rings, Vec3(0, 0, -0.01 * length), Vec3(0, 0, 1.01 * length));
}
}  // namespace

TEST_CASE("cross-section aspect of elliptic and round cylinders", "[geometry]") {
  // The area's second moments of an ellipse of semi-axes a, b are a^2/4 and b^2/4: aspect a / b,
  // whichever way the mesh turns and faces, at a CT-like offset.
  TriangleMesh flat = elliptic_cylinder(3.0, 1.0, 20.0);
  CrossSectionShape shape = cross_section_shape(flat);
  REQUIRE(shape.aspects.size() == 7);
  for (double a : shape.aspects) CHECK(a == Approx(3.0).epsilon(1e-3));
  CHECK(shape.median_aspect == Approx(3.0).epsilon(1e-3));
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  for (Vec3& p : flat.positions) p = turn * p + Vec3(250.0, -1300.0, 900.0);
  CHECK(cross_section_shape(flat).median_aspect == Approx(3.0).epsilon(1e-3));
  for (Triangle& t : flat.triangles) std::swap(t[1], t[2]);
  CHECK(cross_section_shape(flat).median_aspect == Approx(3.0).epsilon(1e-3));
  CHECK(cross_section_shape(elliptic_cylinder(2.0, 2.0, 20.0)).median_aspect == Approx(1.0).epsilon(1e-3));
  // Planes where asked; none for an empty mesh.
  CrossSectionOptions one;
  one.slices = 1;
  CHECK(cross_section_shape(elliptic_cylinder(4.0, 1.0, 30.0), one).aspects.size() == 1);
  CHECK(cross_section_shape(TriangleMesh{}).aspects.empty());
  CHECK(cross_section_shape(TriangleMesh{}).median_aspect == 0.0);
}
