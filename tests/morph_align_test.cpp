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

namespace {

// A flat "Y" in the xz plane, triangulated on a unit grid: a trunk (columns 4-7) from z = 0 to
// z = 24 and two arms (columns 0-3 and 8-11) from z = 20 to z = 30, joined by a bar across
// z = 20..24. Its long axis is z; the upper tenth (z >= 27) is two separate pieces, the arms'
// tips, which meet only at the bar (z <= 24: a band of 0.2 of the length).
TriangleMesh flat_y() {
  TriangleMesh mesh;
  auto cell_in = [](int i, int j) { return (i >= 4 && i <= 7 && j < 24) || (j >= 20 && (i <= 3 || i >= 8)); };
  std::vector<int> id(13 * 31, -1);
  auto vertex = [&](int i, int j) {
    int& v = id[j * 13 + i];
    if (v < 0) {
      v = static_cast<int>(mesh.positions.size());
      mesh.positions.emplace_back(i, 0.0, j);
    }
    return v;
  };
  for (int j = 0; j < 30; ++j)
    for (int i = 0; i < 12; ++i)
      if (cell_in(i, j)) {
        const int a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1), d = vertex(i, j + 1);
        mesh.triangles.push_back({a, b, c});
        mesh.triangles.push_back({a, c, d});
      }
  return mesh;
}

// Connected pieces of the vertices of `points` over the mesh's edges.
int pieces(const TriangleMesh& mesh, const std::vector<SurfacePoint>& points) {
  std::vector<int> label(mesh.positions.size(), -2);  // -2: not in the area
  for (const SurfacePoint& p : points) {
    const Triangle& t = mesh.triangles[p.face];
    for (int k = 0; k < 3; ++k)
      if (p.barycentric[k] == 1.0) label[t[k]] = -1;
  }
  int count = 0;
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t v = 0; v < label.size(); ++v)
      if (label[v] == -1) {
        label[v] = count++;
        changed = true;
        for (bool grew = true; grew;) {
          grew = false;
          for (const Triangle& t : mesh.triangles)
            for (int a = 0; a < 3; ++a)
              for (int b = 0; b < 3; ++b)
                if (label[t[a]] == label[v] && label[t[b]] == -1) {
                  label[t[b]] = label[v];
                  grew = true;
                }
        }
      }
  }
  return count;
}

}  // namespace

TEST_CASE("an automatic end of two pieces is widened until it is one", "[morph][attach]") {
  const TriangleMesh mesh = flat_y();
  AttachmentOptions off;
  off.connected_ends = false;
  const Attachments split = automatic_attachments(mesh, off);
  CHECK(split.origin.end_pieces == 2);
  CHECK(pieces(mesh, split.origin.points) == 2);
  CHECK(split.origin.end_fraction == Approx(0.1));

  const Attachments joined = automatic_attachments(mesh);  // default: connected_ends, margin 0.02
  CHECK(joined.origin.end_pieces == 2);
  CHECK(pieces(mesh, joined.origin.points) == 1);
  // The arms meet the trunk's top row at z = 24: 6 of the 30 from the top, plus the margin.
  CHECK(joined.origin.end_fraction == Approx(0.2 + 0.02));
  for (const SurfacePoint& p : joined.origin.points) CHECK(p.position.z() >= 24.0 - 0.02 * 30.0 - 1e-9);
  CHECK(joined.origin.points.size() > split.origin.points.size());
  // The lower end (the trunk's foot) is one piece: as requested.
  CHECK(joined.insertion.end_pieces == 1);
  CHECK(joined.insertion.end_fraction == Approx(0.1));
  CHECK(joined.insertion.points.size() == split.insertion.points.size());

  AttachmentOptions no_margin;
  no_margin.connect_margin = 0.0;
  CHECK(automatic_attachments(mesh, no_margin).origin.end_fraction == Approx(0.2));
  // Not connected within max_end_fraction: the requested band, still reported as two pieces.
  AttachmentOptions narrow;
  narrow.max_end_fraction = 0.15;
  const Attachments capped = automatic_attachments(mesh, narrow);
  CHECK(capped.origin.end_fraction == Approx(0.1));
  CHECK(capped.origin.end_pieces == 2);
  CHECK(capped.origin.points.size() == split.origin.points.size());

  AttachmentOptions bad;
  bad.connect_margin = -0.01;
  CHECK_THROWS_AS(automatic_attachments(mesh, bad), OptionError);
  bad = {};
  bad.max_end_fraction = 0.05;  // below end_fraction
  CHECK_THROWS_AS(automatic_attachments(mesh, bad), OptionError);
  bad.max_end_fraction = 0.5;
  CHECK_THROWS_AS(automatic_attachments(mesh, bad), OptionError);
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
