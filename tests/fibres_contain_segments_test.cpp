// Fibre segments that leave the muscle between their points, moved back inside
// (fibres/contain_segments.h), on a lattice bent round a half ring whose inner fibres' chords cut
// the inner wall: the geometry says which segments cross and by how much.
#include "fibres/contain_segments.h"
#include "fibres/fibre_check.h"
#include "fibres/fibre_grid.h"
#include "fibres/untangle_lattice.h"
#include "morph/attachments.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "morph/surface_query.h"
#include "springs/lattice.h"

#include <catch2/catch.hpp>

#include <cmath>

using namespace fascicle;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double R = 10.0, r = 2.0;  // the half ring: arc radius, tube radius

/// A 6 x 6 x 4 lattice (4 x 4 interior lines, the fibres) laid round the half ring: point
/// (i, j, k) at angle 0.01 + k (pi - 0.02) / 3, radial offset and height -w + 2 w i / 5 and
/// -w + 2 w j / 5. Consecutive layers are 60 degrees apart, so a segment of the innermost
/// fibres (radius R - 0.78) sags 9.22 (1 - cos 30 deg) = 1.24 towards the centre, past the inner
/// wall (R - 1.84 to R - 1.98 at their heights); the other fibres' segments stay inside.
springs::Lattice bent_lattice(double w = 1.3) {
  springs::LatticeOptions options;
  options.nr = 6;
  options.ns = 6;
  options.resolution = 4;
  springs::Lattice lattice = springs::build_lattice(options);
  REQUIRE(lattice.nx == 6);
  REQUIRE(lattice.ny == 6);
  REQUIRE(lattice.nz == 4);
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) {
        const double a = 0.01 + k * (kPi - 0.02) / 3.0;
        const double u = -w + 2.0 * w * i / 5.0, v = -w + 2.0 * w * j / 5.0;
        lattice.system.positions[static_cast<std::size_t>(lattice.index(i, j, k))] =
            Vec3((R + u) * std::cos(a), (R + u) * std::sin(a), v);
      }
  return lattice;
}

/// Fibre segments that leave the tube (the check's count) and inverted cells.
CheckReport check(const springs::Lattice& lattice, const TriangleMesh& tube) {
  CheckOptions options;
  options.coverage_samples = 200;
  return check_fibres(lattice_interior_fibres(lattice, lattice.system.positions), tube, automatic_attachments(tube),
                      options);
}

/// The segment contact the fibre check uses on `mesh` (its default tolerances).
SegmentContact check_contact(const TriangleMesh& mesh) {
  const double diagonal = bounding_box(mesh.positions).diagonal();
  const CheckOptions check_options;
  return {check_options.end_tolerance * diagonal, check_options.segment_tolerance * diagonal,
          check_options.excursion_samples, {}};
}

}  // namespace

TEST_CASE("segments cutting the inner wall of a bend are moved back inside without folding a cell",
          "[fibres][contain]") {
  const TriangleMesh tube = make_bent_tube(R, r, kPi, 64);
  const SurfaceQuery query(tube);
  springs::Lattice lattice = bent_lattice();
  const CheckReport before = check(lattice, tube);
  CHECK(before.inside_fraction == 1.0);
  CHECK(before.inverted_cells == 0);
  // The 4 innermost fibres (i = 1), 3 segments each.
  CHECK(before.touching_segments == 12);
  for (const CrossingSegment& c : before.crossing_examples) CHECK(c.fibre % 4 == 0);

  const std::vector<Vec3> start = lattice.system.positions;
  const double end_tolerance = CheckOptions{}.end_tolerance * bounding_box(tube.positions).diagonal();  // the check's
  const SegmentContainmentReport report = contain_segments(lattice, lattice.system, query, end_tolerance);
  CHECK(report.crossing_before == 12);
  CHECK(report.crossing_after == 0);
  CHECK(report.moved >= 4);
  const CheckReport after = check(lattice, tube);
  CHECK(after.touching_segments == 0);
  CHECK(after.inside_fraction == 1.0);
  CHECK(after.inverted_cells == 0);
  // Only free points moved (of the innermost lines, and of lines round them where a patch
  // moved), and only outwards from the bend's centre.
  for (int k = 0; k < lattice.nz; ++k)
    for (int j = 0; j < lattice.ny; ++j)
      for (int i = 0; i < lattice.nx; ++i) {
        const std::size_t q = static_cast<std::size_t>(lattice.index(i, j, k));
        const Vec3 d = lattice.system.positions[q] - start[q];
        if (lattice.system.fixed[q]) {
          CHECK(d.norm() == 0.0);
          continue;
        }
        const Vec3 radial(start[q].x(), start[q].y(), 0.0);
        CHECK(d.dot(radial) >= 0.0);
      }

  // Nothing to do: no move, no change.
  const std::vector<Vec3> settled = lattice.system.positions;
  const SegmentContainmentReport again = contain_segments(lattice, lattice.system, query, end_tolerance);
  CHECK(again.crossing_before == 0);
  CHECK(again.moved == 0);
  CHECK(lattice.system.positions == settled);
}

