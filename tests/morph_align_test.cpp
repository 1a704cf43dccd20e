// Attachment areas (landmarks, automatic ends, far landmarks) and their alignment on the sphere.
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "morph/align_on_sphere.h"
#include "morph/attachments.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "tests/morph_test_shapes.h"

#include <catch2/catch.hpp>

using namespace fascicle;

TEST_CASE("automatic attachments are the two ends along the principal direction", "[morph][attach]") {
  const TriangleMesh mesh = test::capsule(1.0, 20.0, 12);  // along z from 0 to 20
  const Attachments a = automatic_attachments(mesh);
  REQUIRE_FALSE(a.origin.points.empty());
  REQUIRE_FALSE(a.insertion.points.empty());
  CHECK(a.automatic);
  // Origin at the upper end (z >= 18), insertion at the lower (z <= 2).
  for (const SurfacePoint& p : a.origin.points) CHECK(p.position.z() >= 18.0 - 1e-9);
  for (const SurfacePoint& p : a.insertion.points) CHECK(p.position.z() <= 2.0 + 1e-9);
  CHECK(a.origin.centroid().z() > 18.0);
}

TEST_CASE("landmarks are projected to the surface", "[morph][attach]") {
  const TriangleMesh mesh = test::icosphere(3);
  const std::vector<Vec3> origin{{0, 0, 1.01}, {0.1, 0, 0.99}}, insertion{{0, 0, -1.0}};
  const Attachments a = landmark_attachments(mesh, origin, "o.xyz", insertion, "i.xyz");
  REQUIRE(a.origin.points.size() == 2);
  CHECK(a.origin.max_distance < 0.02);
  for (const SurfacePoint& p : a.origin.points) CHECK(p.position.norm() == Approx(1.0).margin(0.01));
}

TEST_CASE("far landmarks give the landmarks error naming the file and distance", "[morph][attach]") {
  const TriangleMesh mesh = test::icosphere(2);
  const std::vector<Vec3> near{{0, 0, 1}}, far{{0, 0, 1}, {0, 0, 4.0}};
  try {
    landmark_attachments(mesh, near, "good.xyz", far, "muscle.insertion-far.xyz");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(e.code() == ErrorCode::landmarks);
    const std::string what = e.what();
    CHECK(what.find("muscle.insertion-far.xyz") != std::string::npos);
    CHECK(what.find("landmark 2") != std::string::npos);
    CHECK(what.find("is 3 from") != std::string::npos);
  }
  CHECK_THROWS_AS(landmark_attachments(mesh, {}, "empty.xyz", near, "x"), InputError);
  AttachmentOptions bad;
  bad.end_fraction = 0.7;
  CHECK_THROWS_AS(automatic_attachments(mesh, bad), OptionError);
}

TEST_CASE("alignment puts the origin exactly and never flips a triangle", "[morph][align]") {
  // Template: an icosphere map; muscle: a capsule's map with its automatic areas.
  const TriangleMesh muscle = test::capsule(1.0, 20.0, 12);
  const SphereMap muscle_map = map_to_sphere(muscle);
  REQUIRE(muscle_map.report.quality.bijective());
  const Attachments areas = automatic_attachments(muscle);
  const Vec3 target_o = sphere_centre(areas.origin, muscle_map.positions, muscle.triangles);
  const Vec3 target_i = sphere_centre(areas.insertion, muscle_map.positions, muscle.triangles);

  const TriangleMesh templ = test::icosphere(3);
  std::vector<Vec3> sphere = map_to_sphere(templ).positions;
  const SphereLocator locator(sphere, templ.triangles);
  // Template areas: two points 100 degrees apart, neither at the targets.
  const Vec3 o_dir = Vec3(0.3, 0.2, 1.0).normalized();
  const Vec3 i_dir = Eigen::AngleAxisd(100.0 * M_PI / 180.0, Vec3(1, -0.4, 0).normalized()) * o_dir;
  const SurfacePoint o = locator.locate(o_dir), i = locator.locate(i_dir);
  const double before_deg = std::acos(std::clamp(target_o.dot(target_i), -1.0, 1.0)) * 180.0 / M_PI;

  const AlignReport report = align_on_sphere(templ.triangles, sphere, o, i, target_o, target_i);
  CHECK(report.flipped == 0);
  CHECK(measure_sphere_map(templ, sphere).flipped == 0);
  CHECK(measure_sphere_map(templ, sphere).degenerate == 0);
  CHECK(report.origin_error_deg < 1e-6);
  // The pull closes what the rotation could not.
  CHECK(report.insertion_error_deg <= report.insertion_error_rotation_deg + 1e-9);
  if (std::abs(before_deg - 100.0) > 1.0) CHECK(report.insertion_error_rotation_deg > 0.5);
  CHECK(report.insertion_error_deg < 0.1);
  for (const Vec3& p : sphere) CHECK(p.norm() == Approx(1.0));
}
