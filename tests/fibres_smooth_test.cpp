// Fibres smoothed along themselves (fibres/smooth_fibres.h), on a straight lattice in a cube
// with zigzags put into its lines: the zigzag joints straighten, the joints below the threshold
// stay as they are, and no guard of the check is broken.
#include "fibres/smooth_fibres.h"
#include "fibres/fibre_check.h"
#include "fibres/fibre_grid.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "morph/attachments.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"

#include <catch2/catch.hpp>

using namespace fascicle;

namespace {

constexpr double kSize = 10.0;  // the cube, centred at the origin

/// A 6 x 6 x 9 lattice (4 x 4 interior lines) filling the middle of the cube: x, y in
/// [-3.75, 3.75], z in [-4.8, 4.8] (the ends 0.2 inside the end faces), 1.2 between layers.
springs::Lattice straight_lattice() {
  springs::LatticeOptions options;
  options.nr = 6;
  options.ns = 6;
  options.resolution = 9;
  springs::Lattice lattice = springs::build_lattice(options);
  REQUIRE(lattice.nz == 9);
  for (int k = 0; k < lattice.nz; ++k)
    for (int j = 0; j < lattice.ny; ++j)
      for (int i = 0; i < lattice.nx; ++i)
        lattice.system.positions[static_cast<std::size_t>(lattice.index(i, j, k))] =
            Vec3(-3.75 + 1.5 * i, -3.75 + 1.5 * j, -4.8 + 1.2 * k);
  return lattice;
}

Vec3& at(springs::Lattice& lattice, int i, int j, int k) {
  return lattice.system.positions[static_cast<std::size_t>(lattice.index(i, j, k))];
}

CheckReport check(const springs::Lattice& lattice, const TriangleMesh& cube) {
  CheckOptions options;
  options.coverage_samples = 200;
  return check_fibres(lattice_interior_fibres(lattice, lattice.system.positions), cube, automatic_attachments(cube),
                      options);
}

double end_tolerance(const TriangleMesh& mesh) {
  return CheckOptions{}.end_tolerance * bounding_box(mesh.positions).diagonal();
}

}  // namespace

TEST_CASE("a zigzag joint straightens below the threshold, joints under it stay, nothing folds", "[fibres][smooth]") {
  const TriangleMesh cube = make_cube(kSize, 4);
  const SurfaceQuery query(cube);
  springs::Lattice lattice = straight_lattice();
  // Line (2, 2): point 4 pushed 0.6 sideways (a joint of 2 x 26.6 = 53 degrees, two of 26.6);
  // line (3, 3): point 6 pushed 0.2 (a joint of 18.9 degrees, two of 9.5: under the threshold).
  at(lattice, 2, 2, 4).x() += 0.6;
  at(lattice, 3, 3, 6).y() += 0.2;
  const Vec3 small = at(lattice, 3, 3, 6);
  const CheckReport before = check(lattice, cube);
  REQUIRE(before.inverted_cells == 0);
  REQUIRE(before.turning.max_deg > 50.0);

  const FibreSmoothingReport report = smooth_fibres(lattice, lattice.system, query, end_tolerance(cube));
  CHECK(report.max_turning_before_deg == Approx(before.turning.max_deg));
  CHECK(report.max_turning_after_deg <= FibreSmoothingOptions{}.max_turning_deg);
  CHECK(report.moved >= 1);
  CHECK(at(lattice, 3, 3, 6) == small);  // its joints turn by less than the threshold
  const CheckReport after = check(lattice, cube);
  CHECK(after.turning.max_deg == Approx(report.max_turning_after_deg));
  CHECK(after.inverted_cells == 0);
  CHECK(after.inside_fraction == 1.0);
  CHECK(after.crossing_segments == 0);
  // The end points (on the attachment areas) never move.
  CHECK(at(lattice, 2, 2, 0) == Vec3(-0.75, -0.75, -4.8));
  CHECK(at(lattice, 2, 2, 8) == Vec3(-0.75, -0.75, 4.8));
}

TEST_CASE("smoothing with no steps leaves the lattice as it is, bad options are refused", "[fibres][smooth]") {
  const TriangleMesh cube = make_cube(kSize, 1);
  const SurfaceQuery query(cube);
  springs::Lattice lattice = straight_lattice();
  at(lattice, 2, 2, 4).x() += 0.6;
  const std::vector<Vec3> start = lattice.system.positions;
  FibreSmoothingOptions options;
  options.steps = 0;
  const FibreSmoothingReport report = smooth_fibres(lattice, lattice.system, query, end_tolerance(cube), options);
  CHECK(report.moved == 0);
  CHECK(lattice.system.positions == start);
  options = {};
  options.weight = 0.0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.max_turning_deg = 180.0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.steps = -1;
  CHECK_THROWS_AS(smooth_fibres(lattice, lattice.system, query, 0.1, options), OptionError);
}