TEST_CASE("a segment move that would fold cells is undone", "[fibres][contain]") {
  // The lattice squeezed to a thin bundle (w = 0.3) and pushed against the inner wall: every
  // fibre's segments cross, by more than the spacing between fibres (0.12), so shifting one out
  // crosses its neighbour where that has not moved yet: such moves are undone, and no cell the
  // check counts is folded afterwards.
  const TriangleMesh tube = make_bent_tube(R, r, kPi, 64);
  const SurfaceQuery query(tube);
  springs::Lattice lattice = bent_lattice(0.3);
  for (Vec3& p : lattice.system.positions) {
    const double radius = std::hypot(p.x(), p.y());
    p.x() *= (radius - 1.5) / radius;
    p.y() *= (radius - 1.5) / radius;
  }
  const CheckReport before = check(lattice, tube);
  REQUIRE(before.inside_fraction == 1.0);
  REQUIRE(before.inverted_cells == 0);
  REQUIRE(before.touching_segments > 0);
  SegmentContainmentOptions options;
  options.max_shift = 100.0;  // let every move be tried
  const double end_tolerance = CheckOptions{}.end_tolerance * bounding_box(tube.positions).diagonal();
  const SegmentContainmentReport report = contain_segments(lattice, lattice.system, query, end_tolerance, options);
  const CheckReport after = check(lattice, tube);
  CHECK(after.inverted_cells == 0);
  CHECK(after.inside_fraction == 1.0);
  CHECK(report.crossing_before == before.touching_segments);
  CHECK(report.crossing_after == after.touching_segments);
  CHECK(report.rejected > 0);
}

TEST_CASE("segment containment options are validated", "[fibres][contain]") {
  SegmentContainmentOptions options;
  options.margin = 0.0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.sweeps = -1;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.samples = 0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.steps = 0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.patch_radius = -1;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.max_shift = 0.0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  CHECK_NOTHROW(SegmentContainmentOptions{}.validate());
}

