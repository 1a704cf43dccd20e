// Fibre ends continued along their fibres (fibres/align_ends.h), on straight fibres through a
// cube whose ends were cast shrunk towards the face centres (a hook at each end joint): the
// geometry says where each end must land.
#include "fibres/align_ends.h"
#include "fibres/fibre_check.h"
#include "fibres/fibre_grid.h"
#include "geometry/errors.h"
#include "geometry/primitives.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"

#include <catch2/catch.hpp>

#include <cmath>

using namespace fascicle;

namespace {

/// A 6 x 6 x 5 lattice in the cube [-2, 2]^3: line (i, j) at x = -1.5 + 0.6 i, y = -1.5 + 0.6 j,
/// inner layers at z = -1, 0, 1, the ends on the faces z = -2 and z = 2 at `shrink` times the
/// line's (x, y).
springs::Lattice hooked_lattice(double shrink) {
  springs::LatticeOptions options;
  options.nr = 6;
  options.ns = 6;
  options.resolution = 5;
  springs::Lattice lattice = springs::build_lattice(options);
  REQUIRE(lattice.nx == 6);
  REQUIRE(lattice.ny == 6);
  REQUIRE(lattice.nz == 5);
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) {
        const double f = (k == 0 || k == 4) ? shrink : 1.0;
        lattice.system.positions[static_cast<std::size_t>(lattice.index(i, j, k))] =
            Vec3(f * (-1.5 + 0.6 * i), f * (-1.5 + 0.6 * j), -2.0 + k);
      }
  return lattice;
}

/// The two faces z = -2 (origin) and z = 2 (insertion) as attachment areas: a 21 x 21 grid of
/// surface points on each.
Attachments cube_ends(const SurfaceQuery& query) {
  Attachments areas;
  for (int g = 0; g < 21 * 21; ++g) {
    const double x = -2.0 + 0.2 * (g % 21), y = -2.0 + 0.2 * (g / 21);
    areas.origin.points.push_back(query.closest_point(Vec3(x, y, -2.5)));
    areas.insertion.points.push_back(query.closest_point(Vec3(x, y, 2.5)));
  }
  return areas;
}

/// The areas' points with |x|, |y| < 0.5: the faces' centres.
Attachments centres(Attachments areas) {
  for (AttachmentArea* area : {&areas.origin, &areas.insertion}) {
    std::vector<SurfacePoint> kept;
    for (const SurfacePoint& p : area->points)
      if (std::abs(p.position.x()) < 0.5 && std::abs(p.position.y()) < 0.5) kept.push_back(p);
    area->points = kept;
  }
  return areas;
}

CheckReport check(const springs::Lattice& lattice, const TriangleMesh& cube, const Attachments& areas) {
  CheckOptions options;
  options.coverage_samples = 200;
  return check_fibres(lattice_interior_fibres(lattice, lattice.system.positions), cube, areas, options);
}

}  // namespace

TEST_CASE("hooked fibre ends are continued along their fibres onto the end faces", "[fibres][align_ends]") {
  const TriangleMesh cube = make_cube(4.0, 8);
  const SurfaceQuery query(cube);
  const Attachments areas = cube_ends(query);
  springs::Lattice lattice = hooked_lattice(0.5);
  const CheckReport before = check(lattice, cube, areas);
  CHECK(before.inverted_cells == 0);
  // The corner lines' end joints turn by atan(0.45 sqrt 2) = 32.5 degrees.
  CHECK(before.turning.max_deg == Approx(std::atan(0.45 * std::sqrt(2.0)) * 180.0 / 3.14159265358979323846));

  const EndAlignmentReport report = align_ends(lattice, lattice.system, query, areas, 0.3);
  CHECK(report.moved == 32);
  CHECK(report.halfway == 0);
  CHECK(report.three_quarters == 0);
  CHECK(report.kept == 0);
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i)
      for (int k : {0, lattice.nz - 1}) {
        const Vec3& end = lattice.system.positions[static_cast<std::size_t>(lattice.index(i, j, k))];
        CHECK(end.x() == Approx(-1.5 + 0.6 * i).margin(1e-12));
        CHECK(end.y() == Approx(-1.5 + 0.6 * j).margin(1e-12));
        CHECK(std::abs(end.z()) == Approx(2.0).margin(1e-12));
      }
  const CheckReport after = check(lattice, cube, areas);
  CHECK(after.turning.max_deg < 1e-4);
  CHECK(after.inverted_cells == 0);
  CHECK(after.inside_fraction == 1.0);
  CHECK(after.touching_segments == 0);
  // Spread over the faces rather than their middle quarter.
  CHECK(after.origin_ends.share > before.origin_ends.share);
  CHECK(after.insertion_ends.share > before.insertion_ends.share);
}

TEST_CASE("an end whose casts leave its area, or reach too far, stays", "[fibres][align_ends]") {
  const TriangleMesh cube = make_cube(4.0, 8);
  const SurfaceQuery query(cube);
  Attachments areas = cube_ends(query);
  springs::Lattice lattice = hooked_lattice(0.7);
  const std::vector<Vec3> start = lattice.system.positions;
  SECTION("the area is only the faces' centre") {
    areas = centres(areas);
    const EndAlignmentReport report = align_ends(lattice, lattice.system, query, areas, 0.15);
    // Only the four central lines (x, y = +-0.3) end within 0.15 of the central area's points.
    CHECK(report.moved == 8);
    CHECK(report.halfway == 0);
    CHECK(report.three_quarters == 0);
    CHECK(report.kept == 24);
    CHECK(check(lattice, cube, areas).inverted_cells == 0);
  }
  SECTION("the reach is shorter than the end segment") {
    EndAlignmentOptions options;
    options.max_extension = 0.8;
    const EndAlignmentReport report = align_ends(lattice, lattice.system, query, areas, 0.3, options);
    CHECK(report.moved == 0);
    CHECK(report.halfway == 0);
    CHECK(report.three_quarters == 0);
    CHECK(report.kept == 32);
    CHECK(lattice.system.positions == start);
  }
  EndAlignmentOptions bad;
  bad.max_extension = 0.0;
  CHECK_THROWS_AS(align_ends(lattice, lattice.system, query, areas, 0.3, bad), OptionError);
}

TEST_CASE("ends whose moves would fold their cells are taken back together", "[fibres][align_ends]") {
  const TriangleMesh cube = make_cube(4.0, 8);
  const SurfaceQuery query(cube);
  const Attachments areas = cube_ends(query);
  // Shrunk to half, the central line (0.3, 0.3) continued lands on the diagonal of the cell
  // beside it, whose other end corners stay shrunk off the central area: that cell would flatten.
  springs::Lattice lattice = hooked_lattice(0.5);
  const Attachments centre = centres(areas);
  const EndAlignmentReport report = align_ends(lattice, lattice.system, query, centre, 0.15);
  CHECK(report.moved < 8);
  CHECK(report.moved + report.halfway + report.three_quarters + report.kept == 32);
  CHECK(check(lattice, cube, areas).inverted_cells == 0);
}
