// Landmark areas joined into strips (fibres/landmark_strip.h) and the cast of fibre ends onto a
// strip with separate factors along and across it (fibres/strip_cast.h), on synthetic shapes.
#include "fibres/decompose.h"
#include "fibres/fibre_check.h"
#include "fibres/landmark_strip.h"
#include "fibres/strip_cast.h"
#include "geometry/errors.h"
#include "geometry/primitives.h"
#include "morph/surface_query.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <vector>

using namespace fascicle;

namespace {

// Distance from `p` to the nearest point of `area`.
double distance_to_area(const AttachmentArea& area, const Vec3& p) {
  double best = 1e300;
  for (const SurfacePoint& s : area.points) best = std::min(best, (s.position - p).norm());
  return best;
}

}  // namespace

TEST_CASE("landmark strip: a row of far-apart landmarks becomes a gapless strip", "[fibres][strip]") {
  // A capsule along x (length 10, radius 1.5) and a row of landmarks on its top, one unit apart
  // (about 8 % of the muscle length: the 1 %-of-length disks round them do not touch).
  const TriangleMesh mesh = make_capsule(10.0, 1.5, 24);
  const SurfaceQuery query(mesh);
  const double length = muscle_length(mesh);
  std::vector<Vec3> row;
  for (int i = -3; i <= 3; ++i) row.push_back(Vec3(i, 0.0, 1.6));
  const AttachmentArea area = project_landmarks(query, 20.0, row, "row");
  const double radius = 0.01 * length;
  // Samples along the row, on the surface: most are farther than the region radius from every
  // landmark before the joining, none after.
  std::vector<Vec3> samples;
  for (int s = 0; s <= 60; ++s) samples.push_back(query.closest_point(Vec3(-3.0 + 0.1 * s, 0.0, 1.6)).position);
  int far_before = 0;
  for (const Vec3& p : samples) far_before += distance_to_area(area, p) > radius ? 1 : 0;
  CHECK(far_before > 30);

  StripReport report;
  const AttachmentArea joined = join_landmark_strip(area, query, length, StripOptions{}, &report);
  CHECK(report.joined);
  CHECK(report.landmarks == 7);
  CHECK(report.joins == 6);
  CHECK(report.gaps == 0);
  CHECK(report.added == static_cast<long>(joined.points.size()) - 7);
  CHECK(report.longest_join == Approx(1.0 / length).epsilon(1e-6));
  for (const Vec3& p : samples) CHECK(distance_to_area(joined, p) <= radius);
  // The original points come first, unchanged; the added ones lie on the surface.
  for (std::size_t i = 0; i < area.points.size(); ++i) CHECK(joined.points[i].position == area.points[i].position);
  for (const SurfacePoint& s : joined.points) CHECK(query.closest_point(s.position).distance < 1e-9 * length);
  CHECK(joined.source == "row");

  // Joins longer than max_gap stay open; joining off leaves the area as it was.
  StripOptions short_joins;
  short_joins.max_gap = 0.5 / length;
  const AttachmentArea unjoined = join_landmark_strip(area, query, length, short_joins, &report);
  CHECK(report.joins == 0);
  CHECK(report.gaps == 6);
  CHECK(unjoined.points.size() == area.points.size());
  StripOptions off;
  off.join = false;
  CHECK(join_landmark_strip(area, query, length, off, &report).points.size() == area.points.size());
  CHECK_FALSE(report.joined);

  // Both areas at once (what decompose and check call): each joined as above, or left with off.
  std::vector<Vec3> other;
  for (int i = -2; i <= 2; ++i) other.push_back(Vec3(i, 0.0, -1.6));
  Attachments areas;
  areas.origin = area;
  areas.insertion = project_landmarks(query, 20.0, other, "other");
  Attachments both = areas;
  const nlohmann::json done = join_landmark_strips(both, query, length, StripOptions{});
  CHECK(done["face_shape"] == "joined_strip");
  CHECK(done["origin"]["joins"] == 6);
  CHECK(done["insertion"]["joins"] == 4);
  CHECK(both.origin.points.size() == joined.points.size());
  CHECK(both.insertion.points.size() ==
        join_landmark_strip(areas.insertion, query, length, StripOptions{}).points.size());
  Attachments left = areas;
  CHECK(join_landmark_strips(left, query, length, off)["face_shape"] == "landmark_disks");
  CHECK(left.origin.points.size() == area.points.size());
  CHECK(left.insertion.points.size() == other.size());
}