TEST_CASE("the shifts of the leaving segments push their free points out of the bend, and count as the check does",
          "[fibres][contain]") {
  const TriangleMesh tube = make_bent_tube(R, r, kPi, 64);
  const SurfaceQuery query(tube);
  const springs::Lattice lattice = bent_lattice();
  const SegmentContact contact = check_contact(tube);
  CHECK(crossing_segment_count(lattice, lattice.system, query, contact) == check(lattice, tube).crossing_segments);
  CHECK(crossing_segment_count(lattice, lattice.system, query, contact) > 0);

  const auto shifts = leaving_segment_shifts(lattice, lattice.system, query, contact.end_tolerance);
  // The free points of the innermost lines (i = 1): interior lines j = 1..4, layers 1 and 2.
  CHECK(shifts.size() == 8);
  const double spacing = 2.0 * 1.3 / 5.0;
  for (const auto& [q, shift] : shifts) {
    const int i = q % lattice.nx;
    CHECK(i == 1);
    CHECK_FALSE(lattice.system.fixed[static_cast<std::size_t>(q)]);
    const Vec3& p = lattice.system.positions[static_cast<std::size_t>(q)];
    CHECK(shift.dot(Vec3(p.x(), p.y(), 0.0)) > 0.0);
    CHECK(shift.norm() > 0.0);
    CHECK(shift.norm() < 3.0 * 9.22 + spacing);  // at most max_shift local spacings
  }
  // Segments inside: nothing.
  springs::Lattice straight = bent_lattice(0.5);
  CHECK(leaving_segment_shifts(straight, straight.system, query, contact.end_tolerance).empty());
  CHECK(crossing_segment_count(straight, straight.system, query, contact) == 0);
}

TEST_CASE("the untangling's segment attempt holds the leaving segments in without folding a cell",
          "[fibres][contain][untangle]") {
  const TriangleMesh tube = make_bent_tube(R, r, kPi, 64);
  const SurfaceQuery query(tube);
  const SegmentContact contact = check_contact(tube);

  // Without segments there is nothing to unfold: the lattice stays as it is.
  springs::Lattice plain = bent_lattice();
  const std::vector<Vec3> start = plain.system.positions;
  const LatticeUntangleReport untouched = untangle_lattice(plain, plain.system, query, muscle_length(tube));
  CHECK(untouched.inverted_left == 0);
  CHECK_FALSE(untouched.segments_kept);
  CHECK(plain.system.positions == start);

  springs::Lattice lattice = bent_lattice();
  springs::SpringSystem unheld;
  const LatticeUntangleReport report =
      untangle_lattice(lattice, lattice.system, query, muscle_length(tube), {}, nullptr, &contact, &unheld);
  CHECK(report.crossing_before == check(plain, tube).crossing_segments);
  CHECK(report.crossing_before > 0);
  REQUIRE(report.segments_kept);
  CHECK(report.crossing_after == 0);
  CHECK(report.leaving_after < report.leaving_before);
  CHECK(report.inverted_left == 0);
  const CheckReport after = check(lattice, tube);
  CHECK(after.crossing_segments == 0);
  CHECK(after.inside_fraction == 1.0);
  CHECK(after.inverted_cells == 0);
  // The system before the attempt is handed back, and the fixed points never move.
  CHECK(unheld.positions == start);
  for (std::size_t q = 0; q < start.size(); ++q)
    if (plain.system.fixed[q]) CHECK(lattice.system.positions[q] == start[q]);
}

TEST_CASE("the segment attempt runs only where the caller says it can help", "[fibres][contain][untangle]") {
  const TriangleMesh tube = make_bent_tube(R, r, kPi, 64);
  const SurfaceQuery query(tube);
  const SegmentContact contact = check_contact(tube);
  for (const bool needed : {false, true}) {
    springs::Lattice lattice = bent_lattice();
    const std::vector<Vec3> start = lattice.system.positions;
    std::vector<Vec3> asked_with;
    int asked = 0;
    const LatticeUntangleReport report = untangle_lattice(
        lattice, lattice.system, query, muscle_length(tube), {}, nullptr, &contact, nullptr,
        [&](const springs::SpringSystem& untangled) {
          ++asked;
          asked_with = untangled.positions;
          return needed;
        });
    CAPTURE(needed);
    CHECK(report.crossing_before > 0);
    CHECK(asked == 1);
    CHECK(asked_with == start);  // the kept result: nothing was folded
    CHECK(report.segments_needed == needed);
    CHECK(report.segments_kept == needed);
    // Skipped, the lattice is the kept result and the report says the segments stayed out.
    if (!needed) {
      CHECK(lattice.system.positions == start);
      CHECK(report.crossing_after == report.crossing_before);
      CHECK(report.to_json().at("segments_needed") == false);
    }
  }
}
