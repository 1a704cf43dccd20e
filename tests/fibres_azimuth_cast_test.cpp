// The cast of fibre ends with one shrink factor per azimuth (fibres/azimuth_cast.h), on a plane
// seen from above with an area that is narrow on one side of the layer's centre.
#include "fibres/azimuth_cast.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

using namespace fascicle;

namespace {

// The layer: a 9 x 9 grid of spacing 0.25 round the centre (0, 0, 1); rays go down (-z).
std::vector<Vec3> grid_offsets() {
  std::vector<Vec3> offsets;
  for (int j = -4; j <= 4; ++j)
    for (int i = -4; i <= 4; ++i) offsets.push_back(Vec3(0.25 * i, 0.25 * j, 0.0));
  return offsets;
}

bool down_to_plane(const Vec3& start, const Vec3& axis, Vec3& end) {
  if (!(axis.z() < 0.0)) return false;
  end = start - start.z() / axis.z() * axis;
  return true;
}

// The area: x in [-1, 0.2] and |y| <= 1 on z = 0 (reaches the whole layer's width towards -x,
// a fifth of it towards +x).
bool on_area(const Vec3& end) { return end.x() >= -1.0 && end.x() <= 0.2 && std::abs(end.y()) <= 1.0; }

}  // namespace

TEST_CASE("azimuth cast: the face keeps its size where the area is wide and shrinks only where it is narrow",
          "[fibres][cast]") {
  const std::vector<Vec3> offsets = grid_offsets();
  const Vec3 centre(0.0, 0.0, 1.0), axis(0.0, 0.0, -1.0);
  const auto inside = [](const Vec3&) { return true; };
  const AzimuthCast cast = cast_azimuth_face(centre, offsets, axis, down_to_plane, on_area, inside);
  REQUIRE(cast.placed);
  REQUIRE(cast.ends.size() == offsets.size());
  for (const Vec3& e : cast.ends) CHECK(on_area(e));
  // One factor for the whole face: the +x corner at 1.0 must shrink to 0.2, 0.8^8 = 0.168.
  CHECK(cast.smallest() == Approx(std::pow(0.8, 8)));
  CHECK(cast.largest() == 1.0);
  // Towards -x the face keeps the layer's size: the ends reach the area's far edge.
  double x_min = 1e300;
  for (const Vec3& e : cast.ends) x_min = std::min(x_min, e.x());
  CHECK(x_min == Approx(-1.0));
  // Along every azimuth the order of the points is kept (the factor depends on the azimuth only).
  for (std::size_t a = 0; a < offsets.size(); ++a)
    for (std::size_t b = 0; b < offsets.size(); ++b) {
      const Vec3 &p = offsets[a], &q = offsets[b];
      if (p.norm() == 0.0 || !(q.norm() > p.norm()) || p.normalized().dot(q.normalized()) < 1.0 - 1e-12) continue;
      CHECK((cast.ends[b] - Vec3(0, 0, 0)).head<2>().norm() > (cast.ends[a] - Vec3(0, 0, 0)).head<2>().norm());
    }
}

TEST_CASE("azimuth cast: a larger factor needs its start inside and its end as deep as the uniform ends",
          "[fibres][cast]") {
  const std::vector<Vec3> offsets = grid_offsets();
  const Vec3 centre(0.0, 0.0, 1.0), axis(0.0, 0.0, -1.0);
  // No start beyond the uniform face's lies inside: every end is the uniform cast's.
  const auto only_centre = [&](const Vec3& p) { return (p - centre).norm() < 1e-9; };
  const AzimuthCast held = cast_azimuth_face(centre, offsets, axis, down_to_plane, on_area, only_centre);
  REQUIRE(held.placed);
  CHECK(held.largest() == held.smallest());
  for (std::size_t q = 0; q < offsets.size(); ++q)
    CHECK((held.ends[q] - (centre + held.smallest() * offsets[q] - Vec3(0, 0, 1))).norm() < 1e-12);

  // A step down in the surface for x < -0.5: the ends there would lie deeper than every uniform
  // end, so the face stops short of it.
  const auto stepped = [](const Vec3& start, const Vec3& axis_, Vec3& end) {
    if (!down_to_plane(start, axis_, end)) return false;
    if (end.x() < -0.5) end.z() = -0.5;
    return true;
  };
  const auto inside = [](const Vec3&) { return true; };
  const AzimuthCast shallow = cast_azimuth_face(centre, offsets, axis, stepped, on_area, inside);
  REQUIRE(shallow.placed);
  for (const Vec3& e : shallow.ends) {
    CHECK(e.z() == 0.0);
    CHECK(e.x() >= -0.5);
  }

  // No ray meets the surface: not placed.
  const AzimuthCast missed = cast_azimuth_face(centre, offsets, Vec3(0.0, 0.0, 1.0), down_to_plane, on_area, inside);
  CHECK_FALSE(missed.placed);
  CHECK(missed.ends.empty());
  CHECK(missed.smallest() == 0.0);
}