TEST_CASE("landmark strip: options are checked", "[fibres][strip]") {
  StripOptions options;
  REQUIRE_NOTHROW(options.validate());
  options.max_gap = 0.0;
  CHECK_THROWS_WITH(options.validate(), Catch::Contains("max_gap"));
  options = StripOptions{};
  options.step = 0.5;
  CHECK_THROWS_WITH(options.validate(), Catch::Contains("step"));
  options = StripOptions{};
  options.max_points = 1;
  CHECK_THROWS_WITH(options.validate(), Catch::Contains("max_points"));
  DecomposeOptions decompose;
  decompose.strip.max_gap = 2.0;
  CHECK_THROWS_WITH(decompose.validate(), Catch::Contains("max_gap"));
  // The command line: checked before the input is read.
  test::TempDir dir;
  const std::string start = test::program() + " decompose " + dir.file("missing.off") + " -o " + dir.file("o.vtk");
  CHECK(test::run_command(start + " --strip-max-gap 0 2>/dev/null") == 18);
  CHECK(test::run_command(start + " --strip-max-gap 0.2 2>/dev/null") != 18);
}

TEST_CASE("strip cast: the face keeps its length along a strip and narrows across it", "[fibres][strip]") {
  // The surface z = 0 seen from above; the strip is the x axis from -5 to 5; an end counts as
  // near within 0.3 of a strip point. The layer's offsets: a 9 x 9 grid of spacing 1.
  std::vector<Vec3> strip;
  for (int i = -50; i <= 50; ++i) strip.push_back(Vec3(0.1 * i, 0.0, 0.0));
  std::vector<Vec3> offsets;
  for (int j = -4; j <= 4; ++j)
    for (int i = -4; i <= 4; ++i) offsets.push_back(Vec3(i, j, 0.0));
  const auto hit = [](const Vec3& start, const Vec3& axis, Vec3& end) {
    if (!(axis.z() < 0.0)) return false;
    end = start - start.z() / axis.z() * axis;
    return true;
  };
  const auto near = [&](const Vec3& end) {
    for (const Vec3& p : strip)
      if ((p - end).norm() <= 0.3) return true;
    return false;
  };
  const Vec3 centre(0.0, 0.0, 1.0), axis(0.0, 0.0, -1.0);
  const StripCast cast = cast_strip_face(centre, offsets, axis, strip, hit, near);
  REQUIRE(cast.placed);
  // Along the strip the whole face fits (factor 1); across, 4 * c <= 0.3: c = 0.8^12.
  CHECK(cast.lambda_long == 1.0);
  CHECK(cast.lambda_cross == Approx(std::pow(0.8, 12)));
  REQUIRE(cast.ends.size() == offsets.size());
  double x_min = 1e300, x_max = -1e300;
  for (const Vec3& e : cast.ends) {
    CHECK(near(e));
    x_min = std::min(x_min, e.x());
    x_max = std::max(x_max, e.x());
  }
  CHECK(x_max - x_min == Approx(8.0));  // the ends span the strip, not a spot on it
  // One factor for both directions would have shrunk the face to 0.8^12 of its length.

  // The same strip along y: the direction is found from the area points.
  std::vector<Vec3> turned;
  for (const Vec3& p : strip) turned.push_back(Vec3(p.y(), p.x(), 0.0));
  const auto near_turned = [&](const Vec3& end) {
    for (const Vec3& p : turned)
      if ((p - end).norm() <= 0.3) return true;
    return false;
  };
  const StripCast across = cast_strip_face(centre, offsets, axis, turned, hit, near_turned);
  REQUIRE(across.placed);
  CHECK(across.lambda_long == 1.0);
  CHECK(across.lambda_cross == Approx(std::pow(0.8, 12)));

  // No ray meets the surface: not placed.
  const StripCast missed = cast_strip_face(centre, offsets, Vec3(0.0, 0.0, 1.0), strip, hit, near);
  CHECK_FALSE(missed.placed);
  CHECK(missed.ends.empty());
}
